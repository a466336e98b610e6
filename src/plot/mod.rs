//! Figures of the experiments (feature `plot`): line plots over time and image-plane trajectories, each written as
//! a PNG and an SVG file, ready for a paper.
//!
//! Three data-oriented figure descriptions cover the figures of the paper ([theory §9](crate::theory#s9)) and of
//! the convergence-domain study:
//!
//! * [`LinePlot`]: curves `y(x)` over time (or iterations) — normalised joint positions with the limits and the
//!   activation thresholds drawn as [`HorizontalLine`]s and the stack events (push / remove / reinsert of a task)
//!   as labelled vertical [`Marker`]s (Fig. 5–7), the criteria of each task (Fig. 8), task errors (optionally on a
//!   logarithmic y axis, [`Scale::Log10`]), the distance to an obstacle.
//! * [`TrajectoryPlot`]: x–y paths of image points in pixels (or normalised coordinates), with the image y axis
//!   pointing down as in a camera image, a circle at each start, a cross at each desired position and, as a
//!   [`Border`], the edge of the image.
//! * [`OutcomeMap`]: a grid of situations coloured by outcome, one panel per method.
//!
//! # Reading them without colour
//!
//! Curves differ in three ways at once: colour (the ten-colour Tableau palette), dash pattern (solid, dashed,
//! dash-dot, dash-dot-dot) and point marker (circle, square, triangle, diamond, plus, repeated along the curve at
//! staggered places): the first twenty curves differ in pattern or marker, so a grey-scale print keeps them apart.
//! Reference lines are dark grey, without markers, each with its own [`LinePattern`] (the report draws the joint
//! limits solid and the activation thresholds dotted, a pattern no curve uses); event markers are grey dashed
//! vertical lines.
//!
//! # Layout
//!
//! The legend is drawn in a strip to the right of the plotting area, so it never hides data; [`LinePlot::notes`]
//! go below it, wrapped to its width (the report explains there the task held in reserve, D23). Event labels are
//! drawn centred on their line in a band above the plotting area, each on the lowest row where it does not overlap
//! another label (and shifted inside the figure at its edges): the band has as many rows as close events need, so
//! labels never overlap. When that would take more than a quarter of the figure's height, the lines are numbered
//! in time order instead and the key ("Events: 1 push angle · 2 …") goes below the legend.
//!
//! # Size and resolution
//!
//! Every figure has a [`FigureStyle`]: a layout size `width × height` (default [`DEFAULT_SIZE`], 1024 × 640, from
//! [`MIN_SIZE`] to [`MAX_SIZE`]), the SVG's size in user units, and a `scale` for the PNG (default 1) that
//! multiplies its pixels, text, lines and margins alike — the same figure at a higher resolution.
//! [`FigureStyle::for_print`] sets both from a printed size in inches and a resolution in dots per inch.
//!
//! | option | default | effect |
//! |---|---|---|
//! | `width`, `height` | 1024, 640 | layout size: room for the data against the fixed text sizes (title 28 px, ticks 17 px) |
//! | `scale` | 1 | PNG pixels per layout pixel (2: a 2048 × 1280 PNG of the same figure); no effect on the SVG |
//!
//! # Font
//!
//! Text is rasterised by plotters' `ab_glyph` backend with DejaVu Sans embedded in the crate
//! (`assets/fonts/DejaVuSans.ttf`, Bitstream Vera / Arev license in `assets/fonts/LICENSE-DejaVu.txt`), so no
//! system font library (fontconfig, freetype) is needed. The font is registered once per process under the plotters
//! family name `"DejaVu Sans, Verdana, sans-serif"`, which the SVG files carry as a CSS font list.
//!
//! Invalid data is rejected before any file is touched: an empty figure or series, a non-finite coordinate, a
//! non-positive value on a logarithmic axis, an empty axis range, a size or scale out of range is a [`PlotError`],
//! never a panic.
//!
//! # Example
//!
//! ```
//! use servostack::plot::{FigureStyle, HorizontalLine, LinePattern, LinePlot, Marker, Series};
//!
//! let out_dir = std::env::temp_dir().join(format!("servostack-plot-doc-{}", std::process::id()));
//! let period = 0.01; // s
//! let time = |k: u32| f64::from(k) * period;
//! let joints = LinePlot {
//!     title: "Normalised joint positions".into(),
//!     x_label: "time (s)".into(),
//!     y_label: "(q - q_min) / (q_max - q_min)".into(),
//!     series: vec![
//!         Series::new("shoulder", (0..100).map(|k| (time(k), 0.5 + 0.004 * f64::from(k)))),
//!         Series::new("elbow", (0..100).map(|k| (time(k), 0.5 - 0.003 * f64::from(k)))),
//!     ],
//!     markers: vec![Marker::new(0.40, "push e2"), Marker::new(0.42, "remove e1")],
//!     horizontal_lines: vec![
//!         HorizontalLine::new(0.0, "limit").with_pattern(LinePattern::Solid),
//!         HorizontalLine::new(1.0, "limit").with_pattern(LinePattern::Solid),
//!         HorizontalLine::new(0.9, "activation").with_pattern(LinePattern::Dotted),
//!     ],
//!     x_range: Some((0.0, 100.0 * period)),
//!     y_range: Some((-0.1, 1.1)),
//!     // A column of a two-column paper, 300 dpi.
//!     style: FigureStyle::for_print(3.5, 2.4, 300.0),
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
mod stroke;
mod style;
#[cfg(test)]
pub(crate) mod tests;
mod trajectory;
mod validate;

pub use grid::OutcomeMap;
pub use line::{HorizontalLine, LinePlot, Marker, Scale, Series};
pub use style::{FigureStyle, LinePattern};
pub use trajectory::{Border, Trajectory, TrajectoryPlot};

use clip::*;
use render::*;
use stroke::*;
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

/// Default layout size of a figure in pixels (width, height) ([`FigureStyle`]); the SVG uses the same user units.
pub const DEFAULT_SIZE: (u32, u32) = (1024, 640);

/// Smallest accepted layout size in pixels (width, height): below it titles, labels and legend cannot fit.
pub const MIN_SIZE: (u32, u32) = (320, 240);

/// Largest accepted size in pixels (width, height), of the layout and of the PNG at its scale: 8192 × 8192 RGB
/// pixels are a 200 MB image buffer.
pub const MAX_SIZE: (u32, u32) = (8192, 8192);

/// Smallest accepted [`FigureStyle::scale`].
pub const MIN_SCALE: f64 = 0.25;

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
    /// The layout size of the figure is outside [`MIN_SIZE`]..=[`MAX_SIZE`].
    #[error(
        "figure size {width}x{height} px is outside {}x{} to {}x{} px",
        MIN_SIZE.0,
        MIN_SIZE.1,
        MAX_SIZE.0,
        MAX_SIZE.1
    )]
    InvalidSize {
        /// Layout width in pixels.
        width: u32,
        /// Layout height in pixels.
        height: u32,
    },
    /// The PNG scale is not finite, below [`MIN_SCALE`], or makes the PNG larger than [`MAX_SIZE`].
    #[error(
        "scale {scale} of a {width}x{height} px figure: expected at least {MIN_SCALE} and a PNG of at most {}x{} px",
        MAX_SIZE.0,
        MAX_SIZE.1
    )]
    InvalidScale {
        /// The rejected scale.
        scale: f64,
        /// Layout width in pixels.
        width: u32,
        /// Layout height in pixels.
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
