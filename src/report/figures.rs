//! The figures of a run: joints with the stack events, criteria, image trajectories and task errors.

use crate::camera::CameraIntrinsics;
use crate::controller::EventKind;
use crate::plot::{
    Border, FigureStyle, HorizontalLine, LinePattern, LinePlot, Marker, PlotError, RenderedFiles,
    Scale, Series, Trajectory, TrajectoryPlot,
};
use crate::sim::Run;
use std::path::Path;

/// How many iterations before the first removal the criteria figure shows.
const CRITERIA_WINDOW_BEFORE: usize = 450;
/// The abscissa of every time plot.
const TIME_LABEL: &str = "time (s)";

/// What the figures need besides the run: the camera (for pixels), the desired image, the joints' names, the
/// reserve task and the figures' size.
#[derive(Debug, Clone, Copy)]
pub struct FigureContext<'a> {
    /// The camera intrinsics (pixels, and the image border `width × height`).
    pub intrinsics: &'a CameraIntrinsics,
    /// The desired image points (normalised).
    pub desired: &'a [crate::camera::ImagePoint; 4],
    /// The URDF names of the joints in the chain's order, the legend of the joint figure
    /// (`chain.joints()[j].name()`); a joint without a name here is `q{j}`.
    pub joint_names: &'a [&'a str],
    /// The task the controller held in reserve (D23: the full method's image points, the last task of the
    /// list), explained on the figures where it appears; `None` without one.
    pub reserve_task: Option<usize>,
    /// Size and resolution of the figures.
    pub style: FigureStyle,
}

/// The x range of the time plots of `run`: `0` to its duration, iterations × `Δt`.
fn time_range<const N: usize>(run: &Run<N>) -> (f64, f64) {
    (0.0, run.iterations() as f64 * run.period)
}

/// The task's name, marked when it is the reserve task.
fn task_label<const N: usize>(run: &Run<N>, context: &FigureContext<'_>, task: usize) -> String {
    let name = run.task_names.get(task).map_or("?", String::as_str);
    if context.reserve_task == Some(task) {
        format!("{name} (reserve)")
    } else {
        name.to_owned()
    }
}

/// The note explaining the reserve task, for the figures where it appears.
fn reserve_note<const N: usize>(run: &Run<N>, context: &FigureContext<'_>) -> Vec<String> {
    let Some(task) = context.reserve_task else {
        return Vec::new();
    };
    let name = run.task_names.get(task).map_or("?", String::as_str);
    let escape = run.events.iter().find(|e| e.kind == EventKind::Escape);
    let what = match escape {
        Some(e) => format!("it took that place at t = {:.2} s", e.time),
        None => "it never did in this run, so its error is shown, not controlled".to_owned(),
    };
    vec![format!(
        "{name} (reserve): the full method holds this task back and pushes it in place of the last task only \
         to leave a false equilibrium (event escape, D23); {what}."
    )]
}

fn event_markers<const N: usize>(run: &Run<N>, context: &FigureContext<'_>) -> Vec<Marker> {
    run.events
        .iter()
        .filter(|e| e.iteration > 0)
        .map(|e| {
            let task = run.task_names.get(e.task).map_or("?", String::as_str);
            let label = if context.reserve_task == Some(e.task) {
                format!("{} {task} (reserve)", e.kind.name())
            } else {
                format!("{} {task}", e.kind.name())
            };
            Marker::new(e.time, label)
        })
        .collect()
}

