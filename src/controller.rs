//! The stack controller: push tasks when the robot has settled, predict when the avoidance will fail, remove the task
//! that blocks it, and put it back when the danger has passed (MATH §6, (F20)–(F27), D3–D7).
//!
//! One control iteration ([`StackController::step`], MATH §6.5):
//!
//! 1. the control law D1/\[M18\] runs on the current stack ([`crate::law::control_step`]);
//! 2. **prediction** (D6, \[M22\]): `q̂ = q + T_pred u`, with `u = q̇_n − κ P^A_n ∇h` the law of the current stack. If
//!    `h(q̂) > h_max`, `h(q̂) > h(q)`, `∇h(q) ≠ 0` and a task is stacked, one task is **removed**, chosen by the criteria
//!    below;
//! 3. otherwise, when the robot has **settled** (D5: `‖q̇_n‖ < ε_add` and `t − τ ≥ 5/μ`), a removed task is **put back**
//!    first, at its original priority, if the prediction with it re-inserted stays below `h_max` (D7); else the next
//!    task of the list is **pushed**.
//!
//! The prediction uses `u`, not the blended `q̇` of D1: the transition term is a decaying memory of the *previous* stack
//! and says nothing about the current one. Predicting with `q̇` right after a removal would see the old, dangerous
//! velocity for about `1/μ` and remove a second, innocent task (observed on synthetic stacks); with `u`, a removal is
//! judged by what the remaining stack will do, as the re-insertion test of D7 is. The condition `h(q̂) > h(q)` (our
//! refinement of D6) keeps the controller from removing tasks while the current stack already moves away from the
//! obstacle — for instance just after a removal, when the transition has carried `q` a little past the threshold.
//!
//! A change decided at iteration `k` takes effect at once (§6.5: "remove, τ ← t, recompute"): the law is solved again
//! on the new stack and blended from the velocity sent at iteration `k − 1`, so `q̇(τ⁺) = q̇(τ⁻)` exactly (D1). At most
//! one change happens per iteration. Tasks are identified by their index in the task list, which is also
//! their priority (index 0 highest).
//!
//! **Criteria** (§6.3), for every stacked task `i` with its own Jacobian `J_i` and the gradient `g = ∇h(q)`:
//!
//! ```text
//! [M23]/D3  C1_i  = −(J_i⁺ e_i)ᵀ g ,   C1'_i = C1_i / ‖J_i⁺ e_i‖   (0 when ‖J_i⁺ e_i‖ is below a floor)   [M24]
//! [M25]     C2_i  = ‖(I − J_i⁺ J_i) g‖                               (remove argmin)
//! [M26]     C2'_i = ‖V_1ᵀ g‖ ,  C2_i² + C2'_i² = ‖g‖²               (remove argmax)                     [M27]
//! D4        S_i   = (C1'_i + C2'_i) / ‖g‖ ∈ [−1, 2]                  (remove argmax, default)
//! ```
//!
//! Every push, removal and re-insertion is recorded in an event log ([`StackEvent`]) with its iteration, time and task;
//! removals also record the predicted cost, the joint that dominates the predicted gradient, the cost term that dominates
//! the predicted cost (for a [`crate::avoidance::CompositeCost`] of joint limits, obstacles and visibility), and every
//! task's criteria.

use crate::avoidance::{Cost, CostError};
use crate::law::{
    control_step, ControlLaw, ControlOutput, ControlWorkspace, LawError, StackChange,
};
use crate::linalg::{ColumnSvd, VelocityInverse};
use crate::math::JointVector;
use crate::stack::{solve_stack, StackError, StackWorkspace};
use crate::task::{TaskJacobian, TaskValue};

