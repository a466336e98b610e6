//! The stack controller: push tasks when the robot has settled, predict when the avoidance will fail, remove the task
//! that blocks it, and put it back when the danger has passed ([theory §6](crate::theory#s6),
//! [(F20)](crate::theory#f20)–[(F27)](crate::theory#f27), [D3](crate::theory#d3)–[D7](crate::theory#d7),
//! [D13](crate::theory#d13)).
//!
//! # One iteration ([`StackController::step`], [theory §6.5](crate::theory#s6-5))
//!
//! 1. The control law D1/\[M18\] runs on the current stack ([`crate::law::control_step`]): `u = q̇_n − κ P^A_n ∇h` and
//!    the velocity sent `q̇ = u + e^{−μ(t−τ)}(q̇(τ⁻) − u(τ))`.
//! 2. **Prediction** (D6). The configuration a horizon `T` ahead is predicted along the velocity *actually sent*, with
//!    its transition term still decaying, and `u` held constant:
//!
//!    ```text
//!    q̂(T) = q + T u + (1 − e^{−μT})/μ · (q̇ − u)                 (the exact integral of D1 for a constant u)
//!    T    = max(T_min, n_look / μ)                              (prediction_horizon, look_ahead_transitions)
//!    ```
//!
//!    The `(q̇ − u)` term carries the motion that the transition of D1 will still make, so a removal is judged on
//!    where the robot will really go, not on a law it has not reached yet. A stack **changed now** (a candidate
//!    removal, re-insertion or swap, law `u'`) is predicted the same way from where its own transition starts: `q̇` is
//!    then `q̇(τ⁻)`, the velocity sent at the previous period, not the one the current stack sends now (after a
//!    singular push that one already carries a share of a huge law, and every candidate would inherit it). The horizon may be a number of transitions
//!    (`n_look/μ`); by default it is `T_min` (see [`ControllerParameters::look_ahead_transitions`] for the measured
//!    trade-off). A prediction that takes a target point behind the camera, or that the cost forbids
//!    ([`Cost::forbids`]: a joint beyond its hard limit), counts as an infinite cost, whatever `h_max`.
//! 3. **Relief** (D7). While the cost is predicted to rise (`h(q̂) > h(q)`), a removed task whose dwell is over comes
//!    back at once — without waiting for the robot to settle — when the law with it back, predicted the same way,
//!    gives a lower `h(q̂)` than the current stack and one under `r_back · h_max` (the motion a removal freed may itself
//!    raise the cost: with `a_n` out, the camera may drift until the target grows out of the image). Not within
//!    `n_change/μ` of the last change, never during the fallback. With a **guard** cost (below), the same holds for
//!    the guard, one transition time ahead and during the fallback too: while `g(q̂(max(T, n_resort/μ)))` is positive
//!    and above `g(q)`, the first removed task whose return lowers that prediction comes back at once, whatever its
//!    dwell (**guard relief**: the free motion a removal leaves may carry the target out of the image long after the
//!    removal passed its own guard test).
//!
//!    **Removal** (D6), when `h(q̂) > h_max`, `h(q̂) > h(q)` (the danger grows), the gradient `∇h(q)` — or `∇h(q̂)`
//!    when the robot is still outside every activation band — is non-zero, and the last change is at least
//!    `n_change/μ` old (**one change per transition**: no cascade while the previous change is still being blended
//!    in). The candidates are the stacked tasks ranked by the paper's criteria (C1', C2, C2', D4). The first candidate
//!    that (a) has been removed fewer than `max_removals` times, (b) is not the last task stacked, (c) **helps** — the
//!    law of the stack without it, predicted the same way, gives a smaller `h(q̂)` — and (d) passes the optional
//!    **guard** cost (a removal must not make the guard's prediction worse: in the simulation, the visibility of the
//!    target, so that removing the centroid cannot let the target leave the image) is removed. When no candidate
//!    qualifies, nothing is removed: the controller then behaves as the stack with projected gradient, which is
//!    what "never worse than stack + gradient" needs. A hard limit is also watched as the last resort below watches
//!    it: when the prediction `max(T, 1/μ)` ahead is past a hard limit ([`Cost::forbids`]), a removal is made (the
//!    candidates are compared on that prediction). Seen only `T` ahead — when `h_max` cannot see the joint at all (its
//!    cost at the limit, `ρ² Δq / 2`, is below `h_max`), or when it moves so fast that the change, which needs about
//!    `1/μ` to act, starts too late — the removal came too late.
//! 4. Otherwise, when the robot has **settled** (D5: `‖q̇_n‖ < ε_add` and `t − τ ≥ n_settle/μ`; for a push with no
//!    task out, when removals are allowed, `ε_add` is [`ControllerParameters::settle_velocity_with_removal`], 0.1 by
//!    default against the paper's 0.01, so that the next task is pushed before the higher ones have quite converged;
//!    for the full method also when the stacked tasks' error has stopped falling, its squared norm not down by a fifth
//!    within [`ControllerParameters::progress_window`], whatever the velocity):
//!    * a removed task is **put back** (D7) at its original priority when it has stayed out for its dwell time
//!      (`dwell · 2^{k−1}` after its `k`-th removal: each new removal doubles the wait) and the law with it back,
//!      predicted over the task's own time constant `n_back/λ_i`, keeps `h(q̂) ≤ r_back · h_max` (**hysteresis**: a
//!      lower threshold than the removal's);
//!    * when no removed task can come back, the next task of the list is **pushed** if one remains (the paper's `e4`
//!      achieved while `e3` is out); otherwise a **swap** is tried: a removed task back and a stacked one out in one
//!      transition, if the prediction with that exchange passes the same test and the exchange is not the reverse of
//!      the last swap (**anti-cycling**: two tasks traded back and forth is chatter);
//!    * if a removed task is still refused then (by default at once; after `stall_timeout` seconds if set), the
//!      controller **falls back** (D13): the task is put back without the test, and no task is removed for the rest of the run
//!      on the `h_max` test — only as a **last resort**, when the prediction `max(T, 1/μ)` ahead (the time a removal
//!      needs to act) is past a hard limit or loses the target (the fallback's law is about to fail there), at most once
//!      per task; a task so removed comes back without the test after its dwell.
//!      From there on the law is the stack with projected gradient. The event log says so ([`EventKind::Fallback`]).
//!      With [`ControllerParameters::hold_before_limit`], when the last resort finds no task to remove, the controller
//!      **holds** instead of letting the law cross the limit: every task is dropped, the law is the avoidance alone
//!      ([`EventKind::Hold`], [`ControllerStatus::Held`]);
//!    * when no task is out, the next task of the list is **pushed** (D5).
//! 5. Before the robot has settled, with no task out and a task still to push (full method only, D28): the law the
//!    stack would have with the next task pushed, `u⁺`, is computed at every period from `n_change/μ` after the last
//!    change; once `‖u⁺‖` exceeds [`ControllerParameters::early_push_ratio`] times its smallest value since that change,
//!    the robot is heading for a configuration where the next task's projected Jacobian is singular, and the task is
//!    **pushed** then rather than once the stack has settled past it.
//!
//! With a **reserve task** ([`StackController::with_reserve_task`], D23, D24: the image points for visual servoing), it
//! takes the place of the last task of the sequence, once: before steps 2–4, as soon as the sequence is complete,
//! nothing is out, the last change is `n_change/μ` old and the law drives the reserve task's error up
//! (`e_rᵀ J_r u > r_escape ‖e_r‖²`, D24); or, in step 4, when the settled stack has achieved its tasks with the reserve
//! task's error still above `ε_escape` (D23).
//!
//! When the whole sequence is stacked, nothing is out, no escape is due and the run no longer progresses — the robot
//! has come to rest (`‖q̇_n‖ < ε_add`, the paper's threshold) with a joint **locked** at a limit, or the stacked tasks'
//! error has stopped falling (D5), whatever the locks, while it creeps along a limit or chatters about a singular
//! configuration — and the goal is not reached (a stacked task's error above `ε_achieved` at rest, above the loop's
//! convergence threshold when its error has stopped falling ([`StackController::with_goal_error`]), or the reserve
//! task's above `ε_escape`), the run sits at a false equilibrium that sliding cannot leave. The controller
//! **restarts** the sequence, each time (D29,
//! [`ControllerParameters::restart_rate`]): every task but the first is taken out in one change (one
//! [`EventKind::Restart`] per task), the joints that were locked (if any) are driven to the middle of their range (past it, away
//! from the limit they were locked at, for ranges wider than a half turn: [`ControllerParameters::restart_offset`]) in
//! the first task's null space — every joint with finite limits when the same joints are locked at the same limits as
//! at the previous restart ([`ControllerParameters::recentre_all_on_repeat`]) — and the next task is pushed as before
//! once they are near their targets (or after [`ControllerParameters::restart_timeout`]); the reserve task may escape
//! again.
//!
//! [`DecisionRule::Paper`] keeps the paper's literal rule ([theory §6.2–6.4](crate::theory#s6-2) as first implemented: a fixed horizon along
//! `u`, any task removable, re-insertion at the removal threshold with no dwell, no fallback) for comparison; its
//! measured outcome is in `docs/convergence_domain.md` (the convergence-domain study).
//!
//! A change decided at iteration `k` takes effect at once (§6.5: "remove, τ ← t, recompute"): the law is solved again
//! on the new stack and blended from the velocity sent at iteration `k − 1` (or the one the caller reported with
//! [`StackController::set_sent_velocity`]), so `q̇(τ⁺) = q̇(τ⁻)` exactly (D1), and the transition starts at that
//! iteration only. Tasks are identified by their index in the task list, which is also their priority (0 highest).
//!
//! Every decision above is a prediction; what keeps the joints inside their limits when a prediction comes too late
//! is outside the controller, where the velocity is sent: the **braking** of D25
//! ([`ControllerParameters::braking_rate`], [`crate::avoidance::JointLimits::braking_scale`]; before the border of
//! the image too, [`ControllerParameters::brake_at_image_border`]), applied by the simulation and by
//! [`crate::servo::VisualServo`], and reported back with [`StackController::set_sent_velocity`].
//! Once braked at a limit, a joint the law still drives in is **locked** (D26, [`StackController::with_joint_limits`],
//! [`ControllerParameters::lock_band`]): the law is solved again on the other joints, so the robot slides along the
//! limit; the locks hold in the predictions too, and a change of the locked joints starts a transition (D1).
//!
//! **Criteria** (§6.3), for every stacked task `i` with its own Jacobian `J_i` and the gradient `g`:
//!
//! ```text
//! [M23]/D3  C1_i  = −(J_i⁺ e_i)ᵀ g ,   C1'_i = C1_i / ‖J_i⁺ e_i‖   (0 when ‖J_i⁺ e_i‖ is below a floor)   [M24]
//! [M25]     C2_i  = ‖(I − J_i⁺ J_i) g‖                               (remove argmin)
//! [M26]     C2'_i = ‖V_1ᵀ g‖ ,  C2_i² + C2'_i² = ‖g‖²               (remove argmax)                     [M27]
//! D4        S_i   = (C1'_i + C2'_i) / ‖g‖ ∈ [−1, 2]                  (remove argmax, default)
//! ```
//!
//! Every push, removal, re-insertion and fallback is recorded in an event log ([`StackEvent`]) with its iteration,
//! time, task and the jump the law alone would have made there (`‖u(τ) − q̇(τ⁻)‖`, which the transition term absorbs);
//! removals also record the prediction, the joint that dominates the predicted gradient, the cost term that dominates
//! the predicted cost, and every task's criteria; re-insertions the prediction with the task back.

