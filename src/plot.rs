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

/// The embedded font (DejaVu Sans 2.37, Bitstream Vera / Arev license).
const FONT_BYTES: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");
/// Plotters family name of the embedded font; the SVG backend writes it verbatim as a CSS `font-family` list.
const FONT_FAMILY: &str = "DejaVu Sans, Verdana, sans-serif";

const TITLE_FONT_PX: f64 = 28.0;
const AXIS_DESC_FONT_PX: f64 = 22.0;
const TICK_FONT_PX: f64 = 17.0;
const LEGEND_FONT_PX: f64 = 18.0;
const EVENT_FONT_PX: f64 = 16.0;

const MARGIN_PX: u32 = 16;
const X_LABEL_AREA_PX: u32 = 60;
const Y_LABEL_AREA_PX: u32 = 90;
/// Rows of the band above the plotting area that holds the event labels.
const EVENT_ROWS: u32 = 3;
const EVENT_ROW_PX: u32 = 20;
const LEGEND_ROW_PX: i32 = 30;
const LEGEND_SWATCH_PX: i32 = 36;
const SERIES_STROKE_PX: u32 = 2;

/// Tableau 10 palette (the matplotlib default cycle).
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];
const REFERENCE_COLOR: RGBColor = RGBColor(40, 40, 40);
const EVENT_COLOR: RGBColor = RGBColor(110, 110, 110);
const GRID_BOLD: RGBColor = RGBColor(215, 215, 215);
const GRID_LIGHT: RGBColor = RGBColor(240, 240, 240);

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

/// A named curve: points `(x, y)` joined in order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    /// Legend entry.
    pub name: String,
    /// Points `(x, y)` in data units, drawn in order.
    pub points: Vec<(f64, f64)>,
}

impl Series {
    /// A series from its legend name and points.
    pub fn new(name: impl Into<String>, points: impl IntoIterator<Item = (f64, f64)>) -> Self {
        Self {
            name: name.into(),
            points: points.into_iter().collect(),
        }
    }
}

/// A labelled vertical line at abscissa `x`, e.g. a stack event (push, remove or reinsertion of a task).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Marker {
    /// Abscissa in data units.
    pub x: f64,
    /// Label drawn above the plotting area.
    pub label: String,
}

impl Marker {
    /// A marker at `x` with its label.
    pub fn new(x: f64, label: impl Into<String>) -> Self {
        Self {
            x,
            label: label.into(),
        }
    }
}

/// A dashed horizontal reference line at ordinate `y`, e.g. a joint limit. Lines sharing a label share one legend
/// entry.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct HorizontalLine {
    /// Ordinate in data units.
    pub y: f64,
    /// Legend entry.
    pub label: String,
}

impl HorizontalLine {
    /// A reference line at `y` with its legend label.
    pub fn new(y: f64, label: impl Into<String>) -> Self {
        Self {
            y,
            label: label.into(),
        }
    }
}

/// Scale of the y axis of a [`LinePlot`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Scale {
    /// Linear axis.
    #[default]
    Linear,
    /// Logarithmic axis (decades); every drawn value must be strictly positive.
    Log10,
}

impl Scale {
    /// The coordinate in which the axis is linear on screen.
    fn screen(self, v: f64) -> f64 {
        match self {
            Scale::Linear => v,
            Scale::Log10 => v.log10(),
        }
    }

    /// Inverse of [`Scale::screen`].
    fn unscreen(self, s: f64) -> f64 {
        match self {
            Scale::Linear => s,
            Scale::Log10 => 10f64.powf(s),
        }
    }
}

/// Curves over a common abscissa (iterations or time) with reference lines and event markers.
///
/// Build it with struct-update syntax from [`LinePlot::default`] and call [`LinePlot::render`].
#[derive(Debug, Clone, PartialEq)]
pub struct LinePlot {
    /// Title above the figure.
    pub title: String,
    /// Description of the x axis (with units).
    pub x_label: String,
    /// Description of the y axis (with units).
    pub y_label: String,
    /// The curves, coloured in order from the palette.
    pub series: Vec<Series>,
    /// Labelled vertical lines (stack events); those outside the x range are not drawn.
    pub markers: Vec<Marker>,
    /// Dashed horizontal reference lines (limits, thresholds); those outside the y range are not drawn.
    pub horizontal_lines: Vec<HorizontalLine>,
    /// Explicit x range, outside which curves are clipped; `None` fits the series and markers.
    pub x_range: Option<(f64, f64)>,
    /// Explicit y range, outside which curves are clipped; `None` fits the series and reference lines with a 5 %
    /// margin (of the decades spanned, on a log axis).
    pub y_range: Option<(f64, f64)>,
    /// Scale of the y axis.
    pub y_scale: Scale,
    /// Size in pixels (width, height), at least [`MIN_SIZE`].
    pub size: (u32, u32),
}

impl Default for LinePlot {
    fn default() -> Self {
        Self {
            title: String::new(),
            x_label: String::new(),
            y_label: String::new(),
            series: Vec::new(),
            markers: Vec::new(),
            horizontal_lines: Vec::new(),
            x_range: None,
            y_range: None,
            y_scale: Scale::Linear,
            size: DEFAULT_SIZE,
        }
    }
}

/// The path of one point in the plane, with its optional desired (goal) position.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    /// Legend entry.
    pub name: String,
    /// Points `(x, y)` in data units, in time order; the first one is marked as the start.
    pub points: Vec<(f64, f64)>,
    /// Desired position, marked with a cross.
    pub desired: Option<(f64, f64)>,
}

impl Trajectory {
    /// A trajectory from its legend name, points and desired position.
    pub fn new(
        name: impl Into<String>,
        points: impl IntoIterator<Item = (f64, f64)>,
        desired: Option<(f64, f64)>,
    ) -> Self {
        Self {
            name: name.into(),
            points: points.into_iter().collect(),
            desired,
        }
    }
}

/// Paths in the plane, e.g. image points in normalised coordinates `x = X/Z`, `y = Y/Z` (camera frame: x right,
/// y down) or in pixels.
///
/// Build it with struct-update syntax from [`TrajectoryPlot::default`] and call [`TrajectoryPlot::render`].
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryPlot {
    /// Title above the figure.
    pub title: String,
    /// Description of the x axis (with units).
    pub x_label: String,
    /// Description of the y axis (with units).
    pub y_label: String,
    /// The paths, coloured in order from the palette.
    pub trajectories: Vec<Trajectory>,
    /// Explicit x range (e.g. the image bounds), outside which paths are clipped and start / desired markers
    /// hidden; `None` fits the data with a 5 % margin.
    pub x_range: Option<(f64, f64)>,
    /// Explicit y range, as `x_range`.
    pub y_range: Option<(f64, f64)>,
    /// Draw y increasing downwards, as in a camera image (default `true`).
    pub y_down: bool,
    /// Widen the x or y range about its centre so that one data unit spans as many pixels on both axes
    /// (default `true`).
    pub equal_aspect: bool,
    /// Size in pixels (width, height), at least [`MIN_SIZE`].
    pub size: (u32, u32),
}

