//! Reports of simulated runs: the `summary.json` of the experiments and, with the `plot` feature, their figures
//! (the paper's Fig. 5–8).
//!
//! The summary schema (extra fields allowed):
//!
//! ```text
//! {"scenario": str, "runs": [{"name": str,
//!   "outcome": "converged"|"off_goal"|"joint_limit"|"feature_lost"|"max_iterations"|"stalled"|…,
//!   "reason": str|null, "iterations": int, "joint": int|null, "stacked_at_end": [task names],
//!   "events": [{"iteration": int, "kind": "push"|"remove"|"reinsert"|"fallback"|"escape"|"hold", "task": str,
//!               "law_jump": float, "jump": float, "max_step_after": float}],
//!   "max_velocity_jump": float, "max_velocity_step": float, "max_acceleration": float,
//!   "final_error_norm": float|null, "min_normalized_margin": float}]}
//! ```
//!
//! Continuity (D14): `law_jump` is the jump `‖u(τ) − q̇(τ⁻)‖` the law alone would make at a change, `jump` the step of
//! the velocity actually sent there (zero up to rounding), `max_step_after` its largest step until the next change;
//! `max_velocity_step` is `max_k ‖q̇_k − q̇_{k−1}‖` over the run and `max_acceleration` the same divided by `Δt`.
//!
//! With obstacles, `outcome` may also be `"collision"`, each run has `"min_obstacle_distance"` (m, negative when
//! penetrating) and a collided run `"collision": {"link": str, "obstacle": str}`; a removal event names the cost term
//! that triggered it (`"cost": "joint_limits"|"obstacles"|"visibility"`).

use crate::controller::EventKind;
use crate::scenario::{RunKind, Scenario, ScenarioError};
use crate::sim::{Outcome, Run};
use serde::Serialize;
use std::path::Path;

/// An error and its causes, for people: the error's `Display`, then `: cause` for every source whose message the text
/// does not already hold (a wrapper written `"…: {0}"` repeats its source). Never the `Debug` form, which can hold a
/// whole input file.
///
/// ```
/// use servostack::report::ErrorChain;
/// let error = servostack::scenario::Scenario::from_toml_str("name = 3", None).unwrap_err();
/// let text = ErrorChain(&error).to_string();
/// assert!(text.starts_with("scenario syntax: ") && text.contains("name"));
/// ```
#[derive(Debug, Clone, Copy)]
pub struct ErrorChain<'a>(pub &'a (dyn std::error::Error + 'static));

impl std::fmt::Display for ErrorChain<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut text = self.0.to_string();
        let mut source = self.0.source();
        while let Some(cause) = source {
            let message = cause.to_string();
            if !text.contains(&message) {
                text.push_str(": ");
                text.push_str(&message);
            }
            source = cause.source();
        }
        f.write_str(&text)
    }
}

/// The exit code of a program's `main` (the examples'): success, or `error: ` and the [`ErrorChain`] on stderr and
/// failure.
pub fn exit_code(result: Result<(), Box<dyn std::error::Error>>) -> std::process::ExitCode {
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {}", ErrorChain(&*error));
            std::process::ExitCode::FAILURE
        }
    }
}

/// Errors while writing a report.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// The scenario could not be built or run.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// A file could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The path.
        path: std::path::PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A figure could not be drawn.
    #[cfg(feature = "plot")]
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
}

/// How [`write_experiment_with`] writes its outputs besides `summary.json`.
///
/// ```
/// # #[cfg(feature = "plot")] {
/// use servostack::plot::FigureStyle;
/// use servostack::report::ReportOptions;
/// // Figures for a two-column paper: 3.5 × 2.4 in at 300 dpi.
/// let options = ReportOptions::default().with_figure_style(FigureStyle::for_print(3.5, 2.4, 300.0));
/// # let _ = options;
/// # }
/// ```
#[derive(Debug, Clone, Default, PartialEq)]
#[non_exhaustive]
pub struct ReportOptions {
    /// Size and resolution of the figures (feature `plot`; default 1024 × 640 at scale 1).
    #[cfg(feature = "plot")]
    pub figure_style: crate::plot::FigureStyle,
}

impl ReportOptions {
    /// The options with the figures drawn at `style`.
    #[cfg(feature = "plot")]
    pub fn with_figure_style(self, style: crate::plot::FigureStyle) -> Self {
        Self {
            figure_style: style,
        }
    }
}

