//! The stack controller: push tasks when the robot has settled, predict when the avoidance will fail, remove the task
//! that blocks it, and put it back when the danger has passed ([theory §6](crate::theory#s6), (F20)–(F27), D3–D7, D13).
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
//!    default against the paper's 0.01, so that the next task is pushed before the higher ones have quite converged):
//!    * a removed task is **put back** (D7) at its original priority when it has stayed out for its dwell time
//!      (`dwell · 2^{k−1}` after its `k`-th removal: each new removal doubles the wait) and the law with it back,
//!      predicted over the task's own time constant `n_back/λ_i`, keeps `h(q̂) ≤ r_back · h_max` (**hysteresis**: a
//!      lower threshold than the removal's);
//!    * when no removed task can come back, the next task of the list is **pushed** if one remains (the paper's `e4`
//!      achieved while `e3` is out); otherwise a **swap** is tried: a removed task back and a stacked one out in one
//!      transition, if the prediction with that exchange passes the same test and the exchange is not the reverse of
//!      the last swap (**anti-cycling**: two tasks traded back and forth is chatter);
//!    * if a removed task is still refused `stall_timeout` seconds after its first refused test, the controller
//!      **falls back** (D13): the task is put back without the test, and no task is removed for the rest of the run
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
//! When the whole sequence is stacked, nothing is out, no escape is due and the robot has come to rest (`‖q̇_n‖ <
//! ε_add`, the paper's threshold) with a joint **locked** at a limit and the goal not reached (the reserve task's error
//! above `ε_escape`; without a reserve, a stacked task's above `ε_achieved`), the run sits at a false equilibrium
//! against the limit that sliding cannot leave. The controller **restarts** the sequence, once (D29,
//! [`ControllerParameters::restart_rate`]): every task but the first is taken out in one change (one
//! [`EventKind::Restart`] per task), the joints that were locked are driven towards the middle of their range in the
//! first task's null space, and the next task is pushed as before once they are near it (or after
//! [`ControllerParameters::restart_timeout`]); the reserve task may escape again.
//!
//! [`DecisionRule::Paper`] keeps the paper's literal rule ([theory §6.2–6.4](crate::theory#s6-2) as first implemented: a fixed horizon along
//! `u`, any task removable, re-insertion at the removal threshold with no dwell, no fallback) for comparison; its
//! measured outcome is in the README (convergence-domain study).
//!
//! A change decided at iteration `k` takes effect at once (§6.5: "remove, τ ← t, recompute"): the law is solved again
//! on the new stack and blended from the velocity sent at iteration `k − 1` (or the one the caller reported with
//! [`StackController::set_sent_velocity`]), so `q̇(τ⁺) = q̇(τ⁻)` exactly (D1), and the transition starts at that
//! iteration only. Tasks are identified by their index in the task list, which is also their priority (0 highest).
//!
//! Every decision above is a prediction; what keeps the joints inside their limits when a prediction comes too late
//! is outside the controller, where the velocity is sent: the **braking** of D25
//! ([`ControllerParameters::braking_rate`], [`crate::avoidance::JointLimits::braking_scale`]), applied by the
//! simulation and by [`crate::servo::VisualServo`], and reported back with [`StackController::set_sent_velocity`].
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
use crate::law::{
    control_step, ControlLaw, ControlOutput, ControlWorkspace, LawError, StackChange,
};
use crate::linalg::{solve_small_full_row_rank, ColumnSvd, VelocityInverse};
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
    /// The velocity reported as sent holds a NaN or an infinity.
    #[error("sent velocity: joint {joint} = {value} is not finite")]
    NonFiniteSentVelocity {
        /// The first offending joint (0-based).
        joint: usize,
        /// Its value.
        value: f64,
    },
    /// The control law failed.
    #[error(transparent)]
    Law(#[from] LawError),
    /// The avoidance cost failed.
    #[error(transparent)]
    Cost(#[from] CostError),
}

/// Which criterion picks the task to remove ([theory §6.3](crate::theory#s6-3), D4).
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

/// Which rule decides removals and re-insertions (the criteria above only choose *which* task).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DecisionRule {
    /// The crate's rule (D6, D7, D13; see the module docs): prediction along the velocity sent over a horizon in
    /// transitions, one change per transition, helpful and guarded removals that keep one task stacked, re-insertion
    /// with hysteresis and a doubling dwell, fallback to the stack with gradient when a task cannot come back.
    #[default]
    Robust,
    /// The paper's rule as first read ([theory §6.2–6.4](crate::theory#s6-2)): `q̂ = q + T_min u`, remove the best-scored task when
    /// `h(q̂) > h_max` and `h(q̂) > h(q)`, put it back when settled if the prediction with it stays `≤ h_max`. No dwell,
    /// no guard, no fallback; every task may be removed. Measured to cascade and chatter off the designed scenario.
    Paper,
}