impl Default for TrajectoryPlot {
    fn default() -> Self {
        Self {
            title: String::new(),
            x_label: String::new(),
            y_label: String::new(),
            trajectories: Vec::new(),
            x_range: None,
            y_range: None,
            y_down: true,
            equal_aspect: true,
            size: DEFAULT_SIZE,
        }
    }
}

/// Paths of the files written by a `render` call.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RenderedFiles {
    /// The PNG image.
    pub png: PathBuf,
    /// The SVG image.
    pub svg: PathBuf,
}

impl LinePlot {
    /// Validates the figure and writes `out_dir/stem.png` and `out_dir/stem.svg`, creating `out_dir` if needed.
    ///
    /// # Errors
    /// [`PlotError::NoSeries`], [`PlotError::EmptySeries`], [`PlotError::NonFinite`] (series points, marker
    /// abscissae, reference-line ordinates), [`PlotError::NonPositiveOnLogAxis`] (with [`Scale::Log10`]),
    /// [`PlotError::InvalidRange`], [`PlotError::InvalidSize`], [`PlotError::InvalidStem`] before any file is
    /// written; [`PlotError::Io`], [`PlotError::Draw`] or [`PlotError::Font`] while writing.
    pub fn render(&self, out_dir: &Path, stem: &str) -> Result<RenderedFiles, PlotError> {
        let prepared = self.prepare()?;
        render_files(&prepared, self.size, out_dir, stem)
    }

    fn prepare(&self) -> Result<PreparedLines<'_>, PlotError> {
        check_size(self.size)?;
        if self.series.is_empty() {
            return Err(PlotError::NoSeries {
                figure: self.title.clone(),
            });
        }
        let log = self.y_scale == Scale::Log10;
        let mut bounds = Bounds::default();
        for series in &self.series {
            check_points(&series.name, &series.points, log)?;
            series.points.iter().for_each(|&p| bounds.include(p));
        }
        for line in &self.horizontal_lines {
            check_points(&line.label, &[(0.0, line.y)], log)?;
            bounds.include_y(line.y);
        }
        for marker in &self.markers {
            check_points(&marker.label, &[(marker.x, 0.0)], false)?;
            bounds.include_x(marker.x);
        }
        let x = axis_range("x", self.x_range, bounds.x, Scale::Linear)?;
        let y = axis_range("y", self.y_range, bounds.y, self.y_scale)?;
        Ok(PreparedLines { plot: self, x, y })
    }
}

impl TrajectoryPlot {
    /// Validates the figure and writes `out_dir/stem.png` and `out_dir/stem.svg`, creating `out_dir` if needed.
    ///
    /// # Errors
    /// [`PlotError::NoSeries`], [`PlotError::EmptySeries`], [`PlotError::NonFinite`] (points and desired
    /// positions), [`PlotError::InvalidRange`], [`PlotError::InvalidSize`], [`PlotError::InvalidStem`] before any
    /// file is written; [`PlotError::Io`], [`PlotError::Draw`] or [`PlotError::Font`] while writing.
    pub fn render(&self, out_dir: &Path, stem: &str) -> Result<RenderedFiles, PlotError> {
        let prepared = self.prepare()?;
        render_files(&prepared, self.size, out_dir, stem)
    }

    fn prepare(&self) -> Result<PreparedTrajectories<'_>, PlotError> {
        check_size(self.size)?;
        if self.trajectories.is_empty() {
            return Err(PlotError::NoSeries {
                figure: self.title.clone(),
            });
        }
        let mut bounds = Bounds::default();
        for trajectory in &self.trajectories {
            check_points(&trajectory.name, &trajectory.points, false)?;
            trajectory.points.iter().for_each(|&p| bounds.include(p));
            if let Some(desired) = trajectory.desired {
                check_points(&trajectory.name, &[desired], false)?;
                bounds.include(desired);
            }
        }
        let x = axis_range("x", self.x_range, bounds.x, Scale::Linear)?;
        let y = axis_range("y", self.y_range, bounds.y, Scale::Linear)?;
        Ok(PreparedTrajectories { plot: self, x, y })
    }
}

/// Data extent `(min, max)` on each axis, `None` until a value is included.
#[derive(Debug, Default)]
struct Bounds {
    x: Option<(f64, f64)>,
    y: Option<(f64, f64)>,
}

impl Bounds {
    fn include(&mut self, (x, y): (f64, f64)) {
        self.include_x(x);
        self.include_y(y);
    }
    fn include_x(&mut self, x: f64) {
        self.x = Some(extend(self.x, x));
    }
    fn include_y(&mut self, y: f64) {
        self.y = Some(extend(self.y, y));
    }
}

fn extend(range: Option<(f64, f64)>, v: f64) -> (f64, f64) {
    range.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v)))
}

fn check_size((width, height): (u32, u32)) -> Result<(), PlotError> {
    if width < MIN_SIZE.0 || height < MIN_SIZE.1 {
        return Err(PlotError::InvalidSize { width, height });
    }
    Ok(())
}

/// Rejects an empty point list, non-finite coordinates and, on a log axis, non-positive ordinates.
fn check_points(item: &str, points: &[(f64, f64)], log_y: bool) -> Result<(), PlotError> {
    if points.is_empty() {
        return Err(PlotError::EmptySeries {
            series: item.to_owned(),
        });
    }
    for (index, &(x, y)) in points.iter().enumerate() {
        if !(x.is_finite() && y.is_finite()) {
            return Err(PlotError::NonFinite {
                item: item.to_owned(),
                index,
                x,
                y,
            });
        }
        if log_y && y <= 0.0 {
            return Err(PlotError::NonPositiveOnLogAxis {
                item: item.to_owned(),
                index,
                y,
            });
        }
    }
    Ok(())
}

/// The drawn range of one axis: the explicit one if given (validated), else the data extent with a margin.
fn axis_range(
    axis: &'static str,
    explicit: Option<(f64, f64)>,
    data: Option<(f64, f64)>,
    scale: Scale,
) -> Result<(f64, f64), PlotError> {
    if let Some((min, max)) = explicit {
        let positive = scale == Scale::Linear || min > 0.0;
        if !(min.is_finite() && max.is_finite() && min < max && positive) {
            return Err(PlotError::InvalidRange { axis, min, max });
        }
        return Ok((min, max));
    }
    // Validation guarantees at least one finite point on each axis; (0, 1) only guards the unreachable case.
    let (lo, hi) = data.unwrap_or((0.0, 1.0));
    Ok(match scale {
        Scale::Linear => {
            let span = hi - lo;
            let pad = if span > f64::EPSILON * lo.abs().max(hi.abs()) {
                0.05 * span
            } else if lo == 0.0 {
                0.5
            } else {
                0.1 * lo.abs()
            };
            (lo - pad, hi + pad)
        }
        Scale::Log10 => {
            // Half a decade around a constant, else 5 % of the span in decades.
            let decades = (hi / lo).log10();
            let pad = if decades > 1e-9 { 0.05 * decades } else { 0.5 };
            (lo / 10f64.powf(pad), hi * 10f64.powf(pad))
        }
    })
}

