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

/// A horizontal reference line at ordinate `y`, e.g. a joint limit or an activation threshold, drawn across the
/// plot in dark grey with its [`LinePattern`] (dashed unless set). Lines sharing a label and pattern share one legend
/// entry; give different kinds of line different patterns so that they stay apart in the legend and in grey-scale.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct HorizontalLine {
    /// Ordinate in data units.
    pub y: f64,
    /// Legend entry.
    pub label: String,
    /// Dash pattern.
    pub pattern: LinePattern,
}

impl HorizontalLine {
    /// A dashed reference line at `y` with its legend label.
    pub fn new(y: f64, label: impl Into<String>) -> Self {
        Self {
            y,
            label: label.into(),
            pattern: LinePattern::default(),
        }
    }

    /// The same line drawn with `pattern`.
    pub fn with_pattern(self, pattern: LinePattern) -> Self {
        Self { pattern, ..self }
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
/// Each curve has its own colour, dash pattern and point marker (so that curves stay apart in grey-scale print);
/// reference lines are dark grey with their own patterns, event markers grey dashed vertical lines labelled above
/// the plotting area.
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
    /// The curves, styled in order (colour, dash pattern and marker each cycle through their lists).
    pub series: Vec<Series>,
    /// Labelled vertical lines (stack events); those outside the x range are not drawn.
    pub markers: Vec<Marker>,
    /// Horizontal reference lines (limits, thresholds); those outside the y range are not drawn.
    pub horizontal_lines: Vec<HorizontalLine>,
    /// Short paragraphs drawn below the legend, wrapped to its width: what a curve or line means when its name
    /// cannot say it (e.g. a task held in reserve).
    pub notes: Vec<String>,
    /// Explicit x range, outside which curves are clipped; `None` fits the series and markers.
    pub x_range: Option<(f64, f64)>,
    /// Explicit y range, outside which curves are clipped; `None` fits the series and reference lines with a 5 %
    /// margin (of the decades spanned, on a log axis).
    pub y_range: Option<(f64, f64)>,
    /// Scale of the y axis.
    pub y_scale: Scale,
    /// Size and resolution.
    pub style: FigureStyle,
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
            notes: Vec::new(),
            x_range: None,
            y_range: None,
            y_scale: Scale::Linear,
            style: FigureStyle::default(),
        }
    }
}

impl LinePlot {
    /// Validates the figure and writes `out_dir/stem.png` and `out_dir/stem.svg`, creating `out_dir` if needed.
    ///
    /// # Errors
    /// [`PlotError::NoSeries`], [`PlotError::EmptySeries`], [`PlotError::NonFinite`] (series points, marker
    /// abscissae, reference-line ordinates), [`PlotError::NonPositiveOnLogAxis`] (with [`Scale::Log10`]),
    /// [`PlotError::InvalidRange`], [`PlotError::InvalidSize`], [`PlotError::InvalidScale`],
    /// [`PlotError::InvalidStem`] before any file is written; [`PlotError::Io`], [`PlotError::Draw`] or
    /// [`PlotError::Font`] while writing.
    pub fn render(&self, out_dir: &Path, stem: &str) -> Result<RenderedFiles, PlotError> {
        let prepared = self.prepare()?;
        render_files(&prepared, self.style, out_dir, stem)
    }

    pub(super) fn prepare(&self) -> Result<PreparedLines<'_>, PlotError> {
        self.style.check()?;
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

pub(super) struct PreparedLines<'a> {
    plot: &'a LinePlot,
    x: (f64, f64),
    y: (f64, f64),
}

/// Stroke width of the reference lines, in layout pixels.
const REFERENCE_STROKE_PX: u32 = 2;

