//! What the controller reports: the criteria of each task, the events of the stack and the status of a run.

use super::*;

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
    pub(super) fn score(&self, criterion: RemovalCriterion) -> f64 {
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