fn check_stem(stem: &str) -> Result<(), PlotError> {
    let plain = !stem.is_empty()
        && stem != "."
        && stem != ".."
        && Path::new(stem).file_name().and_then(|n| n.to_str()) == Some(stem);
    if plain {
        Ok(())
    } else {
        Err(PlotError::InvalidStem {
            stem: stem.to_owned(),
        })
    }
}

/// Registers the embedded font with plotters, once per process.
fn ensure_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED
        .get_or_init(|| register_font(FONT_FAMILY, FontStyle::Normal, FONT_BYTES).is_ok());
    if ok {
        Ok(())
    } else {
        Err(PlotError::Font)
    }
}

/// The embedded font at `size` pixels.
fn font(size: f64) -> TextStyle<'static> {
    (FONT_FAMILY, size).into_text_style(&(0u32, 0u32))
}

/// A pixel-addressed drawing area of backend `DB`.
type Area<DB> = DrawingArea<DB, Shift>;
/// Result of drawing on backend `DB`.
type Drawn<DB, T = ()> = Result<T, DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// A validated figure that can draw itself on any plotters backend.
trait Draw {
    fn title(&self) -> &str;
    fn draw_body<DB: DrawingBackend>(&self, area: &Area<DB>) -> Drawn<DB>;
}

/// Fills the background, draws the title and the body.
fn draw_figure<DB: DrawingBackend, F: Draw>(figure: &F, root: &Area<DB>) -> Drawn<DB> {
    root.fill(&WHITE)?;
    let body = if figure.title().is_empty() {
        root.clone()
    } else {
        root.margin(10, 0, 0, 0)
            .titled(figure.title(), font(TITLE_FONT_PX))?
    };
    figure.draw_body(&body)?;
    root.present()
}