/// Errors of the stack controller.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ControllerError {
    /// A parameter is out of its range.
    #[error("controller parameter `{name}` = {value} is invalid: {expected}")]
    InvalidParameter {
        /// The parameter's name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What is expected.
        expected: &'static str,
    },
    /// The task list given to [`StackController::step`] differs in length from the one the controller was built for.
    #[error("controller built for {expected} tasks, stepped with {found}")]
    TaskCount {
        /// The number of tasks at construction.
        expected: usize,
        /// The number given.
        found: usize,
    },
    /// The control law failed.
    #[error(transparent)]
    Law(#[from] LawError),
    /// The avoidance cost failed.
    #[error(transparent)]
    Cost(#[from] CostError),
}

/// Which criterion picks the task to remove (MATH §6.3, D4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RemovalCriterion {
    /// `argmax_i (C1'_i + C2'_i)/‖g‖` (D4, default).
    #[default]
    Combined,
    /// `argmax_i C1'_i` (direction only, \[M24\]).
    NormalizedDirection,
    /// `argmin_i C2_i` (\[M25\]).
    KernelProjection,
}

/// The thresholds of the controller, with their units. Immutable once the controller is built.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerParameters {
    /// `ε_add`: the stack has settled when the Euclidean norm of the stack velocity `‖q̇_n‖` is below this (D5). Its unit
    /// mixes the joints' units per second (m/s for prismatic, rad/s for revolute joints).
    pub settle_velocity: f64,
    /// After a change, wait `t − τ ≥ settle_transitions / μ` seconds before the next push (D5; 5 by default, when the
    /// transition term has decayed to `e^{−5} ≈ 0.7 %`).
    pub settle_transitions: f64,
    /// `T_pred` (s): the prediction horizon `q̂ = q + T_pred u` of D6 / \[M22\], with `u` the current stack's law
    /// (not the blended `q̇`: see the module docs).
    pub prediction_horizon: f64,
    /// `h_max`: a task is removed when `h(q̂) > h_max` (D6), in the cost's unit. `None`: the caller's default (for the
    /// joint-limit cost, [`crate::avoidance::JointLimits::default_removal_threshold`]): the cost's
    /// [`Cost::default_removal_threshold`] (D6), and no removal for a cost without one.
    pub removal_threshold: Option<f64>,
    /// Whether tasks may be removed at all (`false`: push-only, as the paper's runs 2 and 3).
    pub allow_removal: bool,
    /// The criterion that picks the task to remove.
    pub criterion: RemovalCriterion,
}

impl Default for ControllerParameters {
    fn default() -> Self {
        Self {
            settle_velocity: 0.01,
            settle_transitions: 5.0,
            prediction_horizon: 0.05,
            removal_threshold: None,
            allow_removal: true,
            criterion: RemovalCriterion::Combined,
        }
    }
}

impl ControllerParameters {
    /// Checks every parameter.
    ///
    /// # Errors
    /// [`ControllerError::InvalidParameter`] naming the first offending parameter.
    pub fn validate(&self) -> Result<(), ControllerError> {
        let invalid = |name, value, expected| {
            Err(ControllerError::InvalidParameter {
                name,
                value,
                expected,
            })
        };
        if !(self.settle_velocity.is_finite() && self.settle_velocity > 0.0) {
            return invalid("settle_velocity", self.settle_velocity, "finite and > 0");
        }
        if !(self.settle_transitions.is_finite() && self.settle_transitions >= 0.0) {
            return invalid(
                "settle_transitions",
                self.settle_transitions,
                "finite and ≥ 0",
            );
        }
        if !(self.prediction_horizon.is_finite() && self.prediction_horizon >= 0.0) {
            return invalid(
                "prediction_horizon",
                self.prediction_horizon,
                "finite and ≥ 0",
            );
        }
        if let Some(h_max) = self.removal_threshold {
            if !(h_max.is_finite() && h_max > 0.0) {
                return invalid("removal_threshold", h_max, "finite and > 0");
            }
        }
        Ok(())
    }
}

/// The criteria of one stacked task at one instant (MATH §6.3).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct TaskCriteria {
    /// The task's index in the task list.
    pub task: usize,
    /// `C1_i = −(J_i⁺ e_i)ᵀ ∇h` (D3, \[M23\]).
    pub c1: f64,
    /// `C1'_i = C1_i / ‖J_i⁺ e_i‖` (\[M24\]).
    pub c1_normalized: f64,
    /// `C2_i = ‖(I − J_i⁺ J_i) ∇h‖` (\[M25\]).
    pub c2: f64,
    /// `C2'_i = ‖V_1ᵀ ∇h‖` (\[M26\]–\[M27\]).
    pub c2_prime: f64,
    /// `S_i = (C1'_i + C2'_i)/‖∇h‖` (D4).
    pub combined: f64,
}

