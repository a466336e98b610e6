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
//!    With a [`ServoConfig::observer`] ([D32](crate::theory#d32)) the corners the next steps see are the observer's
//!    estimate: predicted from the twist sent over the last period, corrected by a new frame against the estimate of
//!    its capture time.
//! 3. **Tasks** (`e_i`, `L_i`, `J_i = L_i cVe eJe(q)`, [\[M42\]](crate::theory#m42)) on the observation; with an
//!    [`AdaptiveGain`], each task's gain becomes `λ(‖e_i‖∞)`.
//! 4. One [`StackController::step`] with the joint-limit cost ([\[M19\]](crate::theory#m19)); the centroid task is never
//!    removed ([D6](crate::theory#d6)). No visibility guard: the target's pose in the robot base, which it needs, is
//!    unknown to a real robot.
//! 5. **Saturation**: the velocity is scaled uniformly, `q̇_sent = s q̇` with `s = min(1, min_i q̇_i^max / |q̇_i|)`, so
//!    every joint keeps within its limit and the direction is kept; `q̇_sent` is fed back to the controller
//!    ([`StackController::set_sent_velocity`]), so the next stack change blends from what the robot received
//!    ([D1](crate::theory#d1)): continuity holds for the robot, not for a velocity it never got. With acceleration
//!    limits ([`ServoConfig::max_joint_acceleration`]), the braking keeps the distance the limited deceleration needs
//!    to stop, and only the fraction `σ` of the change from the last velocity sent that keeps every
//!    `|Δq̇_i| ≤ a_i Δt` is sent (`Δt` since the last accepted period), each joint still within its stopping distance
//!    ([D31](crate::theory#d31)); that is what is fed back.
//!
//! A step allocates nothing on the heap once built, with three exceptions outside the steady state: a removal copies
//! its report (the dominant cost's name, every task's criteria) into the controller's event log; the log grows beyond
//! its preallocated four events per task; an error naming a task allocates its message. Pushes and re-insertions
//! allocate nothing.
//!
//! [`assign_depths`]: crate::depth::assign_depths

mod adaptive_gain;
mod config;
mod error;
mod output;
mod step;

pub use adaptive_gain::AdaptiveGain;
pub use config::{DesiredImage, ServoConfig, ServoMethod, TaskChoice};
pub use error::ServoError;
pub use output::ServoOutput;

use crate::avoidance::{JointLimits, MotionLimits};
use crate::camera::{CalibratedCamera, EyeInHand, ImagePoint};
use crate::controller::StackController;
use crate::depth::{DepthEstimator, DepthSource};
use crate::law::ControlLaw;
use crate::measurement::FeatureObserver;
use crate::robot::{KinematicsWorkspace, SerialChain};
use crate::target::RectangleTarget;
use crate::task::TaskValue;
use crate::visual_task::VisualTask;
use nalgebra::{Point2, Vector6};

/// The four measured corners of the target, in the order of [`RectangleTarget::points`]: `Some((u, v))` in pixels
/// (or normalised coordinates for [`VisualServo::step_normalized`]), `None` when the detector lost a corner.
pub type Corners = [Option<(f64, f64)>; 4];

/// The largest number of tasks: the paper's sequence and the image points held in reserve ([D23](crate::theory#d23)).
pub const MAX_TASKS: usize = 5;

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
    /// The feature observer ([`ServoConfig::observer`]).
    observer: Option<FeatureObserver>,
    /// The target model, for [`DepthSource::TargetPose`].
    target: RectangleTarget,
    desired_points: [ImagePoint; 4],
    /// The velocity and acceleration limits and the longest hold ([`ServoConfig::control_period_s`], 0 when not given)
    /// that shape the velocity sent (D25, D31).
    motion: MotionLimits<N>,
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

    /// The feature observer ([`ServoConfig::observer`]): its estimate of the corners (normalised) is what the tasks
    /// were evaluated on at the last accepted period.
    pub fn observer(&self) -> Option<&FeatureObserver> {
        self.observer.as_ref()
    }
}
