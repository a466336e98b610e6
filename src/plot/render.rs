//! Drawing shared by every figure kind: files, title, legend, axes and tick labels.

use super::*;

/// A pixel-addressed drawing area of backend `DB`.
pub(super) type Area<DB> = DrawingArea<DB, Shift>;
/// Result of drawing on backend `DB`.
pub(super) type Drawn<DB, T = ()> =
    Result<T, DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// A validated figure that can draw itself on any plotters backend.
pub(super) trait Draw {
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
pub(super) fn render_files<F: Draw>(
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
pub(super) enum Swatch {
    Line(RGBColor),
    Dashed(RGBColor),
    Circle(RGBColor),
    Cross(RGBColor),
}

pub(super) struct LegendEntry<'a> {
    pub(super) label: &'a str,
    pub(super) swatch: Swatch,
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
pub(super) fn draw_legend<DB: DrawingBackend>(
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
pub(super) fn split_legend<DB: DrawingBackend>(
    body: &Area<DB>,
    entries: &[LegendEntry<'_>],
) -> Drawn<DB, (Area<DB>, Area<DB>)> {
    let width = legend_width(body, entries)?;
    Ok(body.split_horizontally(body.dim_in_pixel().0.saturating_sub(width)))
}

pub(super) fn chart_builder<'a, 'b, DB: DrawingBackend>(
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
pub(super) fn draw_mesh<DB: DrawingBackend, X, Y>(
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
pub(super) fn format_tick(v: f64, span: f64) -> String {
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
