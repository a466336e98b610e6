//! The look shared by every figure: the embedded font, the figure's size and resolution ([`FigureStyle`]), text
//! sizes, layout margins, colours, and the line patterns and point markers that tell curves apart without colour.

use super::*;

/// The embedded font (DejaVu Sans 2.37, Bitstream Vera / Arev license).
const FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
/// Plotters family name of the embedded font; the SVG backend writes it verbatim as a CSS `font-family` list.
pub(super) const FONT_FAMILY: &str = "DejaVu Sans, Verdana, sans-serif";

// Sizes in layout pixels (at scale 1); [`Look`] scales them for a PNG of higher resolution.
pub(super) const TITLE_FONT_PX: f64 = 28.0;
pub(super) const AXIS_DESC_FONT_PX: f64 = 22.0;
pub(super) const TICK_FONT_PX: f64 = 17.0;
pub(super) const LEGEND_FONT_PX: f64 = 18.0;
pub(super) const NOTE_FONT_PX: f64 = 14.0;
pub(super) const EVENT_FONT_PX: f64 = 16.0;

pub(super) const MARGIN_PX: u32 = 16;
pub(super) const X_LABEL_AREA_PX: u32 = 60;
pub(super) const Y_LABEL_AREA_PX: u32 = 90;
/// Height of one row of the band above the plotting area that holds the event labels.
pub(super) const EVENT_ROW_PX: u32 = 20;
/// Smallest horizontal gap between two event labels on one row.
pub(super) const EVENT_GAP_PX: i32 = 6;
pub(super) const LEGEND_ROW_PX: i32 = 30;
pub(super) const LEGEND_SWATCH_PX: i32 = 48;
pub(super) const NOTE_ROW_PX: i32 = 18;
pub(super) const SERIES_STROKE_PX: u32 = 2;
/// Horizontal distance between two point markers of a curve.
pub(super) const MARKER_SPACING_PX: f64 = 110.0;
/// Half-size of a point marker.
pub(super) const MARKER_RADIUS_PX: f64 = 4.5;

/// Tableau 10 palette (the matplotlib default cycle).
pub(super) const PALETTE: [RGBColor; 10] = [
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
pub(super) const REFERENCE_COLOR: RGBColor = RGBColor(40, 40, 40);
pub(super) const EVENT_COLOR: RGBColor = RGBColor(110, 110, 110);
pub(super) const GRID_BOLD: RGBColor = RGBColor(215, 215, 215);
pub(super) const GRID_LIGHT: RGBColor = RGBColor(240, 240, 240);

/// Size and resolution of a figure.
///
/// `width × height` is the layout size: the SVG's size in user units, and the PNG's size in pixels at `scale` 1.
/// `scale` multiplies the PNG's resolution only: text, lines, margins and markers grow with it, so the PNG at scale
/// 2 is the same figure as at scale 1 with twice the pixels in each direction (the SVG is vector and does not
/// change). The default is 1024 × 640 at scale 1.
///
/// ```
/// use servostack::plot::FigureStyle;
///
/// // Print: 3.5 × 2.2 in at 300 dpi, a column of a two-column paper.
/// let column = FigureStyle::for_print(3.5, 2.2, 300.0);
/// assert_eq!(column.png_size(), (1050, 660));
/// // Screen figures at twice the resolution.
/// let retina = FigureStyle::default().with_scale(2.0);
/// assert_eq!(retina.png_size(), (2048, 1280));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FigureStyle {
    /// Layout width in pixels, between [`MIN_SIZE`] and [`MAX_SIZE`].
    pub width: u32,
    /// Layout height in pixels, between [`MIN_SIZE`] and [`MAX_SIZE`].
    pub height: u32,
    /// PNG pixels per layout pixel, at least [`MIN_SCALE`], and small enough for the PNG to stay within
    /// [`MAX_SIZE`].
    pub scale: f64,
}

impl Default for FigureStyle {
    fn default() -> Self {
        Self::new(DEFAULT_SIZE.0, DEFAULT_SIZE.1)
    }
}

impl FigureStyle {
    /// Layout pixels per inch of [`FigureStyle::for_print`]: the default 1024 px wide figure prints 5.7 in wide,
    /// its tick labels at 6.8 pt and its title at 11 pt.
    pub const LAYOUT_PX_PER_INCH: f64 = 180.0;