/// Draws `figure` on `area`, mapping a plotters failure to [`PlotError::Draw`] naming `path`.
fn draw_file<DB: DrawingBackend, F: Draw>(
    figure: &F,
    area: Area<DB>,
    path: &Path,
) -> Result<(), PlotError> {
    draw_figure(figure, &area).map_err(|e| PlotError::Draw {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Validates the stem, registers the font, creates `out_dir` and writes `stem.png` and `stem.svg`.
fn render_files<F: Draw>(
    figure: &F,
    size: (u32, u32),
    out_dir: &Path,
    stem: &str,
) -> Result<RenderedFiles, PlotError> {
    check_stem(stem)?;
    ensure_font()?;
    std::fs::create_dir_all(out_dir).map_err(|e| PlotError::Io {
        path: out_dir.to_path_buf(),
        kind: e.kind(),
        message: e.to_string(),
    })?;
    let files = RenderedFiles {
        png: out_dir.join(format!("{stem}.png")),
        svg: out_dir.join(format!("{stem}.svg")),
    };
    draw_file(
        figure,
        BitMapBackend::new(&files.png, size).into_drawing_area(),
        &files.png,
    )?;
    draw_file(
        figure,
        SVGBackend::new(&files.svg, size).into_drawing_area(),
        &files.svg,
    )?;
    Ok(files)
}

/// The sample drawn next to a legend label.
#[derive(Debug, Clone, Copy)]
enum Swatch {
    Line(RGBColor),
    Dashed(RGBColor),
    Circle(RGBColor),
    Cross(RGBColor),
}

struct LegendEntry<'a> {
    label: &'a str,
    swatch: Swatch,
}

/// Width in pixels of the legend strip holding `entries`.
fn legend_width<DB: DrawingBackend>(
    area: &Area<DB>,
    entries: &[LegendEntry<'_>],
) -> Drawn<DB, u32> {
    let style = font(LEGEND_FONT_PX);
    let mut text = 0;
    for entry in entries {
        text = text.max(area.estimate_text_size(entry.label, &style)?.0);
    }
    let wanted = text + LEGEND_SWATCH_PX.unsigned_abs() + 3 * MARGIN_PX / 2;
    Ok(wanted.min(area.dim_in_pixel().0 * 2 / 5))
}

/// Draws the legend entries top-down from pixel row `top` of `area`.
fn draw_legend<DB: DrawingBackend>(
    area: &Area<DB>,
    entries: &[LegendEntry<'_>],
    top: i32,
) -> Drawn<DB> {
    let style = font(LEGEND_FONT_PX).pos(Pos::new(HPos::Left, VPos::Center));
    let x0 = 4;
    let x1 = x0 + LEGEND_SWATCH_PX - 8;
    let xc = (x0 + x1) / 2;
    for (row, entry) in (0..).zip(entries) {
        let y = top + LEGEND_ROW_PX / 2 + row * LEGEND_ROW_PX;
        match entry.swatch {
            Swatch::Line(color) => {
                area.draw(&PathElement::new(
                    [(x0, y), (x1, y)],
                    color.stroke_width(SERIES_STROKE_PX + 1),
                ))?;
            }
            Swatch::Dashed(color) => {
                for dash in [x0, x0 + 11, x0 + 22] {
                    area.draw(&PathElement::new(
                        [(dash, y), (dash + 6, y)],
                        color.stroke_width(2),
                    ))?;
                }
            }
            Swatch::Circle(color) => area.draw(&Circle::new((xc, y), 6, color.stroke_width(2)))?,
            Swatch::Cross(color) => area.draw(&Cross::new((xc, y), 6, color.stroke_width(3)))?,
        }
        area.draw(&Text::new(
            entry.label,
            (x0 + LEGEND_SWATCH_PX, y),
            style.clone(),
        ))?;
    }
    Ok(())
}

/// Splits off the legend strip on the right of `body`; returns (chart area, legend area).
fn split_legend<DB: DrawingBackend>(
    body: &Area<DB>,
    entries: &[LegendEntry<'_>],
) -> Drawn<DB, (Area<DB>, Area<DB>)> {
    let width = legend_width(body, entries)?;
    Ok(body.split_horizontally(body.dim_in_pixel().0.saturating_sub(width)))
}

fn chart_builder<'a, 'b, DB: DrawingBackend>(
    area: &'a Area<DB>,
    top: u32,
) -> ChartBuilder<'a, 'b, DB> {
    let mut builder = ChartBuilder::on(area);
    builder
        .margin_top(top)
        .margin_bottom(MARGIN_PX)
        .margin_left(MARGIN_PX)
        .margin_right(MARGIN_PX)
        .x_label_area_size(X_LABEL_AREA_PX)
        .y_label_area_size(Y_LABEL_AREA_PX);
    builder
}

/// Draws grid, ticks (labelled by [`format_tick`]; the y labels multiplied by `y_sign`) and axis descriptions.
/// Near-zero snapping of the tick labels applies to linear axes only: a log axis has no zero.
fn draw_mesh<DB: DrawingBackend, X, Y>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<X, Y>>,
    x_label: &str,
    y_label: &str,
    y_sign: f64,
    y_scale: Scale,
) -> Drawn<DB>
where
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    let span = |r: std::ops::Range<f64>| (r.end - r.start).abs();
    let x_span = span(chart.x_range());
    let y_span = match y_scale {
        Scale::Linear => span(chart.y_range()),
        Scale::Log10 => 0.0,
    };
    let x_format = |v: &f64| format_tick(*v, x_span);
    let y_format = |v: &f64| format_tick(y_sign * *v, y_span);
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .axis_desc_style(font(AXIS_DESC_FONT_PX))
        .label_style(font(TICK_FONT_PX))
        .bold_line_style(GRID_BOLD)
        .light_line_style(GRID_LIGHT)
        .x_labels(10)
        .y_labels(8)
        .x_label_formatter(&x_format)
        .y_label_formatter(&y_format)
        .draw()
}

/// Tick label of `v` on an axis spanning `span` data units: `0` for values within `1e-9 span` of zero (rounding
/// residue of the tick computation), 8 significant digits without trailing zeros, scientific notation (`1e-6`,
/// `2.5e7`) outside `[1e-3, 1e6)`.
fn format_tick(v: f64, span: f64) -> String {
    if v.abs() <= 1e-9 * span || v == 0.0 {
        return "0".to_owned();
    }
    let scientific = format!("{v:.7e}");
    let Some((mantissa, exponent)) = scientific.split_once('e') else {
        return scientific;
    };
    let exponent: i32 = exponent.parse().unwrap_or(0);
    if (-3..=5).contains(&exponent) {
        let decimals = usize::try_from(7 - exponent).unwrap_or(0);
        trim_fraction(&format!("{v:.decimals$}")).to_owned()
    } else {
        format!("{}e{exponent}", trim_fraction(mantissa))
    }
}

/// Drops trailing zeros of a decimal fraction, and the point if nothing remains after it.
fn trim_fraction(number: &str) -> &str {
    if number.contains('.') {
        number.trim_end_matches('0').trim_end_matches('.')
    } else {
        number
    }
}

/// Whether `v` lies in the closed interval `range`.
fn within(v: f64, (lo, hi): (f64, f64)) -> bool {
    lo <= v && v <= hi
}

/// The runs of the polyline `points` inside the box `x_range × y_range`, each segment cut at the border.
///
/// Plotters clamps out-of-range coordinates onto the border, which would draw false flat lines there, so data
/// outside an explicit range is clipped here instead. Segments are straight on screen, so they are cut in display
/// coordinates (`log10 y` on a [`Scale::Log10`] axis, whose values validation keeps positive).
fn clip_polyline(
    points: &[(f64, f64)],
    x_range: (f64, f64),
    y_range: (f64, f64),
    y_scale: Scale,
) -> Vec<Vec<(f64, f64)>> {
    let y_screen = (y_scale.screen(y_range.0), y_scale.screen(y_range.1));
    let mut runs: Vec<Vec<(f64, f64)>> = Vec::new();
    if let [only] = points {
        if within(only.0, x_range) && within(only.1, y_range) {
            runs.push(vec![*only]);
        }
        return runs;
    }
    // Whether the last run ends at the start of the current segment.
    let mut open = false;
    for pair in points.windows(2) {
        let &[a, b] = pair else { continue };
        let ((xa, ya), (xb, yb)) = ((a.0, y_scale.screen(a.1)), (b.0, y_scale.screen(b.1)));
        // A segment touching the box in one point draws nothing.
        let Some((t0, t1)) =
            clip_segment((xa, ya), (xb, yb), x_range, y_screen).filter(|(t0, t1)| t0 < t1)
        else {
            open = false;
            continue;
        };
        // Kept endpoints are copied exactly; cut points are interpolated on screen.
        let at = |t: f64| match t {
            0.0 => a,
            1.0 => b,
            _ => (xa + t * (xb - xa), y_scale.unscreen(ya + t * (yb - ya))),
        };
        match runs.last_mut() {
            Some(run) if open && t0 == 0.0 => run.push(at(t1)),
            _ => runs.push(vec![at(t0), at(t1)]),
        }
        open = t1 == 1.0;
    }
    runs
}

/// Liang–Barsky: the parameter interval `[t0, t1] ⊂ [0, 1]` of the segment `a + t (b - a)` inside the box, if any.
fn clip_segment(
    a: (f64, f64),
    b: (f64, f64),
    x_range: (f64, f64),
    y_range: (f64, f64),
) -> Option<(f64, f64)> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
    // Each constraint p t <= q keeps the point on the inner side of one border.
    for (p, q) in [
        (-dx, a.0 - x_range.0),
        (dx, x_range.1 - a.0),
        (-dy, a.1 - y_range.0),
        (dy, y_range.1 - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else if p < 0.0 {
            t0 = t0.max(q / p);
        } else {
            t1 = t1.min(q / p);
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

struct PreparedLines<'a> {
    plot: &'a LinePlot,
    x: (f64, f64),
    y: (f64, f64),
}

impl PreparedLines<'_> {
    fn legend(&self) -> Vec<LegendEntry<'_>> {
        let mut entries: Vec<LegendEntry<'_>> = self
            .plot
            .series
            .iter()
            .zip(PALETTE.iter().cycle())
            .map(|(s, &color)| LegendEntry {
                label: &s.name,
                swatch: Swatch::Line(color),
            })
            .collect();
        for (k, line) in self.plot.horizontal_lines.iter().enumerate() {
            let seen = self.plot.horizontal_lines[..k]
                .iter()
                .any(|other| other.label == line.label);
            if !seen {
                entries.push(LegendEntry {
                    label: &line.label,
                    swatch: Swatch::Dashed(REFERENCE_COLOR),
                });
            }
        }
        entries
    }

    /// Builds the chart on `area` with the y coordinate `y_spec` (linear or logarithmic) and draws everything.
    fn draw_chart<DB: DrawingBackend, Y>(&self, area: &Area<DB>, y_spec: Y) -> Drawn<DB, i32>
    where
        Y: AsRangedCoord<Value = f64>,
        Y::CoordDescType: ValueFormatter<f64>,
    {
        let plot = self.plot;
        let top = if plot.markers.is_empty() {
            MARGIN_PX
        } else {
            MARGIN_PX + EVENT_ROWS * EVENT_ROW_PX
        };
        let mut chart = chart_builder(area, top).build_cartesian_2d(self.x.0..self.x.1, y_spec)?;
        draw_mesh(&mut chart, &plot.x_label, &plot.y_label, 1.0, plot.y_scale)?;

        let dashed = |points: [(f64, f64); 2], color: RGBColor| {
            DashedLineSeries::new(points, 8, 6, color.stroke_width(2))
        };
        for line in plot.horizontal_lines.iter().filter(|l| within(l.y, self.y)) {
            chart.draw_series(dashed(
                [(self.x.0, line.y), (self.x.1, line.y)],
                REFERENCE_COLOR,
            ))?;
        }
        let markers: Vec<&Marker> = plot
            .markers
            .iter()
            .filter(|m| within(m.x, self.x))
            .collect();
        for marker in &markers {
            chart.draw_series(dashed(
                [(marker.x, self.y.0), (marker.x, self.y.1)],
                EVENT_COLOR,
            ))?;
        }
        for (series, &color) in plot.series.iter().zip(PALETTE.iter().cycle()) {
            for run in clip_polyline(&series.points, self.x, self.y, plot.y_scale) {
                chart.draw_series(LineSeries::new(run, color.stroke_width(SERIES_STROKE_PX)))?;
            }
        }

        let (_, plot_top) = chart.plotting_area().get_base_pixel();
        let (base_x, base_y) = area.get_base_pixel();
        let mut labels: Vec<(i32, &str)> = markers
            .iter()
            .map(|m| {
                (
                    chart.backend_coord(&(m.x, self.y.1)).0 - base_x,
                    m.label.as_str(),
                )
            })
            .collect();
        draw_event_labels(area, &mut labels, plot_top - base_y)?;
        Ok(plot_top - base_y)
    }
}

/// Draws each `(pixel column, label)` centred on its column, in the band just above pixel row `plot_top` of
/// `area`, on the lowest of [`EVENT_ROWS`] rows where it does not overlap the labels already placed from the left
/// (on the row that ends leftmost when none is free).
fn draw_event_labels<DB: DrawingBackend>(
    area: &Area<DB>,
    labels: &mut [(i32, &str)],
    plot_top: i32,
) -> Drawn<DB> {
    const GAP_PX: i32 = 6;
    let style = font(EVENT_FONT_PX)
        .color(&EVENT_COLOR)
        .pos(Pos::new(HPos::Center, VPos::Bottom));
    labels.sort_by_key(|&(column, _)| column);
    // Right end of the last label placed on each row, bottom row first.
    let mut row_ends = [i32::MIN; EVENT_ROWS as usize];
    for &(column, label) in labels.iter() {
        let width = i32::try_from(area.estimate_text_size(label, &style)?.0).unwrap_or(0);
        let left = column - width / 2;
        let free = row_ends.iter().position(|&end| end + GAP_PX <= left);
        let leftmost = || {
            let rows = row_ends.iter().enumerate();
            rows.min_by_key(|&(_, &end)| end).map_or(0, |(row, _)| row)
        };
        let row = free.unwrap_or_else(leftmost);
        if let Some(end) = row_ends.get_mut(row) {
            *end = left + width;
        }
        let raise = EVENT_ROW_PX * u32::try_from(row).unwrap_or(0);
        let y = plot_top - 4 - i32::try_from(raise).unwrap_or(0);
        area.draw(&Text::new(label, (column, y), style.clone()))?;
    }
    Ok(())
}

impl Draw for PreparedLines<'_> {
    fn title(&self) -> &str {
        &self.plot.title
    }

    fn draw_body<DB: DrawingBackend>(&self, body: &Area<DB>) -> Drawn<DB> {
        let entries = self.legend();
        let (chart_area, legend_area) = split_legend(body, &entries)?;
        let plot_top = match self.plot.y_scale {
            Scale::Linear => self.draw_chart(&chart_area, self.y.0..self.y.1)?,
            Scale::Log10 => self.draw_chart(&chart_area, (self.y.0..self.y.1).log_scale())?,
        };
        draw_legend(&legend_area, &entries, plot_top)
    }
}

struct PreparedTrajectories<'a> {
    plot: &'a TrajectoryPlot,
    x: (f64, f64),
    y: (f64, f64),
}

/// Widens `x` or `y` about its centre so that both axes have the same data units per pixel on a plotting area of
/// `width` × `height` pixels.
fn equalise_aspect(
    x: (f64, f64),
    y: (f64, f64),
    width: u32,
    height: u32,
) -> ((f64, f64), (f64, f64)) {
    let (width, height) = (f64::from(width.max(1)), f64::from(height.max(1)));
    let (sx, sy) = ((x.1 - x.0) / width, (y.1 - y.0) / height);
    let widen = |(lo, hi): (f64, f64), half: f64| {
        let c = 0.5 * (lo + hi);
        (c - half, c + half)
    };
    if sx > sy {
        (x, widen(y, 0.5 * sx * height))
    } else {
        (widen(x, 0.5 * sy * width), y)
    }
}

impl Draw for PreparedTrajectories<'_> {
    fn title(&self) -> &str {
        &self.plot.title
    }

    fn draw_body<DB: DrawingBackend>(&self, body: &Area<DB>) -> Drawn<DB> {
        let plot = self.plot;
        let mut entries: Vec<LegendEntry<'_>> = plot
            .trajectories
            .iter()
            .zip(PALETTE.iter().cycle())
            .map(|(t, &color)| LegendEntry {
                label: &t.name,
                swatch: Swatch::Line(color),
            })
            .collect();
        entries.push(LegendEntry {
            label: "start",
            swatch: Swatch::Circle(REFERENCE_COLOR),
        });
        if plot.trajectories.iter().any(|t| t.desired.is_some()) {
            entries.push(LegendEntry {
                label: "desired",
                swatch: Swatch::Cross(REFERENCE_COLOR),
            });
        }
        let (chart_area, legend_area) = split_legend(body, &entries)?;

        let (x, y) = if plot.equal_aspect {
            let (w, h) = chart_area.dim_in_pixel();
            equalise_aspect(
                self.x,
                self.y,
                w.saturating_sub(2 * MARGIN_PX + Y_LABEL_AREA_PX),
                h.saturating_sub(2 * MARGIN_PX + X_LABEL_AREA_PX),
            )
        } else {
            (self.x, self.y)
        };
        // A camera image has y pointing down: plot -y and label the ticks with y.
        let sign = if plot.y_down { -1.0 } else { 1.0 };
        let (y_lo, y_hi) = if plot.y_down { (-y.1, -y.0) } else { y };
        let mut chart =
            chart_builder(&chart_area, MARGIN_PX).build_cartesian_2d(x.0..x.1, y_lo..y_hi)?;
        draw_mesh(
            &mut chart,
            &plot.x_label,
            &plot.y_label,
            sign,
            Scale::Linear,
        )?;

        for (trajectory, &color) in plot.trajectories.iter().zip(PALETTE.iter().cycle()) {
            let shown = |&(px, py): &(f64, f64)| (px, sign * py);
            let inside = |&&(px, py): &&(f64, f64)| within(px, x) && within(py, y);
            for run in clip_polyline(&trajectory.points, x, y, Scale::Linear) {
                chart.draw_series(LineSeries::new(
                    run.iter().map(shown),
                    color.stroke_width(SERIES_STROKE_PX),
                ))?;
            }
            if let Some(start) = trajectory.points.first().filter(inside) {
                chart.draw_series([Circle::new(shown(start), 7, color.stroke_width(2))])?;
            }
            if let Some(desired) = trajectory.desired.as_ref().filter(inside) {
                chart.draw_series([Cross::new(shown(desired), 7, color.stroke_width(3))])?;
            }
        }
        let plot_top = chart.plotting_area().get_base_pixel().1 - chart_area.get_base_pixel().1;
        draw_legend(&legend_area, &entries, plot_top)
    }
}