impl TaskCriteria {
    /// The score that the criterion maximises.
    fn score(&self, criterion: RemovalCriterion) -> f64 {
        match criterion {
            RemovalCriterion::Combined => self.combined,
            RemovalCriterion::NormalizedDirection => self.c1_normalized,
            RemovalCriterion::KernelProjection => -self.c2,
        }
    }
}

/// What happened to the stack.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    /// The next task of the list was pushed (D5).
    Push,
    /// A task was removed because the avoidance was predicted to fail (D6).
    Remove,
    /// A removed task was put back at its original priority (D7).
    Reinsert,
}

/// Why a task was removed.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RemovalReport {
    /// The predicted cost `h(q̂)` that exceeded the threshold.
    pub predicted_cost: f64,
    /// The threshold `h_max`.
    pub threshold: f64,
    /// The joint with the largest component of the predicted gradient `∇h(q̂)` (0-based).
    pub joint: usize,
    /// The cost term that dominates the predicted cost `h(q̂)` ([`Cost::dominant_term`]: `"joint_limits"`,
    /// `"obstacles"`, `"visibility"`, ...).
    pub cost: String,
    /// The criteria of every stacked task at the removal.
    pub criteria: Vec<TaskCriteria>,
}

/// One change of the stack, as the event log records it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StackEvent {
    /// The control iteration at which the change was made (the velocity sent at this iteration is the new stack's,
    /// blended from the one sent at the previous iteration).
    pub iteration: usize,
    /// The time of that iteration (s).
    pub time: f64,
    /// Push, removal or re-insertion.
    pub kind: EventKind,
    /// The task's index in the task list.
    pub task: usize,
    /// For a removal, why.
    pub removal: Option<RemovalReport>,
}

/// The result of one controller iteration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControllerStep<const N: usize> {
    /// The joint velocity to send (D1).
    pub velocity: JointVector<N>,
    /// `‖q̇_n‖`, the norm of the stack velocity without transition and avoidance (the D5 settling test).
    pub stack_velocity_norm: f64,
    /// `h(q)`.
    pub cost: f64,
    /// `h(q̂)`, the cost predicted at `q̂ = q + T_pred u` (equal to `h(q)` without a cost or with a zero horizon).
    pub predicted_cost: f64,
    /// The change made at this iteration, if any.
    pub event: Option<EventKind>,
}

/// The stack controller's state: which tasks are stacked, pending and removed, the transition memory, the event log.
/// Its buffers are allocated once, at construction; an iteration without event allocates nothing. An event appends to
/// the event log (preallocated for four events per task, growing beyond), and a removal copies the criteria into its
/// report: events are rare and outside the steady state.
#[derive(Debug, Clone)]
pub struct StackController<const N: usize> {
    parameters: ControllerParameters,
    task_count: usize,
    stacked: Vec<usize>,
    next_push: usize,
    removed: Vec<usize>,
    change_pending: bool,
    last_change_time: f64,
    law_workspace: ControlWorkspace<N>,
    trial_workspace: StackWorkspace<N>,
    trial_order: Vec<usize>,
    criteria: Vec<TaskCriteria>,
    jacobian_work: TaskJacobian<N>,
    /// One decomposition per task, each warm-started from the same task's previous criteria.
    svds: Vec<ColumnSvd<N>>,
    events: Vec<StackEvent>,
}