    /// A figure of `width × height` layout pixels at scale 1.
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            scale: 1.0,
        }
    }

    /// The same layout with the PNG's resolution multiplied by `scale`.
    pub fn with_scale(self, scale: f64) -> Self {
        Self { scale, ..self }
    }

    /// A figure printed `width_in × height_in` inches at `dpi` dots per inch: the layout is
    /// [`FigureStyle::LAYOUT_PX_PER_INCH`] pixels per inch (so text keeps a readable size in print), the PNG
    /// `dpi` pixels per inch. Values out of range give a style that `render` refuses ([`PlotError::InvalidSize`],
    /// [`PlotError::InvalidScale`]).
    pub fn for_print(width_in: f64, height_in: f64, dpi: f64) -> Self {
        // `as` saturates (NaN to 0): a bad value becomes a size that validation rejects.
        let layout = |inches: f64| (inches * Self::LAYOUT_PX_PER_INCH).round() as u32;
        Self {
            width: layout(width_in),
            height: layout(height_in),
            scale: dpi / Self::LAYOUT_PX_PER_INCH,
        }
    }

    /// The size of the PNG in pixels: the layout size times the scale, rounded.
    pub fn png_size(&self) -> (u32, u32) {
        let scaled = |v: u32| (f64::from(v) * self.scale).round() as u32;
        (scaled(self.width), scaled(self.height))
    }

    /// Rejects a layout size outside [`MIN_SIZE`]..=[`MAX_SIZE`] and a scale below [`MIN_SCALE`], not finite, or
    /// that makes the PNG larger than [`MAX_SIZE`].
    pub(super) fn check(&self) -> Result<(), PlotError> {
        let (width, height) = (self.width, self.height);
        let fits = |v: u32, lo: u32, hi: u32| (lo..=hi).contains(&v);
        if !(fits(width, MIN_SIZE.0, MAX_SIZE.0) && fits(height, MIN_SIZE.1, MAX_SIZE.1)) {
            return Err(PlotError::InvalidSize { width, height });
        }
        let max_scale = f64::min(
            f64::from(MAX_SIZE.0) / f64::from(width),
            f64::from(MAX_SIZE.1) / f64::from(height),
        );
        if !(self.scale.is_finite() && self.scale >= MIN_SCALE && self.scale <= max_scale) {
            return Err(PlotError::InvalidScale {
                scale: self.scale,
                width,
                height,
            });
        }
        Ok(())
    }
}

/// How a figure is drawn on one backend: layout pixels times `scale` (1 for the SVG, [`FigureStyle::scale`] for the
/// PNG).
#[derive(Debug, Clone, Copy)]
pub(super) struct Look {
    pub(super) scale: f64,
}

impl Look {
    /// A length of `v` layout pixels, in backend pixels.
    pub(super) fn px(self, v: u32) -> u32 {
        (f64::from(v) * self.scale).round() as u32
    }

    /// A signed length of `v` layout pixels, in backend pixels.
    pub(super) fn pxi(self, v: i32) -> i32 {
        (f64::from(v) * self.scale).round() as i32
    }

    /// A length of `v` layout pixels, in backend pixels, unrounded.
    pub(super) fn pxf(self, v: f64) -> f64 {
        v * self.scale
    }

    /// The embedded font at `size` layout pixels.
    pub(super) fn font(self, size: f64) -> TextStyle<'static> {
        (FONT_FAMILY, size * self.scale).into_text_style(&(0u32, 0u32))
    }

    /// A stroke of `color`, `width` layout pixels wide (at least one backend pixel).
    pub(super) fn stroke(self, color: RGBColor, width: u32) -> ShapeStyle {
        color.stroke_width(self.px(width).max(1))
    }
}

/// The dash pattern of a line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[non_exhaustive]
pub enum LinePattern {
    /// A continuous line.
    Solid,
    /// Long dashes (9 px on, 5 off).
    #[default]
    Dashed,
    /// Dots (2 px on, 4 off).
    Dotted,
    /// Dash and dot (9 px on, 4 off, 2 on, 4 off).
    DashDot,
    /// Dash and two dots (9 px on, 3 off, then twice 2 on, 3 off).
    DashDotDot,
}

impl LinePattern {
    /// The on / off lengths in layout pixels, starting with "on"; empty for a solid line.
    pub(super) fn dashes(self) -> &'static [f64] {
        match self {
            LinePattern::Solid => &[],
            LinePattern::Dashed => &[9.0, 5.0],
            LinePattern::Dotted => &[2.0, 4.0],
            LinePattern::DashDot => &[9.0, 4.0, 2.0, 4.0],
            LinePattern::DashDotDot => &[9.0, 3.0, 2.0, 3.0, 2.0, 3.0],
        }
    }
}

/// The symbol repeated along a curve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(super) enum PointMarker {
    Circle,
    Square,
    Triangle,
    Diamond,
    Plus,
}

/// The patterns of the series, in order: with [`SERIES_MARKERS`] (a count prime to this one) the first 20 series
/// differ in pattern or marker, so curves stay apart in grey-scale print. Dotted is left to reference lines (the
/// report's activation thresholds).
pub(super) const SERIES_PATTERNS: [LinePattern; 4] = [
    LinePattern::Solid,
    LinePattern::Dashed,
    LinePattern::DashDot,
    LinePattern::DashDotDot,
];
/// The markers of the series, in order.
pub(super) const SERIES_MARKERS: [PointMarker; 5] = [
    PointMarker::Circle,
    PointMarker::Square,
    PointMarker::Triangle,
    PointMarker::Diamond,
    PointMarker::Plus,
];

/// Colour, dash pattern and marker of one curve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(super) struct SeriesStyle {
    pub(super) color: RGBColor,
    pub(super) pattern: LinePattern,
    pub(super) marker: Option<PointMarker>,
}

impl SeriesStyle {
    /// The style of series `index`: colour, pattern and marker each cycle through their lists.
    pub(super) fn nth(index: usize) -> Self {
        Self {
            color: PALETTE[index % PALETTE.len()],
            pattern: SERIES_PATTERNS[index % SERIES_PATTERNS.len()],
            marker: Some(SERIES_MARKERS[index % SERIES_MARKERS.len()]),
        }
    }
}

/// Registers the embedded font with plotters, once per process.
pub(super) fn ensure_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED
        .get_or_init(|| register_font(FONT_FAMILY, FontStyle::Normal, FONT_BYTES).is_ok());
    if ok {
        Ok(())
    } else {
        Err(PlotError::Font)
    }
}