/// [`write_experiment`] for the joint count of the scenario's robot, chosen at run time
/// ([`crate::scenario::with_joint_count`]: 1 to [`crate::scenario::MAX_JOINTS`]).
///
/// # Errors
/// As [`write_experiment`]; a joint count out of range.
pub fn write_scenario_experiment(
    scenario: &Scenario,
    out_dir: &Path,
) -> Result<Summary, ReportError> {
    write_scenario_experiment_with(scenario, out_dir, &ReportOptions::default())
}

/// [`write_scenario_experiment`] with `options` (e.g. the figures' size and resolution).
///
/// # Errors
/// As [`write_experiment`]; a joint count out of range.
pub fn write_scenario_experiment_with(
    scenario: &Scenario,
    out_dir: &Path,
    options: &ReportOptions,
) -> Result<Summary, ReportError> {
    struct Write<'a> {
        scenario: &'a Scenario,
        out_dir: &'a Path,
        options: &'a ReportOptions,
    }
    impl crate::scenario::ForJointCount for Write<'_> {
        type Output = Result<Summary, ReportError>;
        fn call<const N: usize>(self) -> Self::Output {
            write_experiment_with::<N>(self.scenario, self.out_dir, self.options)
        }
    }
    let write = Write {
        scenario,
        out_dir,
        options,
    };
    crate::scenario::with_joint_count(scenario.joint_count()?, write)?
}

/// Runs the four runs of [theory §9](crate::theory#s9) on `scenario` (a robot with `N` joints), writes their figures (feature `plot`) and
/// `summary.json` into `out_dir`, and returns the summary.
///
/// # Errors
/// Scenario, simulation, figure or I/O failures.
pub fn write_experiment<const N: usize>(
    scenario: &Scenario,
    out_dir: &Path,
) -> Result<Summary, ReportError> {
    write_experiment_with::<N>(scenario, out_dir, &ReportOptions::default())
}

/// [`write_experiment`] with `options` (e.g. the figures' size and resolution).
///
/// # Errors
/// Scenario, simulation, figure or I/O failures.
pub fn write_experiment_with<const N: usize>(
    scenario: &Scenario,
    out_dir: &Path,
    options: &ReportOptions,
) -> Result<Summary, ReportError> {
    #[cfg(not(feature = "plot"))]
    let _ = options;
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| ReportError::Io { path, source }
    };
    std::fs::create_dir_all(out_dir).map_err(io(out_dir))?;
    let experiment = scenario.experiment::<N>()?;
    #[cfg(feature = "plot")]
    let joint_names: Vec<&str> = experiment
        .scene
        .chain()
        .joints()
        .iter()
        .map(crate::robot::Joint::name)
        .collect();
    let mut runs = Vec::new();
    for kind in RunKind::ALL {
        let run = experiment.run(&scenario.settings(), kind)?;
        #[cfg(feature = "plot")]
        {
            let desired = experiment
                .scene
                .view_from(&experiment.desired_camera_from_target)
                .map_err(ScenarioError::from)?
                .points;
            let context = FigureContext {
                intrinsics: experiment.scene.intrinsics(),
                desired: &desired,
                joint_names: &joint_names,
                // The full method holds the last task, the image points, in reserve (D23).
                reserve_task: (kind == RunKind::FullMethod)
                    .then(|| run.task_names.len().checked_sub(1))
                    .flatten(),
                style: options.figure_style,
            };
            write_figures(&run, kind.name(), context, out_dir)?;
        }
        runs.push(RunSummary::new(kind.name(), &run));
    }
    let summary = Summary {
        scenario: scenario.name.clone(),
        runs,
    };
    let path = out_dir.join("summary.json");
    let json = serde_json::to_string_pretty(&summary).map_err(|e| ReportError::Io {
        path: path.clone(),
        source: e.into(),
    })?;
    std::fs::write(&path, json).map_err(io(&path))?;
    Ok(summary)
}

