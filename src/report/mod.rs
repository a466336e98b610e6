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

/// Runs the four runs of [theory §9](crate::theory#s9), then SNS and the QP cascade as extra rows
/// ([theory §13](crate::theory#s13), [§14](crate::theory#s14)), on
/// `scenario` (a robot with `N` joints), writes their figures (feature `plot`) and
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
    let joint_names = experiment.scene.chain().joint_names();
    let mut runs = Vec::new();
    for kind in RunKind::SELECTABLE {
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
mod figures;
#[cfg(test)]
mod tests;