/// The thresholds of the controller, with their units. Immutable once the controller is built.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerParameters {
    /// `ε_add`: the stack has settled when the Euclidean norm of the stack velocity `‖q̇_n‖` is below this (D5). Its unit
    /// mixes the joints' units per second (m/s for prismatic, rad/s for revolute joints). Default 0.01, the paper's
    /// sequencing: each task converges before the next is pushed. Used for every push of a controller that does not
    /// remove tasks (the stack and stack-with-gradient laws) or follows [`DecisionRule::Paper`], and, under the robust
    /// rule, for the tests that put a removed task back.
    pub settle_velocity: f64,
    /// `ε_add` of the pushes of a controller that removes tasks under [`DecisionRule::Robust`] (the full method; same
    /// unit; default 0.1): with no task out, the next task is pushed while the stack still moves at up to this speed
    /// (a removed task's re-insertion is still tested at [`Self::settle_velocity`]). A departure from the paper (D5):
    /// waiting for the higher tasks to converge first lands the robot on configurations where the next task's
    /// projected Jacobian is nearly singular (the goal-moved failures of the convergence-domain study); pushing
    /// earlier, with the removals to keep the limits, avoids them. Measured window: 0.05 to 0.2 give the same study
    /// within a few draws; 0.01 (the paper's) loses 10–16 % of the Afma6's goal-moved draws.
    pub settle_velocity_with_removal: f64,
    /// `n_settle`: after a change, wait `t − τ ≥ n_settle / μ` before the next push or re-insertion (D5; default 5,
    /// when the transition term has decayed to `e^{−5} ≈ 0.7 %`).
    pub settle_transitions: f64,
    /// `T_min` (s): the shortest prediction horizon (D6; default 0.05 s). With [`DecisionRule::Paper`] it is the
    /// horizon. Measured at 0.1 s (200 draws per family, seed 1, velocities saturated): the UR5e's uniform starts
    /// converge in 82 instead of 68 (the elbow's 0.055 rad band is crossed in 8 periods at 0.7 rad/s) but cover the
    /// same 37 of the 48 draws a baseline wins, while the Afma6 loses turned views (191 instead of 200 at ≤ 10°) and
    /// uniform starts (115 instead of 119).
    pub prediction_horizon: f64,
    /// `n_look`: the prediction horizon is `T = max(T_min, n_look/μ)` (D6; default 0: `T = T_min`). Measured by the
    /// convergence-domain study, a longer horizon (1 or 2 transitions) raises false alarms right after a push, when
    /// the law's transient is extrapolated linearly: on the square-marker scenario the full method then fails where
    /// the stack with gradient converges (mild starts: 60 of 60 converge with 0, none with 2), while on the paper
    /// scenario it helps the uniform starts (42 of 200 with 0, 79 with 2; both without velocity saturation). The default favours never doing worse
    /// than the stack with gradient; this parameter works in a narrow window and is reported as such.
    pub look_ahead_transitions: f64,
    /// `h_max`: a task is removed when `h(q̂) > h_max` (D6), in the cost's unit. `None`: the cost's
    /// [`Cost::default_removal_threshold`] (for joint limits, one joint half-way through its activation band), and no
    /// removal for a cost without one.
    pub removal_threshold: Option<f64>,
    /// `r_back` in `(0, 1]`: a removed task comes back only if the prediction with it keeps `h(q̂) ≤ r_back · h_max`
    /// (D7 hysteresis; default 0.5).
    pub reinsertion_ratio: f64,
    /// `n_back`: the re-insertion test predicts over `n_back / λ_i`, in time constants of the task put back (D7;
    /// default 1: `q + u/λ_i` is where the linearised law with the task back would take the robot). Its window,
    /// measured by the convergence-domain study (200 draws per family, seed 1, the four scenarios): 1 to 2 give the
    /// same uniform-start figures within 1–4 draws (2: Afma6 121, UR5e 70, 7-joint chain 19, square 124, the square's
    /// median removals 2 instead of 4; seeds 2 and 3 within 2 draws too) and every other family unchanged within a
    /// draw; shorter look-aheads re-insert tasks that the next removal takes out again — 0.5 costs the UR5e's
    /// goal-moved draws (162 / 171 of 200 at ±2 / ±4 cm), 0.25 gives a median of 10–11 removals per uniform run on
    /// the Afma6 and the square.
    pub reinsertion_look_ahead: f64,
    /// `n_change`: no removal within `n_change / μ` of the last change (D6, one change per transition; default 1).
    pub change_transitions: f64,
    /// `T_dwell` (s): a task stays out at least `T_dwell · 2^{k−1}` after its `k`-th removal (D7; default 1 s).
    /// Window (convergence-domain study, 200 draws per family, seed 1, the four scenarios): 0.5 s gives the same
    /// figures within 2 draws; 2 s costs the square marker's uniform starts (113 instead of 124, 11 draws lost to the
    /// stack with gradient).
    pub reinsertion_dwell: f64,
    /// A task removed this many times is no longer a removal candidate (D7; default 4).
    pub max_removals: u32,
    /// `T_stall` (s): a removed task still refused this long after its first refused re-insertion test is put back
    /// anyway, and removals stop except as a last resort (D13 fallback; default 5 s). Window (as for `T_dwell`):
    /// 2.5 s gives the same figures within 1 draw; 10 s costs the square marker's uniform starts (74 instead of 124:
    /// with a task out that long the robot drifts until a feature of the view is undefined — 42 runs end
    /// `image_degenerate` — or a joint reaches its limit, 69 runs).
    pub stall_timeout: f64,
    /// Whether tasks may be removed at all (`false`: push-only, as the paper's runs 2 and 3).
    pub allow_removal: bool,
    /// The criterion that picks the task to remove.
    pub criterion: RemovalCriterion,
    /// The decision rule.
    pub rule: DecisionRule,
    /// `ε_achieved`: with a reserve task ([`StackController::with_reserve_task`], D23), the stack counts as having
    /// achieved its tasks when every stacked task's error norm `‖e_i‖` is below this (the tasks' units; default 1e−3).
    pub escape_achieved_error: f64,
    /// `ε_escape`: the reserve task replaces the last task of the sequence when the stack has achieved its tasks and
    /// the reserve task's error norm is still above this (its units; default 0.005: for the image points, 1.5 px per
    /// corner at a 600 px focal length). Window (convergence-domain study, 200 draws per family, seed 1): 0.002 and
    /// 0.005 give the same figures; 0.01 leaves 2–3 of the Afma6's turned views at near-goal false equilibria, 0.02
    /// and 0.05 leave 15–23. Below the noise of the corners the escape may happen at the goal itself, where it does
    /// no harm (the points' goal is the same): the noisy Afma6 scenarios give the same figures at 0.005 as at 0.01.
    pub escape_error: f64,
    /// `r_escape` (s⁻¹): the reserve task also replaces the last task of the sequence, before anything settles, when
    /// the law of the complete stack drives the reserve task's error away from zero faster than this:
    /// `e_rᵀ J_r u / ‖e_r‖² > r_escape`, the growth rate of `‖e_r‖` under `u` (D24; default 0: any growth). With the
    /// image points in reserve, the paper's features are then leading the camera towards one of their false
    /// equilibria, and the corners notice first. `+∞` switches the early escape off (D23 alone). Window
    /// (convergence-domain study, 200 draws per family, seed 1): 0 and 0.05 s⁻¹ give the Afma6's uniform starts 107
    /// and 101 converged, 0.2 s⁻¹ 69; the other families do not move.
    pub escape_growth_rate: f64,
    /// `r_push` (> 1, dimensionless), the early push of D28: with no task out and the sequence incomplete, the next
    /// task is pushed before the stack has settled when the law with it pushed, `‖u⁺‖` (the joint units per second of
    /// `ε_add`), has grown to `r_push` times its smallest value since the last change (tested from one transition
    /// after that change). The current stack is then carrying the robot towards a configuration where the next task's
    /// projected Jacobian is singular: the task is pushed while the robot approaches it, not once it has passed it.
    /// Full method only (robust rule, removals allowed); default 4; `+∞` switches it off. Window and measurements:
    /// theory D28.
    pub early_push_ratio: f64,
    /// Whether the controller **holds** rather than let the law cross a hard limit (D13; default `false` since the
    /// lock of D26, which lets the runs the hold would stop slide along the limit instead): after the
    /// fallback, when the configuration predicted `max(T, 1/μ)` ahead is past a hard limit (or loses the target, the
    /// last resort's other trigger) and no task can be removed (the last resorts are spent, or the one task left is
    /// the last), every task is dropped at once; the law is then
    /// the avoidance alone, `u = −κ ∇h`, blended in by the transition of D1, the robot comes to rest inside its
    /// limits, and the controller stays [`ControllerStatus::Held`] (a simulation then ends `stalled`, naming the
    /// hold). The stack with gradient, the fallback's law, would cross the limit there, where a real robot stops with
    /// a fault. `false` keeps that law to the end. Measured on the uniform starts of the four scenarios (seeds 1–3):
    /// the runs that end past a hard limit fall from 75–181 to 3–77 of 200; as many draws converge within 0–2 and
    /// the same draws a baseline wins are covered (theory D13, *hold*). With the braking of D25 and the lock of D26 on,
    /// the hold changes nothing but to stop, at the limit, runs that the lock would carry to the goal (theory D26).
    pub hold_before_limit: bool,
    /// `ξ` (s⁻¹), the braking rate of D25: whoever sends the full method's velocity to the joints (the simulation,
    /// [`crate::servo::VisualServo`]) scales it uniformly so that every joint moving towards a hard limit keeps
    /// `|q̇_i| ≤ ξ d_i`, `d_i` its distance to the limit ([`crate::avoidance::JointLimits::braking_scale`]), and tells
    /// the controller what was sent ([`StackController::set_sent_velocity`]). With a period `Δt ≤ 1/ξ` no joint
    /// crosses its limit: the removals, the fallback and the hold of D13 decide from predictions, and a fast joint
    /// (the UR5e's elbow, 0.55 rad of range) can reach its limit before a change made in time takes effect. Default
    /// 5 s⁻¹ (a limit approached with a time constant of 0.2 s); `+∞` switches it off; a simulation refuses `ξ Δt > 1`.
    /// Measured (full tables of the four scenarios, seeds 1–3, 200 draws per family): no run of the full method ends
    /// past a hard limit (8–149 per study before), every family but the uniform starts unchanged, and there 0–13 more
    /// draws converge; 5 and 20 s⁻¹ give the same figures within 3 draws (theory D25).
    pub braking_rate: f64,
    /// `δ`, the lock band of D26 as a fraction of each joint's range: a joint closer than `δ Δq_i` to a hard limit
    /// that the law drives towards it is held still, and the stack is solved on the other joints
    /// ([`crate::stack::StackWorkspace::lock_joints`]); the robot slides along the limit instead of stopping at it
    /// (the braking of D25 stops it there). Needs the limits ([`StackController::with_joint_limits`]); `0` switches
    /// the lock off. Default `10⁻⁵` (a joint reaches the band only after the braking has slowed it down); valid in
    /// `[0, 0.5)`.
    pub lock_band: f64,
    /// `k_restart` (s⁻¹), the restart of D29: at rest against a limit short of the goal, with every task stacked, the
    /// sequence restarts from its first task, once, and the joints that were locked are driven towards the middle of
    /// their range at this rate, `q̇_i = −k_restart (q_i − q̄_i)` before the projection into the first task's null
    /// space (the law's secondary term becomes the gradient of `h + ½ (k_restart/κ) Σ (q_i − q̄_i)²`). Needs the
    /// limits ([`StackController::with_joint_limits`]) and `κ > 0`; full method only (robust rule, removals
    /// allowed). Default 1 s⁻¹; `0` switches the restart off. Measured: theory D29.
    pub restart_rate: f64,
    /// `b_restart`: the recentring ends, and the sequence goes on, once every recentred joint is within
    /// `b_restart Δq_i` of the middle of its range (D29; a fraction of the range, default 0.05, in `(0, 0.5]`).
    pub restart_centre_band: f64,
    /// `T_restart` (s): the recentring ends after this long even if a joint has not reached the middle of its range
    /// (D29; default 5 s, the stall timeout's).
    pub restart_timeout: f64,
}

