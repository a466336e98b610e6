//! A hardware-loop façade: one [`VisualServo`] built once from the robot, the camera, the target and the parameters,
//! and one call per control period that turns the measured corners and joint positions into the joint velocity to
//! send.
//!
//! ```rust,no_run
//! use servostack::{camera::CalibratedCamera, robot::builtin, servo::*, target::RectangleTarget};
//! # fn read_corners() -> Corners { [None; 4] }
//! # fn read_joints() -> servostack::math::JointVector<6> { nalgebra::zero() }
//! # fn send_velocity(_: &servostack::math::JointVector<6>) {}
//! let (robot, camera) = (builtin::afma6()?, CalibratedCamera::from_yaml_file("camera.yaml")?);
//! let goal = DesiredImage::Pose(nalgebra::Isometry3::translation(0.0, 0.0, 0.5)); // cdMo (m)
//! let config = ServoConfig::new(robot.chain, robot.mount, camera, RectangleTarget::new(0.2, 0.1)?, goal);
//! let (mut servo, clock, mut velocity) = (VisualServo::new(config)?, std::time::Instant::now(), nalgebra::zero());
//! loop {
//!     let (corners, q) = (read_corners(), read_joints()); // DRIVER: read the corners (px) and joints (rad, m)
//!     match servo.step(clock.elapsed().as_secs_f64(), &corners, &q) {
//!         Ok(out) if out.converged => break,
//!         Ok(out) => velocity = out.velocity,
//!         Err(error) => eprintln!("{error}: holding the last velocity"), // a bad frame
//!     }
//!     send_velocity(&velocity); // DRIVER: send the joint velocities (rad/s, m/s)
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! (The same loop is in the guide [`crate::guide::camera_loop`].)
//!
//! # One period ([`VisualServo::step`])
//!
//! 1. **Checks**, before any state changes: the time is finite and strictly after the last accepted call's; `q` is
//!    finite; each corner is present, finite, inside the image `[0, width] × [0, height]` (px), and undistorts
//!    ([`CalibratedCamera::normalized_of`]). A failure is a named [`ServoError`] and changes nothing: the servo's
//!    memory (the controller's transition, the depth estimator, the last accepted time) is kept, so the next good
//!    period continues as if the bad one had not been called. (One exception: a new frame that reached the online
//!    depth estimator before a later stage failed — a feature undefined on the image, a controller failure — stays
//!    in the estimator, and its time counts as accepted.) The memory assumes the robot kept the last velocity
//!    sent: **hold** it through a bad frame (as the loop above does) for a continuous velocity; a driver should also
//!    stop the robot (send zero) when bad frames last (a watchdog), which is a velocity step.
//! 2. **Depths** of the four points from the [`DepthSource`] ([`assign_depths`]); the online estimator is updated when a
//!    new frame arrives — a frame is *new* when one corner differs from the previous accepted call's (a camera slower
//!    than the control loop repeats its last frame), with the mean camera twist `cVe eJe(q) q̇_sent` over the periods
//!    since the previous frame.
//! 3. **Tasks** (`e_i`, `L_i`, `J_i = L_i cVe eJe(q)`, [\[M42\]](crate::theory#m42)) on the observation; with an
//!    [`AdaptiveGain`], each task's gain becomes `λ(‖e_i‖∞)`.
//! 4. One [`StackController::step`] with the joint-limit cost ([\[M19\]](crate::theory#m19)); the centroid task is never
//!    removed ([D6](crate::theory#d6)). No visibility guard: the target's pose in the robot base, which it needs, is
//!    unknown to a real robot.
//! 5. **Saturation**: the velocity is scaled uniformly, `q̇_sent = s q̇` with `s = min(1, min_i q̇_i^max / |q̇_i|)`, so
//!    every joint keeps within its limit and the direction is kept; `q̇_sent` is fed back to the controller
//!    ([`StackController::set_sent_velocity`]), so the next stack change blends from what the robot received
//!    ([D1](crate::theory#d1)): continuity holds for the robot, not for a velocity it never got.
//!
//! A step allocates nothing on the heap once built, with three exceptions outside the steady state: a removal copies
//! its report (the dominant cost's name, every task's criteria) into the controller's event log; the log grows beyond
//! its preallocated four events per task; an error naming a task allocates its message. Pushes and re-insertions
//! allocate nothing.

use crate::avoidance::{CostError, JointLimits};
use crate::camera::{CalibratedCamera, CameraError, EyeInHand, ImagePoint};
use crate::controller::{ControllerError, ControllerParameters, EventKind, StackController};
use crate::depth::{assign_depths, DepthError, DepthEstimator, DepthSource, Depths};
use crate::feature::{InteractionSource, Observation};
use crate::law::{ControlLaw, LawError};
use crate::math::{first_non_finite, JointVector};
use crate::robot::{KinematicsWorkspace, RobotError, SerialChain};
use crate::target::{RectangleTarget, TargetError};
use crate::task::{Task, TaskError, TaskValue};
use crate::visual_task::{
    classical_task_with, image_points_task, paper_tasks_with, FourthTask, VisualContext, VisualTask,
};
use nalgebra::{Isometry3, Point2, Vector6};

