//! The controller's errors and parameters, with the ranges they are checked against.

use super::*;

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

/// How the full method keeps its joints inside their hard limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HardLimitRule {
    /// The braking of D25 before a limit and the lock of D26 along it (default).
    #[default]
    BrakeAndLock,
    /// Saturation in the null space ([theory §13](crate::theory#s13)) in place of both: every velocity inside the
    /// box of the limits, the robot's velocity limits and the period. A measured alternative, not the default.
    SaturateInNullSpace,
}

/// How the tasks of the sequence enter the stack.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TaskSequencing {
    /// The paper's sequencing (D5, default): the first task from the first iteration, each next one pushed when the
    /// stack has settled (or earlier by D28).
    #[default]
    OneByOne,
    /// The whole sequence (every task but a reserve one, D23) stacked at the first iteration, in priority order, as a
    /// hierarchical controller without sequencing would: the form the Stack of Tasks, OpenSoT or a QP cascade usually
    /// run. Pushes after a restart (D29) are then also made at once.
    AllAtOnce,
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
    /// `T_stall` (s): how long a removed task refused by its re-insertion test (with nothing to push and no swap) waits
    /// before it is put back anyway and removals stop except as a last resort (D13 fallback). Default 0: at the first
    /// refusal. Waiting was measured and not kept (docs/controller_study.md): over the zoo's uniform starts (K = 100)
    /// the fallback at once converges in 11 more draws than 5 s of waiting, and the 95th percentile of the iterations
    /// to converge falls on 16 of 17 arms; longer waits let the robot drift (10 s cost the square marker's uniform
    /// starts 50 of 200 draws).
    pub stall_timeout: f64,
    /// Whether tasks may be removed at all (`false`: push-only, as the paper's runs 2 and 3).
    pub allow_removal: bool,
    /// The criterion that picks the task to remove.
    pub criterion: RemovalCriterion,
    /// The decision rule.
    pub rule: DecisionRule,
    /// `ε_achieved`: with a reserve task ([`StackController::with_reserve_task`], D23), the stack counts as having
    /// achieved its tasks when every stacked task's error norm `‖e_i‖` is below this (the tasks' units; default 1e−3).
    /// The restart of D29 also counts a run at rest (by its velocity) below it as at its goal.
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
    /// Full method only (robust rule, removals allowed); default 16 (4 until the zoo's `feasible` family showed 4
    /// pushing too early on `kinova`); `+∞` switches it off. Window and measurements: theory D28.
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
    /// Whether the braking of D25 also holds at the border of the image (default `true`): the velocity sent is scaled
    /// so that no target point moves towards the border faster than `ξ` times its distance to it in pixels
    /// ([`crate::avoidance::image_braking_scale`]). `false`: the joint limits alone. Measured: theory D25.
    pub brake_at_image_border: bool,
    /// `δ`, the lock band of D26 as a fraction of each joint's range: a joint closer than `δ Δq_i` to a hard limit
    /// that the law drives towards it is held still, and the stack is solved on the other joints
    /// ([`crate::stack::StackWorkspace::lock_joints`]); the robot slides along the limit instead of stopping at it
    /// (the braking of D25 stops it there). Needs the limits ([`StackController::with_joint_limits`]); `0` switches
    /// the lock off. Default `10⁻⁵` (a joint reaches the band only after the braking has slowed it down); valid in
    /// `[0, 0.5)`.
    pub lock_band: f64,
    /// `k_restart` (s⁻¹), the restart of D29: at rest against a limit short of the goal, with every task stacked, the
    /// sequence restarts from its first task (each time), and the joints that were locked are driven towards the middle of
    /// their range at this rate, `q̇_i = −k_restart (q_i − q̄_i)` before the projection into the first task's null
    /// space (the law's secondary term becomes the gradient of `h + ½ (k_restart/κ) Σ (q_i − q̄_i)²`). Needs the
    /// limits ([`StackController::with_joint_limits`]) and `κ > 0`; full method only (robust rule, removals
    /// allowed). Default 1 s⁻¹; `0` switches the restart off. Measured: theory D29.
    pub restart_rate: f64,
    /// `s_restart`: where the restart of D29 drives each locked joint whose range exceeds a half turn: past the middle
    /// of its range, away from the side it is on, by this fraction of a quarter turn,
    /// `q̂_i = q̄_i − s_restart · sign(q_i − q̄_i) · π/2`; joints of narrower ranges go to their middle `q̄_i`. Default
    /// 0.5 (π/4 past the middle); `0`: every joint to its middle; in `[0, 1)`. Measured: theory D29.
    pub restart_offset: f64,
    /// Whether a restart of D29 that finds the same joints locked at the same limits as the previous restart recentres
    /// every joint with finite limits, not only the locked ones: the replay from the same recentring came back to the
    /// same rest, and would again. Default `true`; `false`: the locked joints alone, at every restart. Measured:
    /// theory D29.
    pub recentre_all_on_repeat: bool,
    /// `b_restart`: the recentring ends, and the sequence goes on, once every recentred joint is within
    /// `b_restart Δq_i` of its target `q̂_i` (D29; a fraction of the range, default 0.05, in `(0, 0.5]`).
    pub restart_centre_band: f64,
    /// `T_restart` (s): the recentring ends after this long even if a joint has not reached the middle of its range
    /// (D29; default 5 s, the stall timeout's).
    pub restart_timeout: f64,
    /// `W_progress` (s), full method only (robust rule, removals allowed): the stack has also settled (D5) when the
    /// stacked tasks' error has stopped falling — its squared norm `Σ‖e_i‖²` not below 0.8 times its value
    /// `W_progress` earlier, no change made since — whatever its velocity. The next task is then pushed or a removed
    /// one tested, and with the sequence complete the restart of D29 may fire: a stack that creeps along a limit or
    /// chatters in place has settled as much as one at rest. Default 5 s; `+∞`: the velocity test alone; in
    /// `(0, 86400]` s or `+∞`. Measured: theory D5, D29.
    pub progress_window: f64,
    /// `ε_σ`, the floor of D30 relative to each level's scale: the law inverts every stack level with the gain of each
    /// singular direction capped at `1/ε` (`ε = ε_σ · max(σ_max(J̃_i), ‖J_i‖_F)`, [`VelocityInverse::Filtered`]), so a
    /// level that is nearly singular — a task left with too few free joints by a locked joint or a higher level — is
    /// achieved more slowly in that direction instead of being inverted at gains up to `10⁶` that the velocity limits
    /// then scale, and that flip sign from one period to the next. Levels whose singular values all clear `ε` are
    /// solved as by the truncated pseudo-inverse. The projectors stay exact (D2). Default `3·10⁻⁴`; `0` switches it off
    /// (the truncated pseudo-inverse of D2); valid in `[0, 0.01]`. Full method only in the study (the baselines are
    /// the paper's laws).
    pub singular_value_floor: f64,
    /// How the full method keeps the joints inside their hard limits: the braking and the lock (D25, D26, default), or
    /// saturation in the null space (theory §13), which then replaces both (`braking_rate` and `lock_band` unused).
    pub hard_limit_rule: HardLimitRule,
    /// Whether the tasks are pushed one by one (the paper's sequencing, default) or all at the first iteration.
    pub sequencing: TaskSequencing,
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
            stall_timeout: 0.0,
            allow_removal: true,
            criterion: RemovalCriterion::Combined,
            rule: DecisionRule::Robust,
            escape_achieved_error: 1e-3,
            escape_error: 0.005,
            escape_growth_rate: 0.0,
            early_push_ratio: 16.0,
            hold_before_limit: false,
            braking_rate: 5.0,
            lock_band: 1e-5,
            restart_rate: 1.0,
            restart_offset: 0.5,
            recentre_all_on_repeat: true,
            brake_at_image_border: true,
            restart_centre_band: 0.05,
            restart_timeout: 5.0,
            progress_window: 5.0,
            singular_value_floor: 3e-4,
            hard_limit_rule: HardLimitRule::BrakeAndLock,
            sequencing: TaskSequencing::OneByOne,
        }
    }
}