impl Default for ControllerParameters {
    fn default() -> Self {
        Self {
            settle_velocity: 0.01,
            settle_velocity_with_removal: 0.1,
            settle_transitions: 5.0,
            prediction_horizon: 0.05,
            look_ahead_transitions: 0.0,
            removal_threshold: None,
            reinsertion_ratio: 0.5,
            reinsertion_look_ahead: 1.0,
            change_transitions: 1.0,
            reinsertion_dwell: 1.0,
            max_removals: 4,
            stall_timeout: 5.0,
            allow_removal: true,
            criterion: RemovalCriterion::Combined,
            rule: DecisionRule::Robust,
            escape_achieved_error: 1e-3,
            escape_error: 0.005,
            escape_growth_rate: 0.0,
            early_push_ratio: 4.0,
            hold_before_limit: false,
            braking_rate: 5.0,
            lock_band: 1e-5,
            restart_rate: 1.0,
            restart_centre_band: 0.05,
            restart_timeout: 5.0,
        }
    }
}

/// The largest count of transitions (`1/μ`) a wait or horizon may span.
const MAX_TRANSITIONS: f64 = 1e4;

impl ControllerParameters {
    /// Checks every parameter.
    ///
    /// # Errors
    /// [`ControllerError::InvalidParameter`] naming the first offending parameter.
    pub fn validate(&self) -> Result<(), ControllerError> {
        let check = |name: &'static str, value: f64, ok: bool, expected: &'static str| {
            if ok {
                Ok(())
            } else {
                Err(ControllerError::InvalidParameter {
                    name,
                    value,
                    expected,
                })
            }
        };
        let in_range = |v: f64, low: f64, high: f64| v.is_finite() && low <= v && v <= high;
        for (name, v) in [
            ("settle_velocity", self.settle_velocity),
            (
                "settle_velocity_with_removal",
                self.settle_velocity_with_removal,
            ),
        ] {
            check(
                name,
                v,
                v.is_finite() && v > 0.0 && v < 1e6,
                "finite, > 0 and < 1e6",
            )?;
        }
        let v = self.settle_transitions;
        check(
            "settle_transitions",
            v,
            in_range(v, 0.0, MAX_TRANSITIONS),
            "in [0, 1e4]",
        )?;
        let v = self.prediction_horizon;
        check(
            "prediction_horizon",
            v,
            DURATION_S.contains(v),
            DURATION_S.text,
        )?;
        let v = self.look_ahead_transitions;
        check(
            "look_ahead_transitions",
            v,
            in_range(v, 0.0, MAX_TRANSITIONS),
            "in [0, 1e4]",
        )?;
        if let Some(h_max) = self.removal_threshold {
            check(
                "removal_threshold",
                h_max,
                h_max.is_finite() && h_max > 0.0,
                "finite and > 0",
            )?;
        }
        let v = self.reinsertion_ratio;
        check(
            "reinsertion_ratio",
            v,
            v.is_finite() && v > 0.0 && v <= 1.0,
            "in (0, 1]",
        )?;
        let v = self.reinsertion_look_ahead;
        check(
            "reinsertion_look_ahead",
            v,
            v > 0.0 && in_range(v, 0.0, MAX_TRANSITIONS),
            "in (0, 1e4]",
        )?;
        let v = self.change_transitions;
        check(
            "change_transitions",
            v,
            in_range(v, 0.0, MAX_TRANSITIONS),
            "in [0, 1e4]",
        )?;
        let v = self.reinsertion_dwell;
        check(
            "reinsertion_dwell",
            v,
            DURATION_S.contains(v),
            DURATION_S.text,
        )?;
        for (name, v) in [
            ("stall_timeout", self.stall_timeout),
            ("restart_timeout", self.restart_timeout),
        ] {
            check(
                name,
                v,
                v > 0.0 && DURATION_S.contains(v),
                "> 0 and within [0, 86400] s",
            )?;
        }
        let v = f64::from(self.max_removals);
        check("max_removals", v, self.max_removals >= 1, "≥ 1")?;
        for (name, v) in [
            ("escape_achieved_error", self.escape_achieved_error),
            ("escape_error", self.escape_error),
        ] {
            check(name, v, !v.is_nan() && v > 0.0, "> 0 (+∞: never)")?;
        }
        let v = self.escape_growth_rate;
        check(
            "escape_growth_rate",
            v,
            !v.is_nan() && v >= 0.0,
            "≥ 0 (+∞: never)",
        )?;
        let v = self.early_push_ratio;
        check(
            "early_push_ratio",
            v,
            !v.is_nan() && v > 1.0,
            "> 1 (+∞: never)",
        )?;
        let v = self.braking_rate;
        check(
            "braking_rate",
            v,
            !v.is_nan() && v > 0.0,
            "> 0 (+∞: no braking)",
        )?;
        let v = self.lock_band;
        check(
            "lock_band",
            v,
            (0.0..0.5).contains(&v),
            "in [0, 0.5) (0: no lock)",
        )?;
        let v = self.restart_rate;
        check(
            "restart_rate",
            v,
            in_range(v, 0.0, 1e4),
            "in [0, 1e4] s⁻¹ (0: no restart)",
        )?;
        let v = self.restart_centre_band;
        check(
            "restart_centre_band",
            v,
            v > 0.0 && in_range(v, 0.0, 0.5),
            "in (0, 0.5]",
        )?;
        Ok(())
    }

    /// `T = max(T_min, n_look/μ)` (s), the removal prediction's horizon for a transition gain `μ` (s⁻¹); `T_min` alone
    /// with [`DecisionRule::Paper`].
    pub fn horizon(&self, transition_gain: f64) -> f64 {
        match self.rule {
            DecisionRule::Robust => self
                .prediction_horizon
                .max(self.look_ahead_transitions / transition_gain),
            DecisionRule::Paper => self.prediction_horizon,
        }
    }
}

/// The criteria of one stacked task at one instant ([theory §6.3](crate::theory#s6-3)).
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
    /// A removed task was put back without the test: the first that could not come back, after which removals stop
    /// except as a last resort, or one removed as a last resort, after its dwell (D13).
    Fallback,
    /// The reserve task took the place of the last task of the sequence: the stack had achieved its tasks with the
    /// reserve task's error still large, a false equilibrium of the sequence's features (D23), or the complete stack
    /// was driving the reserve task's error up (D24). The event's task is the reserve task.
    Escape,
    /// Every task was dropped rather than let the law cross a hard limit
    /// ([`ControllerParameters::hold_before_limit`], D13); the event's task is the highest-priority one dropped.
    Hold,
    /// The sequence was restarted from its first task, at rest against a limit short of the goal (D29); one event per
    /// task taken out, all at the same iteration.
    Restart,
}

impl EventKind {
    /// The verb used in logs and figures: `push`, `remove`, `reinsert`, `fallback`, `escape`, `hold`, `restart`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Push => "push",
            Self::Remove => "remove",
            Self::Reinsert => "reinsert",
            Self::Escape => "escape",
            Self::Fallback => "fallback",
            Self::Hold => "hold",
            Self::Restart => "restart",
        }
    }
}