use crate::avoidance::{Cost, CostError, JointLimits};
use crate::bounds::DURATION_S;
use crate::law::sns::SnsBounds;
use crate::law::{
    control_step, BoundedLaw, ControlLaw, ControlOutput, ControlWorkspace, LawError, StackChange,
};
use crate::linalg::{solve_small_full_row_rank, ColumnSvd, VelocityInverse};
use crate::math::JointVector;
use crate::stack::{solve_stack, StackError, StackWorkspace};
use crate::task::{TaskJacobian, TaskValue};

mod events;
mod insertion;
mod parameters;
mod recovery;
mod removal;

use recovery::{LockedAt, Standstill};

pub use events::{
    ControllerStatus, ControllerStep, EventKind, ReinsertionReport, ReinsertionTest, RemovalReport,
    StackEvent, TaskCriteria,
};
pub use parameters::{
    ControllerError, ControllerParameters, DecisionRule, HardLimitRule, RemovalCriterion,
    TaskSequencing,
};

/// The controller's phase: what it may do at the next iteration ([theory §6.6](crate::theory#s6-6)). Its
/// transitions are made in one place each: Sequencing → Recentring by the restart (D29, `recovery.rs`),
/// Recentring → Sequencing once the recentred joints are back in their centre band or the restart's timeout has passed
/// (D29, `insertion.rs`), and Sequencing or Recentring → Held by the hold before a hard limit (D13, `removal.rs`),
/// which is final.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase<const N: usize> {
    /// Tasks are pushed, removed and put back (D5–D7, D28), the reserve task may escape (D23, D24).
    Sequencing,
    /// D29: the sequence has restarted; the joints that were locked (`joints`; every limited joint when the same were
    /// locked at the previous restart) are driven to their targets `centre`
    /// (the middle of their range, past it for ranges wider than a half turn) in the first task's null space since
    /// `since` (s), and nothing is pushed or put back until they are there.
    Recentring {
        /// The recentred joints.
        joints: [bool; N],
        /// Each recentred joint's target `q̂_i` (the others' entries are not used).
        centre: JointVector<N>,
        /// When the restart began (s).
        since: f64,
    },
    /// D13: every task has been dropped before a hard limit (the highest-priority one `task`, at `since`): the law is
    /// the avoidance alone, for good.
    Held {
        /// The highest-priority task dropped.
        task: usize,
        /// When (s).
        since: f64,
    },
}

