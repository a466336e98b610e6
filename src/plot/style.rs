//! The look shared by every figure: the embedded font, text sizes, layout margins and colours.

use super::*;

/// The embedded font (DejaVu Sans 2.37, Bitstream Vera / Arev license).
const FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
/// Plotters family name of the embedded font; the SVG backend writes it verbatim as a CSS `font-family` list.
pub(super) const FONT_FAMILY: &str = "DejaVu Sans, Verdana, sans-serif";

pub(super) const TITLE_FONT_PX: f64 = 28.0;
pub(super) const AXIS_DESC_FONT_PX: f64 = 22.0;
pub(super) const TICK_FONT_PX: f64 = 17.0;
pub(super) const LEGEND_FONT_PX: f64 = 18.0;
pub(super) const EVENT_FONT_PX: f64 = 16.0;

pub(super) const MARGIN_PX: u32 = 16;
pub(super) const X_LABEL_AREA_PX: u32 = 60;
pub(super) const Y_LABEL_AREA_PX: u32 = 90;
/// Rows of the band above the plotting area that holds the event labels.
pub(super) const EVENT_ROWS: u32 = 3;
pub(super) const EVENT_ROW_PX: u32 = 20;
pub(super) const LEGEND_ROW_PX: i32 = 30;
pub(super) const LEGEND_SWATCH_PX: i32 = 36;
pub(super) const SERIES_STROKE_PX: u32 = 2;

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

/// The embedded font at `size` pixels.
pub(super) fn font(size: f64) -> TextStyle<'static> {
    (FONT_FAMILY, size).into_text_style(&(0u32, 0u32))
}
