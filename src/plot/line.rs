//! Line plots: curves over iterations or time, with reference lines and labelled event markers.

use super::*;

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
    pub(super) fn screen(self, v: f64) -> f64 {
        match self {
            Scale::Linear => v,
            Scale::Log10 => v.log10(),
        }
    }

    /// Inverse of [`Scale::screen`].
    pub(super) fn unscreen(self, s: f64) -> f64 {
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