#[cfg(test)]
mod tests {
    //! Figures are written under `std::env::temp_dir()` and removed afterwards; set `SERVOSTACK_KEEP_FIGURES=1` to
    //! keep them for inspection.

    use super::*;
    use approx::assert_relative_eq;

    /// A fresh, unique output directory for one test.
    struct OutDir(PathBuf);

    impl OutDir {
        fn new(test: &str) -> Self {
            let dir =
                std::env::temp_dir().join(format!("servostack-plot-{}-{test}", std::process::id()));
            std::fs::remove_dir_all(&dir).ok();
            Self(dir)
        }
    }

    impl Drop for OutDir {
        fn drop(&mut self) {
            if std::env::var_os("SERVOSTACK_KEEP_FIGURES").is_none() {
                std::fs::remove_dir_all(&self.0).ok();
            }
        }
    }

    /// Width and height from the IHDR chunk of a PNG file, after checking the signature.
    fn png_dimensions(bytes: &[u8]) -> (u32, u32) {
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
        assert_eq!(&bytes[12..16], b"IHDR", "first chunk is IHDR");
        let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
        (be(&bytes[16..20]), be(&bytes[20..24]))
    }

    /// Checks both files: PNG of the right size and not blank, SVG containing every expected text.
    fn assert_rendered(files: &RenderedFiles, size: (u32, u32), texts: &[&str]) {
        let png = std::fs::read(&files.png).unwrap();
        assert_eq!(png_dimensions(&png), size);
        // A blank white 1024x640 PNG compresses to a few kB; drawn curves and text give far more.
        assert!(png.len() > 10_000, "PNG only {} bytes", png.len());
        let svg = std::fs::read_to_string(&files.svg).unwrap();
        assert!(svg.starts_with("<svg"), "SVG header");
        assert!(svg.contains(&format!(r#"width="{}" height="{}""#, size.0, size.1)));
        assert!(
            svg.contains(FONT_FAMILY),
            "text uses the embedded font family"
        );
        for text in texts {
            assert!(
                svg.lines().any(|line| line.trim() == *text),
                "SVG lacks text {text:?}"
            );
        }
    }

    fn joints_plot() -> LinePlot {
        let n = 400;
        let series = (0..6)
            .map(|j| {
                let phase = f64::from(j) * 0.9;
                Series::new(
                    format!("q{}", j + 1),
                    (0..n).map(|k| {
                        let t = f64::from(k) / f64::from(n);
                        (
                            f64::from(k),
                            0.5 + 0.45 * (6.0 * t + phase).sin() * (1.0 - 0.5 * t),
                        )
                    }),
                )
            })
            .collect();
        LinePlot {
            title: "Normalised joint positions".into(),
            x_label: "iteration".into(),
            y_label: "normalised joint position".into(),
            series,
            markers: vec![
                Marker::new(60.0, "push e2"),
                Marker::new(70.0, "push e3"),
                Marker::new(78.0, "remove e1"),
                Marker::new(250.0, "reinsert e1"),
            ],
            horizontal_lines: vec![
                HorizontalLine::new(0.0, "joint limits"),
                HorizontalLine::new(1.0, "joint limits"),
            ],
            y_range: Some((-0.1, 1.1)),
            ..LinePlot::default()
        }
    }

    #[test]
    fn tick_labels_are_short_and_exact() {
        assert_eq!(format_tick(50.0, 400.0), "50");
        assert_eq!(format_tick(0.1 + 0.2, 1.0), "0.3");
        assert_eq!(format_tick(-0.25, 1.0), "-0.25");
        assert_eq!(format_tick(-1.3e-17, 0.6), "0");
        assert_eq!(format_tick(-0.0, 0.6), "0");
        assert_eq!(format_tick(10f64.powf(-4.000_000_000_1), 0.0), "1e-4");
        assert_eq!(format_tick(0.001, 0.0), "0.001");
        assert_eq!(format_tick(2.5e7, 1e8), "2.5e7");
        assert_eq!(format_tick(123_456.0, 1e6), "123456");
    }

    #[test]
    fn line_plot_writes_png_and_svg_with_text() {
        let out = OutDir::new("lines");
        let plot = joints_plot();
        let files = plot.render(&out.0, "joints").unwrap();
        assert_eq!(files.png, out.0.join("joints.png"));
        assert_eq!(files.svg, out.0.join("joints.svg"));
        assert_rendered(
            &files,
            DEFAULT_SIZE,
            &[
                "Normalised joint positions",
                "iteration",
                "normalised joint position",
                "q1",
                "q6",
                "joint limits",
                "push e2",
                "reinsert e1",
            ],
        );
        // The two reference lines share one legend entry.
        let svg = std::fs::read_to_string(&files.svg).unwrap();
        assert_eq!(
            svg.lines()
                .filter(|line| line.trim() == "joint limits")
                .count(),
            1
        );
    }

    #[test]
    fn log_scale_plot_renders_decades() {
        let out = OutDir::new("log");
        let plot = LinePlot {
            title: "Task errors".into(),
            x_label: "iteration".into(),
            y_label: "‖e‖".into(),
            series: (1..=3)
                .map(|i| {
                    let rate = 0.02 * f64::from(i);
                    Series::new(
                        format!("‖e{i}‖"),
                        (0..300).map(move |k| (f64::from(k), 0.5 * (-rate * f64::from(k)).exp())),
                    )
                })
                .collect(),
            y_scale: Scale::Log10,
            size: (800, 500),
            ..LinePlot::default()
        };
        let files = plot.render(&out.0, "errors").unwrap();
        assert_rendered(&files, (800, 500), &["Task errors", "‖e1‖", "‖e3‖"]);
    }

    fn image_plot() -> TrajectoryPlot {
        let start = [(-0.25, -0.15), (0.2, -0.2), (0.22, 0.18), (-0.2, 0.2)];
        let desired = [(-0.1, -0.1), (0.1, -0.1), (0.1, 0.1), (-0.1, 0.1)];
        let trajectories = start
            .iter()
            .zip(&desired)
            .enumerate()
            .map(|(i, (&(x0, y0), &(xd, yd)))| {
                let points = (0..=100).map(move |k| {
                    let s = f64::from(k) / 100.0;
                    let bend = 0.05 * (std::f64::consts::PI * s).sin();
                    (x0 + (xd - x0) * s + bend, y0 + (yd - y0) * s)
                });
                Trajectory::new(format!("point {}", i + 1), points, Some((xd, yd)))
            })
            .collect();
        TrajectoryPlot {
            title: "Image trajectories".into(),
            x_label: "x = X/Z".into(),
            y_label: "y = Y/Z".into(),
            trajectories,
            ..TrajectoryPlot::default()
        }
    }

    #[test]
    fn trajectory_plot_writes_png_and_svg_with_text() {
        let out = OutDir::new("image");
        let files = image_plot().render(&out.0, "image").unwrap();
        assert_rendered(
            &files,
            DEFAULT_SIZE,
            &[
                "Image trajectories",
                "x = X/Z",
                "y = Y/Z",
                "point 1",
                "point 4",
                "start",
                "desired",
            ],
        );
    }

    /// `(x, y, content)` of every `<text>` element of an SVG written by plotters.
    fn svg_texts(svg: &str) -> Vec<(f64, f64, String)> {
        let attr = |tag: &str, name: &str| -> f64 {
            let start = tag.find(&format!(" {name}=\"")).unwrap() + name.len() + 3;
            let len = tag[start..].find('"').unwrap();
            tag[start..start + len].parse().unwrap()
        };
        svg.split("<text ")
            .skip(1)
            .map(|chunk| {
                let (tag, rest) = chunk.split_once('>').unwrap();
                let tag = format!(" {tag}");
                let content = rest.split("</text>").next().unwrap().trim().to_owned();
                (attr(&tag, "x"), attr(&tag, "y"), content)
            })
            .collect()
    }

    fn text_position(texts: &[(f64, f64, String)], content: &str) -> (f64, f64) {
        let found = texts.iter().find(|t| t.2 == content);
        let (x, y, _) = found.unwrap_or_else(|| panic!("no text {content:?}"));
        (*x, *y)
    }

    #[test]
    fn legend_is_right_of_the_data_and_event_labels_are_staggered() {
        let out = OutDir::new("layout");
        let files = joints_plot().render(&out.0, "joints").unwrap();
        let svg = std::fs::read_to_string(&files.svg).unwrap();
        // Rightmost pixel of any curve or line.
        let data_right = svg
            .split("points=\"")
            .skip(1)
            .flat_map(|chunk| chunk.split('"').next().unwrap().split_whitespace())
            .map(|point| point.split(',').next().unwrap().parse::<f64>().unwrap())
            .fold(f64::NEG_INFINITY, f64::max);
        let texts = svg_texts(&svg);
        for name in ["q1", "q6", "joint limits"] {
            assert!(
                text_position(&texts, name).0 > data_right,
                "legend entry {name:?} overlaps the data"
            );
        }
        // Events at 60, 70 and 78 are a few pixels apart: three rows. The event at 250 is far: first row.
        let rows: Vec<f64> = ["push e2", "push e3", "remove e1", "reinsert e1"]
            .iter()
            .map(|label| text_position(&texts, label).1)
            .collect();
        assert!(
            rows[0] > rows[1] && rows[1] > rows[2],
            "close labels not stacked: {rows:?}"
        );
        assert_eq!(rows[3], rows[0]);
    }

    /// Pixel row of the start circle of a single trajectory going from y = -1 to y = +1.
    fn start_circle_row(y_down: bool) -> f64 {
        let out = OutDir::new(if y_down { "down" } else { "up" });
        let plot = TrajectoryPlot {
            trajectories: vec![Trajectory::new("p", [(0.0, -1.0), (0.0, 1.0)], None)],
            y_down,
            ..TrajectoryPlot::default()
        };
        let files = plot.render(&out.0, "flip").unwrap();
        let svg = std::fs::read_to_string(&files.svg).unwrap();
        let circle = svg.split("<circle ").nth(1).unwrap();
        let cy = circle
            .split("cy=\"")
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap();
        cy.parse().unwrap()
    }

    #[test]
    fn image_y_axis_points_down() {
        let (_, height) = DEFAULT_SIZE;
        let half = f64::from(height) / 2.0;
        assert!(
            start_circle_row(true) < half,
            "y = -1 must be at the top of a camera image"
        );
        assert!(
            start_circle_row(false) > half,
            "y = -1 must be at the bottom of an upward axis"
        );
    }

    #[test]
    fn equal_aspect_matches_units_per_pixel() {
        // x spans 2 on 400 px (0.005/px), y spans 1 on 100 px (0.01/px): x widens to 4 about its centre 1.
        let (x, y) = equalise_aspect((0.0, 2.0), (0.0, 1.0), 400, 100);
        assert_eq!((x, y), ((-1.0, 3.0), (0.0, 1.0)));
        // x spans 4 on 400 px (0.01/px), y spans 1 on 200 px (0.005/px): y widens to 2 about its centre 0.5.
        let (x, y) = equalise_aspect((0.0, 4.0), (0.0, 1.0), 400, 200);
        assert_eq!((x, y), ((0.0, 4.0), (-0.5, 1.5)));
    }

    #[test]
    fn segments_are_cut_at_the_border() {
        let unit = (0.0, 1.0);
        assert_eq!(
            clip_segment((-1.0, 0.5), (2.0, 0.5), unit, unit),
            Some((1.0 / 3.0, 2.0 / 3.0))
        );
        assert_eq!(
            clip_segment((0.25, 0.5), (0.75, 0.5), unit, unit),
            Some((0.0, 1.0))
        );
        assert_eq!(clip_segment((-1.0, 2.0), (2.0, 2.0), unit, unit), None);
        // Diagonal through the corner region outside: misses the box.
        assert_eq!(clip_segment((-1.0, 0.5), (0.5, 2.0), unit, unit), None);
    }

    #[test]
    fn polylines_split_into_runs_inside_the_box() {
        let unit = (0.0, 1.0);
        // Up through the top border (y = 1 at x = 0.3), back down through it (at x = 0.7).
        let zigzag = [(0.1, 0.5), (0.5, 1.5), (0.9, 0.5)];
        let runs = clip_polyline(&zigzag, unit, unit, Scale::Linear);
        let expected = [[(0.1, 0.5), (0.3, 1.0)], [(0.7, 1.0), (0.9, 0.5)]];
        assert_eq!(runs.len(), expected.len(), "{runs:?}");
        for (run, want) in runs.iter().zip(&expected) {
            assert_eq!(run.len(), want.len(), "{runs:?}");
            for (got, want) in run.iter().zip(want) {
                assert_relative_eq!(got.0, want.0, epsilon = 1e-12);
                assert_relative_eq!(got.1, want.1, epsilon = 1e-12);
            }
        }
        // A vertex touching the border from outside adds no zero-length piece.
        let touch = [(0.5, 1.5), (0.7, 1.0), (0.9, 0.5)];
        assert_eq!(
            clip_polyline(&touch, unit, unit, Scale::Linear),
            vec![vec![(0.7, 1.0), (0.9, 0.5)]]
        );
        // Fully inside: one run, unchanged.
        let inside = [(0.1, 0.1), (0.2, 0.9), (0.3, 0.1)];
        assert_eq!(
            clip_polyline(&inside, unit, unit, Scale::Linear),
            vec![inside.to_vec()]
        );
        // A single point is kept only inside.
        assert_eq!(
            clip_polyline(&[(0.5, 0.5)], unit, unit, Scale::Linear).len(),
            1
        );
        assert!(clip_polyline(&[(1.5, 0.5)], unit, unit, Scale::Linear).is_empty());
    }

    #[test]
    fn log_axis_cuts_in_decades() {
        // log10 y goes linearly from -3 to 1 over x in [0, 1]: it crosses -2 at x = 0.25 and 0 at x = 0.75.
        let runs = clip_polyline(
            &[(0.0, 1e-3), (1.0, 10.0)],
            (0.0, 1.0),
            (1e-2, 1.0),
            Scale::Log10,
        );
        assert_eq!(runs.len(), 1);
        let [(x0, y0), (x1, y1)] = runs[0][..] else {
            panic!("{runs:?}")
        };
        assert_relative_eq!(x0, 0.25, epsilon = 1e-12);
        assert_relative_eq!(y0, 1e-2, max_relative = 1e-12);
        assert_relative_eq!(x1, 0.75, epsilon = 1e-12);
        assert_relative_eq!(y1, 1.0, max_relative = 1e-12);
    }

    #[test]
    fn automatic_ranges_pad_the_data() {
        let r = axis_range("y", None, Some((0.0, 10.0)), Scale::Linear).unwrap();
        assert_eq!(r, (-0.5, 10.5));
        // Constant data: ±10 % of the value, or ±0.5 around zero.
        assert_eq!(
            axis_range("y", None, Some((2.0, 2.0)), Scale::Linear).unwrap(),
            (1.8, 2.2)
        );
        assert_eq!(
            axis_range("y", None, Some((0.0, 0.0)), Scale::Linear).unwrap(),
            (-0.5, 0.5)
        );
        // Three decades: 0.15 decade each side.
        let (lo, hi) = axis_range("y", None, Some((1e-3, 1.0)), Scale::Log10).unwrap();
        assert_relative_eq!(lo.log10(), -3.15, epsilon = 1e-12);
        assert_relative_eq!(hi.log10(), 0.15, epsilon = 1e-12);
        // An explicit range wins.
        assert_eq!(
            axis_range("x", Some((1.0, 2.0)), Some((0.0, 9.0)), Scale::Linear).unwrap(),
            (1.0, 2.0)
        );
    }

    /// Renders `plot`, expects `expected` and checks that nothing was written.
    fn assert_line_error(plot: &LinePlot, stem: &str, expected: &PlotError) {
        let out = OutDir::new("bad");
        assert_eq!(&plot.render(&out.0, stem).unwrap_err(), expected);
        assert!(!out.0.exists(), "no output on invalid input");
    }

    #[test]
    fn invalid_line_plots_are_errors() {
        let good = || LinePlot {
            title: "t".into(),
            series: vec![Series::new("a", [(0.0, 1.0), (1.0, 2.0)])],
            ..LinePlot::default()
        };
        let no_series = LinePlot {
            series: vec![],
            ..good()
        };
        assert_line_error(&no_series, "f", &PlotError::NoSeries { figure: "t".into() });

        let mut empty = good();
        empty.series.push(Series::new("b", []));
        assert_line_error(&empty, "f", &PlotError::EmptySeries { series: "b".into() });

        let mut nan = good();
        nan.series[0].points[1].1 = f64::NAN;
        let err = nan.render(&OutDir::new("nan").0, "f").unwrap_err();
        assert!(
            matches!(&err, PlotError::NonFinite { item, index: 1, x, y } if item == "a" && *x == 1.0 && y.is_nan()),
            "{err:?}"
        );

        let mut marker = good();
        marker.markers.push(Marker::new(f64::INFINITY, "push"));
        let expected = PlotError::NonFinite {
            item: "push".into(),
            index: 0,
            x: f64::INFINITY,
            y: 0.0,
        };
        assert_line_error(&marker, "f", &expected);

        let mut log = good();
        log.y_scale = Scale::Log10;
        log.series[0].points[0].1 = 0.0;
        let expected = PlotError::NonPositiveOnLogAxis {
            item: "a".into(),
            index: 0,
            y: 0.0,
        };
        assert_line_error(&log, "f", &expected);

        let mut log_range = good();
        log_range.y_scale = Scale::Log10;
        log_range.y_range = Some((0.0, 1.0));
        let expected = PlotError::InvalidRange {
            axis: "y",
            min: 0.0,
            max: 1.0,
        };
        assert_line_error(&log_range, "f", &expected);

        let mut reversed = good();
        reversed.x_range = Some((2.0, 1.0));
        let expected = PlotError::InvalidRange {
            axis: "x",
            min: 2.0,
            max: 1.0,
        };
        assert_line_error(&reversed, "f", &expected);

        let small = LinePlot {
            size: (100, 100),
            ..good()
        };
        let expected = PlotError::InvalidSize {
            width: 100,
            height: 100,
        };
        assert_line_error(&small, "f", &expected);

        for stem in ["", ".", "..", "../f", "a/b"] {
            let expected = PlotError::InvalidStem { stem: stem.into() };
            assert_line_error(&good(), stem, &expected);
        }
    }

    #[test]
    fn invalid_trajectory_plots_are_errors() {
        let out = OutDir::new("bad-trajectory");
        let empty = TrajectoryPlot::default();
        assert_eq!(
            empty.render(&out.0, "f").unwrap_err(),
            PlotError::NoSeries {
                figure: String::new()
            }
        );
        let desired_nan = TrajectoryPlot {
            trajectories: vec![Trajectory::new("p", [(0.0, 0.0)], Some((0.0, f64::NAN)))],
            ..TrajectoryPlot::default()
        };
        let err = desired_nan.render(&out.0, "f").unwrap_err();
        assert!(
            matches!(&err, PlotError::NonFinite { item, .. } if item == "p"),
            "{err:?}"
        );
        assert!(!out.0.exists());
    }

    #[test]
    fn unwritable_output_directory_is_an_io_error() {
        let out = OutDir::new("io");
        std::fs::create_dir_all(&out.0).unwrap();
        let file = out.0.join("not-a-directory");
        std::fs::write(&file, b"x").unwrap();
        let err = joints_plot().render(&file.join("sub"), "f").unwrap_err();
        assert!(
            matches!(&err, PlotError::Io { path, .. } if *path == file.join("sub")),
            "{err:?}"
        );
    }
}
