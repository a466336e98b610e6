//! What a study finds: per run a [`MethodResult`], per draw a [`DrawResult`], per family and method a
//! [`MethodSummary`], per family a [`FamilyResult`], and the whole [`StudyResult`]; with the summary of one run that
//! the study keeps.

use super::{shard, wilson_lower_95, Family, Shard, StudyError};
use crate::robot::KinematicsWorkspace;
use crate::scenario::RunKind;
use crate::sim::{Outcome, Run};
use serde::{Deserialize, Serialize};

/// An outcome's name: an alias that keeps serde's derive from borrowing the name from the text it reads (it reads
/// one of [`Outcome::NAMES`]).
type OutcomeName = &'static str;

/// What one method did on one draw.
///
/// Read back from a study's `study.json` to merge shards ([`StudyResult::merge`]): a non-finite value, written as
/// `null`, reads as `+∞`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodResult {
    /// The method.
    pub method: RunKind,
    /// The outcome's name ([`Outcome::name`]).
    #[serde(deserialize_with = "shard::outcome_name")]
    pub outcome: OutcomeName,
    /// Iterations performed.
    pub iterations: usize,
    /// Removals over the run (D6: a task taken out because the avoidance was predicted to fail; the tasks a restart
    /// takes out are counted apart, [`Self::restart_take_outs`]).
    pub removals: usize,
    /// The largest number of removals of one task.
    pub max_removals_of_a_task: usize,
    /// Tasks taken out by a restart of the sequence ([D29](crate::theory#d29); 0 when it did not restart).
    pub restart_take_outs: usize,
    /// The largest number of times one task was taken out: its removals and a restart's taking it out alike.
    pub max_take_outs_of_a_task: usize,
    /// The iteration at which the sequence restarted ([D29](crate::theory#d29)); absent when it did not. With
    /// [`Self::iterations`] it tells how much of a win the replay took.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restart_iteration: Option<usize>,
    /// Whether the controller fell back to the stack with gradient (D13).
    pub fallback: bool,
    /// `max_k ‖q̇_k − q̇_{k−1}‖` (D14).
    #[serde(deserialize_with = "shard::finite_or_infinity")]
    pub max_velocity_step: f64,
    /// The largest change of one joint's sent velocity from one period to the next, `max_k max_i |q̇_i(k) −
    /// q̇_i(k−1)|` (rad/s or m/s, [`Run::max_joint_velocity_step`]).
    #[serde(default, deserialize_with = "shard::finite_or_infinity")]
    pub max_joint_velocity_step: f64,
    /// That change against the robot's acceleration limit, `max_k max_i |q̇_i(k) − q̇_i(k−1)| / (a_i Δt)`
    /// ([`Run::max_acceleration_ratio`], [D31](crate::theory#d31)): at most 1 (up to rounding) when the velocity sent
    /// keeps within the scenario's `max_*_acceleration_*`; 0 without acceleration limits (and in a `study.json`
    /// written before the field).
    #[serde(default, deserialize_with = "shard::finite_or_infinity")]
    pub max_acceleration_ratio: f64,
    /// The camera's distance to its goal at the end (m).
    #[serde(deserialize_with = "shard::finite_or_infinity")]
    pub camera_translation_error: f64,
    /// The camera's rotation to its goal at the end (degrees).
    #[serde(deserialize_with = "shard::finite_or_infinity")]
    pub camera_rotation_error_deg: f64,
    /// The smallest distance of a joint to its nearest hard limit over the run, as a fraction of the joint's range.
    #[serde(deserialize_with = "shard::finite_or_infinity")]
    pub min_normalized_margin: f64,
    /// The configuration at the end of the run (m or rad per joint).
    pub end: Vec<f64>,
    /// The reason of a `stalled` or `max_iterations` outcome.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

impl MethodResult {
    /// `true` when the run converged.
    pub fn converged(&self) -> bool {
        self.outcome == "converged"
    }

    /// `true` when the run converged, at some time within [`AT_LIMIT_MARGIN`] of a hard limit.
    pub fn converged_at_limit(&self) -> bool {
        self.converged() && self.min_normalized_margin < AT_LIMIT_MARGIN
    }
}

/// A run that came closer than this fraction of a joint's range to one of its hard limits touched it: on the UR5e's
/// ±2π joints 0.013 rad. Such a run converges with no room left: a tracking error or a measurement error of that size
/// would have taken the joint past its limit. The classical law does so when a copy of its goal configuration lies on
/// a limit (on the UR5e, a wrist or base joint's goal at 0 and its copy at 2π, which it approaches without crossing).
/// The study reports these wins apart ([`FamilyResult::baseline_wins_at_limit`]); they still count as wins.
pub const AT_LIMIT_MARGIN: f64 = 1e-3;