/// Fig. 5–7: the joints normalised to their limits, by URDF name, with the limits, the activation thresholds
/// and the stack events.
pub(super) fn joints_figure<const N: usize>(
    run: &Run<N>,
    name: &str,
    context: &FigureContext<'_>,
) -> LinePlot {
    let rho = run.limits.activation_ratio();
    let reserve_escaped = run.events.iter().any(|e| e.kind == EventKind::Escape);
    LinePlot {
        title: format!("{name}: normalised joint positions"),
        x_label: TIME_LABEL.into(),
        y_label: "(q − q_min) / (q_max − q_min)".into(),
        // An unlimited (continuous) joint has no limits to be normalised by: it is left out.
        series: (0..N)
            .filter(|&j| !run.limits.is_unlimited(j))
            .map(|j| {
                let joint = context
                    .joint_names
                    .get(j)
                    .map_or_else(|| format!("q{j}"), |n| (*n).to_owned());
                Series::new(
                    joint,
                    run.records
                        .iter()
                        .map(|r| (r.time, run.limits.normalized(&r.q)[j])),
                )
            })
            .collect(),
        markers: event_markers(run, context),
        horizontal_lines: vec![
            HorizontalLine::new(0.0, "limit").with_pattern(LinePattern::Solid),
            HorizontalLine::new(1.0, "limit").with_pattern(LinePattern::Solid),
            HorizontalLine::new(rho, format!("activation (ρ = {rho})"))
                .with_pattern(LinePattern::Dotted),
            HorizontalLine::new(1.0 - rho, format!("activation (ρ = {rho})"))
                .with_pattern(LinePattern::Dotted),
        ],
        notes: if reserve_escaped {
            reserve_note(run, context)
        } else {
            Vec::new()
        },
        x_range: Some(time_range(run)),
        y_range: Some((-0.05, 1.05)),
        style: context.style,
        ..LinePlot::default()
    }
}

/// The norm of each task's error, on a log axis; the reserve task marked and explained.
pub(super) fn errors_figure<const N: usize>(
    run: &Run<N>,
    name: &str,
    context: &FigureContext<'_>,
) -> LinePlot {
    LinePlot {
        title: format!("{name}: task errors"),
        x_label: TIME_LABEL.into(),
        y_label: "‖e_i‖".into(),
        series: (0..run.task_names.len())
            .map(|i| {
                Series::new(
                    task_label(run, context, i),
                    run.records
                        .iter()
                        .map(|r| (r.time, r.task_errors[i].max(1e-9))),
                )
            })
            .collect(),
        markers: event_markers(run, context),
        notes: reserve_note(run, context),
        x_range: Some(time_range(run)),
        y_scale: Scale::Log10,
        style: context.style,
        ..LinePlot::default()
    }
}

/// The four points in the image, in pixels, inside the image border.
pub(super) fn image_figure<const N: usize>(
    run: &Run<N>,
    name: &str,
    context: &FigureContext<'_>,
) -> TrajectoryPlot {
    let pixel = |x: f64, y: f64| context.intrinsics.normalized_to_pixel(x, y);
    let (width, height) = (context.intrinsics.width(), context.intrinsics.height());
    // Room around the border, so that it shows as a frame inside the axes.
    let (pad_x, pad_y) = (0.04 * width, 0.04 * height);
    TrajectoryPlot {
        title: format!("{name}: image trajectories of the four points"),
        x_label: "u (px)".into(),
        y_label: "v (px)".into(),
        trajectories: (0..4)
            .map(|p| {
                let d = context.desired[p];
                Trajectory::new(
                    format!("point {p}"),
                    run.records
                        .iter()
                        .map(|r| pixel(r.image[p].x, r.image[p].y)),
                    Some(pixel(d.x, d.y)),
                )
            })
            .collect(),
        border: Some(Border::new(
            (0.0, width),
            (0.0, height),
            format!("image {width} × {height} px"),
        )),
        x_range: Some((-pad_x, width + pad_x)),
        y_range: Some((-pad_y, height + pad_y)),
        style: context.style,
        ..TrajectoryPlot::default()
    }
}

