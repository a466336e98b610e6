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

/// [`write_experiment`] for the joint count of the scenario's robot, chosen at run time
/// ([`crate::scenario::with_joint_count`]: 1 to [`crate::scenario::MAX_JOINTS`]).
///
/// # Errors
/// As [`write_experiment`]; a joint count out of range.
pub fn write_scenario_experiment(
    scenario: &Scenario,
    out_dir: &Path,
) -> Result<Summary, ReportError> {
    struct Write<'a> {
        scenario: &'a Scenario,
        out_dir: &'a Path,
    }
    impl crate::scenario::ForJointCount for Write<'_> {
        type Output = Result<Summary, ReportError>;
        fn call<const N: usize>(self) -> Self::Output {
            write_experiment::<N>(self.scenario, self.out_dir)
        }
    }
    crate::scenario::with_joint_count(scenario.joint_count()?, Write { scenario, out_dir })?
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
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| ReportError::Io { path, source }
    };
    std::fs::create_dir_all(out_dir).map_err(io(out_dir))?;
    let experiment = scenario.experiment::<N>()?;
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

impl std::fmt::Display for Summary {
    /// A table of the runs: outcome, iterations, joint, events, continuity, error, margin.
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
        Ok(())
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
        HorizontalLine, LinePlot, Marker, PlotError, RenderedFiles, Scale, Series, Trajectory,
        TrajectoryPlot,
    };
    use crate::sim::Run;
    use std::path::Path;

    /// How many iterations before the first removal the criteria figure shows.
    const CRITERIA_WINDOW_BEFORE: usize = 450;

    /// What the figures need besides the run: the camera (for pixels) and the desired image.
    #[derive(Debug, Clone, Copy)]
    pub struct FigureContext<'a> {
        /// The camera intrinsics.
        pub intrinsics: &'a CameraIntrinsics,
        /// The desired image points (normalised).
        pub desired: &'a [crate::camera::ImagePoint; 4],
    }

    fn event_markers<const N: usize>(run: &Run<N>) -> Vec<Marker> {
        run.events
            .iter()
            .filter(|e| e.iteration > 0)
            .map(|e| {
                Marker::new(
                    e.iteration as f64,
                    format!("{} {}", e.kind.name(), run.task_names[e.task]),
                )
            })
            .collect()
    }

    /// Writes the figures of `run` into `out_dir` as `{name}_joints` (Fig. 5–7), `{name}_errors`, `{name}_image`, with
    /// obstacles `{name}_obstacle_distance`, and, when the run computed criteria, `{name}_criteria` (Fig. 8: the window
    /// before the first removal, or the whole run), PNG and SVG each. A run without any iteration has no figure.
    ///
    /// # Errors
    /// [`PlotError`] on I/O or invalid data (an empty run).
    pub fn write_figures<const N: usize>(
        run: &Run<N>,
        name: &str,
        context: FigureContext<'_>,
        out_dir: &Path,
    ) -> Result<Vec<RenderedFiles>, PlotError> {
        let iteration = |k: usize| run.records[k].iteration as f64;
        let mut files = Vec::new();
        if run.records.is_empty() {
            return Ok(files); // the run ended before its first iteration (e.g. the target not visible at the start)
        }
        let joints = LinePlot {
            title: format!("{name}: normalised joint positions (limits at 0 and 1)"),
            x_label: "iteration".into(),
            y_label: "(q − q_min) / (q_max − q_min)".into(),
            // An unlimited (continuous) joint has no limits to be normalised by: it is left out.
            series: (0..N)
                .filter(|&j| !run.limits.is_unlimited(j))
                .map(|j| {
                    Series::new(
                        format!("q{j}"),
                        run.records
                            .iter()
                            .enumerate()
                            .map(|(k, r)| (iteration(k), run.limits.normalized(&r.q)[j])),
                    )
                })
                .collect(),
            markers: event_markers(run),
            horizontal_lines: vec![
                HorizontalLine::new(0.0, "limit"),
                HorizontalLine::new(1.0, "limit"),
                HorizontalLine::new(run.limits.activation_ratio(), "activation"),
                HorizontalLine::new(1.0 - run.limits.activation_ratio(), "activation"),
            ],
            y_range: Some((-0.05, 1.05)),
            ..LinePlot::default()
        };
        files.push(joints.render(out_dir, &format!("{name}_joints"))?);
        let errors = LinePlot {
            title: format!("{name}: task errors"),
            x_label: "iteration".into(),
            y_label: "‖e_i‖".into(),
            series: run
                .task_names
                .iter()
                .enumerate()
                .map(|(i, task)| {
                    Series::new(
                        task.clone(),
                        run.records
                            .iter()
                            .enumerate()
                            .map(|(k, r)| (iteration(k), r.task_errors[i].max(1e-9))),
                    )
                })
                .collect(),
            markers: event_markers(run),
            y_scale: Scale::Log10,
            ..LinePlot::default()
        };
        files.push(errors.render(out_dir, &format!("{name}_errors"))?);
        let pixel = |x: f64, y: f64| context.intrinsics.normalized_to_pixel(x, y);
        let image = TrajectoryPlot {
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
            x_range: Some((0.0, context.intrinsics.width())),
            y_range: Some((0.0, context.intrinsics.height())),
            ..TrajectoryPlot::default()
        };
        files.push(image.render(out_dir, &format!("{name}_image"))?);
        // Fig. 8: the criteria around the first removal (the whole run without one), for the tasks stacked at each
        // iteration; 0 where the gradient is zero and the criteria are undefined (as the paper plots them).
        let window = match run.events.iter().find(|e| e.kind == EventKind::Remove) {
            Some(removal) => {
                removal.iteration.saturating_sub(CRITERIA_WINDOW_BEFORE)..removal.iteration + 1
            }
            None => 0..run.records.len(),
        };
        let records =
            &run.records[window.start.min(run.records.len())..window.end.min(run.records.len())];
        let any_criteria = records.iter().any(|r| !r.criteria.is_empty());
        let criteria: Vec<Series> = run
            .task_names
            .iter()
            .enumerate()
            .filter_map(|(i, task)| {
                let points: Vec<(f64, f64)> = records
                    .iter()
                    .filter(|r| r.stacked.contains(&i))
                    .map(|r| {
                        let score = r
                            .criteria
                            .iter()
                            .find(|c| c.task == i)
                            .map_or(0.0, |c| c.combined);
                        (r.iteration as f64, score)
                    })
                    .collect();
                (!points.is_empty()).then(|| Series::new(task.clone(), points))
            })
            .collect();
        let distances: Vec<(f64, f64)> = run
            .records
            .iter()
            .enumerate()
            .filter_map(|(k, r)| r.obstacle_distance.map(|d| (iteration(k), d)))
            .collect();
        if !distances.is_empty() {
            let plot = LinePlot {
                title: format!("{name}: smallest link–obstacle distance"),
                x_label: "iteration".into(),
                y_label: "distance (m)".into(),
                series: vec![Series::new("min distance", distances)],
                markers: event_markers(run),
                horizontal_lines: vec![HorizontalLine::new(0.0, "contact")],
                ..LinePlot::default()
            };
            files.push(plot.render(out_dir, &format!("{name}_obstacle_distance"))?);
        }
        if any_criteria && !criteria.is_empty() {
            let plot = LinePlot {
                title: format!(
                    "{name}: removal criterion S_i = (C1'_i + C2'_i)/‖∇h‖ of the stacked tasks"
                ),
                x_label: "iteration".into(),
                y_label: "S_i (0 where ∇h = 0)".into(),
                series: criteria,
                markers: event_markers(run)
                    .into_iter()
                    .filter(|m| (window.start as f64..=window.end as f64).contains(&m.x))
                    .collect(),
                ..LinePlot::default()
            };
            files.push(plot.render(out_dir, &format!("{name}_criteria"))?);
        }
        Ok(files)
    }
}