/// Why a task was removed.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RemovalReport {
    /// The predicted cost `h(q̂)` at [`Self::horizon`] that exceeded the threshold (`+∞` past a hard limit or with the
    /// target lost, as for the last resort of D13).
    pub predicted_cost: f64,
    /// The threshold `h_max`.
    pub threshold: f64,
    /// The predicted cost with the task removed (smaller than `predicted_cost` under [`DecisionRule::Robust`]).
    pub predicted_cost_without: f64,
    /// The prediction horizon (s): `T`, or `max(T, n_resort/μ)` for the last resort of D13 and for a hard limit
    /// predicted to be crossed within it (D6, [`Cost::forbids`]).
    pub horizon: f64,
    /// The joint with the largest component of the gradient `∇h(q̂)` predicted `T` ahead (0-based).
    pub joint: usize,
    /// The cost term that dominates the predicted cost `h(q̂)` ([`Cost::dominant_term`]: `"joint_limits"`,
    /// `"obstacles"`, `"visibility"`, ...).
    pub cost: String,
    /// The criteria of every stacked task at the removal.
    pub criteria: Vec<TaskCriteria>,
    /// For a removal made to let a removed task come back (a D7 swap), that task; `None` for a removal made because
    /// the avoidance was predicted to fail.
    pub swapped_for: Option<usize>,
}

/// Why a removed task came back.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ReinsertionReport {
    /// The cost predicted with the task back, `h(q̂)` over the re-insertion horizon (for a guard relief, D7: the
    /// guard's prediction `g(q̂)` one transition time ahead).
    pub predicted_cost: f64,
    /// What it was compared with: the re-insertion threshold `r_back · h_max` (for a guard relief: the guard's
    /// prediction without the task, which the return must lower).
    pub threshold: f64,
    /// How long the task was out (s).
    pub removed_for: f64,
}

/// One change of the stack, as the event log records it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StackEvent {
    /// The control iteration at which the change was made (the velocity sent at this iteration is the new stack's,
    /// blended from the one sent at the previous iteration).
    pub iteration: usize,
    /// The time of that iteration (s).
    pub time: f64,
    /// Push, removal, re-insertion or fallback.
    pub kind: EventKind,
    /// The task's index in the task list.
    pub task: usize,
    /// `‖u(τ) − q̇(τ⁻)‖`: the jump the law alone would have made at this change, which the transition term of D1
    /// turns into a ramp (D14).
    pub law_jump: f64,
    /// For a removal, why.
    pub removal: Option<RemovalReport>,
    /// For a re-insertion or a fallback, the prediction it was judged on.
    pub reinsertion: Option<ReinsertionReport>,
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
    /// `h(q̂)`, the cost predicted over the horizon (equal to `h(q)` without a cost).
    pub predicted_cost: f64,
    /// The change made at this iteration, if any.
    pub event: Option<EventKind>,
}

/// What the controller is waiting for, to say why a run that ran out of time did not converge.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ControllerStatus {
    /// Every task of the list is stacked.
    Complete,
    /// Every task was dropped rather than let the law cross a hard limit ([`ControllerParameters::hold_before_limit`]).
    Held {
        /// The highest-priority task dropped.
        task: usize,
        /// The time of the hold (s).
        time: f64,
    },
    /// Tasks remain to be pushed; the stack has not settled (`‖q̇_n‖ ≥ ε_add`) since the last change.
    Pushing {
        /// The next task to push.
        next: usize,
        /// The last `‖q̇_n‖`.
        stack_velocity_norm: f64,
    },
    /// A removed task waits to come back.
    Reinserting {
        /// The task.
        task: usize,
        /// Its last re-insertion test; `None` before the first (a test waits for the stack to settle, `‖q̇_n‖ <
        /// ε_add`, and for the task's dwell, D7).
        last_test: Option<ReinsertionTest>,
        /// The last `‖q̇_n‖`.
        stack_velocity_norm: f64,
    },
}