/// Writes the figures of `run` into `out_dir` as `{name}_joints` (Fig. 5–7), `{name}_errors`, `{name}_image`, with
/// obstacles `{name}_obstacle_distance`, and, when the run computed criteria, `{name}_criteria` (Fig. 8: the window
/// before the first removal, or the whole run), PNG and SVG each, over time in seconds. A run without any
/// iteration has no figure.
///
/// # Errors
/// [`PlotError`] on I/O or invalid data (an empty run, a style out of range).
pub fn write_figures<const N: usize>(
    run: &Run<N>,
    name: &str,
    context: FigureContext<'_>,
    out_dir: &Path,
) -> Result<Vec<RenderedFiles>, PlotError> {
    let mut files = Vec::new();
    if run.records.is_empty() {
        return Ok(files); // the run ended before its first iteration (e.g. the target not visible at the start)
    }
    let context = &context;
    files.push(joints_figure(run, name, context).render(out_dir, &format!("{name}_joints"))?);
    files.push(errors_figure(run, name, context).render(out_dir, &format!("{name}_errors"))?);
    files.push(image_figure(run, name, context).render(out_dir, &format!("{name}_image"))?);
    // Fig. 8: the criteria around the first removal (the whole run without one), for the tasks stacked at each
    // iteration; 0 where the gradient is zero and the criteria are undefined (as the paper plots them).
    let window = match run.events.iter().find(|e| e.kind == EventKind::Remove) {
        Some(removal) => {
            removal.iteration.saturating_sub(CRITERIA_WINDOW_BEFORE)..removal.iteration + 1
        }
        None => 0..usize::MAX,
    };
    let records: Vec<_> = run
        .records
        .iter()
        .filter(|r| window.contains(&r.iteration))
        .collect();
    let any_criteria = records.iter().any(|r| !r.criteria.is_empty());
    let criteria: Vec<Series> = (0..run.task_names.len())
        .filter_map(|i| {
            let points: Vec<(f64, f64)> = records
                .iter()
                .filter(|r| r.stacked.contains(&i))
                .map(|r| {
                    let score = r
                        .criteria
                        .iter()
                        .find(|c| c.task == i)
                        .map_or(0.0, |c| c.combined);
                    (r.time, score)
                })
                .collect();
            (!points.is_empty()).then(|| Series::new(task_label(run, context, i), points))
        })
        .collect();
    let distances: Vec<(f64, f64)> = run
        .records
        .iter()
        .filter_map(|r| r.obstacle_distance.map(|d| (r.time, d)))
        .collect();
    if !distances.is_empty() {
        let plot = LinePlot {
            title: format!("{name}: smallest link–obstacle distance"),
            x_label: TIME_LABEL.into(),
            y_label: "distance (m)".into(),
            series: vec![Series::new("min distance", distances)],
            markers: event_markers(run, context),
            horizontal_lines: vec![HorizontalLine::new(0.0, "contact")],
            x_range: Some(time_range(run)),
            style: context.style,
            ..LinePlot::default()
        };
        files.push(plot.render(out_dir, &format!("{name}_obstacle_distance"))?);
    }
    if any_criteria && !criteria.is_empty() {
        let shown = |iteration: usize| iteration as f64 * run.period;
        let first = records.first().map_or(0.0, |r| r.time);
        let last = records.last().map_or(0.0, |r| r.time);
        let reserve_shown = context
            .reserve_task
            .is_some_and(|t| records.iter().any(|r| r.stacked.contains(&t)));
        let plot = LinePlot {
            title: format!(
                "{name}: removal criterion S_i = (C1'_i + C2'_i)/‖∇h‖ of the stacked tasks"
            ),
            x_label: TIME_LABEL.into(),
            y_label: "S_i (0 where ∇h = 0)".into(),
            series: criteria,
            markers: event_markers(run, context)
                .into_iter()
                .filter(|m| (shown(window.start)..=shown(window.end)).contains(&m.x))
                .collect(),
            notes: if reserve_shown {
                reserve_note(run, context)
            } else {
                Vec::new()
            },
            x_range: (last > first).then_some((first, last)),
            style: context.style,
            ..LinePlot::default()
        };
        files.push(plot.render(out_dir, &format!("{name}_criteria"))?);
    }
    Ok(files)
}