/// One draw: its situation and what each method did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DrawResult {
    /// The draw's index in its family.
    pub draw: usize,
    /// Invalid situations rejected before this one.
    pub rejected: usize,
    /// Whether the straight joint-space path from the start to the goal keeps the target in the image, within the
    /// incidence bound, and the joints inside their limits ([`straight_feasible`](super::straight_feasible)).
    #[serde(default)]
    pub straight_feasible: bool,
    /// The start configuration.
    pub start: Vec<f64>,
    /// The goal configuration.
    pub goal: Vec<f64>,
    /// One result per method, in the study's order.
    pub methods: Vec<MethodResult>,
}

impl DrawResult {
    /// `true` when a paper baseline ([`RunKind::is_paper_baseline`]) converged on this draw, and every baseline that
    /// converged touched a hard limit on the way ([`MethodResult::converged_at_limit`]).
    pub fn baselines_converged_only_at_limit(&self) -> bool {
        let mut baselines = self
            .methods
            .iter()
            .filter(|m| m.method.is_paper_baseline() && m.converged())
            .peekable();
        baselines.peek().is_some() && baselines.all(MethodResult::converged_at_limit)
    }
}

/// Per method, over a family.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MethodSummary {
    /// The method.
    pub method: RunKind,
    /// Draws that converged.
    pub converged: usize,
    /// Draws.
    pub draws: usize,
    /// Count per outcome name.
    pub outcomes: std::collections::BTreeMap<&'static str, usize>,
    /// The median number of removals per run.
    pub median_removals: f64,
    /// The median over runs of the largest number of removals of one task in the run (how often the same task is
    /// taken out: the measure of chatter).
    pub median_removals_of_a_task: f64,
    /// The largest number of removals of one task in one run.
    pub max_removals_of_a_task: usize,
    /// Runs that fell back (D13).
    pub fallbacks: usize,
    /// Runs that restarted their sequence ([D29](crate::theory#d29)).
    pub restarts: usize,
    /// The median over runs of the largest number of times one task was taken out, counting its removals and a
    /// restart's taking it out (D29) alike.
    pub median_take_outs_of_a_task: f64,
    /// The median over runs of `max_k ‖q̇_k − q̇_{k−1}‖`.
    pub median_max_velocity_step: f64,
    /// The largest [`MethodResult::max_acceleration_ratio`] over the runs: at most 1 (up to rounding) when every
    /// velocity sent kept within the acceleration limits; 0 without them.
    pub max_acceleration_ratio: f64,
    /// Runs that converged with the camera within [`POSE_TOLERANCE_M`] and [`POSE_TOLERANCE_DEG`] of its goal (with a
    /// measurement model, the run converges on the noise-free errors; this says where the camera really ended).
    pub converged_within_pose_tolerance: usize,
    /// The median of the iterations the converged runs took; absent when none converged.
    pub median_iterations_to_converge: Option<f64>,
    /// The 95th percentile (nearest rank: the smallest count that at least 95 % of the converged runs did not
    /// exceed) of the iterations the converged runs took; absent when none converged. Against
    /// [`StudyResult::budget`]: how close the wins came to the end of their budget.
    pub p95_iterations_to_converge: Option<usize>,
}

/// The camera-position tolerance of [`MethodSummary::converged_within_pose_tolerance`] (m).
pub const POSE_TOLERANCE_M: f64 = 0.002;
/// The camera-orientation tolerance of [`MethodSummary::converged_within_pose_tolerance`] (degrees).
pub const POSE_TOLERANCE_DEG: f64 = 0.2;

/// A family's results.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FamilyResult {
    /// The family.
    pub family: Family,
    /// Per method.
    pub methods: Vec<MethodSummary>,
    /// Draws where at least one of the other methods converged.
    pub any_baseline_converged: usize,
    /// Of those, draws where the full method converged too.
    pub full_method_also_converged: usize,
    /// Draws where the stack with gradient converged and the full method did not.
    pub full_method_worse_than_stack_gradient: usize,
    /// Of the draws where a baseline converged, those where every baseline that converged touched a hard limit on the
    /// way ([`MethodResult::converged_at_limit`]).
    pub baseline_wins_at_limit: usize,
    /// Of those, draws where the full method converged too.
    pub full_method_also_converged_at_limit: usize,
    /// Draws that are straight-feasible ([`DrawResult::straight_feasible`]).
    pub straight_feasible: usize,
    /// Of those, draws where the full method converged.
    pub full_method_straight_feasible: usize,
    /// Every draw.
    pub draws: Vec<DrawResult>,
}

impl FamilyResult {
    /// `converged/feasible (≥ bound %)`: the full method's share of the straight-feasible draws with its Wilson 95 %
    /// lower bound ([`wilson_lower_95`]); `-` without such a draw.
    pub fn straight_feasible_text(&self) -> String {
        if self.straight_feasible == 0 {
            return "-".to_owned();
        }
        format!(
            "{}/{} (≥ {:.0} %)",
            self.full_method_straight_feasible,
            self.straight_feasible,
            100.0 * wilson_lower_95(self.full_method_straight_feasible, self.straight_feasible)
        )
    }
}