impl<const N: usize> StackController<N> {
    /// A controller for `tasks` (their order is their priority), at rest, with the first task stacked from the first
    /// iteration (a push at iteration 0, logged). A one-task list gives the classical law.
    ///
    /// # Errors
    /// [`ControllerError::InvalidParameter`].
    pub fn new(
        parameters: ControllerParameters,
        tasks: &[TaskValue<N>],
    ) -> Result<Self, ControllerError> {
        parameters.validate()?;
        let max_rows = tasks.iter().map(TaskValue::rows).max().unwrap_or(1);
        Ok(Self {
            parameters,
            task_count: tasks.len(),
            stacked: Vec::with_capacity(tasks.len()),
            next_push: 0,
            removed: Vec::with_capacity(tasks.len()),
            change_pending: true,
            last_change_time: 0.0,
            law_workspace: ControlWorkspace::new(tasks),
            trial_workspace: StackWorkspace::new(tasks),
            trial_order: Vec::with_capacity(tasks.len()),
            criteria: Vec::with_capacity(tasks.len()),
            jacobian_work: TaskJacobian::zeros(max_rows),
            svds: vec![ColumnSvd::default(); tasks.len()],
            events: Vec::with_capacity(4 * tasks.len() + 8),
        })
    }

    /// The parameters.
    pub fn parameters(&self) -> &ControllerParameters {
        &self.parameters
    }

    /// The tasks currently stacked, highest priority first (after this iteration's change, if any).
    pub fn stacked(&self) -> &[usize] {
        &self.stacked
    }

    /// The tasks removed and waiting to be put back.
    pub fn removed(&self) -> &[usize] {
        &self.removed
    }

    /// `true` when every task of the list is stacked (none pending, none removed).
    pub fn is_complete(&self) -> bool {
        self.next_push == self.task_count && self.removed.is_empty()
    }

    /// The event log.
    pub fn events(&self) -> &[StackEvent] {
        &self.events
    }

    /// The control law's workspace (last output, stack solution, transition state).
    pub fn law_workspace(&self) -> &ControlWorkspace<N> {
        &self.law_workspace
    }

    /// The criteria of the stacked tasks computed at the last iteration (empty when `∇h = 0` or no cost is given).
    pub fn criteria(&self) -> &[TaskCriteria] {
        &self.criteria
    }

    fn push_next(&mut self, iteration: usize, time: f64) {
        let task = self.next_push;
        self.next_push += 1;
        self.insert_by_priority(task);
        self.record(iteration, time, EventKind::Push, task, None);
    }

    fn insert_by_priority(&mut self, task: usize) {
        let at = self.stacked.partition_point(|&t| t < task);
        self.stacked.insert(at, task);
    }

    fn record(
        &mut self,
        iteration: usize,
        time: f64,
        kind: EventKind,
        task: usize,
        removal: Option<RemovalReport>,
    ) {
        self.change_pending = true;
        self.last_change_time = time;
        self.events.push(StackEvent {
            iteration,
            time,
            kind,
            task,
            removal,
        });
    }

    /// One iteration at time `time` (s) for the configuration `q`, with the tasks evaluated at `q`, an optional
    /// avoidance cost, and the law (its `κ` may be 0 for no avoidance term).
    ///
    /// # Errors
    /// A task list of another length than at construction, law and cost failures.
    pub fn step(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: Option<&dyn Cost<N>>,
        q: &JointVector<N>,
        iteration: usize,
        time: f64,
    ) -> Result<ControllerStep<N>, ControllerError> {
        if tasks.len() != self.task_count {
            return Err(ControllerError::TaskCount {
                expected: self.task_count,
                found: tasks.len(),
            });
        }
        let first_step = self.events.is_empty() && self.next_push == 0;
        if first_step && self.task_count > 0 {
            // The first task is stacked from the first iteration, at its time.
            self.push_next(iteration, time);
        }
        let change = if self.change_pending {
            StackChange::Changed
        } else {
            StackChange::Unchanged
        };
        // q̇(τ⁻) of a change decided at this iteration: the velocity sent at the previous one.
        let velocity_sent_before = *self.law_workspace.last_output().velocity();
        let output = control_step(
            law,
            &mut self.law_workspace,
            tasks,
            &self.stacked,
            cost,
            q,
            time,
            change,
        )?
        .clone();
        let mut result = self.summarize(&output);
        self.change_pending = false;
        let gradient = *output.gradient();
        let law_velocity = *output.law();
        let decided = self.decide(
            law,
            tasks,
            cost,
            q,
            &gradient,
            &law_velocity,
            iteration,
            time,
            &mut result,
        );
        let event = match decided {
            Ok(event) => event,
            Err(error) => {
                // Nothing is sent: the next step must blend from the velocity actually sent before.
                self.law_workspace.reset(&velocity_sent_before);
                self.change_pending = change == StackChange::Changed;
                return Err(error);
            }
        };
        if let Some(kind) = event {
            // MATH §6.5: the change takes effect now; the law is solved again on the new stack and blended from the
            // velocity actually sent before, so q̇(τ⁺) = q̇(τ⁻) (D1).
            self.law_workspace.reset(&velocity_sent_before);
            let changed = StackChange::Changed;
            let output = control_step(
                law,
                &mut self.law_workspace,
                tasks,
                &self.stacked,
                cost,
                q,
                time,
                changed,
            )?
            .clone();
            let predicted_cost = result.predicted_cost;
            result = self.summarize(&output);
            result.predicted_cost = predicted_cost;
            result.event = Some(kind);
        }
        Ok(result)
    }