/// A re-insertion test of a removed task (D7): the cost predicted with the task back, against the threshold it must
/// stay under.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReinsertionTest {
    /// The cost predicted with the task back.
    pub predicted_cost: f64,
    /// The threshold.
    pub threshold: f64,
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
    /// D13: removals stopped after a fallback, except as a last resort.
    fallback: bool,
    /// The hold (highest-priority task dropped, time), once every task was dropped before a hard limit.
    held: Option<(usize, f64)>,
    /// The joint limits given to [`Self::with_joint_limits`]: the lock of D26, the restart of D29.
    limits: Option<JointLimits<N>>,
    /// D29: whether the sequence has been restarted (once per run).
    restarted: bool,
    /// D29: while the restart recentres joints, which ones and since when.
    recentring: Option<([bool; N], f64)>,
    change_pending: bool,
    last_change_time: f64,
    /// D28: `(k, m)`, the smallest `‖u⁺‖` (the law with the next task pushed) seen since the change logged as event
    /// `k − 1` (`k` = the event count then); reset at each change.
    early_push_reference: Option<(usize, f64)>,
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
            held: None,
            limits: None,
            restarted: false,
            recentring: None,
            change_pending: false,
            last_change_time: 0.0,
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
        self.held.is_some()
    }

    /// What the controller waits for (to explain a run that did not converge in its budget).
    pub fn status(&self) -> ControllerStatus {
        if let Some((task, time)) = self.held {
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
        let was_recentring = self.recentring.is_some();
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
        if event.is_none() && was_recentring && self.recentring.is_none() {
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

    /// `h_max`: the parameter, else the cost's D6 default, else no removal.
    fn removal_threshold(&self, cost: &dyn Cost<N>) -> f64 {
        self.parameters
            .removal_threshold
            .or_else(|| cost.default_removal_threshold())
            .unwrap_or(f64::INFINITY)
    }

    fn push_next(&mut self, iteration: usize, time: f64) {
        let task = self.next_push;
        self.next_push += 1;
        self.insert_by_priority(task);
        self.record(StackEvent {
            iteration,
            time,
            kind: EventKind::Push,
            task,
            law_jump: 0.0,
            removal: None,
            reinsertion: None,
        });
    }

    /// D23: the reserve task replaces the last task of the sequence when the stack has achieved its tasks and the
    /// reserve task has not (called with the sequence complete, no task out and the stack settled).
    fn escape(&mut self, tasks: &[TaskValue<N>], iteration: usize, time: f64) -> Option<EventKind> {
        let reserve = self.waiting_reserve()?;
        let achieved = self
            .stacked
            .iter()
            .all(|&t| tasks[t].error().norm() < self.parameters.escape_achieved_error);
        if !achieved || tasks[reserve].error().norm() <= self.parameters.escape_error {
            return None;
        }
        self.swap_in_reserve(reserve, iteration, time)
    }

    /// D24: the reserve task replaces the last task of the sequence as soon as the law of the complete stack, nothing
    /// out, drives the reserve task's error away from zero (`e_rᵀ J_r u > r_escape ‖e_r‖²`) while it is above
    /// `ε_escape`; not within `n_change/μ` of the last change (the law's transient after a push is not judged).
    fn escape_early(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        output: &ControlOutput<N>,
        iteration: usize,
        time: f64,
    ) -> Option<EventKind> {
        let reserve = self.waiting_reserve()?;
        let parameters = &self.parameters;
        if self.next_push < self.sequence_len()
            || !self.removed.is_empty()
            || time - self.last_change_time < parameters.change_transitions / law.transition_gain()
        {
            return None;
        }
        let value = &tasks[reserve];
        let error_squared = value.error().norm_squared();
        if error_squared.sqrt() <= parameters.escape_error {
            return None;
        }
        // e_rᵀ J_r u = (J_rᵀ e_r)ᵀ u, with J_rᵀ e_r a fixed-size N-vector (no allocation).
        let growth = value.jacobian().tr_mul(value.error()).dot(output.law()) / error_squared;
        if growth > parameters.escape_growth_rate {
            self.swap_in_reserve(reserve, iteration, time)
        } else {
            None
        }
    }

    /// D23, D24: the reserve task takes the place of the last stacked task, once; logged as [`EventKind::Escape`].
    fn swap_in_reserve(
        &mut self,
        reserve: usize,
        iteration: usize,
        time: f64,
    ) -> Option<EventKind> {
        let last = *self.stacked.last()?;
        self.stacked.retain(|&t| t != last);
        self.insert_by_priority(reserve);
        self.escaped = true;
        self.record(StackEvent {
            iteration,
            time,
            kind: EventKind::Escape,
            task: reserve,
            law_jump: 0.0,
            removal: None,
            reinsertion: None,
        });
        Some(EventKind::Escape)
    }

    /// D29: at rest (`‖q̇_n‖ < ε_add`, the paper's threshold) with the whole sequence stacked, nothing out and no
    /// escape due, a joint locked at a limit and the goal not reached (the reserve task's error above `ε_escape`;
    /// without a reserve, a stacked task's above `ε_achieved`): every task but the first is taken out in one change,
    /// once per run, and the locked joints are recentred ([`Self::recentring_cost`]) before the sequence goes on.
    fn restart(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: Option<&dyn Cost<N>>,
        result: &ControllerStep<N>,
        iteration: usize,
        time: f64,
    ) -> Option<EventKind> {
        let parameters = &self.parameters;
        if parameters.restart_rate <= 0.0
            || self.restarted
            || !parameters.allow_removal
            || parameters.rule != DecisionRule::Robust
            || self.limits.is_none()
            || cost.is_none()
            || law.avoidance_gain() <= 0.0
            || result.stack_velocity_norm >= parameters.settle_velocity
        {
            return None;
        }
        let goal_missed = match self.reserve {
            Some(reserve) => tasks[reserve].error().norm() > parameters.escape_error,
            None => self
                .stacked
                .iter()
                .any(|&t| tasks[t].error().norm() > parameters.escape_achieved_error),
        };
        let locked = *self.law_workspace.locked_joints();
        if !goal_missed || !locked.contains(&true) {
            return None;
        }
        let first = *self.stacked.first()?;
        self.restarted = true;
        self.recentring = Some((locked, time));
        self.escaped = false;
        self.next_push = first + 1;
        // One change: every task taken out is logged at this iteration, in priority order.
        let stacked = std::mem::take(&mut self.stacked);
        for &task in &stacked[1..] {
            self.record(StackEvent {
                iteration,
                time,
                kind: EventKind::Restart,
                task,
                law_jump: 0.0,
                removal: None,
                reinsertion: None,
            });
        }
        self.stacked = stacked;
        self.stacked.truncate(1);
        Some(EventKind::Restart)
    }

    /// D29: every recentred joint within `b_restart Δq_i` of the middle of its range.
    fn recentred(&self, joints: &[bool; N], q: &JointVector<N>) -> bool {
        let Some(limits) = &self.limits else {
            return true;
        };
        let band = self.parameters.restart_centre_band;
        (0..N).all(|i| {
            let (lower, upper) = (limits.lower()[i], limits.upper()[i]);
            !joints[i] || (q[i] - 0.5 * (lower + upper)).abs() <= band * (upper - lower)
        })
    }

    /// D29: while a restart recentres joints, the cost whose gradient the law descends.
    fn recentring_cost<'a>(
        &self,
        law: &ControlLaw,
        cost: Option<&'a dyn Cost<N>>,
    ) -> Option<RecentringCost<'a, N>> {
        let ((joints, _), limits, avoidance) = (self.recentring?, self.limits.as_ref()?, cost?);
        let kappa = law.avoidance_gain();
        if kappa <= 0.0 {
            return None;
        }
        let weight = self.parameters.restart_rate / kappa;
        Some(RecentringCost {
            avoidance,
            centre: (limits.lower() + limits.upper()) * 0.5,
            weights: JointVector::from_fn(|i, _| if joints[i] { weight } else { 0.0 }),
        })
    }

    fn insert_by_priority(&mut self, task: usize) {
        let at = self.stacked.partition_point(|&t| t < task);
        self.stacked.insert(at, task);
    }

    fn record(&mut self, event: StackEvent) {
        self.last_change_time = event.time;
        self.refused_since = None;
        self.events.push(event);
    }

    /// Steps 2–4 of the module docs: a relieving re-insertion (D7), else a removal (D6), else a settled re-insertion
    /// (D7), a fallback (D13) or a push (D5), applied to the stack and logged. `result` receives the predicted cost.
    #[allow(clippy::too_many_arguments)]
    fn decide(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: Option<&dyn Cost<N>>,
        guard: Option<&dyn Cost<N>>,
        q: &JointVector<N>,
        output: &ControlOutput<N>,
        sent_before: &JointVector<N>,
        iteration: usize,
        time: f64,
        result: &mut ControllerStep<N>,
    ) -> Result<Option<EventKind>, ControllerError> {
        self.criteria.clear();
        if self.held.is_some() {
            return Ok(None);
        }
        if let Some(kind) = self.escape_early(law, tasks, output, iteration, time) {
            return Ok(Some(kind));
        }
        let prediction = Prediction {
            q,
            sent: output.velocity(),
            sent_before,
            gradient: output.gradient(),
            transition_gain: law.transition_gain(),
            rule: self.parameters.rule,
        };
        let Some(cost) = cost else {
            return self.settle_and_add(law, tasks, None, &prediction, iteration, time, result);
        };
        let horizon = self.parameters.horizon(law.transition_gain());
        let predicted = prediction.at(output.law(), horizon);
        let mut predicted_gradient = JointVector::zeros();
        result.predicted_cost = match cost.value_and_gradient(&predicted, &mut predicted_gradient) {
            Err(CostError::PointBehindCamera { .. }) => f64::INFINITY,
            _ if self.parameters.rule == DecisionRule::Robust && cost.forbids(&predicted) => {
                f64::INFINITY
            }
            other => other?,
        };
        // The direction of the danger: ∇h(q), or ∇h(q̂) while the robot is still outside every band (robust rule). While
        // a restart recentres joints (D29) the law's gradient carries the recentring term: ∇h is evaluated apart.
        let mut gradient = *output.gradient();
        if self.recentring.is_some() {
            cost.value_and_gradient(q, &mut gradient)?;
        }
        let danger = if gradient.norm() > 0.0 || self.parameters.rule == DecisionRule::Paper {
            gradient
        } else {
            predicted_gradient
        };
        if danger.norm() > 0.0 {
            self.compute_criteria(law, tasks, &danger)?;
        }
        let threshold = self.removal_threshold(cost);
        let danger_predicted =
            result.predicted_cost > threshold && result.predicted_cost > result.cost;
        if let Some((task, predicted_back)) =
            self.choose_relieving_reinsertion(law, tasks, cost, &prediction, horizon, result, time)?
        {
            let threshold = self.parameters.reinsertion_ratio * threshold;
            self.reinsert(
                task,
                EventKind::Reinsert,
                iteration,
                time,
                predicted_back,
                threshold,
            );
            return Ok(Some(EventKind::Reinsert));
        }
        if let Some(guard) = guard {
            if let Some((task, predicted_back, predicted_without)) =
                self.choose_guard_relief(law, tasks, guard, &prediction, output, horizon, time)?
            {
                self.reinsert(
                    task,
                    EventKind::Reinsert,
                    iteration,
                    time,
                    predicted_back,
                    predicted_without,
                );
                return Ok(Some(EventKind::Reinsert));
            }
        }
        // After the fallback, only the last resort of D13: the law is about to cross a hard limit (or lose the target)
        // within the time a removal needs to act, `max(T, n_resort/μ)`. Before it, the `h_max` test of D6, and the
        // same hard-limit check (D6): the `h_max` test looks `T` ahead only.
        let far = horizon.max(LAST_RESORT_TRANSITIONS / law.transition_gain());
        let (trigger, removal_horizon, reference) = if self.fallback {
            let far_value = self.predicted_value(cost, &prediction.at(output.law(), far))?;
            let imminent = self.parameters.rule == DecisionRule::Robust && far_value.is_infinite();
            (imminent, far, f64::INFINITY)
        } else if !danger_predicted
            && self.parameters.rule == DecisionRule::Robust
            && cost.forbids(&prediction.at(output.law(), far))
        {
            (true, far, f64::INFINITY)
        } else {
            (danger_predicted, horizon, result.predicted_cost)
        };
        if trigger && danger.norm() > 0.0 && self.may_remove(law, time) {
            let choice = self.choose_removal(
                law,
                tasks,
                cost,
                guard,
                &prediction,
                removal_horizon,
                reference,
                &predicted,
            )?;
            if let Some((task, predicted_cost_without)) = choice {
                // At the prediction a target point may be behind the camera (an infinite cost, D6): the cost is
                // then named as a whole when it cannot name its term.
                let dominant = match cost.dominant_term(&predicted) {
                    Err(CostError::PointBehindCamera { .. }) => cost.name(),
                    named => named?,
                }
                .to_owned();
                self.stacked.retain(|&t| t != task);
                let at = self.removed.partition_point(|&t| t < task);
                self.removed.insert(at, task);
                self.removal_count[task] += 1;
                self.last_resort_used[task] |= self.fallback;
                self.removed_at[task] = time;
                self.last_removal_time = time;
                self.last_reinsertion_test = None;
                let report = RemovalReport {
                    predicted_cost: reference,
                    threshold,
                    predicted_cost_without,
                    horizon: removal_horizon,
                    joint: predicted_gradient.iamax(),
                    cost: dominant,
                    criteria: self.criteria.clone(),
                    swapped_for: None,
                };
                self.record(StackEvent {
                    iteration,
                    time,
                    kind: EventKind::Remove,
                    task,
                    law_jump: 0.0,
                    removal: Some(report),
                    reinsertion: None,
                });
                return Ok(Some(EventKind::Remove));
            }
            if self.fallback && self.parameters.hold_before_limit {
                return Ok(Some(self.hold(iteration, time)));
            }
        }
        self.settle_and_add(law, tasks, Some(cost), &prediction, iteration, time, result)
    }

    /// D13 hold: every stacked task is dropped (into the removed list, never to come back), so that the law is the
    /// avoidance alone. Moves indices between preallocated lists: no allocation.
    fn hold(&mut self, iteration: usize, time: f64) -> EventKind {
        let first = self.stacked.first().copied().unwrap_or(0);
        while let Some(task) = self.stacked.pop() {
            let at = self.removed.partition_point(|&t| t < task);
            self.removed.insert(at, task);
        }
        self.held = Some((first, time));
        self.record(StackEvent {
            iteration,
            time,
            kind: EventKind::Hold,
            task: first,
            law_jump: 0.0,
            removal: None,
            reinsertion: None,
        });
        EventKind::Hold
    }

    /// Whether a removal may be made now: removals allowed, a task stacked, and (robust rule) the last removal at least
    /// `n_change/μ` old. A removal right after a push is allowed: the push is what the removal answers. After the
    /// fallback the caller asks this only for the last resort of D13.
    fn may_remove(&self, law: &ControlLaw, time: f64) -> bool {
        let parameters = &self.parameters;
        let spaced = match parameters.rule {
            DecisionRule::Robust => {
                time - self.last_removal_time
                    >= parameters.change_transitions / law.transition_gain()
            }
            DecisionRule::Paper => true,
        };
        parameters.allow_removal && !self.stacked.is_empty() && spaced
    }

    /// D6: the task to remove and the cost predicted without it, or `None` when no candidate qualifies.
    #[allow(clippy::too_many_arguments)]
    fn choose_removal(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: &dyn Cost<N>,
        guard: Option<&dyn Cost<N>>,
        prediction: &Prediction<'_, N>,
        horizon: f64,
        predicted_cost: f64,
        predicted: &JointVector<N>,
    ) -> Result<Option<(usize, f64)>, ControllerError> {
        let criterion = self.parameters.criterion;
        self.ranking.clear();
        self.ranking.extend_from_slice(&self.criteria);
        // Best score first; on equal scores the lowest priority (largest index) first.
        self.ranking.sort_unstable_by(|a, b| {
            b.score(criterion)
                .total_cmp(&a.score(criterion))
                .then(b.task.cmp(&a.task))
        });
        let robust = self.parameters.rule == DecisionRule::Robust;
        if robust && self.stacked.len() <= 1 {
            return Ok(None);
        }
        let guard_now = match guard {
            Some(guard) if robust => self.predicted_value(guard, predicted)?,
            _ => 0.0,
        };
        for rank in 0..self.ranking.len() {
            let task = self.ranking[rank].task;
            if robust
                && (self.protected[task]
                    || self.removal_count[task] >= self.parameters.max_removals
                    || self.last_resort_used[task])
            {
                continue;
            }
            self.set_trial_stack(None, Some(task));
            let without =
                prediction.after_change(&self.trial_law(law, tasks, prediction.gradient)?, horizon);
            let predicted_without = self.predicted_value(cost, &without)?;
            if !robust {
                return Ok(Some((task, predicted_without)));
            }
            if predicted_without >= predicted_cost {
                continue;
            }
            if let Some(guard) = guard {
                if self.predicted_value(guard, &without)? > guard_now {
                    continue;
                }
            }
            return Ok(Some((task, predicted_without)));
        }
        Ok(None)
    }

    /// D7 relief: while the cost is predicted to rise (`h(q̂) > h(q)` over the removal horizon `T`), a removed task whose
    /// dwell is over comes back, without waiting for the stack to settle, when the law with it back predicts a lower
    /// cost than the current stack's and one under the re-insertion threshold `r_back · h_max`: the first such task by
    /// priority, with its predicted cost. Robust rule only, never during the fallback, not within `n_change/μ` of the
    /// last change.
    #[allow(clippy::too_many_arguments)]
    fn choose_relieving_reinsertion(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: &dyn Cost<N>,
        prediction: &Prediction<'_, N>,
        horizon: f64,
        now: &ControllerStep<N>,
        time: f64,
    ) -> Result<Option<(usize, f64)>, ControllerError> {
        if !self.may_relieve(law, time) || self.fallback || now.predicted_cost <= now.cost {
            return Ok(None);
        }
        let threshold = self.parameters.reinsertion_ratio * self.removal_threshold(cost);
        self.first_task_back(law, tasks, cost, prediction, horizon, Some(time), |back| {
            back < now.predicted_cost && back <= threshold
        })
    }

    /// D7 guard relief: while the `guard` cost (the visibility of the target, in the simulation) is predicted to rise
    /// to a positive value one transition time ahead (`g(q̂(max(T, n_resort/μ))) > max(g(q), 0)`), the first removed
    /// task by priority whose return lowers that prediction comes back at once, whatever its dwell and during the
    /// fallback too: losing the target ends the run, and the free motion a removal leaves may carry the target out of
    /// the image long after the removal's own guard test. Returns the task, the guard's prediction with it back and
    /// without it. Robust rule only, not within `n_change/μ` of the last change.
    #[allow(clippy::too_many_arguments)]
    fn choose_guard_relief(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        guard: &dyn Cost<N>,
        prediction: &Prediction<'_, N>,
        output: &ControlOutput<N>,
        horizon: f64,
        time: f64,
    ) -> Result<Option<(usize, f64, f64)>, ControllerError> {
        if !self.may_relieve(law, time) {
            return Ok(None);
        }
        let far = horizon.max(LAST_RESORT_TRANSITIONS / law.transition_gain());
        let now = self.predicted_value(guard, prediction.q)?;
        let without = self.predicted_value(guard, &prediction.at(output.law(), far))?;
        if without <= now.max(0.0) {
            return Ok(None);
        }
        let found = self.first_task_back(law, tasks, guard, prediction, far, None, |back| {
            back < without
        })?;
        Ok(found.map(|(task, back)| (task, back, without)))
    }

    /// Whether a relief (D7) may be considered: a task is out, robust rule, the last change at least `n_change/μ` old.
    fn may_relieve(&self, law: &ControlLaw, time: f64) -> bool {
        !self.removed.is_empty()
            && self.parameters.rule == DecisionRule::Robust
            && time - self.last_change_time
                >= self.parameters.change_transitions / law.transition_gain()
    }

    /// The first removed task by priority whose return `accept`s the value of `cost` predicted `horizon` ahead along
    /// the law of the stack with it back, with that value. With `dwell_at = Some(t)`, tasks still within their dwell
    /// at time `t` are passed over.
    #[allow(clippy::too_many_arguments)]
    fn first_task_back(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: &dyn Cost<N>,
        prediction: &Prediction<'_, N>,
        horizon: f64,
        dwell_at: Option<f64>,
        accept: impl Fn(f64) -> bool,
    ) -> Result<Option<(usize, f64)>, ControllerError> {
        for rank in 0..self.removed.len() {
            let task = self.removed[rank];
            if dwell_at.is_some_and(|time| time - self.removed_at[task] < self.dwell(task)) {
                continue;
            }
            self.set_trial_stack(Some(task), None);
            let back =
                prediction.after_change(&self.trial_law(law, tasks, prediction.gradient)?, horizon);
            let predicted_back = self.predicted_value(cost, &back)?;
            if accept(predicted_back) {
                return Ok(Some((task, predicted_back)));
            }
        }
        Ok(None)
    }

    /// `self.trial_order` ← the stacked tasks without `left_out`, with `added` at its priority: the stack a removal,
    /// a re-insertion or a swap would make.
    fn set_trial_stack(&mut self, added: Option<usize>, left_out: Option<usize>) {
        self.trial_order.clear();
        self.trial_order.extend(
            self.stacked
                .iter()
                .copied()
                .filter(|&t| Some(t) != left_out),
        );
        if let Some(task) = added {
            let at = self.trial_order.partition_point(|&t| t < task);
            self.trial_order.insert(at, task);
        }
    }

    /// The law `u = q̇_n − κ P^A_n ∇h` of the stack `self.trial_order`.
    fn trial_law(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        gradient: &JointVector<N>,
    ) -> Result<JointVector<N>, ControllerError> {
        let solution = solve_stack(
            law.stack_parameters(),
            &mut self.trial_workspace,
            tasks,
            &self.trial_order,
        )
        .map_err(LawError::from)?;
        let avoidance = law.avoidance_term(solution, tasks, &self.trial_order, gradient)?;
        Ok(solution.velocity() + avoidance)
    }

    /// D5: the stack velocity is below `epsilon_add` and the last transition has died out.
    fn settled(
        &self,
        law: &ControlLaw,
        time: f64,
        stack_velocity_norm: f64,
        epsilon_add: f64,
    ) -> bool {
        stack_velocity_norm < epsilon_add
            && time - self.last_change_time
                >= self.parameters.settle_transitions / law.transition_gain()
    }

    /// D28: before the stack has settled, push the next task once the law with it, `‖u⁺‖`, has grown to `r_push`
    /// times its smallest value since the last change (full method, no task out, one transition after the change).
    fn push_early(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        gradient: &JointVector<N>,
        iteration: usize,
        time: f64,
    ) -> Result<Option<EventKind>, ControllerError> {
        let parameters = &self.parameters;
        if !parameters.early_push_ratio.is_finite()
            || !parameters.allow_removal
            || parameters.rule != DecisionRule::Robust
            || !self.removed.is_empty()
            || self.next_push >= self.sequence_len()
            || time - self.last_change_time < parameters.change_transitions / law.transition_gain()
        {
            return Ok(None);
        }
        let ratio = parameters.early_push_ratio;
        self.set_trial_stack(Some(self.next_push), None);
        let with_next = self.trial_law(law, tasks, gradient)?.norm();
        let changes = self.events.len();
        match self.early_push_reference {
            Some((since, smallest)) if since == changes => {
                if with_next > ratio * smallest {
                    self.push_next(iteration, time);
                    return Ok(Some(EventKind::Push));
                }
                self.early_push_reference = Some((since, smallest.min(with_next)));
            }
            _ => self.early_push_reference = Some((changes, with_next)),
        }
        Ok(None)
    }

    /// D7, D13, D5: once settled, put a removed task back (with hysteresis and dwell), fall back when one cannot come
    /// back, or push the next task.
    #[allow(clippy::too_many_arguments)]
    fn settle_and_add(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: Option<&dyn Cost<N>>,
        prediction: &Prediction<'_, N>,
        iteration: usize,
        time: f64,
        result: &ControllerStep<N>,
    ) -> Result<Option<EventKind>, ControllerError> {
        // D29: while a restart recentres joints, nothing is pushed or put back.
        if let Some((joints, since)) = self.recentring {
            if time - since < self.parameters.restart_timeout
                && !self.recentred(&joints, prediction.q)
            {
                return Ok(None);
            }
            self.recentring = None;
        }
        // With no task out, the next push waits for the full method's threshold when tasks may be removed (robust
        // rule), the paper's otherwise; a removed task is tested for re-insertion at the paper's, once the stack has
        // nearly stopped (D5).
        let parameters = &self.parameters;
        let epsilon_add = if self.removed.is_empty()
            && parameters.allow_removal
            && parameters.rule == DecisionRule::Robust
        {
            parameters.settle_velocity_with_removal
        } else {
            parameters.settle_velocity
        };
        if !self.settled(law, time, result.stack_velocity_norm, epsilon_add) {
            return self.push_early(law, tasks, prediction.gradient, iteration, time);
        }
        if self.removed.is_empty() {
            if self.next_push < self.sequence_len() {
                self.push_next(iteration, time);
                return Ok(Some(EventKind::Push));
            }
            if let Some(kind) = self.escape(tasks, iteration, time) {
                return Ok(Some(kind));
            }
            return Ok(self.restart(law, tasks, cost, result, iteration, time));
        }
        let robust = self.parameters.rule == DecisionRule::Robust;
        let h_max = cost.map_or(f64::INFINITY, |c| self.removal_threshold(c));
        let threshold = if robust {
            self.parameters.reinsertion_ratio * h_max
        } else {
            h_max
        };
        let mut tested = false;
        for rank in 0..self.removed.len() {
            let task = self.removed[rank];
            let removed_for = time - self.removed_at[task];
            if robust && removed_for < self.dwell(task) {
                continue;
            }
            let predicted_cost = match cost {
                Some(cost) if !self.fallback => {
                    self.set_trial_stack(Some(task), None);
                    // The look-ahead spans the task's own time constant 1/λ_i: for a task converging as e^{−λ_i t},
                    // q + u/λ_i is where its linearised law would take the robot.
                    let horizon = match (robust, tasks.get(task)) {
                        (true, Some(value)) => {
                            self.parameters.reinsertion_look_ahead / value.gain()
                        }
                        _ => self.parameters.prediction_horizon,
                    };
                    let back = prediction
                        .after_change(&self.trial_law(law, tasks, prediction.gradient)?, horizon);
                    self.predicted_value(cost, &back)?
                }
                _ => 0.0,
            };
            tested = true;
            self.last_reinsertion_test = Some((task, predicted_cost, threshold));
            if predicted_cost <= threshold || self.fallback {
                let kind = if self.fallback {
                    EventKind::Fallback
                } else {
                    EventKind::Reinsert
                };
                self.reinsert(task, kind, iteration, time, predicted_cost, threshold);
                return Ok(Some(kind));
            }
        }
        if !tested {
            return Ok(None);
        }
        if robust && self.next_push < self.sequence_len() {
            // No removed task can come back here: make progress with the next task instead (the paper's e4 achieved
            // while e3 is out). The removed ones are tested again once the stack has settled.
            self.push_next(iteration, time);
            return Ok(Some(EventKind::Push));
        }
        if let (true, false, Some(cost)) = (robust, self.fallback, cost) {
            if let Some((back, out, predicted_cost)) =
                self.find_swap(law, tasks, cost, prediction, threshold, time)?
            {
                self.last_swap = Some((back, out));
                // One transition: `back` returns at its priority and `out` leaves (the configuration has changed since
                // `back` was removed, and now `out` is the task in the way).
                self.reinsert(
                    back,
                    EventKind::Reinsert,
                    iteration,
                    time,
                    predicted_cost,
                    threshold,
                );
                self.stacked.retain(|&t| t != out);
                let at = self.removed.partition_point(|&t| t < out);
                self.removed.insert(at, out);
                self.removal_count[out] += 1;
                self.removed_at[out] = time;
                self.last_removal_time = time;
                self.record(StackEvent {
                    iteration,
                    time,
                    kind: EventKind::Remove,
                    task: out,
                    law_jump: 0.0,
                    removal: Some(RemovalReport {
                        predicted_cost: result.predicted_cost,
                        threshold: h_max,
                        predicted_cost_without: predicted_cost,
                        horizon: self.parameters.reinsertion_look_ahead
                            / tasks.get(back).map_or(1.0, TaskValue::gain),
                        joint: prediction.gradient.iamax(),
                        cost: cost.dominant_term(prediction.q)?.to_owned(),
                        criteria: self.criteria.clone(),
                        swapped_for: Some(back),
                    }),
                    reinsertion: None,
                });
                return Ok(Some(EventKind::Remove));
            }
        }
        let waiting_since = *self.refused_since.get_or_insert(time);
        if robust && time - waiting_since >= self.parameters.stall_timeout {
            // D13: the first removed task comes back without the test; from now on tasks are removed only as a last
            // resort.
            self.fallback = true;
            let task = self.removed[0];
            let (predicted_cost, threshold) = match self.last_reinsertion_test {
                Some((tested, predicted, threshold)) if tested == task => (predicted, threshold),
                _ => (f64::NAN, threshold),
            };
            self.reinsert(
                task,
                EventKind::Fallback,
                iteration,
                time,
                predicted_cost,
                threshold,
            );
            return Ok(Some(EventKind::Fallback));
        }
        Ok(None)
    }

    /// D7 swap: a removed task `back` (dwell over) and a stacked task `out` (removable), not the reverse of the last
    /// swap, such that the stack with `back` in and `out` out keeps the prediction over `n_back/λ_back` below the
    /// re-insertion threshold.
    fn find_swap(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: &dyn Cost<N>,
        prediction: &Prediction<'_, N>,
        threshold: f64,
        time: f64,
    ) -> Result<Option<(usize, usize, f64)>, ControllerError> {
        for back_rank in 0..self.removed.len() {
            let back = self.removed[back_rank];
            let Some(back_gain) = tasks.get(back).map(TaskValue::gain) else {
                continue;
            };
            if time - self.removed_at[back] < self.dwell(back) {
                continue;
            }
            for out_rank in 0..self.stacked.len() {
                let out = self.stacked[out_rank];
                // Never the reverse of the last swap: two tasks traded back and forth is chatter, not progress.
                if self.last_swap == Some((out, back)) {
                    continue;
                }
                if self.protected[out] || self.removal_count[out] >= self.parameters.max_removals {
                    continue;
                }
                self.set_trial_stack(Some(back), Some(out));
                let horizon = self.parameters.reinsertion_look_ahead / back_gain;
                let swapped = prediction
                    .after_change(&self.trial_law(law, tasks, prediction.gradient)?, horizon);
                let predicted_cost = self.predicted_value(cost, &swapped)?;
                if predicted_cost <= threshold {
                    return Ok(Some((back, out, predicted_cost)));
                }
            }
        }
        Ok(None)
    }

    /// The cost of a predicted configuration: [`predicted_value`], and under the robust rule `+∞` where the cost
    /// forbids it ([`Cost::forbids`], D6).
    fn predicted_value(&self, cost: &dyn Cost<N>, q: &JointVector<N>) -> Result<f64, CostError> {
        if self.parameters.rule == DecisionRule::Robust && cost.forbids(q) {
            return Ok(f64::INFINITY);
        }
        predicted_value(cost, q)
    }

    /// `T_dwell · 2^{k−1}`: how long a task removed `k` times stays out at least (D7).
    fn dwell(&self, task: usize) -> f64 {
        let doublings = self.removal_count[task].saturating_sub(1).min(30);
        self.parameters.reinsertion_dwell * f64::from(1u32 << doublings)
    }

    fn reinsert(
        &mut self,
        task: usize,
        kind: EventKind,
        iteration: usize,
        time: f64,
        predicted_cost: f64,
        threshold: f64,
    ) {
        self.removed.retain(|&t| t != task);
        self.insert_by_priority(task);
        let removed_for = time - self.removed_at[task];
        self.record(StackEvent {
            iteration,
            time,
            kind,
            task,
            law_jump: 0.0,
            removal: None,
            reinsertion: Some(ReinsertionReport {
                predicted_cost,
                threshold,
                removed_for,
            }),
        });
    }

    /// Computes [`TaskCriteria`] for every stacked task ([theory §6.3](crate::theory#s6-3)) into `self.criteria`, with the danger direction
    /// `gradient`.
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
            // J_i⁺ e_i and ‖J_i⁺J_i ∇h‖: for a one- or two-row task of full, well-conditioned rank in closed form,
            // otherwise by the SVD.
            let mut direction = JointVector::zeros();
            let c2_prime = match solve_small_full_row_rank(
                task.jacobian(),
                task.error(),
                gradient,
                &policy,
                &mut direction,
            ) {
                Some(c2_prime) => c2_prime,
                None => {
                    let mut work = self.jacobian_work.rows_mut(0, task.rows());
                    work.copy_from(task.jacobian());
                    let linalg = |source| {
                        ControllerError::Law(LawError::Stack(StackError::Linalg {
                            level: index,
                            source,
                        }))
                    };
                    svd.decompose_warm(&mut work, &policy, 0.0)
                        .map_err(linalg)?;
                    svd.solve(
                        &work,
                        task.error(),
                        VelocityInverse::Truncated,
                        &mut direction,
                    )
                    .map_err(linalg)?;
                    svd.row_space_component_norm(gradient)
                }
            };
            let c1 = -direction.dot(gradient);
            let direction_norm = direction.norm();
            let c1_normalized = if direction_norm > DIRECTION_FLOOR {
                c1 / direction_norm
            } else {
                0.0
            };
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
}

