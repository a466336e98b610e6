//! Drawing shared by every figure kind: files, title, legend, notes, axes and tick labels.

use super::*;

/// A pixel-addressed drawing area of backend `DB`.
pub(super) type Area<DB> = DrawingArea<DB, Shift>;
/// Result of drawing on backend `DB`.
pub(super) type Drawn<DB, T = ()> =
    Result<T, DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// A validated figure that can draw itself on any plotters backend.
pub(super) trait Draw {
    fn title(&self) -> &str;
    fn draw_body<DB: DrawingBackend>(&self, area: &Area<DB>, look: Look) -> Drawn<DB>;
}

/// Fills the background, draws the title and the body.
fn draw_figure<DB: DrawingBackend, F: Draw>(figure: &F, root: &Area<DB>, look: Look) -> Drawn<DB> {
    root.fill(&WHITE)?;
    let body = if figure.title().is_empty() {
        root.clone()
    } else {
        root.margin(look.px(10), 0, 0, 0)
            .titled(figure.title(), look.font(TITLE_FONT_PX))?
    };
    figure.draw_body(&body, look)?;
    root.present()
}

/// Draws `figure` on `area`, mapping a plotters failure to [`PlotError::Draw`] naming `path`.
fn draw_file<DB: DrawingBackend, F: Draw>(
    figure: &F,
    area: Area<DB>,
    look: Look,
    path: &Path,
) -> Result<(), PlotError> {
    draw_figure(figure, &area, look).map_err(|e| PlotError::Draw {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Validates the stem, registers the font, creates `out_dir` and writes `stem.png` (at the style's scale) and
/// `stem.svg` (at scale 1).
pub(super) fn render_files<F: Draw>(
    figure: &F,
    style: FigureStyle,
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
    let (width, height) = style.png_size();
    let mut pixels = vec![0u8; 3 * width as usize * height as usize];
    draw_file(
        figure,
        BitMapBackend::with_buffer(&mut pixels, (width, height)).into_drawing_area(),
        Look { scale: style.scale },
        &files.png,
    )?;
    write_png(&files.png, width, height, &pixels)?;
    draw_file(
        figure,
        SVGBackend::new(&files.svg, (style.width, style.height)).into_drawing_area(),
        Look { scale: 1.0 },
        &files.svg,
    )?;
    Ok(files)
}

/// Writes `pixels` (RGB, 8 bits, row-major, `width × height`) to `path` as a PNG file. plotters draws into the buffer;
/// the `png` crate encodes it (plotters' own encoder would pull in the whole `image` crate and its JPEG decoder).
fn write_png(path: &Path, width: u32, height: u32, pixels: &[u8]) -> Result<(), PlotError> {
    let io_error = |e: std::io::Error| PlotError::Io {
        path: path.to_path_buf(),
        kind: e.kind(),
        message: e.to_string(),
    };
    let encoding_error = |e: png::EncodingError| match e {
        png::EncodingError::IoError(e) => io_error(e),
        other => PlotError::Draw {
            path: path.to_path_buf(),
            message: other.to_string(),
        },
    };
    let file = std::fs::File::create(path).map_err(io_error)?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    // A filter chosen per row: less than half the file size of a fixed one on these flat-coloured figures.
    encoder.set_adaptive_filter(png::AdaptiveFilterType::Adaptive);
    let mut writer = encoder.write_header().map_err(encoding_error)?;
    writer.write_image_data(pixels).map_err(encoding_error)?;
    writer.finish().map_err(encoding_error)
}

/// The sample drawn next to a legend label.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Swatch {
    /// A curve: its colour, pattern and marker.
    Series(SeriesStyle),
    /// A reference line of `color` with `pattern`, `width` layout pixels wide.
    Line {
        color: RGBColor,
        pattern: LinePattern,
        width: u32,
    },
    /// An outlined rectangle (a border).
    Frame(RGBColor),
    /// A filled square (a category).
    Fill(RGBColor),
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
    look: Look,
) -> Drawn<DB, u32> {
    let style = look.font(LEGEND_FONT_PX);
    let mut text = 0;
    for entry in entries {
        text = text.max(area.estimate_text_size(entry.label, &style)?.0);
    }
    let wanted = text + look.pxi(LEGEND_SWATCH_PX).unsigned_abs() + look.px(3 * MARGIN_PX / 2);
    Ok(wanted.min(area.dim_in_pixel().0 * 2 / 5))
}

/// Draws the legend entries top-down from pixel row `top` of `area`, then the `notes` below them (each wrapped to
/// the strip's width); returns the pixel row below the last line.
pub(super) fn draw_legend<DB: DrawingBackend>(
    area: &Area<DB>,
    entries: &[LegendEntry<'_>],
    notes: &[String],
    top: i32,
    look: Look,
) -> Drawn<DB, i32> {
    let style = look
        .font(LEGEND_FONT_PX)
        .pos(Pos::new(HPos::Left, VPos::Center));
    let x0 = look.pxi(4);
    let x1 = x0 + look.pxi(LEGEND_SWATCH_PX - 8);
    let xc = f64::from(x0 + x1) / 2.0;
    let row_px = look.pxi(LEGEND_ROW_PX);
    let mut y = top + row_px / 2;
    for entry in entries {
        let yf = f64::from(y);
        let (left, right) = ((f64::from(x0), yf), (f64::from(x1), yf));
        match entry.swatch {
            Swatch::Series(series) => {
                draw_line(
                    area,
                    &[left, right],
                    series.color,
                    SERIES_STROKE_PX,
                    series.pattern,
                    look,
                )?;
                if let Some(marker) = series.marker {
                    draw_marker(area, (xc, yf), marker, series.color, look)?;
                }
            }
            Swatch::Line {
                color,
                pattern,
                width,
            } => draw_line(area, &[left, right], color, width, pattern, look)?,
            Swatch::Frame(color) => {
                let h = look.pxi(7);
                area.draw(&Rectangle::new(
                    [(x0 + look.pxi(6), y - h), (x1 - look.pxi(6), y + h)],
                    look.stroke(color, 2),
                ))?;
            }
            Swatch::Fill(color) => {
                let h = look.pxi(7);
                area.draw(&Rectangle::new(
                    [(x0 + look.pxi(8), y - h), (x1 - look.pxi(8), y + h)],
                    color.filled(),
                ))?;
            }
            Swatch::Circle(color) => area.draw(&Circle::new(
                (xc.round() as i32, y),
                look.pxi(6),
                look.stroke(color, 2),
            ))?,
            Swatch::Cross(color) => area.draw(&Cross::new(
                (xc.round() as i32, y),
                look.pxi(6),
                look.stroke(color, 3),
            ))?,
        }
        area.draw(&Text::new(
            entry.label,
            (x0 + look.pxi(LEGEND_SWATCH_PX), y),
            style.clone(),
        ))?;
        y += row_px;
    }
    let mut bottom = y - row_px / 2;
    if !notes.is_empty() {
        let note_style = look
            .font(NOTE_FONT_PX)
            .color(&EVENT_COLOR)
            .pos(Pos::new(HPos::Left, VPos::Top));
        let width = area
            .dim_in_pixel()
            .0
            .saturating_sub(x0.unsigned_abs() + look.px(4));
        bottom += look.pxi(NOTE_ROW_PX) / 2;
        for note in notes {
            for line in wrap_text(area, note, &note_style, width)? {
                area.draw(&Text::new(line, (x0, bottom), note_style.clone()))?;
                bottom += look.pxi(NOTE_ROW_PX);
            }
            bottom += look.pxi(NOTE_ROW_PX) / 3;
        }
    }
    Ok(bottom)
}

/// `text` broken at its (ASCII) spaces into lines no wider than `width` pixels (a single word wider than that is a
/// line of its own); no-break spaces hold words together.
pub(super) fn wrap_text<DB: DrawingBackend>(
    area: &Area<DB>,
    text: &str,
    style: &TextStyle<'_>,
    width: u32,
) -> Drawn<DB, Vec<String>> {
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in text.split(' ').filter(|w| !w.is_empty()) {
        let candidate = if line.is_empty() {
            word.to_owned()
        } else {
            format!("{line} {word}")
        };
        if line.is_empty() || area.estimate_text_size(&candidate, style)?.0 <= width {
            line = candidate;
        } else {
            lines.push(std::mem::replace(&mut line, word.to_owned()));
        }
    }
    if !line.is_empty() {
        lines.push(line);
    }
    Ok(lines)
}

/// Splits off the legend strip on the right of `body`; returns (chart area, legend area).
pub(super) fn split_legend<DB: DrawingBackend>(
    body: &Area<DB>,
    entries: &[LegendEntry<'_>],
    look: Look,
) -> Drawn<DB, (Area<DB>, Area<DB>)> {
    let width = legend_width(body, entries, look)?;
    Ok(body.split_horizontally(body.dim_in_pixel().0.saturating_sub(width)))
}

pub(super) fn chart_builder<'a, 'b, DB: DrawingBackend>(
    area: &'a Area<DB>,
    top: u32,
    look: Look,
) -> ChartBuilder<'a, 'b, DB> {
    let mut builder = ChartBuilder::on(area);
    builder
        .margin_top(top)
        .margin_bottom(look.px(MARGIN_PX))
        .margin_left(look.px(MARGIN_PX))
        .margin_right(look.px(MARGIN_PX))
        .x_label_area_size(look.px(X_LABEL_AREA_PX))
        .y_label_area_size(look.px(Y_LABEL_AREA_PX));
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
    look: Look,
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
        .axis_desc_style(look.font(AXIS_DESC_FONT_PX))
        .label_style(look.font(TICK_FONT_PX))
        .bold_line_style(look.stroke(GRID_BOLD, 1))
        .light_line_style(look.stroke(GRID_LIGHT, 1))
        .axis_style(look.stroke(BLACK, 1))
        .set_all_tick_mark_size(look.pxi(5))
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
