//! What a run leaves: one [`Record`] per iteration, the continuity at each stack change ([`EventContinuity`]), and
//! the finished [`Run`] with its summary, accumulated record by record so that it is exact whatever the log kept.

use super::Outcome;
use crate::avoidance::{JointLimits, MotionLimits};
use crate::camera::ImagePoint;
use crate::controller::{EventKind, StackEvent, TaskCriteria};
use crate::math::JointVector;

/// One iteration of the run log.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Record<const N: usize> {
    /// The iteration.
    pub iteration: usize,
    /// Its time (s).
    pub time: f64,
    /// The configuration.
    pub q: JointVector<N>,
    /// The velocity sent (zero at the last record of a run that ended before stepping).
    pub velocity: JointVector<N>,
    /// Whether a velocity was sent at this iteration (`false` for the last record of a run that ended before stepping).
    pub sent: bool,
    /// `‖e_i‖` for every task of the list (stacked or not).
    pub task_errors: Vec<f64>,
    /// The tasks stacked at this iteration.
    pub stacked: Vec<usize>,
    /// `h(q)` of the joint-limit cost alone (whatever the run avoids; for the joint-limit figures and margins).
    pub cost: f64,
    /// The controller's predicted `h(q̂)` of the cost it drives with (joint limits, plus obstacles and visibility when
    /// the scene has them; 0 for runs without avoidance): not comparable with [`Record::cost`] when obstacles are on.
    pub predicted_cost: f64,
    /// The criteria of the stacked tasks (empty when `∇h = 0` or without avoidance).
    pub criteria: Vec<TaskCriteria>,
    /// The image points (normalised).
    pub image: [ImagePoint; 4],
    /// The smallest link–obstacle signed distance at `q` (m), when the scene has obstacles.
    pub obstacle_distance: Option<f64>,
}

impl<const N: usize> Record<N> {
    /// A record with empty buffers, filled by the simulation.
    pub(super) fn empty() -> Self {
        Self {
            iteration: 0,
            time: 0.0,
            q: JointVector::zeros(),
            velocity: JointVector::zeros(),
            sent: false,
            task_errors: Vec::new(),
            stacked: Vec::new(),
            cost: 0.0,
            predicted_cost: 0.0,
            criteria: Vec::new(),
            image: [ImagePoint::default(); 4],
            obstacle_distance: None,
        }
    }
}

/// Continuity of the velocity sent at one stack change (D14), from [`Run::event_continuity`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct EventContinuity {
    /// The iteration of the change.
    pub iteration: usize,
    /// What changed.
    pub kind: EventKind,
    /// The task.
    pub task: usize,
    /// `‖u(τ) − q̇(τ⁻)‖`: the jump the law alone would have made.
    pub law_jump: f64,
    /// `‖q̇_k − q̇_{k−1}‖` at the change (zero up to rounding with the transition term).
    pub jump: f64,
    /// The largest `‖q̇_j − q̇_{j−1}‖` after the change, up to the next one: the transition spreads the law's jump over
    /// a ramp whose first step is about `(1 − e^{−μΔt})` times it.
    pub max_step_after: f64,
}

/// The summary of a run, accumulated record by record (exact without the records).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Totals<const N: usize> {
    pub(super) iterations: usize,
    pub(super) last: Option<Record<N>>,
    /// The last velocity sent (zero before the first: the run starts at rest).
    pub(super) last_sent: JointVector<N>,
    pub(super) max_velocity_step: f64,
    /// `a_i Δt`: the change of joint `i`'s velocity its acceleration limit allows in one period (`+∞`: no limit).
    pub(super) step_allowance: JointVector<N>,
    /// The largest `|q̇_i(k) − q̇_i(k−1)|` over the iterations and joints.
    pub(super) max_joint_velocity_step: f64,
    /// The largest `|q̇_i(k) − q̇_i(k−1)| / (a_i Δt)` over the iterations and joints.
    pub(super) max_acceleration_ratio: f64,
    pub(super) min_normalized_margin: f64,
    pub(super) min_obstacle_distance: Option<f64>,
    pub(super) continuity: Vec<EventContinuity>,
}