    /// `h_max`: the parameter, else the cost's D6 default, else no removal.
    fn removal_threshold(&self, cost: &dyn Cost<N>) -> f64 {
        self.parameters
            .removal_threshold
            .or_else(|| cost.default_removal_threshold())
            .unwrap_or(f64::INFINITY)
    }

    fn summarize(&self, output: &ControlOutput<N>) -> ControllerStep<N> {
        ControllerStep {
            velocity: *output.velocity(),
            stack_velocity_norm: self.law_workspace.stack_solution().velocity().norm(),
            cost: output.cost(),
            predicted_cost: output.cost(),
            event: None,
        }
    }

    /// Steps 4–5 of MATH §6.5: a removal (D6) or else a re-insertion (D7) or a push (D5), applied to the stack and
    /// logged. `result` receives the predicted cost.
    #[allow(clippy::too_many_arguments)]
    fn decide(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: Option<&dyn Cost<N>>,
        q: &JointVector<N>,
        gradient: &JointVector<N>,
        law_velocity: &JointVector<N>,
        iteration: usize,
        time: f64,
        result: &mut ControllerStep<N>,
    ) -> Result<Option<EventKind>, ControllerError> {
        self.criteria.clear();
        if let Some(cost) = cost {
            let predicted = q + law_velocity * self.parameters.prediction_horizon;
            let mut predicted_gradient = JointVector::zeros();
            result.predicted_cost = cost.value_and_gradient(&predicted, &mut predicted_gradient)?;
            if gradient.norm() > 0.0 {
                self.compute_criteria(law, tasks, gradient)?;
            }
            let threshold = self.removal_threshold(cost);
            let may_remove =
                self.parameters.allow_removal && !self.stacked.is_empty() && gradient.norm() > 0.0;
            let worsening = result.predicted_cost > result.cost;
            if may_remove && worsening && result.predicted_cost > threshold {
                let dominant = cost.dominant_term(&predicted)?.to_owned();
                let task = self.choose_removal();
                self.stacked.retain(|&t| t != task);
                self.removed.push(task);
                let report = RemovalReport {
                    predicted_cost: result.predicted_cost,
                    threshold,
                    joint: predicted_gradient.iamax(),
                    cost: dominant,
                    criteria: self.criteria.clone(),
                };
                self.record(iteration, time, EventKind::Remove, task, Some(report));
                return Ok(Some(EventKind::Remove));
            }
        }
        if !self.settled(law, time, result.stack_velocity_norm) {
            return Ok(None);
        }
        if let Some(task) = self.reinsertable(law, tasks, cost, q, gradient)? {
            self.removed.retain(|&t| t != task);
            self.insert_by_priority(task);
            self.record(iteration, time, EventKind::Reinsert, task, None);
            return Ok(Some(EventKind::Reinsert));
        }
        if self.removed.is_empty() && self.next_push < self.task_count {
            self.push_next(iteration, time);
            return Ok(Some(EventKind::Push));
        }
        Ok(None)
    }