impl PreparedLines<'_> {
    /// One entry per series, then one per distinct (label, pattern) of the reference lines.
    pub(super) fn legend(&self) -> Vec<LegendEntry<'_>> {
        let mut entries: Vec<LegendEntry<'_>> = self
            .plot
            .series
            .iter()
            .enumerate()
            .map(|(i, s)| LegendEntry {
                label: &s.name,
                swatch: Swatch::Series(SeriesStyle::nth(i)),
            })
            .collect();
        for (k, line) in self.plot.horizontal_lines.iter().enumerate() {
            let seen = self.plot.horizontal_lines[..k]
                .iter()
                .any(|other| other.label == line.label && other.pattern == line.pattern);
            if !seen {
                entries.push(LegendEntry {
                    label: &line.label,
                    swatch: Swatch::Line {
                        color: REFERENCE_COLOR,
                        pattern: line.pattern,
                        width: REFERENCE_STROKE_PX,
                    },
                });
            }
        }
        entries
    }

    /// Builds the chart on `area` with the y coordinate `y_spec` (linear or logarithmic) and draws everything;
    /// returns the pixel row of the plotting area's top in `area` and, when the events are numbered, their key.
    fn draw_chart<DB: DrawingBackend, Y>(
        &self,
        area: &Area<DB>,
        y_spec: impl Fn() -> Y,
        look: Look,
    ) -> Drawn<DB, (i32, Option<String>)>
    where
        Y: AsRangedCoord<Value = f64>,
        Y::CoordDescType: ValueFormatter<f64>,
    {
        let plot = self.plot;
        let markers: Vec<&Marker> = plot
            .markers
            .iter()
            .filter(|m| within(m.x, self.x))
            .collect();
        // The columns of the markers do not depend on the top margin: a first chart, not drawn, gives them, and
        // the label layout gives the height of the band above the plotting area.
        let label_style = look
            .font(EVENT_FONT_PX)
            .color(&EVENT_COLOR)
            .pos(Pos::new(HPos::Center, VPos::Bottom));
        let (base_x, base_y) = area.get_base_pixel();
        let probe = chart_builder(area, look.px(MARGIN_PX), look)
            .build_cartesian_2d(self.x.0..self.x.1, y_spec())?;
        let columns: Vec<i32> = markers
            .iter()
            .map(|m| probe.backend_coord(&(m.x, self.y.1)).0 - base_x)
            .collect();
        let area_width = i32::try_from(area.dim_in_pixel().0).unwrap_or(i32::MAX);
        let layout = |texts: &[String]| -> Drawn<DB, Vec<LabelBox>> {
            let mut items = Vec::with_capacity(texts.len());
            for (&column, text) in columns.iter().zip(texts) {
                let width = area.estimate_text_size(text, &label_style)?.0;
                items.push((column, i32::try_from(width).unwrap_or(i32::MAX)));
            }
            Ok(place_labels(
                &items,
                (0, area_width),
                look.pxi(EVENT_GAP_PX),
            ))
        };
        let row_count = |boxes: &[LabelBox]| boxes.iter().map(|b| b.row + 1).max().unwrap_or(0);
        let mut texts: Vec<String> = markers.iter().map(|m| m.label.clone()).collect();
        let mut boxes = layout(&texts)?;
        // Too many close events for their labels to fit a quarter of the height: numbers on the lines, the key
        // below the legend.
        let max_rows = (area.dim_in_pixel().1 / 4 / look.px(EVENT_ROW_PX).max(1)).max(3);
        let mut key = None;
        if row_count(&boxes) > usize::try_from(max_rows).unwrap_or(usize::MAX) {
            let mut order: Vec<usize> = (0..markers.len()).collect();
            order.sort_by(|&a, &b| markers[a].x.total_cmp(&markers[b].x));
            let mut entries = Vec::with_capacity(order.len());
            for (number, &k) in (1..).zip(&order) {
                texts[k] = number.to_string();
                // No-break spaces keep each entry on one line of the wrapped key.
                let label = markers[k].label.replace(' ', "\u{a0}");
                entries.push(format!("{number}\u{a0}{label}"));
            }
            key = Some(format!("Events: {}.", entries.join("\u{a0}· ")));
            boxes = layout(&texts)?;
        }
        let rows = row_count(&boxes);
        let band = look.px(EVENT_ROW_PX) * u32::try_from(rows).unwrap_or(0);
        let top = look.px(MARGIN_PX) + band + if rows > 0 { look.px(4) } else { 0 };

        let mut chart =
            chart_builder(area, top, look).build_cartesian_2d(self.x.0..self.x.1, y_spec())?;
        draw_mesh(
            &mut chart,
            &plot.x_label,
            &plot.y_label,
            1.0,
            plot.y_scale,
            look,
        )?;
        let plotting = chart.plotting_area().strip_coord_spec();
        let (plot_x, plot_y) = plotting.get_base_pixel();
        let pixel = |p: &(f64, f64)| {
            let (x, y) = chart.backend_coord(p);
            (f64::from(x - plot_x), f64::from(y - plot_y))
        };
        for line in plot.horizontal_lines.iter().filter(|l| within(l.y, self.y)) {
            let ends = [pixel(&(self.x.0, line.y)), pixel(&(self.x.1, line.y))];
            draw_line(
                &plotting,
                &ends,
                REFERENCE_COLOR,
                REFERENCE_STROKE_PX,
                line.pattern,
                look,
            )?;
        }
        for marker in &markers {
            let ends = [pixel(&(marker.x, self.y.0)), pixel(&(marker.x, self.y.1))];
            draw_line(&plotting, &ends, EVENT_COLOR, 2, LinePattern::Dashed, look)?;
        }
        let count = plot.series.len().max(1) as f64;
        for (i, series) in plot.series.iter().enumerate() {
            // Markers of the curves interleaved along the arc length.
            let phase = (i as f64 + 0.5) / count;
            for run in clip_polyline(&series.points, self.x, self.y, plot.y_scale) {
                let pixels: Vec<Px> = run.iter().map(pixel).collect();
                draw_curve(&plotting, &pixels, SeriesStyle::nth(i), phase, look)?;
            }
        }

        let plot_top = plot_y - base_y;
        for (text, label) in texts.iter().zip(&boxes) {
            let centre = (label.left + label.right) / 2;
            let raise = look.pxi(EVENT_ROW_PX as i32) * i32::try_from(label.row).unwrap_or(0);
            let bottom = plot_top - look.pxi(4) - raise;
            area.draw(&Text::new(
                text.as_str(),
                (centre, bottom),
                label_style.clone(),
            ))?;
        }
        Ok((plot_top, key))
    }
}