/// The stack controller's state: which tasks are stacked, pending and removed, the transition memory, the event log.
/// Its buffers are allocated once, at construction; an iteration without event allocates nothing. An event appends to
/// the event log (preallocated for four events per task, growing beyond), and a removal copies the criteria into its
/// report: events are rare and outside the steady state.
#[derive(Debug, Clone)]
pub struct StackController<const N: usize> {
    parameters: ControllerParameters,
    task_count: usize,
    /// The reserve task (the last of the list) and whether it has taken its place (D23).
    reserve: Option<usize>,
    escaped: bool,
    stacked: Vec<usize>,
    next_push: usize,
    /// Removed tasks, in priority order.
    removed: Vec<usize>,
    /// Per task: never removed (D6 (e)).
    protected: Vec<bool>,
    /// Per task: how many times it was removed, and when last.
    removal_count: Vec<u32>,
    removed_at: Vec<f64>,
    /// Per task: whether the last resort of D13 has removed it (at most once per task).
    last_resort_used: Vec<bool>,
    /// The time of the first refused re-insertion test since the last change (the stall clock of D13).
    refused_since: Option<f64>,
    /// The last re-insertion test: (task, predicted cost, threshold).
    last_reinsertion_test: Option<(usize, f64, f64)>,
    /// Where the controller is in its sequence: sequencing, recentring after a restart, or held.
    phase: Phase<N>,
    /// D13: removals stopped after a fallback, except as a last resort; orthogonal to the phase (a restart keeps it).
    fallback: bool,
    /// The joint limits given to [`Self::with_joint_limits`]: the lock of D26, the restart of D29.
    limits: Option<JointLimits<N>>,
    change_pending: bool,
    last_change_time: f64,
    /// D28: `(k, m)`, the smallest `‖u⁺‖` (the law with the next task pushed) seen since the change logged as event
    /// `k − 1` (`k` = the event count then); reset at each change.
    early_push_reference: Option<(usize, f64)>,
    /// D5: `(t₀, E₀)`, the time and the stacked tasks' squared error norm at the first settling test after the last
    /// change, or when that error last fell below `0.8 E₀`.
    progress_reference: Option<(f64, f64)>,
    last_removal_time: f64,
    last_stack_velocity_norm: f64,
    law_workspace: ControlWorkspace<N>,
    trial_workspace: StackWorkspace<N>,
    trial_order: Vec<usize>,
    criteria: Vec<TaskCriteria>,
    /// Removal candidates, best score first.
    ranking: Vec<TaskCriteria>,
    jacobian_work: TaskJacobian<N>,
    /// One decomposition per task, each warm-started from the same task's previous criteria.
    svds: Vec<ColumnSvd<N>>,
    events: Vec<StackEvent>,
    /// The last D7 swap made, `(back, out)`: the next swap may not be its reverse `(out, back)` (anti-cycling).
    last_swap: Option<(usize, usize)>,
    /// D29: the joints locked at the last restart, and at which limit; a restart that finds the same recentres every
    /// limited joint ([`ControllerParameters::recentre_all_on_repeat`]).
    last_restart_locks: Option<[LockedAt; N]>,
    /// D29: the loop's convergence threshold; no restart while every stacked task's error is below it
    /// ([`Self::with_goal_error`]).
    goal_error: f64,
}