/// What the columns of the printed [`Summary`] mean, printed under it (in full in the guide `reading_results`,
/// `docs/guide/reading_results.md`).
pub const SUMMARY_COLUMNS: &str = "\
columns: iter = iterations run (time = iter × Δt); joint = the joint that reached its limit (0-based, chain order);
  max jump = largest ‖q̇(τ⁺) − q̇(τ⁻)‖ at a stack change (rad/s; D1 makes it 0 up to rounding);
  max step = largest ‖q̇_k − q̇_(k−1)‖ between two iterations over the run (rad/s; ÷ Δt is the largest acceleration);
  final ‖e‖ = norm of every task's error at the end; margin = closest any joint came to a limit, as a fraction of
  its range (0 = at the limit); events = kind task@iteration.
  Details: docs/guide/reading_results.md (rustdoc: servostack::guide::reading_results).
";

impl std::fmt::Display for Summary {
    /// A table of the runs (outcome, iterations, joint, continuity, error, margin, events), then
    /// [`SUMMARY_COLUMNS`], what its columns mean.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "scenario {}", self.scenario)?;
        writeln!(
            f,
            "{:<17} {:<15} {:>6} {:>5} {:>10} {:>10} {:>10} {:>7}  events",
            "run", "outcome", "iter", "joint", "max jump", "max step", "final ‖e‖", "margin"
        )?;
        for run in &self.runs {
            let events: Vec<String> = run
                .events
                .iter()
                .map(|e| format!("{} {}@{}", e.kind.name(), e.task, e.iteration))
                .collect();
            writeln!(
                f,
                "{:<17} {:<15} {:>6} {:>5} {:>10.1e} {:>10.1e} {:>10} {:>7.3}  {}",
                run.name,
                run.outcome,
                run.iterations,
                run.joint.map_or("-".into(), |j| j.to_string()),
                run.max_velocity_jump,
                run.max_velocity_step,
                run.final_error_norm
                    .map_or("-".into(), |e| format!("{e:.2e}")),
                run.min_normalized_margin,
                events.join(", ")
            )?;
            if let Some(reason) = &run.reason {
                writeln!(f, "{:<17} {reason}", "")?;
            }
            if let Some(distance) = run.min_obstacle_distance {
                writeln!(f, "{:<17} min obstacle distance {distance:.4} m", "")?;
            }
        }
        f.write_str(SUMMARY_COLUMNS)
    }
}

/// The summary of an experiment: one entry per run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// The scenario's name.
    pub scenario: String,
    /// The runs, in order.
    pub runs: Vec<RunSummary>,
}

/// One stack change, as summarised.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EventSummary {
    /// The iteration of the change.
    pub iteration: usize,
    /// `push`, `remove`, `reinsert` or `fallback`.
    pub kind: EventKind,
    /// The task's name.
    pub task: String,
    /// `‖u(τ) − q̇(τ⁻)‖`, the jump the law alone would make (D14).
    pub law_jump: f64,
    /// The step of the velocity sent at the change (D14).
    pub jump: f64,
    /// The largest step of the velocity sent after the change, up to the next one (D14).
    pub max_step_after: f64,
    /// For a removal, the cost term that dominated the predicted cost (extra field).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cost: Option<String>,
    /// For a removal, the predicted cost `h(q̂)`; for a re-insertion or fallback, the cost predicted with the task
    /// back (extra field).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub predicted_cost: Option<f64>,
    /// The threshold `predicted_cost` was compared with: `h_max` for a removal, `r_back · h_max` for a re-insertion
    /// (extra field).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub threshold: Option<f64>,
}

/// Which link hit which obstacle.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CollisionSummary {
    /// The link.
    pub link: String,
    /// The obstacle.
    pub obstacle: String,
}

/// The summary of one run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunSummary {
    /// The run's name (`classical`, `stack`, `stack_gradient`, `stack_controller`, or any).
    pub name: String,
    /// `converged`, `joint_limit`, `feature_lost`, `max_iterations`, `stalled` or `collision`.
    pub outcome: &'static str,
    /// Why a `stalled` or `max_iterations` run did not converge.
    pub reason: Option<String>,
    /// The number of iterations performed.
    pub iterations: usize,
    /// The joint that reached its limit (0-based), or `null`.
    pub joint: Option<usize>,
    /// The names of the tasks stacked at the end.
    pub stacked_at_end: Vec<String>,
    /// The stack changes.
    pub events: Vec<EventSummary>,
    /// The largest `‖q̇(τ⁺) − q̇(τ⁻)‖` over the events.
    pub max_velocity_jump: f64,
    /// `max_k ‖q̇_k − q̇_{k−1}‖` over the run (D14).
    pub max_velocity_step: f64,
    /// `max_velocity_step / Δt` (per s²).
    pub max_acceleration: f64,
    /// `‖e‖` over all tasks at the end; `null` for a run that ended before its first iteration (no image to measure).
    pub final_error_norm: Option<f64>,
    /// The smallest distance to a joint limit over time and joints, as a fraction of the range.
    pub min_normalized_margin: f64,
    /// The point lost, for a `feature_lost` outcome (extra field).
    pub lost_point: Option<usize>,
    /// The smallest link–obstacle signed distance over the run (m, negative when penetrating), for scenes with
    /// obstacles (extra field).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min_obstacle_distance: Option<f64>,
    /// The link and obstacle, for a `collision` outcome (extra field).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub collision: Option<CollisionSummary>,
}