/// Where an event label goes: its horizontal extent in pixels and its row above the plotting area (0 nearest).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct LabelBox {
    pub(super) left: i32,
    pub(super) right: i32,
    pub(super) row: usize,
}

/// Places labels `(column, width)` (pixels), each centred on its column but shifted to stay within `bounds`, on
/// the lowest row where it keeps `gap` pixels from the labels already there; a new row opens when none has room,
/// so no two labels overlap. Returns the boxes in the order of `items`. Placing from the left on the lowest free
/// row uses the fewest rows any placement of these intervals can.
pub(super) fn place_labels(items: &[(i32, i32)], bounds: (i32, i32), gap: i32) -> Vec<LabelBox> {
    let mut boxes: Vec<LabelBox> = items
        .iter()
        .map(|&(column, width)| {
            let left = (column - width / 2).min(bounds.1 - width).max(bounds.0);
            LabelBox {
                left,
                right: left + width,
                row: 0,
            }
        })
        .collect();
    let mut order: Vec<usize> = (0..boxes.len()).collect();
    order.sort_by_key(|&k| (boxes[k].left, k));
    // Right end of the last label placed on each row.
    let mut row_ends: Vec<i32> = Vec::new();
    for k in order {
        let label = &mut boxes[k];
        let row = match row_ends.iter().position(|&end| end + gap <= label.left) {
            Some(row) => row,
            None => {
                row_ends.push(i32::MIN);
                row_ends.len() - 1
            }
        };
        if let Some(end) = row_ends.get_mut(row) {
            *end = label.right;
        }
        label.row = row;
    }
    boxes
}

impl Draw for PreparedLines<'_> {
    fn title(&self) -> &str {
        &self.plot.title
    }

    fn draw_body<DB: DrawingBackend>(&self, body: &Area<DB>, look: Look) -> Drawn<DB> {
        let entries = self.legend();
        let (chart_area, legend_area) = split_legend(body, &entries, look)?;
        let (lo, hi) = self.y;
        let (plot_top, key) = match self.plot.y_scale {
            Scale::Linear => self.draw_chart(&chart_area, || lo..hi, look)?,
            Scale::Log10 => self.draw_chart(&chart_area, || (lo..hi).log_scale(), look)?,
        };
        let mut notes = self.plot.notes.clone();
        notes.extend(key);
        draw_legend(&legend_area, &entries, &notes, plot_top, look)?;
        Ok(())
    }
}