/// D29: the avoidance cost `h` with the restart's recentring term in its gradient only,
/// `∇h + W (q − q̄)` with `W = diag(k_restart/κ)` over the recentred joints and `q̄` the middle of each range: the law's
/// term `−κ P^A_n (∇h + W (q − q̄))` moves each recentred joint towards `q̄` at the rate `k_restart`, within the stack's
/// null space. Its value is `h` alone: the controller's decisions (removal, re-insertion, prediction) see the
/// avoidance cost, not the recentring.
struct RecentringCost<'a, const N: usize> {
    avoidance: &'a dyn Cost<N>,
    centre: JointVector<N>,
    weights: JointVector<N>,
}

impl<const N: usize> Cost<N> for RecentringCost<'_, N> {
    fn value(&self, q: &JointVector<N>) -> Result<f64, CostError> {
        self.avoidance.value(q)
    }

    fn value_and_gradient(
        &self,
        q: &JointVector<N>,
        gradient: &mut JointVector<N>,
    ) -> Result<f64, CostError> {
        let value = self.avoidance.value_and_gradient(q, gradient)?;
        *gradient += self.weights.component_mul(&(q - self.centre));
        Ok(value)
    }

    fn name(&self) -> &str {
        self.avoidance.name()
    }

    fn dominant_term(&self, q: &JointVector<N>) -> Result<&str, CostError> {
        self.avoidance.dominant_term(q)
    }

    fn default_removal_threshold(&self) -> Option<f64> {
        self.avoidance.default_removal_threshold()
    }

    fn forbids(&self, q: &JointVector<N>) -> bool {
        self.avoidance.forbids(q)
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

/// Below this norm of `J_i⁺ e_i` the task is achieved and `C1'_i` is set to 0 ([D3](crate::theory#d3)).
const DIRECTION_FLOOR: f64 = 1e-12;