    /// D5: the stack velocity is small and the last transition has died out.
    fn settled(&self, law: &ControlLaw, time: f64, stack_velocity_norm: f64) -> bool {
        stack_velocity_norm < self.parameters.settle_velocity
            && time - self.last_change_time
                >= self.parameters.settle_transitions / law.transition_gain()
    }

    /// D7: the first removed task whose re-insertion keeps the prediction `h(q + T_pred u) ≤ h_max`, where `u` is the
    /// law of the stack with the task put back.
    fn reinsertable(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: Option<&dyn Cost<N>>,
        q: &JointVector<N>,
        gradient: &JointVector<N>,
    ) -> Result<Option<usize>, ControllerError> {
        let Some(&task) = self.removed.first() else {
            return Ok(None);
        };
        let Some(cost) = cost else {
            return Ok(Some(task));
        };
        self.trial_order.clear();
        self.trial_order.extend_from_slice(&self.stacked);
        let at = self.trial_order.partition_point(|&t| t < task);
        self.trial_order.insert(at, task);
        let solution = solve_stack(
            law.stack_parameters(),
            &mut self.trial_workspace,
            tasks,
            &self.trial_order,
        )
        .map_err(LawError::from)?;
        let mut trial_law = *solution.velocity();
        trial_law.gemv(-law.avoidance_gain(), solution.projector(), gradient, 1.0);
        let predicted = q + trial_law * self.parameters.prediction_horizon;
        let threshold = self.removal_threshold(cost);
        Ok((cost.value(&predicted)? <= threshold).then_some(task))
    }

    /// Computes [`TaskCriteria`] for every stacked task (MATH §6.3) into `self.criteria`.
    ///
    /// # Errors
    /// A failed decomposition of a task Jacobian (the removal must not be chosen from an incomplete set).
    fn compute_criteria(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        gradient: &JointVector<N>,
    ) -> Result<(), ControllerError> {
        let policy = law.stack_parameters().rank_policy;
        let gradient_norm = gradient.norm();
        for &index in &self.stacked {
            let (Some(task), Some(svd)) = (tasks.get(index), self.svds.get_mut(index)) else {
                continue;
            };
            let rows = task.rows();
            let mut work = self.jacobian_work.rows_mut(0, rows);
            work.copy_from(task.jacobian());
            let linalg = |source| {
                ControllerError::Law(LawError::Stack(StackError::Linalg {
                    level: index,
                    source,
                }))
            };
            svd.decompose_warm(&mut work, &policy, 0.0)
                .map_err(linalg)?;
            let mut direction = JointVector::zeros(); // J_i⁺ e_i
            svd.solve(
                &work,
                task.error(),
                VelocityInverse::Truncated,
                &mut direction,
            )
            .map_err(linalg)?;
            let c1 = -direction.dot(gradient);
            let direction_norm = direction.norm();
            let c1_normalized = if direction_norm > DIRECTION_FLOOR {
                c1 / direction_norm
            } else {
                0.0
            };
            let c2_prime = svd.row_space_component_norm(gradient);
            let c2 = (gradient_norm * gradient_norm - c2_prime * c2_prime)
                .max(0.0)
                .sqrt();
            self.criteria.push(TaskCriteria {
                task: index,
                c1,
                c1_normalized,
                c2,
                c2_prime,
                combined: (c1_normalized + c2_prime) / gradient_norm,
            });
        }
        Ok(())
    }

    /// The stacked task with the best score; the lowest-priority one on ties (or when no criteria exist).
    fn choose_removal(&self) -> usize {
        let criterion = self.parameters.criterion;
        // `max_by` keeps the last of equal maxima: the lowest priority.
        self.criteria
            .iter()
            .max_by(|a, b| a.score(criterion).total_cmp(&b.score(criterion)))
            .map(|c| c.task)
            .or_else(|| self.stacked.last().copied())
            .unwrap_or(0)
    }
}

/// Below this norm of `J_i⁺ e_i` the task is achieved and `C1'_i` is set to 0 (MATH D3).
const DIRECTION_FLOOR: f64 = 1e-12;