impl<const N: usize> Totals<N> {
    /// Before the first iteration, at `start`, with the robot's `motion` limits over the period `period` (s).
    pub(super) fn new(
        limits: &JointLimits<N>,
        start: &JointVector<N>,
        motion: &MotionLimits<N>,
        period: f64,
    ) -> Self {
        Self {
            iterations: 0,
            last: None,
            last_sent: JointVector::zeros(),
            max_velocity_step: 0.0,
            step_allowance: motion.max_acceleration * period,
            max_joint_velocity_step: 0.0,
            max_acceleration_ratio: 0.0,
            min_normalized_margin: limits.normalized_margin(start),
            min_obstacle_distance: None,
            continuity: Vec::new(),
        }
    }

    /// Adds the record of the next iteration, with the controller's event log after it.
    pub(super) fn add(
        &mut self,
        record: Record<N>,
        limits: &JointLimits<N>,
        events: &[StackEvent],
    ) {
        self.iterations = record.iteration + 1;
        self.min_normalized_margin = self
            .min_normalized_margin
            .min(limits.normalized_margin(&record.q));
        self.min_obstacle_distance = match (self.min_obstacle_distance, record.obstacle_distance) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        if record.sent {
            // D14: the step at this iteration is the jump of the changes made at it, and otherwise belongs to the window
            // after the last change.
            let change = record.velocity - self.last_sent;
            let step = change.norm();
            self.last_sent = record.velocity;
            self.max_velocity_step = self.max_velocity_step.max(step);
            for (c, allowance) in change.iter().zip(self.step_allowance.iter()) {
                self.max_joint_velocity_step = self.max_joint_velocity_step.max(c.abs());
                // `|c| / +∞ = 0`: a joint without an acceleration limit never counts.
                self.max_acceleration_ratio = self.max_acceleration_ratio.max(c.abs() / allowance);
            }
            let known = self.continuity.len();
            let changes = events
                .get(known..)
                .unwrap_or_default()
                .iter()
                .take_while(|e| e.iteration == record.iteration);
            self.continuity.extend(changes.map(|e| EventContinuity {
                iteration: e.iteration,
                kind: e.kind,
                task: e.task,
                law_jump: e.law_jump,
                jump: step,
                max_step_after: 0.0,
            }));
            if self.continuity.len() == known {
                if let Some(last) = self.continuity.last_mut() {
                    last.max_step_after = last.max_step_after.max(step);
                }
            }
        }
        self.last = Some(record);
    }
}

/// A finished run: its outcome, the records its log kept, the event log and the run's summary.
#[derive(Debug, Clone, PartialEq)]
pub struct Run<const N: usize> {
    /// How it ended.
    pub outcome: Outcome,
    /// The control period `Δt` (s).
    pub period: f64,
    /// The names of the tasks, by index.
    pub task_names: Vec<String>,
    /// One record per iteration from [`simulate`](super::simulate); empty from [`simulate_with`](super::simulate_with)
    /// (its [`RunLog`](super::RunLog) has the records).
    pub records: Vec<Record<N>>,
    /// The controller's event log.
    pub events: Vec<StackEvent>,
    /// The joint limits, for normalised plots and margins.
    pub limits: JointLimits<N>,
    pub(super) totals: Totals<N>,
}

impl<const N: usize> Run<N> {
    /// The number of iterations recorded: the index of the last recorded iteration, plus one. A run whose target is
    /// lost when iteration `k` observes it (out of the image, behind the camera, seen too obliquely) records `k`; 0
    /// when it ended before its first record, e.g. a target lost at the start.
    pub fn iterations(&self) -> usize {
        self.totals.iterations
    }

    /// The record of the last iteration, `None` when the run ended before its first record.
    pub fn last_record(&self) -> Option<&Record<N>> {
        self.totals.last.as_ref()
    }