impl RunSummary {
    /// The summary of `run`, under `name`.
    pub fn new<const N: usize>(name: &str, run: &Run<N>) -> Self {
        let (joint, lost_point) = match &run.outcome {
            Outcome::JointLimit { joint, .. } => (Some(*joint), None),
            Outcome::FeatureLost { point } => (None, Some(*point)),
            _ => (None, None),
        };
        let reason = match &run.outcome {
            Outcome::Stalled { reason, .. } | Outcome::MaxIterations { reason } => {
                Some(reason.clone())
            }
            _ => None,
        };
        let collision = match &run.outcome {
            Outcome::Collision { link, obstacle, .. } => Some(CollisionSummary {
                link: link.clone(),
                obstacle: obstacle.clone(),
            }),
            _ => None,
        };
        Self {
            name: name.into(),
            outcome: run.outcome.name(),
            reason,
            iterations: run.iterations(),
            joint,
            stacked_at_end: run.stacked_at_end().into_iter().map(String::from).collect(),
            events: run
                .events
                .iter()
                .zip(run.event_continuity())
                .map(|(e, continuity)| EventSummary {
                    iteration: e.iteration,
                    kind: e.kind,
                    task: run.task_names[e.task].clone(),
                    law_jump: continuity.law_jump,
                    jump: continuity.jump,
                    max_step_after: continuity.max_step_after,
                    cost: e.removal.as_ref().map(|r| r.cost.clone()),
                    predicted_cost: e
                        .removal
                        .as_ref()
                        .map(|r| r.predicted_cost)
                        .or(e.reinsertion.map(|r| r.predicted_cost)),
                    threshold: e
                        .removal
                        .as_ref()
                        .map(|r| r.threshold)
                        .or(e.reinsertion.map(|r| r.threshold)),
                })
                .collect(),
            max_velocity_jump: run.max_velocity_jump(),
            max_velocity_step: run.max_velocity_step(),
            max_acceleration: run.max_velocity_step() / run.period,
            final_error_norm: run.final_error_norm(),
            min_normalized_margin: run.min_normalized_margin(),
            lost_point,
            min_obstacle_distance: run.min_obstacle_distance(),
            collision,
        }
    }
}

#[cfg(feature = "plot")]
pub use figures::{write_figures, FigureContext};