/// The four measured corners of the target, in the order of [`RectangleTarget::points`]: `Some((u, v))` in pixels
/// (or normalised coordinates for [`VisualServo::step_normalized`]), `None` when the detector lost a corner.
pub type Corners = [Option<(f64, f64)>; 4];

/// The largest number of tasks: the paper's sequence and the image points held in reserve ([D23](crate::theory#d23)).
pub const MAX_TASKS: usize = 5;

/// Errors of the façade. Measurement errors (per period) leave the servo's memory as it was: the caller sends zero (or
/// holds its last command) and goes on with the next period.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ServoError {
    /// A configuration parameter is out of range (at construction).
    #[error("servo parameter `{name}` = {value} is invalid: {expected}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is expected.
        expected: &'static str,
    },
    /// [`DepthSource::PreviousPlane`] is the simulation's perfect pose one period late, which a real loop does not have
    /// (at construction); [`DepthSource::TargetPose`] estimates the pose from the measured corners instead.
    #[error("depth source `previous_plane` is not supported by the servo façade (use desired, constant, target_pose or estimated)")]
    UnsupportedDepthSource,
    /// The detector did not deliver corner `index` (`None`).
    #[error("corner {index} is missing")]
    MissingCorner {
        /// The corner (0-based, in the target's order).
        index: usize,
    },
    /// A corner coordinate is NaN or infinite.
    #[error("corner {index} is not finite: ({u}, {v})")]
    NonFiniteCorner {
        /// The corner.
        index: usize,
        /// Abscissa (px, or normalised for [`VisualServo::step_normalized`]).
        u: f64,
        /// Ordinate (same unit).
        v: f64,
    },
    /// A corner lies outside the image `[0, width] × [0, height]` (px; a normalised point is checked at its distorted
    /// pixel).
    #[error("corner {index} at ({u}, {v}) px is outside the {width} × {height} px image")]
    OutsideImage {
        /// The corner.
        index: usize,
        /// Its abscissa (px).
        u: f64,
        /// Its ordinate (px).
        v: f64,
        /// Image width (px).
        width: f64,
        /// Image height (px).
        height: f64,
    },
    /// A pixel could not be undistorted (beyond the lens model's invertible radius).
    #[error("corner {index}: {source}")]
    Undistortion {
        /// The corner.
        index: usize,
        /// The camera's error.
        source: CameraError,
    },
    /// A depth is zero, negative or not finite: the online estimator would give it (noise larger than the motion; the
    /// estimator keeps its previous state), or the depth source does.
    #[error("point {index}: depth {depth} m is not positive")]
    NonPositiveDepth {
        /// The point.
        index: usize,
        /// The depth (m).
        depth: f64,
    },
    /// The time is not finite, or not strictly after the last accepted call's.
    #[error("time {time} s is not after the last accepted period at {previous} s")]
    TimeNotIncreasing {
        /// The last accepted time (s).
        previous: f64,
        /// The time given (s).
        time: f64,
    },
    /// A joint position is NaN or infinite.
    #[error("joint {joint} = {value} is not finite")]
    NonFiniteJoint {
        /// The joint (0-based).
        joint: usize,
        /// Its value.
        value: f64,
    },
    /// The camera model failed (at construction: desired pixels, intrinsics).
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// The robot model failed.
    #[error(transparent)]
    Robot(#[from] RobotError),
    /// A task failed: at construction, a feature undefined on the desired image; per period, a feature undefined on
    /// the measured image (collinear corners, a vanishing area).
    #[error(transparent)]
    Task(#[from] TaskError),
    /// The controller failed.
    #[error(transparent)]
    Controller(#[from] ControllerError),
    /// The control law's parameters are invalid.
    #[error(transparent)]
    Law(#[from] LawError),
    /// The joint-limit cost's parameters are invalid.
    #[error(transparent)]
    Cost(#[from] CostError),
    /// The depth source's parameters are invalid.
    #[error(transparent)]
    Depth(#[from] DepthError),
    /// [`DepthSource::TargetPose`]: the measured corners give no target pose (three collinear corners, or a plane at or
    /// behind the camera). Nothing of the period is committed.
    #[error("no target pose from the measured corners: {0}")]
    TargetPose(#[from] TargetError),
}

/// ViSP's adaptive gain (`vpAdaptiveGain::initStandard`): `λ(x) = a e^{−b x} + c` with `a = λ(0) − λ(∞)`,
/// `b = λ'(0)/a`, `c = λ(∞)`, evaluated at `x = ‖e_i‖∞` (ViSP's `vpAdaptiveGain::operator()(vpColVector)`), so the gain
/// is `λ(0)` at the goal and tends to `λ(∞)` far from it. `λ'(0)` is the parameter as ViSP takes it; the derivative of
/// `λ` at 0 is `−a b = −λ'(0)`: a gain that decreases with the error (ViSP's use: faster near the goal) has
/// `λ(0) > λ(∞)` and `λ'(0) > 0`; one that increases with the error (slower near the goal, which filters pixel noise)
/// has `λ(0) < λ(∞)` and `λ'(0) < 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdaptiveGain {
    a: f64,
    b: f64,
    c: f64,
}

impl AdaptiveGain {
    /// `λ(0)` (s⁻¹, > 0), `λ(∞)` (s⁻¹, > 0), `λ'(0)` (s⁻¹ per unit of `‖e‖∞`, of the sign of `λ(0) − λ(∞)`; 0, or
    /// `λ(0) = λ(∞)`, gives the constant `λ(0)`).
    ///
    /// # Errors
    /// [`ServoError::InvalidParameter`] for a non-finite or non-positive gain, a non-finite slope, or a slope of the
    /// other sign than `λ(0) − λ(∞)` (`b < 0`: the gain would leave `[min, max]` of `λ(0), λ(∞)` without bound).
    pub fn new(at_zero: f64, at_infinity: f64, slope_at_zero: f64) -> Result<Self, ServoError> {
        let invalid = |name, value, expected| ServoError::InvalidParameter {
            name,
            value,
            expected,
        };
        for (name, value) in [("λ(0)", at_zero), ("λ(∞)", at_infinity)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(invalid(name, value, "finite and > 0 (s⁻¹)"));
            }
        }
        if !slope_at_zero.is_finite() {
            return Err(invalid("λ'(0)", slope_at_zero, "finite"));
        }
        let a = at_zero - at_infinity;
        if a == 0.0 || slope_at_zero == 0.0 {
            return Ok(Self {
                a: 0.0,
                b: 0.0,
                c: at_zero,
            });
        }
        let b = slope_at_zero / a;
        if !(b.is_finite() && b > 0.0) {
            return Err(invalid(
                "λ'(0)",
                slope_at_zero,
                "of the sign of λ(0) − λ(∞) (b = λ'(0)/(λ(0) − λ(∞)) must be > 0)",
            ));
        }
        Ok(Self {
            a,
            b,
            c: at_infinity,
        })
    }

    /// `λ(x) = a e^{−b x} + c` (s⁻¹) at `x ≥ 0` (a non-finite `x` gives `λ(∞)`).
    pub fn value(&self, x: f64) -> f64 {
        if x.is_finite() {
            self.a * (-self.b * x.abs()).exp() + self.c
        } else {
            self.c
        }
    }

    /// The largest gain it takes, `max(λ(0), λ(∞))` (s⁻¹), for the transition gain `μ = 10 max λ`.
    pub fn max_gain(&self) -> f64 {
        (self.a + self.c).max(self.c)
    }

    /// Sets the gain of the evaluated task `value` (named `name` in errors) to `λ(‖e‖∞)` of its current error.
    ///
    /// # Errors
    /// [`TaskError`] for a gain outside [`crate::bounds::GAIN_PER_S`] (only when `λ(0)` or `λ(∞)` is).
    pub fn apply<const N: usize>(
        &self,
        name: &str,
        value: &mut TaskValue<N>,
    ) -> Result<(), TaskError> {
        value.set_gain(name, self.value(value.error().amax()))
    }
}

/// The desired image of the target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DesiredImage {
    /// The desired pose of the target in the camera frame, `cdMo` (m, rotation): the desired points and their depths
    /// are projected from the target model; the desired depth `Z*` of `a_n` is its translation's `z`.
    Pose(Isometry3<f64>),
    /// Taught pixels (px, measured through the same camera, so a calibration error cancels at the goal) with the
    /// depth `Z*` (m) of the target at the goal, given to every point.
    Pixels {
        /// The four corners (px), in the target's order.
        pixels: [(f64, f64); 4],
        /// The desired depth `Z*` (m, > 0).
        depth_m: f64,
    },
}

/// Which tasks drive the robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TaskChoice {
    /// The paper's sequence, stacked by the controller: centroid, angle, `a_n`, and the fourth task
    /// ([`FourthTask::Auto`]: `P_x, P_y`, or the side ratios on a square seen head-on), with gains `λ_i` (s⁻¹); and, in
    /// reserve, the four image points at the fourth task's gain, which take its place when the stack settles with the
    /// corners away from their desired positions ([D23](crate::theory#d23)).
    Sequence {
        /// `λ_1 … λ_4` (s⁻¹, > 0).
        gains: [f64; 4],
        /// The fourth task's feature.
        fourth: FourthTask,
    },
    /// The classical law: the same six features in one task of gain `λ` (s⁻¹).
    Classical {
        /// `λ` (s⁻¹, > 0).
        gain: f64,
        /// The sixth feature pair's choice.
        fourth: FourthTask,
    },
}

impl Default for TaskChoice {
    fn default() -> Self {
        Self::Sequence {
            gains: [0.5; 4],
            fourth: FourthTask::Auto,
        }
    }
}

/// Everything [`VisualServo::new`] needs. [`ServoConfig::new`] takes the models and sets every parameter to its
/// default; change the public fields to tune.
#[derive(Debug, Clone)]
pub struct ServoConfig<const N: usize> {
    /// The robot: joint axes and position limits (rad for revolute, m for prismatic joints).
    pub chain: SerialChain<N>,
    /// Where the camera is mounted on the end effector (`eMc`).
    pub mount: EyeInHand,
    /// The calibrated camera: intrinsics (px), image size (px) and lens distortion.
    pub camera: CalibratedCamera,
    /// The target model (m, object frame); the corners are given in the order of [`RectangleTarget::points`].
    pub target: RectangleTarget,
    /// The desired image.
    pub desired: DesiredImage,
    /// The tasks (default: the paper's sequence, `λ_i = 0.5 s⁻¹`, [`FourthTask::Auto`]).
    pub tasks: TaskChoice,
    /// Where `L_i` is evaluated (default: exact, on the current image).
    pub interaction: InteractionSource,
    /// The transition gain `μ` (s⁻¹) of [D1](crate::theory#d1); `None` (default): `10 · max_i λ_i` (with an adaptive
    /// gain, `10 · max(λ(0), λ(∞))`).
    pub transition_gain: Option<f64>,
    /// The avoidance gain `κ` (s⁻¹, ≥ 0; 0 disables the projected gradient) of [\[M18\]](crate::theory#m18). Default 10.
    pub avoidance_gain: f64,
    /// The activation ratio `ρ` of the joint-limit cost ([\[M19\]](crate::theory#m19)): the cost is active in the outer
    /// `ρ` fraction of each joint's range at each end (in `(0, 0.5)`). Default 0.1.
    pub activation_ratio: f64,
    /// The stack controller's parameters (push, removal, re-insertion).
    pub controller: ControllerParameters,
    /// Where the points' depths come from (default: each point's depth in the desired image).
    pub depth: DepthSource,
    /// `q̇_i^max` per joint (rad/s for revolute, m/s for prismatic joints, > 0; `+∞`: no limit). Default: no limit.
    pub max_joint_velocity: JointVector<N>,
    /// An adaptive gain `λ(‖e_i‖∞)` replacing every task's constant gain (default `None`: the constant gains).
    pub adaptive_gain: Option<AdaptiveGain>,
    /// The servo has converged when every task is stacked and `‖e_i‖ < convergence_error` for each (in the tasks'
    /// units: normalised image coordinates, rad, dimensionless; see [`ServoOutput::converged`]). Default 1e−4.
    pub convergence_error: f64,
    /// Whether the centroid task (the first) is never removed ([D6](crate::theory#d6)): it keeps the target in the
    /// image. Default `true`.
    pub protect_centroid: bool,
}

impl<const N: usize> ServoConfig<N> {
    /// The models, with every parameter at its default (see each field).
    pub fn new(
        chain: SerialChain<N>,
        mount: EyeInHand,
        camera: CalibratedCamera,
        target: RectangleTarget,
        desired: DesiredImage,
    ) -> Self {
        Self {
            chain,
            mount,
            camera,
            target,
            desired,
            tasks: TaskChoice::default(),
            interaction: InteractionSource::Exact,
            transition_gain: None,
            avoidance_gain: 10.0,
            activation_ratio: JointLimits::<N>::DEFAULT_ACTIVATION_RATIO,
            controller: ControllerParameters::default(),
            depth: DepthSource::Desired,
            max_joint_velocity: JointVector::repeat(f64::INFINITY),
            adaptive_gain: None,
            convergence_error: 1e-4,
            protect_centroid: true,
        }
    }
}

/// What one period gives: the velocity to send and what the servo did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoOutput<const N: usize> {
    /// The joint velocity to send (rad/s, m/s): the controller's, scaled so that every `|q̇_i| ≤ q̇_i^max` and, near a
    /// hard limit, every joint moving towards it keeps `|q̇_i| ≤ ξ d_i` (the braking of [D25](crate::theory#d25),
    /// [`crate::controller::ControllerParameters::braking_rate`]).
    pub velocity: JointVector<N>,
    /// The controller's velocity before scaling.
    pub unscaled_velocity: JointVector<N>,
    /// The uniform scale factor `s ∈ [0, 1]` (`velocity = s · unscaled_velocity`): the velocity limits' times the
    /// braking's.
    pub scale: f64,
    /// `true` when `s < 1` (a velocity limit or the braking was active).
    pub scaled: bool,
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
    pub stack_velocity_norm: f64,
    /// Every task of the sequence stacked, `‖e_i‖ < convergence_error` for each, and the corners at their desired
    /// positions: the reserve image points' error at most [`ControllerParameters::escape_error`] while they wait,
    /// below `convergence_error` once they have taken the fourth task's place ([D23](crate::theory#d23)). The
    /// paper's features alone can be achieved at a pose other than the goal. (`escape_error = +∞` switches off both the
    /// escape and this check.)
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

/// The hardware-loop façade (module docs): models, controller and workspaces, allocated once.
#[derive(Debug)]
pub struct VisualServo<const N: usize> {
    chain: SerialChain<N>,
    mount: EyeInHand,
    camera: CalibratedCamera,
    tasks: Vec<VisualTask>,
    values: Vec<TaskValue<N>>,
    controller: StackController<N>,
    law: ControlLaw,
    limits: JointLimits<N>,
    kinematics: KinematicsWorkspace<N>,
    depth: DepthSource,
    estimator: Option<DepthEstimator>,
    /// The target model, for [`DepthSource::TargetPose`].
    target: RectangleTarget,
    desired_points: [ImagePoint; 4],
    max_velocity: JointVector<N>,
    adaptive: Option<AdaptiveGain>,
    convergence_error: f64,
    /// Time of the first accepted period (s); the controller runs on `time − start`.
    start_time: Option<f64>,
    last_time: f64,
    /// The points of the last accepted period (normalised), to tell a new frame from a repeated one.
    last_points: [Point2<f64>; 4],
    /// `∫ twist dt` and `∫ dt` since the last frame given to the estimator.
    twist_sum: Vector6<f64>,
    twist_time: f64,
    iteration: usize,
    output: ServoOutput<N>,
}

impl<const N: usize> VisualServo<N> {
    /// Builds the servo: desired image, tasks, controller, law, joint-limit cost, depth estimator.
    ///
    /// # Errors
    /// [`ServoError::InvalidParameter`] (velocity limits, convergence threshold, desired depth),
    /// [`ServoError::UnsupportedDepthSource`], and the models' errors (a desired corner that does not undistort, a
    /// feature undefined on the desired image, invalid gains, `μ`, `κ`, `ρ`, controller or depth parameters).
    pub fn new(config: ServoConfig<N>) -> Result<Self, ServoError> {
        let invalid = |name, value, expected| ServoError::InvalidParameter {
            name,
            value,
            expected,
        };
        if let Some(v) = config
            .max_joint_velocity
            .iter()
            .find(|v| v.is_nan() || **v <= 0.0)
        {
            return Err(invalid("max_joint_velocity", *v, "> 0 (or +∞)"));
        }
        let e = config.convergence_error;
        if !(e.is_finite() && e > 0.0) {
            return Err(invalid("convergence_error", e, "finite and > 0"));
        }
        if config.depth == DepthSource::PreviousPlane {
            return Err(ServoError::UnsupportedDepthSource);
        }
        config.depth.validate()?;
        let (desired_points, desired_depth) = desired_points(&config)?;
        let desired =
            Observation::new(&desired_points, None).map_err(|source| TaskError::Feature {
                name: "desired image".into(),
                source,
            })?;
        let tasks = match config.tasks {
            TaskChoice::Sequence { gains, fourth } => {
                let mut tasks = paper_tasks_with(
                    &desired,
                    desired_depth,
                    desired_depth,
                    gains,
                    config.interaction,
                    fourth,
                )?;
                tasks.push(image_points_task(&desired, gains[3], config.interaction)?);
                tasks
            }
            TaskChoice::Classical { gain, fourth } => vec![classical_task_with(
                &desired,
                desired_depth,
                desired_depth,
                gain,
                config.interaction,
                fourth,
            )?],
        };
        let values: Vec<TaskValue<N>> = tasks
            .iter()
            .map(TaskValue::for_task::<VisualContext<'_, N>, _>)
            .collect::<Result<_, _>>()?;
        let max_gain = match config.adaptive_gain {
            Some(adaptive) => adaptive.max_gain(),
            None => values.iter().map(TaskValue::gain).fold(0.0, f64::max),
        };
        let mu = config
            .transition_gain
            .unwrap_or(ControlLaw::TRANSITION_TO_TASK_GAIN_RATIO * max_gain);
        let law = ControlLaw::new(mu, config.avoidance_gain)?;
        let protected: &[usize] = if config.protect_centroid && tasks.len() > 1 {
            &[0]
        } else {
            &[]
        };
        let limits = JointLimits::new(
            *config.chain.lower_limits(),
            *config.chain.upper_limits(),
            config.activation_ratio,
        )?;
        let mut controller = StackController::new(config.controller, &values)?
            .with_protected_tasks(protected)?
            .with_joint_limits(limits.clone())?;
        if matches!(config.tasks, TaskChoice::Sequence { .. }) {
            controller = controller.with_reserve_task()?;
        }
        let estimator = config.depth.estimator(4)?;
        let task_count = tasks.len();
        let mut task_gains = [0.0; MAX_TASKS];
        for (g, v) in task_gains.iter_mut().zip(&values) {
            *g = v.gain();
        }
        Ok(Self {
            chain: config.chain,
            mount: config.mount,
            camera: config.camera,
            tasks,
            values,
            controller,
            law,
            limits,
            kinematics: KinematicsWorkspace::new(),
            depth: config.depth,
            estimator,
            target: config.target,
            desired_points,
            max_velocity: config.max_joint_velocity,
            adaptive: config.adaptive_gain,
            convergence_error: config.convergence_error,
            start_time: None,
            last_time: f64::NEG_INFINITY,
            last_points: [Point2::origin(); 4],
            twist_sum: Vector6::zeros(),
            twist_time: 0.0,
            iteration: 0,
            output: ServoOutput {
                velocity: JointVector::zeros(),
                unscaled_velocity: JointVector::zeros(),
                scale: 1.0,
                scaled: false,
                error_norm: f64::NAN,
                task_errors: [f64::NAN; MAX_TASKS],
                task_gains,
                task_count,
                stack: [0; MAX_TASKS],
                stack_len: 0,
                event: None,
                held: false,
                locked: [false; N],
                stack_velocity_norm: f64::NAN,
                converged: false,
                depths: [f64::NAN; 4],
                camera_twist: Vector6::zeros(),
                new_frame: false,
                iteration: 0,
            },
        })
    }

    /// One period at `time_s` (s, any clock, strictly increasing) with the measured corners in pixels (distorted, as
    /// the camera delivers them) and the measured joint positions `q` (rad, m). Returns the velocity to send and what
    /// the servo did. Allocates nothing.
    ///
    /// # Errors
    /// [`ServoError::TimeNotIncreasing`], [`ServoError::NonFiniteJoint`], [`ServoError::MissingCorner`],
    /// [`ServoError::NonFiniteCorner`], [`ServoError::OutsideImage`], [`ServoError::Undistortion`],
    /// [`ServoError::NonPositiveDepth`], [`ServoError::Task`] (a feature undefined on this image),
    /// [`ServoError::Controller`]. On error nothing is to be sent and the servo's memory is unchanged — but for a new
    /// frame already given to the online depth estimator when a later stage fails (a feature undefined on the image, a
    /// controller failure): that update stands, and its time becomes the last accepted one.
    pub fn step(
        &mut self,
        time_s: f64,
        pixels: &Corners,
        q: &JointVector<N>,
    ) -> Result<&ServoOutput<N>, ServoError> {
        self.check_time_and_joints(time_s, q)?;
        let mut points = [Point2::origin(); 4];
        let intrinsics = &self.camera.intrinsics;
        for (index, (corner, point)) in pixels.iter().zip(points.iter_mut()).enumerate() {
            let (u, v) = corner.ok_or(ServoError::MissingCorner { index })?;
            check_pixel(index, u, v, intrinsics.width(), intrinsics.height())?;
            let (x, y) = self
                .camera
                .normalized_of(u, v)
                .map_err(|source| ServoError::Undistortion { index, source })?;
            *point = Point2::new(x, y);
        }
        self.run(time_s, &points, q)
    }

    /// As [`Self::step`] with corners already undistorted and normalised (`x = X/Z`, `y = Y/Z`); each is checked to lie
    /// in the image at its distorted pixel.
    ///
    /// # Errors
    /// As [`Self::step`] (no [`ServoError::Undistortion`]).
    pub fn step_normalized(
        &mut self,
        time_s: f64,
        normalized: &Corners,
        q: &JointVector<N>,
    ) -> Result<&ServoOutput<N>, ServoError> {
        self.check_time_and_joints(time_s, q)?;
        let mut points = [Point2::origin(); 4];
        let intrinsics = &self.camera.intrinsics;
        for (index, (corner, point)) in normalized.iter().zip(points.iter_mut()).enumerate() {
            let (x, y) = corner.ok_or(ServoError::MissingCorner { index })?;
            if !(x.is_finite() && y.is_finite()) {
                return Err(ServoError::NonFiniteCorner { index, u: x, v: y });
            }
            let (u, v) = self.camera.pixel_of(x, y);
            check_pixel(index, u, v, intrinsics.width(), intrinsics.height())?;
            *point = Point2::new(x, y);
        }
        self.run(time_s, &points, q)
    }

    /// The output of the last accepted period.
    pub fn last_output(&self) -> &ServoOutput<N> {
        &self.output
    }

    /// The stack controller (stack, event log, status).
    pub fn controller(&self) -> &StackController<N> {
        &self.controller
    }

    /// The tasks, in priority order.
    pub fn tasks(&self) -> &[VisualTask] {
        &self.tasks
    }

    /// The desired image: normalised points and depths (m).
    pub fn desired_points(&self) -> &[ImagePoint; 4] {
        &self.desired_points
    }

    /// The joint-limit cost.
    pub fn limits(&self) -> &JointLimits<N> {
        &self.limits
    }

    fn check_time_and_joints(&self, time_s: f64, q: &JointVector<N>) -> Result<(), ServoError> {
        if !(time_s.is_finite() && time_s > self.last_time) {
            return Err(ServoError::TimeNotIncreasing {
                previous: self.last_time,
                time: time_s,
            });
        }
        if let Some((joint, value)) = first_non_finite(q) {
            return Err(ServoError::NonFiniteJoint { joint, value });
        }
        Ok(())
    }

    /// Steps 2–5 of the module docs, on validated points.
    fn run(
        &mut self,
        time_s: f64,
        measured: &[Point2<f64>; 4],
        q: &JointVector<N>,
    ) -> Result<&ServoOutput<N>, ServoError> {
        let first = self.start_time.is_none();
        let start = self.start_time.unwrap_or(time_s);
        let time = time_s - start;
        // The motion since the last accepted period, at the twist sent then.
        let dt = if first { 0.0 } else { time_s - self.last_time };
        let twist_sum = self.twist_sum + self.output.camera_twist * dt;
        let twist_time = self.twist_time + dt;
        let new_frame = first || *measured != self.last_points;
        let mut depth_updated = false;
        if let (Some(estimator), true) = (self.estimator.as_mut(), new_frame) {
            let mean = if twist_time > 0.0 {
                twist_sum / twist_time
            } else {
                Vector6::zeros()
            };
            // On error the estimator keeps its state: nothing of this period is committed.
            estimator
                .update(time, measured, &mean)
                .map_err(depth_error)?;
            depth_updated = true;
        }
        let plane = match self.depth {
            DepthSource::TargetPose => Some(self.target.plane_from_image(measured)),
            _ => None,
        };
        let depths = match (&self.estimator, self.depth, &plane) {
            (Some(estimator), _, _) => Ok(Depths::Estimated(estimator.depths())),
            (None, _, Some(Ok(plane))) => Ok(Depths::Plane(plane)),
            (None, _, Some(Err(e))) => Err(ServoError::TargetPose(e.clone())),
            (None, DepthSource::Constant { depth_m }, None) => Ok(Depths::Constant(depth_m)),
            (None, _, None) => Ok(Depths::Desired(&self.desired_points)),
        };
        let mut points = [ImagePoint::default(); 4];
        let result = depths
            .and_then(|depths| assign_depths(depths, measured, &mut points).map_err(depth_error))
            .and_then(|()| self.control(time, &points, q));
        if result.is_err() && !depth_updated {
            // Nothing changed (the controller restores its own memory on error).
            return result.map(|()| &self.output);
        }
        // The frame is committed: accepted, or given to the depth estimator before a later failure (a feature undefined
        // on this image, a controller failure), whose update cannot be undone.
        if new_frame {
            self.twist_sum = Vector6::zeros();
            self.twist_time = 0.0;
        } else {
            self.twist_sum = twist_sum;
            self.twist_time = twist_time;
        }
        self.start_time = Some(start);
        self.last_time = time_s;
        self.last_points = *measured;
        result?;
        let output = &mut self.output;
        output.new_frame = new_frame;
        output.iteration = self.iteration;
        for (d, p) in output.depths.iter_mut().zip(&points) {
            *d = p.depth;
        }
        self.iteration += 1;
        Ok(&self.output)
    }

    /// Tasks, adaptive gains, controller step, saturation and feedback.
    fn control(
        &mut self,
        time: f64,
        points: &[ImagePoint; 4],
        q: &JointVector<N>,
    ) -> Result<(), ServoError> {
        let state = self.chain.kinematics(&mut self.kinematics, q)?;
        let camera_jacobian = self.mount.camera_jacobian(state.tip_jacobian());
        let observation = Observation::new(points, None).map_err(|source| {
            ServoError::Task(TaskError::Feature {
                name: "observation".into(),
                source,
            })
        })?;
        let context = VisualContext {
            observation: &observation,
            camera_jacobian: &camera_jacobian,
        };
        let mut task_errors = [0.0; MAX_TASKS];
        let mut task_gains = [0.0; MAX_TASKS];
        for (i, (task, value)) in self.tasks.iter().zip(self.values.iter_mut()).enumerate() {
            task.evaluate(&context, value)?;
            task_errors[i] = value.error().norm();
            if let Some(adaptive) = &self.adaptive {
                adaptive.apply(Task::<N, VisualContext<'_, N>>::name(task), value)?;
            }
            task_gains[i] = value.gain();
        }
        let cost: &dyn crate::avoidance::Cost<N> = &self.limits;
        let step =
            self.controller
                .step(&self.law, &self.values, Some(cost), q, self.iteration, time)?;
        // Uniform scaling into the velocity limits, then the braking before a hard limit (D25): the direction is kept.
        let unscaled = step.velocity;
        let braking_rate = self.controller.parameters().braking_rate;
        let scale = self
            .limits
            .sent_velocity_scale(q, &unscaled, &self.max_velocity, braking_rate);
        let velocity = unscaled * scale;
        self.controller.set_sent_velocity(&velocity)?;
        let output = &mut self.output;
        output.velocity = velocity;
        output.unscaled_velocity = unscaled;
        output.scale = scale;
        output.scaled = scale < 1.0;
        output.task_errors = task_errors;
        output.task_gains = task_gains;
        output.error_norm = task_errors.iter().map(|e| e * e).sum::<f64>().sqrt();
        output.event = step.event;
        output.held = self.controller.is_held();
        output.locked = *self.controller.law_workspace().locked_joints();
        output.stack_velocity_norm = step.stack_velocity_norm;
        let stacked = self.controller.stacked();
        output.stack_len = stacked.len().min(MAX_TASKS);
        output.stack[..output.stack_len].copy_from_slice(&stacked[..output.stack_len]);
        // A reserve task not stacked yet (D23) counts only as a check that the corners are where they should be.
        let waiting_reserve = self.controller.waiting_reserve();
        let escape_error = self.controller.parameters().escape_error;
        output.converged = self.controller.is_complete()
            && task_errors[..output.task_count]
                .iter()
                .enumerate()
                .all(|(i, &e)| match waiting_reserve {
                    Some(reserve) if i == reserve => e <= escape_error,
                    _ => e < self.convergence_error,
                });
        output.camera_twist = camera_jacobian * velocity;
        Ok(())
    }
}

/// `Ok` when `(u, v)` is finite and inside `[0, width] × [0, height]` (px).
fn check_pixel(index: usize, u: f64, v: f64, width: f64, height: f64) -> Result<(), ServoError> {
    if !(u.is_finite() && v.is_finite()) {
        return Err(ServoError::NonFiniteCorner { index, u, v });
    }
    if !((0.0..=width).contains(&u) && (0.0..=height).contains(&v)) {
        return Err(ServoError::OutsideImage {
            index,
            u,
            v,
            width,
            height,
        });
    }
    Ok(())
}

/// A depth error of a period: a non-positive depth is named, the rest passes through.
fn depth_error(error: DepthError) -> ServoError {
    match error {
        DepthError::NonPositiveDepth {
            index,
            inverse_depth,
        } => ServoError::NonPositiveDepth {
            index,
            depth: 1.0 / inverse_depth,
        },
        other => ServoError::Depth(other),
    }
}

/// The desired points (normalised, with depths) and the desired depth `Z*` (m).
fn desired_points<const N: usize>(
    config: &ServoConfig<N>,
) -> Result<([ImagePoint; 4], f64), ServoError> {
    let mut points = [ImagePoint::default(); 4];
    match config.desired {
        DesiredImage::Pose(c_from_o) => {
            crate::camera::project_points(&c_from_o, config.target.points(), &mut points)?;
            Ok((points, c_from_o.translation.z))
        }
        DesiredImage::Pixels { pixels, depth_m } => {
            if !(depth_m.is_finite() && depth_m > 0.0) {
                return Err(ServoError::InvalidParameter {
                    name: "desired depth_m",
                    value: depth_m,
                    expected: "finite and > 0 (m)",
                });
            }
            let intrinsics = &config.camera.intrinsics;
            for (index, ((u, v), point)) in pixels.iter().zip(points.iter_mut()).enumerate() {
                check_pixel(index, *u, *v, intrinsics.width(), intrinsics.height())?;
                let (x, y) = config
                    .camera
                    .normalized_of(*u, *v)
                    .map_err(|source| ServoError::Undistortion { index, source })?;
                *point = ImagePoint::new(x, y, depth_m);
            }
            Ok((points, depth_m))
        }
    }
}