/// What the prediction of D6 needs: the configuration, the velocity the current stack sends now and the one sent at
/// the previous period (where a change made now starts its transition), the gradient and `μ`.
struct Prediction<'a, const N: usize> {
    q: &'a JointVector<N>,
    sent: &'a JointVector<N>,
    sent_before: &'a JointVector<N>,
    gradient: &'a JointVector<N>,
    transition_gain: f64,
    rule: DecisionRule,
}

impl<const N: usize> Prediction<'_, N> {
    /// Where the current stack's law `u` takes the robot in `T`: `q̂(T) = q + T u + (1 − e^{−μT})/μ (q̇ − u)` with `q̇`
    /// the velocity it sends now, still carrying its transition ([`DecisionRule::Robust`]), or `q + T u`
    /// ([`DecisionRule::Paper`]).
    fn at(&self, law: &JointVector<N>, horizon: f64) -> JointVector<N> {
        self.integrate(law, self.sent, horizon)
    }

    /// Where the law `u'` of a stack changed now takes the robot in `T`: the same integral, its transition starting
    /// from `q̇(τ⁻)`, the velocity sent at the previous period (D1), not from the velocity the current stack would send
    /// now. The two differ little, except after a singular push: the current stack's velocity then already carries a
    /// share of its huge law, which every candidate change would otherwise inherit.
    fn after_change(&self, law: &JointVector<N>, horizon: f64) -> JointVector<N> {
        self.integrate(law, self.sent_before, horizon)
    }

    fn integrate(
        &self,
        law: &JointVector<N>,
        start: &JointVector<N>,
        horizon: f64,
    ) -> JointVector<N> {
        let mut predicted = self.q + law * horizon;
        if self.rule == DecisionRule::Robust {
            let mu = self.transition_gain;
            let memory = -(-mu * horizon).exp_m1() / mu;
            predicted.axpy(memory, start, 1.0);
            predicted.axpy(-memory, law, 1.0);
        }
        predicted
    }
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
        let count = tasks.len();
        Ok(Self {
            parameters,
            task_count: count,
            reserve: None,
            escaped: false,
            stacked: Vec::with_capacity(count),
            next_push: 0,
            removed: Vec::with_capacity(count),
            protected: vec![false; count],
            removal_count: vec![0; count],
            last_resort_used: vec![false; count],
            removed_at: vec![0.0; count],
            refused_since: None,
            last_reinsertion_test: None,
            fallback: false,
            phase: Phase::Sequencing,
            limits: None,
            change_pending: false,
            last_change_time: 0.0,
            progress_reference: None,
            early_push_reference: None,
            last_removal_time: f64::NEG_INFINITY,
            last_stack_velocity_norm: f64::INFINITY,
            law_workspace: ControlWorkspace::new(tasks),
            trial_workspace: StackWorkspace::new(tasks),
            trial_order: Vec::with_capacity(count),
            criteria: Vec::with_capacity(count),
            ranking: Vec::with_capacity(count),
            jacobian_work: TaskJacobian::zeros(max_rows),
            svds: vec![ColumnSvd::default(); count],
            events: Vec::with_capacity(4 * count + 8),
            last_swap: None,
            last_restart_locks: None,
            goal_error: DEFAULT_GOAL_ERROR,
        })
    }

    /// The controller with `tasks` never removed (D6 (e)): in visual servoing, the task that keeps the target in the
    /// image (the centroid), since a removal that lets the target leave the image cannot be undone.
    ///
    /// # Errors
    /// [`ControllerError::InvalidParameter`] for an index beyond the task list.
    pub fn with_protected_tasks(mut self, tasks: &[usize]) -> Result<Self, ControllerError> {
        for &task in tasks {
            let flag = self
                .protected
                .get_mut(task)
                .ok_or(ControllerError::InvalidParameter {
                    name: "protected task",
                    value: task as f64,
                    expected: "an index into the task list",
                })?;
            *flag = true;
        }
        Ok(self)
    }

    /// The controller whose loop counts as converged when every stacked task's error norm is below `error` (the tasks'
    /// units; default [`DEFAULT_GOAL_ERROR`], the convergence threshold of [`crate::sim`] and [`crate::servo`], which
    /// pass theirs): the restart of D29 takes a run whose error has stopped falling against a limit for short of its
    /// goal until then (a run at rest by its velocity alone, until `ε_achieved`). A threshold below the noise of the
    /// measured errors lets a run resting at its goal restart.
    ///
    /// # Errors
    /// [`ControllerError::InvalidParameter`] unless `error` is finite and > 0.
    pub fn with_goal_error(mut self, error: f64) -> Result<Self, ControllerError> {
        if !(error.is_finite() && error > 0.0) {
            return Err(ControllerError::InvalidParameter {
                name: "goal error",
                value: error,
                expected: "finite and > 0",
            });
        }
        self.goal_error = error;
        Ok(self)
    }

    /// The controller that slides along the hard limits `limits` (D26, [`ControllerParameters::lock_band`]): at each
    /// iteration, a joint within the lock band that the law drives towards its limit is held still and the stack is
    /// solved again on the other joints, until no joint in the band is driven in. The same locks hold in the
    /// controller's predictions, so that its settling and its re-insertion tests see the law it sends. A change of
    /// the locked joints starts a transition (D1), as a stack change does. Without limits, nothing is locked.
    ///
    /// # Errors
    /// None with a validated `lock_band` ([`ControllerError::Law`] otherwise).
    pub fn with_joint_limits(mut self, limits: JointLimits<N>) -> Result<Self, ControllerError> {
        let band = self.parameters.lock_band;
        if band > 0.0 {
            self.law_workspace.lock_at_limits(limits.clone(), band)?;
        }
        self.limits = Some(limits);
        Ok(self)
    }

    /// The controller whose law saturates in the null space within `bounds` ([theory §13](crate::theory#s13),
    /// [`ControlWorkspace::saturate_in_null_space`]) instead of locking joints (D26).
    pub fn with_null_space_saturation(mut self, bounds: SnsBounds<N>) -> Self {
        self.law_workspace.saturate_in_null_space(bounds);
        self
    }

    /// The controller whose law keeps every velocity within `bounds` by `law` ([`ControlWorkspace::bound`]): SNS
    /// ([theory §13](crate::theory#s13)) or the hierarchical QP cascade ([theory §14](crate::theory#s14)), instead of
    /// locking joints (D26).
    ///
    /// # Errors
    /// None with the default settings ([`ControllerError::Law`] otherwise).
    pub fn with_bounded_law(
        mut self,
        law: BoundedLaw,
        bounds: SnsBounds<N>,
    ) -> Result<Self, ControllerError> {
        self.law_workspace.bound(law, bounds)?;
        Ok(self)
    }

    /// The controller with the last task of the list held in reserve (D23): it is not pushed in sequence; once the
    /// sequence is complete, no task is out, the stack has settled and every stacked task's error is below
    /// [`ControllerParameters::escape_achieved_error`] while the reserve task's is above
    /// [`ControllerParameters::escape_error`], the reserve task takes the place of the last task of the sequence, once
    /// ([`EventKind::Escape`]); earlier if the complete stack drives the reserve task's error up
    /// ([`ControllerParameters::escape_growth_rate`], D24). For visual servoing: the four image points, which the paper's features do not
    /// determine — the features can be achieved at a pose other than the goal.
    ///
    /// # Errors
    /// [`ControllerError::InvalidParameter`] for a list of fewer than two tasks.
    pub fn with_reserve_task(mut self) -> Result<Self, ControllerError> {
        if self.task_count < 2 {
            return Err(ControllerError::InvalidParameter {
                name: "reserve task",
                value: self.task_count as f64,
                expected: "a list of at least two tasks",
            });
        }
        self.reserve = Some(self.task_count - 1);
        Ok(self)
    }

    /// The number of tasks pushed in sequence: all but a reserve task (D23).
    fn sequence_len(&self) -> usize {
        self.task_count - usize::from(self.reserve.is_some())
    }

    /// The reserve task (D23) while it waits: `None` without one, or once it has taken its place in the stack.
    pub fn waiting_reserve(&self) -> Option<usize> {
        self.reserve.filter(|_| !self.escaped)
    }

    /// The parameters.
    pub fn parameters(&self) -> &ControllerParameters {
        &self.parameters
    }

    /// The tasks currently stacked, highest priority first (after this iteration's change, if any).
    pub fn stacked(&self) -> &[usize] {
        &self.stacked
    }

    /// The tasks removed and waiting to be put back, in priority order.
    pub fn removed(&self) -> &[usize] {
        &self.removed
    }

    /// `true` when every task of the sequence is pushed and none is removed (a reserve task, D23, is not waited for).
    pub fn is_complete(&self) -> bool {
        self.next_push == self.sequence_len() && self.removed.is_empty()
    }

    /// `true` once the controller has fallen back to the stack with gradient (D13): no task is removed any more, except
    /// as a last resort when the prediction is past a hard limit or loses the target.
    pub fn has_fallen_back(&self) -> bool {
        self.fallback
    }

    /// `true` once the controller has held before a hard limit ([`ControllerParameters::hold_before_limit`], D13): every
    /// task is dropped for good, and the velocity is the avoidance's alone.
    pub fn is_held(&self) -> bool {
        matches!(self.phase, Phase::Held { .. })
    }

    /// What the controller waits for (to explain a run that did not converge in its budget).
    pub fn status(&self) -> ControllerStatus {
        if let Phase::Held { task, since: time } = self.phase {
            ControllerStatus::Held { task, time }
        } else if let Some(&task) = self.removed.first() {
            let last_test = match self.last_reinsertion_test {
                Some((tested, predicted_cost, threshold)) if tested == task => {
                    Some(ReinsertionTest {
                        predicted_cost,
                        threshold,
                    })
                }
                _ => None,
            };
            ControllerStatus::Reinserting {
                task,
                last_test,
                stack_velocity_norm: self.last_stack_velocity_norm,
            }
        } else if self.next_push < self.sequence_len() {
            ControllerStatus::Pushing {
                next: self.next_push,
                stack_velocity_norm: self.last_stack_velocity_norm,
            }
        } else {
            ControllerStatus::Complete
        }
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

    /// Tells the controller the velocity the robot actually received at the last iteration (after the caller's
    /// saturation, for instance), so that the next stack change starts its transition from it: `q̇(τ⁻)` is what the
    /// robot got, and continuity holds for the robot.
    ///
    /// # Errors
    /// [`ControllerError::NonFiniteSentVelocity`].
    pub fn set_sent_velocity(&mut self, velocity: &JointVector<N>) -> Result<(), ControllerError> {
        if let Some((joint, value)) = crate::math::first_non_finite(velocity) {
            return Err(ControllerError::NonFiniteSentVelocity { joint, value });
        }
        self.law_workspace.set_sent_velocity(velocity);
        Ok(())
    }

    /// One iteration at time `time` (s) for the configuration `q`, with the tasks evaluated at `q`, an optional
    /// avoidance cost, and the law (its `κ` may be 0 for no avoidance term). As [`Self::step_guarded`] without guard.
    ///
    /// # Errors
    /// As [`Self::step_guarded`].
    pub fn step(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: Option<&dyn Cost<N>>,
        q: &JointVector<N>,
        iteration: usize,
        time: f64,
    ) -> Result<ControllerStep<N>, ControllerError> {
        self.step_guarded(law, tasks, cost, None, q, iteration, time)
    }

    /// One iteration, with a `guard` cost that a removal must not make worse (D6 (d); the simulation guards the
    /// visibility of the target). On error nothing is sent: the controller keeps the transition memory of the last
    /// velocity it returned.
    ///
    /// # Errors
    /// A task list of another length than at construction, law and cost failures.
    #[allow(clippy::too_many_arguments)]
    pub fn step_guarded(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: Option<&dyn Cost<N>>,
        guard: Option<&dyn Cost<N>>,
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
        if self.events.is_empty() && self.task_count > 0 {
            // The first task is stacked from the first iteration, at its time.
            self.push_next(iteration, time);
            self.change_pending = true;
        }
        // The transition memory before this step, restored if nothing is sent; its velocity is q̇(τ⁻) of a change
        // decided at this iteration.
        let memory = self.law_workspace.memory();
        let velocity_sent_before = *memory.velocity();
        let change = if self.change_pending {
            StackChange::Changed
        } else {
            StackChange::Unchanged
        };
        let recentring = self.recentring_cost(law, cost);
        let output = control_step(
            law,
            &mut self.law_workspace,
            tasks,
            &self.stacked,
            recentring
                .as_ref()
                .map_or(cost, |c| Some(c as &dyn Cost<N>)),
            q,
            time,
            change,
        )?
        .clone();
        // The predictions see the joints the law locked (D26).
        self.trial_workspace
            .lock_joints(self.law_workspace.locked_joints());
        self.change_pending = false;
        if change == StackChange::Changed {
            self.note_law_jump(iteration, &output, &velocity_sent_before);
        }
        let mut result = self.summarize(&output);
        let was_recentring = matches!(self.phase, Phase::Recentring { .. });
        let event = match self.decide(
            law,
            tasks,
            cost,
            guard,
            q,
            &output,
            &velocity_sent_before,
            iteration,
            time,
            &mut result,
        ) {
            Ok(event) => event,
            Err(error) => {
                self.law_workspace.restore(memory);
                self.change_pending = change == StackChange::Changed;
                return Err(error);
            }
        };
        if event.is_none() && was_recentring && !matches!(self.phase, Phase::Recentring { .. }) {
            // D29: the recentring term leaves the law at the next step, which starts a transition from the velocity
            // sent now (D1), as a stack change does.
            self.change_pending = true;
        }
        if let Some(kind) = event {
            // theory §6.5: the change takes effect now; the law is solved again on the new stack and blended from the
            // velocity actually sent before, so q̇(τ⁺) = q̇(τ⁻) (D1). The transition starts here, once.
            self.law_workspace.restore(memory);
            let recentring = self.recentring_cost(law, cost);
            let output = match control_step(
                law,
                &mut self.law_workspace,
                tasks,
                &self.stacked,
                recentring
                    .as_ref()
                    .map_or(cost, |c| Some(c as &dyn Cost<N>)),
                q,
                time,
                StackChange::Changed,
            ) {
                Ok(output) => output.clone(),
                Err(error) => {
                    // The stack has changed: the next step starts the transition.
                    self.change_pending = true;
                    return Err(error.into());
                }
            };
            self.note_law_jump(iteration, &output, &velocity_sent_before);
            let predicted_cost = result.predicted_cost;
            result = self.summarize(&output);
            result.predicted_cost = predicted_cost;
            result.event = Some(kind);
        }
        Ok(result)
    }

    /// Fills `law_jump` of the event made at `iteration`: `‖u(τ) − q̇(τ⁻)‖`.
    fn note_law_jump(
        &mut self,
        iteration: usize,
        output: &ControlOutput<N>,
        velocity_before: &JointVector<N>,
    ) {
        if let Some(event) = self.events.last_mut().filter(|e| e.iteration == iteration) {
            event.law_jump = (output.law() - velocity_before).norm();
        }
    }

    fn summarize(&mut self, output: &ControlOutput<N>) -> ControllerStep<N> {
        let stack_velocity_norm = self.law_workspace.stack_solution().velocity().norm();
        self.last_stack_velocity_norm = stack_velocity_norm;
        ControllerStep {
            velocity: *output.velocity(),
            stack_velocity_norm,
            cost: output.cost(),
            predicted_cost: output.cost(),
            event: None,
        }
    }

    fn record(&mut self, event: StackEvent) {
        self.last_change_time = event.time;
        self.refused_since = None;
        self.events.push(event);
    }
}

/// A cost at a predicted configuration `q̂`: `+∞` when it cannot be evaluated there because a target point would be
/// behind the camera (the worst there is: the prediction says the target is lost).
fn predicted_value<const N: usize>(
    cost: &dyn Cost<N>,
    q: &JointVector<N>,
) -> Result<f64, CostError> {
    match cost.value(q) {
        Err(CostError::PointBehindCamera { .. }) => Ok(f64::INFINITY),
        other => other,
    }
}

/// `n_resort`: the last resort of D13 looks `max(T, n_resort/μ)` ahead, the time a removal needs to take effect
/// through the transition of D1.
const LAST_RESORT_TRANSITIONS: f64 = 1.0;

/// The default convergence threshold of the restart's goal test ([`StackController::with_goal_error`]), the task
/// errors' norm below which [`crate::sim`] and [`crate::servo`] count a run as converged by default.
pub const DEFAULT_GOAL_ERROR: f64 = 1e-4;

/// Below this norm of `J_i⁺ e_i` the task is achieved and `C1'_i` is set to 0 ([D3](crate::theory#d3)).
const DIRECTION_FLOOR: f64 = 1e-12;
