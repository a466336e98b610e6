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

/// A labelled rectangle drawn on a [`TrajectoryPlot`], e.g. the image border: `0..width × 0..height` pixels.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Border {
    /// Left and right ends, in data units.
    pub x: (f64, f64),
    /// Top and bottom ends (in a camera image, y down), in data units.
    pub y: (f64, f64),
    /// Legend entry.
    pub label: String,
}

impl Border {
    /// The rectangle `x.0..x.1 × y.0..y.1` with its legend label.
    pub fn new(x: (f64, f64), y: (f64, f64), label: impl Into<String>) -> Self {
        Self {
            x,
            y,
            label: label.into(),
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
    /// The paths, styled in order (colour and dash pattern each cycle through their lists).
    pub trajectories: Vec<Trajectory>,
    /// A rectangle drawn as a solid dark line, e.g. the image border (included in the automatic ranges).
    pub border: Option<Border>,
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
    /// Size and resolution.
    pub style: FigureStyle,
}

impl Default for TrajectoryPlot {
    fn default() -> Self {
        Self {
            title: String::new(),
            x_label: String::new(),
            y_label: String::new(),
            trajectories: Vec::new(),
            border: None,
            x_range: None,
            y_range: None,
            y_down: true,
            equal_aspect: true,
            style: FigureStyle::default(),
        }
    }
}

impl TrajectoryPlot {
    /// Validates the figure and writes `out_dir/stem.png` and `out_dir/stem.svg`, creating `out_dir` if needed.
    ///
    /// # Errors
    /// [`PlotError::NoSeries`], [`PlotError::EmptySeries`], [`PlotError::NonFinite`] (points and desired
    /// positions), [`PlotError::InvalidRange`] (axis ranges, an empty or non-finite border),
    /// [`PlotError::InvalidSize`], [`PlotError::InvalidScale`], [`PlotError::InvalidStem`] before any file is
    /// written; [`PlotError::Io`], [`PlotError::Draw`] or [`PlotError::Font`] while writing.
    pub fn render(&self, out_dir: &Path, stem: &str) -> Result<RenderedFiles, PlotError> {
        let prepared = self.prepare()?;
        render_files(&prepared, self.style, out_dir, stem)
    }

    fn prepare(&self) -> Result<PreparedTrajectories<'_>, PlotError> {
        self.style.check()?;
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
        if let Some(border) = &self.border {
            for (axis, (min, max)) in [("x", border.x), ("y", border.y)] {
                if !(min.is_finite() && max.is_finite() && min < max) {
                    return Err(PlotError::InvalidRange { axis, min, max });
                }
            }
            bounds.include((border.x.0, border.y.0));
            bounds.include((border.x.1, border.y.1));
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

/// The style of trajectory `index`: colour and pattern of the series, no marker (circles and crosses mark the
/// start and the goal).
fn trajectory_style(index: usize) -> SeriesStyle {
    SeriesStyle {
        marker: None,
        ..SeriesStyle::nth(index)
    }
}

impl Draw for PreparedTrajectories<'_> {
    fn title(&self) -> &str {
        &self.plot.title
    }

    fn draw_body<DB: DrawingBackend>(&self, body: &Area<DB>, look: Look) -> Drawn<DB> {
        let plot = self.plot;
        let mut entries: Vec<LegendEntry<'_>> = plot
            .trajectories
            .iter()
            .enumerate()
            .map(|(i, t)| LegendEntry {
                label: &t.name,
                swatch: Swatch::Series(trajectory_style(i)),
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
        if let Some(border) = &plot.border {
            entries.push(LegendEntry {
                label: &border.label,
                swatch: Swatch::Frame(REFERENCE_COLOR),
            });
        }
        let (chart_area, legend_area) = split_legend(body, &entries, look)?;

        let (x, y) = if plot.equal_aspect {
            let (w, h) = chart_area.dim_in_pixel();
            equalise_aspect(
                self.x,
                self.y,
                w.saturating_sub(look.px(2 * MARGIN_PX + Y_LABEL_AREA_PX)),
                h.saturating_sub(look.px(2 * MARGIN_PX + X_LABEL_AREA_PX)),
            )
        } else {
            (self.x, self.y)
        };
        // A camera image has y pointing down: plot -y and label the ticks with y.
        let sign = if plot.y_down { -1.0 } else { 1.0 };
        let (y_lo, y_hi) = if plot.y_down { (-y.1, -y.0) } else { y };
        let mut chart = chart_builder(&chart_area, look.px(MARGIN_PX), look)
            .build_cartesian_2d(x.0..x.1, y_lo..y_hi)?;
        draw_mesh(
            &mut chart,
            &plot.x_label,
            &plot.y_label,
            sign,
            Scale::Linear,
            look,
        )?;
        let plotting = chart.plotting_area().strip_coord_spec();
        let (plot_x, plot_y) = plotting.get_base_pixel();
        let pixel = |&(px, py): &(f64, f64)| {
            let (bx, by) = chart.backend_coord(&(px, sign * py));
            (f64::from(bx - plot_x), f64::from(by - plot_y))
        };
        if let Some(border) = &plot.border {
            let (bx, by) = (border.x, border.y);
            let corners = [
                (bx.0, by.0),
                (bx.1, by.0),
                (bx.1, by.1),
                (bx.0, by.1),
                (bx.0, by.0),
            ];
            for run in clip_polyline(&corners, x, y, Scale::Linear) {
                let pixels: Vec<Px> = run.iter().map(pixel).collect();
                draw_line(
                    &plotting,
                    &pixels,
                    REFERENCE_COLOR,
                    2,
                    LinePattern::Solid,
                    look,
                )?;
            }
        }
        for (i, trajectory) in plot.trajectories.iter().enumerate() {
            let style = trajectory_style(i);
            let inside = |&&(px, py): &&(f64, f64)| within(px, x) && within(py, y);
            for run in clip_polyline(&trajectory.points, x, y, Scale::Linear) {
                let pixels: Vec<Px> = run.iter().map(pixel).collect();
                draw_curve(&plotting, &pixels, style, 0.0, look)?;
            }
            let at = |p: &(f64, f64)| {
                let (px, py) = pixel(p);
                (px.round() as i32, py.round() as i32)
            };
            if let Some(start) = trajectory.points.first().filter(inside) {
                plotting.draw(&Circle::new(
                    at(start),
                    look.pxi(7),
                    look.stroke(style.color, 2),
                ))?;
            }
            if let Some(desired) = trajectory.desired.as_ref().filter(inside) {
                plotting.draw(&Cross::new(
                    at(desired),
                    look.pxi(7),
                    look.stroke(style.color, 3),
                ))?;
            }
        }
        let plot_top = plot_y - chart_area.get_base_pixel().1;
        draw_legend(&legend_area, &entries, &[], plot_top, look)?;
        Ok(())
    }
}
