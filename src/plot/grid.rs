//! Outcome maps: a grid of situations (two varied coordinates), one panel per method, each cell coloured by the
//! category of what happened there (converged, joint limit, feature lost, ...).

use super::*;

/// Categories over a regular 2-D grid, one panel per method, with a legend of the categories.
///
/// Cell `(i, j)` of a panel is centred at `(x_values[i], y_values[j])`; its category is
/// `panels[p].1[j * x_values.len() + i]`, an index into `categories` (coloured in order from the palette).
#[derive(Debug, Clone, PartialEq)]
pub struct OutcomeMap {
    /// Title above the figure.
    pub title: String,
    /// Description of the x axis (with units).
    pub x_label: String,
    /// Description of the y axis (with units).
    pub y_label: String,
    /// Cell centres along x, increasing.
    pub x_values: Vec<f64>,
    /// Cell centres along y, increasing.
    pub y_values: Vec<f64>,
    /// The category names.
    pub categories: Vec<String>,
    /// Per panel, its name and the category of every cell (row-major, y outer).
    pub panels: Vec<(String, Vec<usize>)>,
    /// Size and resolution.
    pub style: FigureStyle,
}

impl OutcomeMap {
    /// Validates the map and writes `out_dir/stem.png` and `out_dir/stem.svg`.
    ///
    /// # Errors
    /// [`PlotError::NoSeries`] without panels or cells, [`PlotError::EmptySeries`] for a panel whose cell count is
    /// not `x_values.len() · y_values.len()` or that names a category beyond the list, [`PlotError::InvalidRange`]
    /// for non-finite or non-increasing cell centres, [`PlotError::InvalidSize`], [`PlotError::InvalidScale`],
    /// [`PlotError::InvalidStem`] before any file is written; [`PlotError::Io`], [`PlotError::Draw`] or
    /// [`PlotError::Font`] while writing.
    pub fn render(&self, out_dir: &Path, stem: &str) -> Result<RenderedFiles, PlotError> {
        self.style.check()?;
        if self.panels.is_empty() || self.x_values.is_empty() || self.y_values.is_empty() {
            return Err(PlotError::NoSeries {
                figure: self.title.clone(),
            });
        }
        for (axis, values) in [("x", &self.x_values), ("y", &self.y_values)] {
            let increasing = values.windows(2).all(|w| w[0] < w[1]);
            if !(values.iter().all(|v| v.is_finite()) && increasing) {
                return Err(PlotError::InvalidRange {
                    axis,
                    min: values.first().copied().unwrap_or(f64::NAN),
                    max: values.last().copied().unwrap_or(f64::NAN),
                });
            }
        }
        let cells = self.x_values.len() * self.y_values.len();
        for (name, panel) in &self.panels {
            if panel.len() != cells || panel.iter().any(|&c| c >= self.categories.len()) {
                return Err(PlotError::EmptySeries {
                    series: name.clone(),
                });
            }
        }
        render_files(self, self.style, out_dir, stem)
    }

    /// The cell edges along one axis: midpoints between centres, extended by half a step at both ends.
    fn edges(values: &[f64]) -> Vec<f64> {
        let step = |i: usize| match values.len() {
            1 => 1.0,
            _ => values[(i + 1).min(values.len() - 1)] - values[i.min(values.len() - 2)],
        };
        let mut edges = Vec::with_capacity(values.len() + 1);
        edges.push(values[0] - 0.5 * step(0));
        edges.extend(values.windows(2).map(|w| 0.5 * (w[0] + w[1])));
        edges.push(values[values.len() - 1] + 0.5 * step(values.len() - 1));
        edges
    }
}

impl Draw for OutcomeMap {
    fn title(&self) -> &str {
        &self.title
    }

    fn draw_body<DB: DrawingBackend>(&self, area: &Area<DB>, look: Look) -> Drawn<DB> {
        let entries: Vec<LegendEntry<'_>> = self
            .categories
            .iter()
            .zip(PALETTE.iter().cycle())
            .map(|(label, &color)| LegendEntry {
                label,
                swatch: Swatch::Fill(color),
            })
            .collect();
        let (maps, legend) = split_legend(area, &entries, look)?;
        draw_legend(&legend, &entries, &[], look.pxi(MARGIN_PX as i32), look)?;
        let x_edges = Self::edges(&self.x_values);
        let y_edges = Self::edges(&self.y_values);
        let (x0, x1) = (x_edges[0], x_edges[x_edges.len() - 1]);
        let (y0, y1) = (y_edges[0], y_edges[y_edges.len() - 1]);
        let nx = self.x_values.len();
        for ((name, cells), panel) in self
            .panels
            .iter()
            .zip(maps.split_evenly((1, self.panels.len())))
        {
            let mut chart = chart_builder(&panel, look.px(MARGIN_PX), look)
                .caption(name, look.font(AXIS_DESC_FONT_PX))
                .build_cartesian_2d(x0..x1, y0..y1)?;
            draw_mesh(
                &mut chart,
                &self.x_label,
                &self.y_label,
                1.0,
                Scale::Linear,
                look,
            )?;
            chart.draw_series(cells.iter().enumerate().map(|(k, &category)| {
                let (i, j) = (k % nx, k / nx);
                let color = PALETTE[category % PALETTE.len()];
                Rectangle::new(
                    [(x_edges[i], y_edges[j]), (x_edges[i + 1], y_edges[j + 1])],
                    color.filled(),
                )
            }))?;
        }
        Ok(())
    }
}