/// The results of a study.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StudyResult {
    /// The scenario's name.
    pub scenario: String,
    /// The seed.
    pub seed: u64,
    /// Draws per family.
    pub draws_per_family: usize,
    /// Each run's iteration budget, the scenario's `simulation.max_iterations` (0 in a `study.json` written before
    /// the field).
    pub budget: usize,
    /// The part of the draws run ([`Study::with_shard`](super::Study::with_shard)); absent: every draw.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shard: Option<Shard>,
    /// Per family (of a shard: over the shard's draws).
    pub families: Vec<FamilyResult>,
    /// Simulated control iterations over the study.
    pub iterations: usize,
    /// Wall-clock time of the study (s).
    pub seconds: f64,
    /// Threads used.
    pub threads: usize,
}

/// The summary of one run, with the camera's distance to its goal at the end.
pub(super) fn method_result<const N: usize>(
    method: RunKind,
    run: &Run<N>,
    experiment: &crate::scenario::Experiment<N>,
) -> Result<MethodResult, StudyError> {
    let mut per_task = vec![0usize; run.task_names.len()];
    for event in run.events_of(crate::controller::EventKind::Remove) {
        per_task[event.task] += 1;
    }
    let mut take_outs = per_task.clone();
    for event in run.events_of(crate::controller::EventKind::Restart) {
        take_outs[event.task] += 1;
    }
    let q_end = run.last_record().map_or(experiment.start, |r| r.q);
    let (camera_translation_error, camera_rotation_error_deg) = match experiment
        .scene
        .observe(&mut KinematicsWorkspace::new(), &q_end)
    {
        Ok(view) => experiment.scene.distance_to_goal(&view.c_from_o),
        Err(_) => (f64::INFINITY, f64::INFINITY),
    };
    let reason = match &run.outcome {
        Outcome::Stalled { reason, .. } | Outcome::MaxIterations { reason } => Some(reason.clone()),
        _ => None,
    };
    Ok(MethodResult {
        method,
        outcome: run.outcome.name(),
        iterations: run.iterations(),
        removals: per_task.iter().sum(),
        max_removals_of_a_task: per_task.iter().copied().max().unwrap_or(0),
        restart_take_outs: run.events_of(crate::controller::EventKind::Restart).count(),
        max_take_outs_of_a_task: take_outs.iter().copied().max().unwrap_or(0),
        restart_iteration: run
            .events_of(crate::controller::EventKind::Restart)
            .next()
            .map(|event| event.iteration),
        fallback: run
            .events_of(crate::controller::EventKind::Fallback)
            .next()
            .is_some(),
        max_velocity_step: run.max_velocity_step(),
        max_joint_velocity_step: run.max_joint_velocity_step(),
        max_acceleration_ratio: run.max_acceleration_ratio(),
        camera_translation_error,
        camera_rotation_error_deg,
        min_normalized_margin: run.min_normalized_margin(),
        end: q_end.iter().copied().collect(),
        reason,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn result(method: RunKind, outcome: &'static str, min_normalized_margin: f64) -> MethodResult {
        MethodResult {
            method,
            outcome,
            iterations: 100,
            removals: 0,
            max_removals_of_a_task: 0,
            restart_take_outs: 0,
            max_take_outs_of_a_task: 0,
            restart_iteration: None,
            fallback: false,
            max_velocity_step: 0.0,
            max_joint_velocity_step: 0.0,
            max_acceleration_ratio: 0.0,
            camera_translation_error: 0.0,
            camera_rotation_error_deg: 0.0,
            min_normalized_margin,
            end: vec![0.0; 6],
            reason: None,
        }
    }

    fn draw(methods: Vec<MethodResult>) -> DrawResult {
        DrawResult {
            draw: 0,
            rejected: 0,
            straight_feasible: false,
            start: vec![0.0; 6],
            goal: vec![0.0; 6],
            methods,
        }
    }

    /// A win at a limit is a converged run whose margin fell below `AT_LIMIT_MARGIN`; a draw counts apart only when
    /// every baseline that converged did so, and the full method's own margin plays no part.
    #[test]
    fn a_draw_is_won_only_at_a_limit_when_every_converged_baseline_touched_one() {
        use RunKind::{Classical, FullMethod, StackGradient};
        assert!(result(Classical, "converged", 5e-4).converged_at_limit());
        assert!(!result(Classical, "converged", 2e-3).converged_at_limit());
        assert!(!result(Classical, "joint_limit", 0.0).converged_at_limit());
        let at_limit = result(Classical, "converged", 0.0);
        let clean = result(StackGradient, "converged", 0.05);
        let failed = result(StackGradient, "joint_limit", 0.0);
        let full = result(FullMethod, "converged", 0.0);
        assert!(draw(vec![at_limit.clone(), failed.clone(), full.clone()])
            .baselines_converged_only_at_limit());
        assert!(
            !draw(vec![at_limit.clone(), clean, full.clone()]).baselines_converged_only_at_limit()
        );
        let failed_classical = result(Classical, "joint_limit", 0.0);
        assert!(!draw(vec![failed_classical, failed, full]).baselines_converged_only_at_limit());
    }
}
