//! Trajectory plots: paths in the image plane with their start and desired positions.

use super::*;

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

struct PreparedTrajectories<'a> {
    plot: &'a TrajectoryPlot,
    x: (f64, f64),
    y: (f64, f64),
}

/// Widens `x` or `y` about its centre so that both axes have the same data units per pixel on a plotting area of
/// `width` × `height` pixels.
pub(super) fn equalise_aspect(
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