/// The largest count of transitions (`1/μ`) a wait or horizon may span.
pub(super) const MAX_TRANSITIONS: f64 = 1e4;

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
        let v = self.stall_timeout;
        check("stall_timeout", v, DURATION_S.contains(v), DURATION_S.text)?;
        let v = self.restart_timeout;
        check(
            "restart_timeout",
            v,
            v > 0.0 && DURATION_S.contains(v),
            "in (0, 86400] s",
        )?;
        let v = self.progress_window;
        check(
            "progress_window",
            v,
            v > 0.0 && (v == f64::INFINITY || DURATION_S.contains(v)),
            "in (0, 86400] s (+∞: the velocity test alone)",
        )?;
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
        let v = self.restart_offset;
        check(
            "restart_offset",
            v,
            (0.0..1.0).contains(&v),
            "in [0, 1) (0: the middle of the range)",
        )?;
        let v = self.restart_centre_band;
        check(
            "restart_centre_band",
            v,
            v > 0.0 && in_range(v, 0.0, 0.5),
            "in (0, 0.5]",
        )?;
        let v = self.singular_value_floor;
        check(
            "singular_value_floor",
            v,
            in_range(v, 0.0, 0.01),
            "in [0, 0.01] (0: the truncated pseudo-inverse)",
        )?;
        Ok(())
    }

    /// The inverse of the law's stack levels that [`Self::singular_value_floor`] asks for (D30): filtered, or the
    /// truncated pseudo-inverse of D2 when the floor is 0.
    pub fn velocity_inverse(&self) -> VelocityInverse {
        if self.singular_value_floor > 0.0 {
            VelocityInverse::Filtered {
                floor: self.singular_value_floor,
            }
        } else {
            VelocityInverse::Truncated
        }
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