#[cfg(feature = "plot")]
mod figures {
    use crate::camera::CameraIntrinsics;
    use crate::controller::EventKind;
    use crate::plot::{
        Border, FigureStyle, HorizontalLine, LinePattern, LinePlot, Marker, PlotError,
        RenderedFiles, Scale, Series, Trajectory, TrajectoryPlot,
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
    fn task_label<const N: usize>(
        run: &Run<N>,
        context: &FigureContext<'_>,
        task: usize,
    ) -> String {
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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_printed_table_explains_every_column() {
        let summary = Summary {
            scenario: "s".into(),
            runs: Vec::new(),
        };
        let text = summary.to_string();
        let header = text.lines().nth(1).unwrap_or_default();
        for column in [
            "iter",
            "joint",
            "max jump",
            "max step",
            "final ‖e‖",
            "margin",
            "events",
        ] {
            assert!(header.contains(column), "{column:?} not in {header:?}");
            assert!(
                text.contains(&format!("{column} = ")),
                "{column:?} not explained"
            );
        }
        assert!(text.contains("docs/guide/reading_results.md"));
    }
}

#[cfg(all(test, feature = "plot"))]
mod figure_tests {
    use super::figures::{errors_figure, image_figure, joints_figure};
    use super::*;
    use crate::plot::tests::{assert_disjoint, event_label_boxes, svg_texts, OutDir};
    use crate::plot::FigureStyle;
    use crate::scenario::Experiment;

    /// The full method on the reference scenario: its experiment and run.
    fn full_method() -> (Experiment<6>, Run<6>) {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/assets/scenarios/paper_afma6.toml"
        );
        let scenario = Scenario::from_file(Path::new(path)).unwrap();
        let experiment = scenario.experiment::<6>().unwrap();
        let run = experiment
            .run(&scenario.settings(), RunKind::FullMethod)
            .unwrap();
        (experiment, run)
    }

    /// Renders the figures of the full method and checks them on what they show.
    #[test]
    fn full_method_figures_are_paper_ready() {
        let (experiment, run) = full_method();
        let desired = experiment
            .scene
            .view_from(&experiment.desired_camera_from_target)
            .unwrap()
            .points;
        let names: Vec<&str> = experiment
            .scene
            .chain()
            .joints()
            .iter()
            .map(crate::robot::Joint::name)
            .collect();
        let context = FigureContext {
            intrinsics: experiment.scene.intrinsics(),
            desired: &desired,
            joint_names: &names,
            reserve_task: Some(run.task_names.len() - 1),
            style: FigureStyle::default(),
        };

        // Time in seconds: the x axis spans the run's duration, iterations × Δt; the events sit at their time.
        let duration = run.iterations() as f64 * run.period;
        assert!((duration - 27.77).abs() < 1e-9, "{duration}");
        let joints = joints_figure(&run, "full", &context);
        assert_eq!(joints.x_label, "time (s)");
        assert_eq!(joints.x_range, Some((0.0, duration)));
        let errors = errors_figure(&run, "full", &context);
        assert_eq!(errors.x_range, Some((0.0, duration)));
        for series in joints.series.iter().chain(&errors.series) {
            let last = series.points.last().unwrap().0;
            assert!((last - (duration - run.period)).abs() < 1e-9, "{last}");
        }
        let times: Vec<f64> = joints.markers.iter().map(|m| m.x).collect();
        let expected: Vec<f64> = run
            .events
            .iter()
            .filter(|e| e.iteration > 0)
            .map(|e| e.iteration as f64 * run.period)
            .collect();
        assert_eq!(times.len(), expected.len());
        for (t, e) in times.iter().zip(&expected) {
            assert!((t - e).abs() < 1e-9, "{t} vs {e}");
        }

        let out = OutDir::new("report-full-method");
        let files = write_figures(&run, "full", context, &out.0).unwrap();
        let svg = |stem: &str| {
            let file = files
                .iter()
                .find(|f| f.svg.ends_with(format!("{stem}.svg")));
            std::fs::read_to_string(&file.unwrap().svg).unwrap()
        };
        let has_text = |svg: &str, text: &str| svg_texts(svg).iter().any(|t| t.2 == text);

        // Joints by their URDF names, not q0…q5.
        let joints_svg = svg("full_joints");
        for name in &names {
            assert!(
                has_text(&joints_svg, name),
                "joint {name:?} not in the legend"
            );
        }
        assert!(!has_text(&joints_svg, "q0"));
        assert!(has_text(&joints_svg, "time (s)"));
        // Limit and activation: two legend entries.
        assert!(has_text(&joints_svg, "limit"));
        assert!(has_text(&joints_svg, "activation (ρ = 0.1)"));

        // The close events of this run (1, 2, 3 and 3.51 s on 27.8 s) get labels that do not overlap.
        let labels: Vec<&str> = joints.markers.iter().map(|m| m.label.as_str()).collect();
        assert!(labels.len() >= 5, "{labels:?}");
        assert_disjoint(&event_label_boxes(&joints_svg, &labels), &labels);

        // The reserve task is named as such and explained.
        let errors_svg = svg("full_errors");
        let reserve = format!("{} (reserve)", run.task_names.last().unwrap());
        assert!(has_text(&errors_svg, &reserve), "{reserve:?}");
        assert!(errors_svg.contains("D23"), "the note cites D23");

        // The image border: 640 × 480 px in the legend, inside the plotted range.
        let image = image_figure(&run, "full", &context);
        let border = image.border.as_ref().unwrap();
        assert_eq!((border.x, border.y), ((0.0, 640.0), (0.0, 480.0)));
        assert!(has_text(&svg("full_image"), "image 640 × 480 px"));
    }
}