    /// `‖q̇_k − q̇_{k−1}‖` for every iteration `k` of [`Run::records`] that sent a velocity (D14; `q̇_{−1} = 0`: the
    /// run starts at rest). Needs every record ([`simulate`](super::simulate)); the summaries below do not.
    pub fn velocity_steps(&self) -> Vec<f64> {
        let sent = || {
            std::iter::once(JointVector::zeros())
                .chain(self.records.iter().filter(|r| r.sent).map(|r| r.velocity))
        };
        sent()
            .zip(sent().skip(1))
            .map(|(before, after): (JointVector<N>, _)| (after - before).norm())
            .collect()
    }

    /// The largest step-to-step change of the velocity sent over the run, `max_k ‖q̇_k − q̇_{k−1}‖` (D14; 0 when
    /// nothing was sent); divide by [`Run::period`] for the largest acceleration.
    pub fn max_velocity_step(&self) -> f64 {
        self.totals.max_velocity_step
    }

    /// The largest change of one joint's sent velocity from one period to the next, `max_k max_i |q̇_i(k) −
    /// q̇_i(k−1)|` (rad/s or m/s; `q̇(−1) = 0`: the run starts at rest; 0 when nothing was sent).
    pub fn max_joint_velocity_step(&self) -> f64 {
        self.totals.max_joint_velocity_step
    }

    /// The same change against what the robot's acceleration limits allow in a period,
    /// `max_k max_i |q̇_i(k) − q̇_i(k−1)| / (a_i Δt)` ([`SimulationParameters`](super::SimulationParameters)'s
    /// `max_*_acceleration_*`, [D31](crate::theory#d31)): at most 1 (up to rounding) when the velocity sent keeps
    /// within the limits; 0 without acceleration limits (joints without one do not count).
    pub fn max_acceleration_ratio(&self) -> f64 {
        self.totals.max_acceleration_ratio
    }

    /// The largest `‖q̇(τ⁺) − q̇(τ⁻)‖` over the stack changes: the velocity sent at the iteration of a change against
    /// the one sent at the iteration before (zero before the first iteration: the run starts at rest). D1 makes it
    /// zero up to rounding; [`Run::event_continuity`] says what happens after.
    pub fn max_velocity_jump(&self) -> f64 {
        self.totals
            .continuity
            .iter()
            .map(|c| c.jump)
            .fold(0.0, f64::max)
    }

    /// Continuity at and after every stack change that sent a velocity (D14): the jump at the change, the largest
    /// velocity step in the window from the change to the next one, and the jump the law alone would have made.
    pub fn event_continuity(&self) -> Vec<EventContinuity> {
        self.totals.continuity.clone()
    }

    /// `‖[e_1; …; e_n]‖` at the last iteration; `None` when the run ended before its first record.
    pub fn final_error_norm(&self) -> Option<f64> {
        self.last_record()
            .map(|r| r.task_errors.iter().map(|e| e * e).sum::<f64>().sqrt())
    }

    /// The smallest distance to a limit over time (the start and every iteration) and joints, as a fraction of the
    /// joint's range.
    pub fn min_normalized_margin(&self) -> f64 {
        self.totals.min_normalized_margin
    }

    /// The smallest link–obstacle signed distance over the run (m; negative when penetrating), including the
    /// configuration where a collision ended it; `None` without obstacles.
    pub fn min_obstacle_distance(&self) -> Option<f64> {
        let at_collision = match &self.outcome {
            Outcome::Collision { distance, .. } => Some(*distance),
            _ => None,
        };
        self.totals
            .min_obstacle_distance
            .into_iter()
            .chain(at_collision)
            .reduce(f64::min)
    }

    /// The names of the tasks stacked at the end.
    pub fn stacked_at_end(&self) -> Vec<&str> {
        self.last_record()
            .map(|r| {
                r.stacked
                    .iter()
                    .map(|&i| self.task_names[i].as_str())
                    .collect()
            })
            .unwrap_or_default()
    }

    /// The events of one kind.
    pub fn events_of(&self, kind: EventKind) -> impl Iterator<Item = &StackEvent> {
        self.events.iter().filter(move |e| e.kind == kind)
    }
}
