//! Figures of the experiments (feature `plot`): line plots over iterations and image-plane trajectories, each
//! written as a PNG and an SVG file.
//!
//! Two data-oriented figure descriptions cover the figures of the paper ([theory §9](crate::theory#s9)):
//!
//! * [`LinePlot`]: curves `y(x)` over iterations or time — normalised joint positions with the limits drawn as
//!   [`HorizontalLine`]s at 0 and 1 and the stack events (push / remove / reinsert of a task) as labelled vertical
//!   [`Marker`]s (Fig. 5–7), the criteria of each task (Fig. 8), task errors (optionally on a logarithmic y axis,
//!   [`Scale::Log10`]), the distance to an obstacle.
//! * [`TrajectoryPlot`]: x–y paths of image points in normalised coordinates (or pixels), with the image y axis
//!   pointing down as in a camera image, a circle at each start and a cross at each desired position.
//!
//! Colours cycle through the ten-colour Tableau palette (distinguishable up to ten series). The legend is drawn in
//! a strip to the right of the plotting area, so it never hides data; event labels are drawn in a band above the
//! plotting area, staggered over up to three rows so that neighbouring events stay readable.
//!
//! Text is rasterised by plotters' `ab_glyph` backend with DejaVu Sans embedded in the crate
//! (`assets/fonts/DejaVuSans.ttf`, Bitstream Vera / Arev license in `assets/fonts/LICENSE-DejaVu.txt`), so no
//! system font library (fontconfig, freetype) is needed. The font is registered once per process under the plotters
//! family name `"DejaVu Sans, Verdana, sans-serif"`, which the SVG files carry as a CSS font list.
//!
//! Invalid data is rejected before any file is touched: an empty figure or series, a non-finite coordinate, a
//! non-positive value on a logarithmic axis or an empty axis range is a [`PlotError`], never a panic.
//!
//! # Example
//!
//! ```
//! use servostack::plot::{HorizontalLine, LinePlot, Marker, Series};
//!
//! let out_dir = std::env::temp_dir().join(format!("servostack-plot-doc-{}", std::process::id()));
//! let joints = LinePlot {
//!     title: "Normalised joint positions".into(),
//!     x_label: "iteration".into(),
//!     y_label: "(q - q_min) / (q_max - q_min)".into(),
//!     series: vec![
//!         Series::new("q1", (0..100).map(|k| (k as f64, 0.5 + 0.004 * k as f64))),
//!         Series::new("q2", (0..100).map(|k| (k as f64, 0.5 - 0.003 * k as f64))),
//!     ],
//!     markers: vec![Marker::new(40.0, "push e2"), Marker::new(70.0, "remove e1")],
//!     horizontal_lines: vec![
//!         HorizontalLine::new(0.0, "joint limits"),
//!         HorizontalLine::new(1.0, "joint limits"),
//!     ],
//!     y_range: Some((-0.1, 1.1)),
//!     ..LinePlot::default()
//! };
//! let files = joints.render(&out_dir, "joints")?;
//! assert!(files.png.exists() && files.svg.exists());
//! # std::fs::remove_dir_all(&out_dir).ok();
//! # Ok::<(), servostack::plot::PlotError>(())
//! ```

mod clip;
mod grid;
mod line;
mod render;
mod style;
#[cfg(test)]
mod tests;
mod trajectory;
mod validate;

pub use grid::OutcomeMap;
pub use line::{HorizontalLine, LinePlot, Marker, Scale, Series};
pub use trajectory::{Trajectory, TrajectoryPlot};

use clip::*;
use render::*;
use style::*;
use validate::*;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::combinators::IntoLogRange;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle};

/// Default figure size in pixels (width, height); the SVG uses the same user units.
pub const DEFAULT_SIZE: (u32, u32) = (1024, 640);

/// Smallest accepted figure size in pixels (width, height): below it titles, labels and legend cannot fit.
pub const MIN_SIZE: (u32, u32) = (320, 240);

/// Errors of figure validation and rendering.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PlotError {
    /// The figure has no series or trajectory to draw.
    #[error("figure {figure:?} has no data series")]
    NoSeries {
        /// Title of the figure.
        figure: String,
    },
    /// A series or trajectory has no points.
    #[error("series {series:?} has no points")]
    EmptySeries {
        /// Name of the series.
        series: String,
    },
    /// A point (of a series, a marker, a reference line or a desired position) is NaN or infinite.
    #[error("{item:?}: point {index} ({x}, {y}) is not finite")]
    NonFinite {
        /// Name of the series, or label of the marker / reference line.
        item: String,
        /// Index of the point in its series (0 for single-point items).
        index: usize,
        /// Abscissa of the point.
        x: f64,
        /// Ordinate of the point.
        y: f64,
    },
    /// A value drawn on a logarithmic axis is zero or negative.
    #[error("{item:?}: point {index} has y = {y}, not positive on a logarithmic axis")]
    NonPositiveOnLogAxis {
        /// Name of the series, or label of the reference line.
        item: String,
        /// Index of the point in its series.
        index: usize,
        /// The offending ordinate.
        y: f64,
    },
    /// An explicit axis range is not finite, empty or reversed, or not positive on a logarithmic axis.
    #[error("invalid {axis} range [{min}, {max}]")]
    InvalidRange {
        /// `"x"` or `"y"`.
        axis: &'static str,
        /// Lower end.
        min: f64,
        /// Upper end.
        max: f64,
    },
    /// The figure size is smaller than [`MIN_SIZE`].
    #[error("figure size {width}x{height} px is below the minimum {}x{} px", MIN_SIZE.0, MIN_SIZE.1)]
    InvalidSize {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    /// The file stem is empty or is not a plain file name (it contains a path separator or `..`).
    #[error("invalid file stem {stem:?}: expected a plain file name without extension")]
    InvalidStem {
        /// The rejected stem.
        stem: String,
    },
    /// The embedded font could not be registered with plotters.
    #[error("the embedded DejaVu Sans font could not be loaded")]
    Font,
    /// A file-system operation failed.
    #[error("I/O error on {path:?}: {message}")]
    Io {
        /// The path being created or written.
        path: PathBuf,
        /// Kind of the underlying I/O error.
        kind: std::io::ErrorKind,
        /// Message of the underlying I/O error.
        message: String,
    },
    /// Plotters failed while drawing or writing the figure.
    #[error("drawing {path:?} failed: {message}")]
    Draw {
        /// The output file.
        path: PathBuf,
        /// Message of the plotters error.
        message: String,
    },
}

/// Paths of the files written by a `render` call.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RenderedFiles {
    /// The PNG image.
    pub png: PathBuf,
    /// The SVG image.
    pub svg: PathBuf,
}
