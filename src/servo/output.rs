//! What one period of the façade gives ([`ServoOutput`]): the velocity to send and what the servo did.

use super::MAX_TASKS;
use crate::controller::EventKind;
use crate::math::JointVector;
use nalgebra::Vector6;

/// What one period gives: the velocity to send and what the servo did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoOutput<const N: usize> {
    /// The joint velocity to send (rad/s, m/s): the controller's, scaled so that every `|q̇_i| ≤ q̇_i^max` and, near a
    /// hard limit, every joint moving towards it keeps `|q̇_i| ≤ ξ d_i` (the braking of [D25](crate::theory#d25),
    /// [`crate::controller::ControllerParameters::braking_rate`]), and every corner moving towards the border of the
    /// image moves no faster than `ξ` times its distance to it in pixels
    /// ([`crate::controller::ControllerParameters::brake_at_image_border`]); with acceleration limits, only the fraction
    /// [`Self::acceleration_scale`] of the change from the last velocity sent ([D31](crate::theory#d31)).
    pub velocity: JointVector<N>,
    /// The controller's velocity before scaling.
    pub unscaled_velocity: JointVector<N>,
    /// The uniform scale factor `s ∈ [0, 1]` (`velocity = s · unscaled_velocity` when the acceleration limits are
    /// not active, [`Self::acceleration_scale`] `= 1`): the velocity limits' times the braking's, before the joint
    /// limits and before the border of the image ([D25](crate::theory#d25)).
    pub scale: f64,
    /// `true` when `s < 1` (a velocity limit or the braking was active).
    pub scaled: bool,
    /// The fraction `σ ∈ [0, 1]` of the change towards `s · unscaled_velocity` sent this period:
    /// `velocity = q̇_prev + σ (s · unscaled_velocity − q̇_prev)`, `q̇_prev` the velocity sent at the last accepted
    /// period (zero before the first). `σ < 1` when an acceleration limit
    /// ([`crate::servo::ServoConfig::max_joint_acceleration`]) was active ([D31](crate::theory#d31)); `1` without
    /// limits.
    pub acceleration_scale: f64,
    /// `true` when, with the acceleration limits active, a joint was slowed on its own (not with the whole velocity)
    /// to keep the speed from which it can still stop before its limit ([D31](crate::theory#d31),
    /// [`crate::avoidance::JointLimits::clamp_to_stopping_distance`]): the change's direction then bends.
    pub stopping_clamp: bool,
    /// `‖[e_1; …; e_n]‖` over every task, stacked or not (the reserve image points included).
    pub error_norm: f64,
    /// `‖e_i‖` of each task (the first [`Self::task_count`] entries).
    pub task_errors: [f64; MAX_TASKS],
    /// `λ_i` (s⁻¹) used this period (adaptive or constant).
    pub task_gains: [f64; MAX_TASKS],
    /// The number of tasks (5 for the sequence: the paper's four and the image points held in reserve,
    /// [D23](crate::theory#d23); 1 for the classical task).
    pub task_count: usize,
    /// The tasks stacked after this period's change (the first [`Self::stack_len`] entries, highest priority first).
    pub stack: [usize; MAX_TASKS],
    /// How many tasks are stacked.
    pub stack_len: usize,
    /// The stack change made this period (push, removal, re-insertion, fallback, escape, hold), if any.
    pub event: Option<EventKind>,
    /// `true` once the controller has held before a hard limit (D13, [`EventKind::Hold`]): it has dropped every task
    /// for good, the velocity is the joint-limit avoidance's alone (the arm comes to rest inside its limits), and the
    /// goal will not be reached from here; the application should stop servoing and plan another approach.
    pub held: bool,
    /// The joints the controller holds still at a hard limit this period, because the tasks drive them into it (the
    /// lock of [D26](crate::theory#d26), [`crate::controller::ControllerParameters::lock_band`]): the other joints carry
    /// on, and a task that needs a locked joint is achieved only in least squares.
    pub locked: [bool; N],
    /// `‖q̇_n‖`, the norm of the stack velocity without transition and avoidance (mixed rad/s and m/s): the controller
    /// pushes the next task, or tries to put a removed one back, once it is below
    /// [`ControllerParameters::settle_velocity_with_removal`] ([D5](crate::theory#d5)).
    ///
    /// [`ControllerParameters::settle_velocity_with_removal`]: crate::controller::ControllerParameters::settle_velocity_with_removal
    pub stack_velocity_norm: f64,
    /// Every task of the sequence stacked, `‖e_i‖ < convergence_error` for each, and the corners at their desired
    /// positions: the reserve image points' error at most [`ControllerParameters::escape_error`] while they wait,
    /// below `convergence_error` once they have taken the fourth task's place ([D23](crate::theory#d23)). The
    /// paper's features alone can be achieved at a pose other than the goal. (`escape_error = +∞` switches off both the
    /// escape and this check.)
    ///
    /// [`ControllerParameters::escape_error`]: crate::controller::ControllerParameters::escape_error
    pub converged: bool,
    /// The depths used (m), one per corner.
    pub depths: [f64; 4],
    /// The camera twist `(υ, ω)` (m/s, rad/s, camera frame) the sent velocity gives, `cVe eJe(q) q̇_sent`.
    pub camera_twist: Vector6<f64>,
    /// `true` when this period brought a new frame (a corner differs from the previous accepted period's).
    pub new_frame: bool,
    /// The number of accepted periods before this one.
    pub iteration: usize,
}

impl<const N: usize> ServoOutput<N> {
    /// The tasks stacked, highest priority first.
    pub fn stacked(&self) -> &[usize] {
        &self.stack[..self.stack_len]
    }
}
