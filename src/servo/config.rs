//! The façade's configuration ([`ServoConfig`]: models, desired image, tasks and parameters with their defaults) and
//! how [`VisualServo::new`] builds a servo from it.

use super::step::check_pixel;
use super::{AdaptiveGain, ServoError, ServoOutput, VisualServo, MAX_TASKS};
use crate::avoidance::{JointLimits, MotionLimits};
use crate::camera::{CalibratedCamera, EyeInHand, ImagePoint};
use crate::controller::{ControllerParameters, HardLimitRule, StackController};
use crate::depth::DepthSource;
use crate::feature::{InteractionSource, Observation};
use crate::law::sns::SnsBounds;
use crate::law::{BoundedLaw, ControlLaw};
use crate::linalg::VelocityInverse;
use crate::math::JointVector;
use crate::measurement::{FeatureObserver, ObserverParameters};
use crate::robot::{KinematicsWorkspace, SerialChain};
use crate::stack::StackParameters;
use crate::target::RectangleTarget;
use crate::task::{TaskError, TaskValue};
use crate::visual_task::{
    classical_task_with, image_points_task, paper_tasks_with, FourthTask, VisualContext,
};
use nalgebra::{Isometry3, Point2, Vector6};

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

/// Which law drives the robot and keeps its joints inside their limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ServoMethod {
    /// The paper's full method (default): the stack controller removes and puts back tasks, with the avoidance term,
    /// and keeps the joints inside their limits as [`ControllerParameters::hard_limit_rule`] says (the braking and
    /// the lock of D25 and D26 by default).
    #[default]
    FullMethod,
    /// Saturation in the null space ([theory §13](crate::theory#s13)): the same tasks in the same sequence (or all at
    /// once, [`ControllerParameters::sequencing`]), the joint-limit cost as a last level, every joint velocity inside
    /// the box of the position limits over [`ServoConfig::control_period_s`] and of [`ServoConfig::max_joint_velocity`];
    /// no removal, no reserve task, the truncated pseudo-inverse (as in the study).
    SaturationInNullSpace,
    /// The hierarchical QP cascade ([theory §14](crate::theory#s14)) in the same box, with the same tasks and
    /// sequence as [`Self::SaturationInNullSpace`].
    HierarchicalQp,
}

impl ServoMethod {
    /// The law that keeps the velocity in the box of the hard bounds, if any (the full method with its default rule
    /// brakes and locks instead).
    fn bounded_law(self, rule: HardLimitRule) -> Option<BoundedLaw> {
        match (self, rule) {
            (Self::FullMethod, HardLimitRule::BrakeAndLock) => None,
            (Self::FullMethod, HardLimitRule::SaturateInNullSpace)
            | (Self::SaturationInNullSpace, _) => Some(BoundedLaw::SaturationInNullSpace),
            (Self::HierarchicalQp, _) => Some(BoundedLaw::HierarchicalQp),
        }
    }
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
    /// `a_i`, the largest change of joint `i`'s velocity per second (`> 0`, rad/s² for revolute, m/s² for prismatic
    /// joints; `+∞`: no limit). Default: no limit (the paper's runs and the README's figures are without); an industrial
    /// arm's controller allows a few rad/s² (2 to 5) and about 1 m/s² on a gantry's axes. The change from the last
    /// velocity sent is scaled uniformly so that `|Δq̇_i| ≤ a_i Δt`, `Δt` the time since the last accepted period, and
    /// the braking of [D25](crate::theory#d25) keeps the stopping distance ([D31](crate::theory#d31)); SNS and the QP
    /// cascade get the limits in their box too.
    pub max_joint_acceleration: JointVector<N>,
    /// An adaptive gain `λ(‖e_i‖∞)` replacing every task's constant gain (default `None`: the constant gains).
    pub adaptive_gain: Option<AdaptiveGain>,
    /// The servo has converged when every task is stacked and `‖e_i‖ < convergence_error` for each (in the tasks'
    /// units: normalised image coordinates, rad, dimensionless; see [`ServoOutput::converged`]). Default 1e−4. The
    /// full method's restart ([D29](crate::theory#d29)) takes a servo whose error has stopped falling against a limit
    /// for short of its goal while a stacked task's error is above it: set it above the noise of your corners.
    pub convergence_error: f64,
    /// The law (default: the paper's full method).
    pub method: ServoMethod,
    /// The period of the control loop (s, in `(0, 1]`): the time over which a velocity is held, which sizes the box
    /// `q_min ≤ q + q̇ Δt ≤ q_max` of saturation in the null space and of the QP cascade. Required by those laws (a
    /// [`ServoMethod`] other than the full method, or the full method's `hard_limit_rule = SaturateInNullSpace`); give
    /// the longest period the loop may take. With acceleration limits it also sizes the braking's stopping distance
    /// ([D31](crate::theory#d31)): a velocity is assumed held for at most `max(Δt, control_period_s)`, `Δt` the last
    /// period, so give the longest hold (a bad frame held adds a period). Default `None`.
    pub control_period_s: Option<f64>,
    /// The feature observer ([D32](crate::theory#d32)): between camera frames the corners are predicted from the
    /// velocity sent (through `L_x` and the camera Jacobian), and each new frame corrects the prediction against the
    /// estimate of its capture time (`latency_s` before the period it arrives in) with a Kalman gain that weighs the
    /// detector's noise against the prediction's error. The law then sees a smooth signal, and the noise of a still
    /// camera is averaged over up to `memory_s`. Default `None`: each period uses the corners given (a camera slower
    /// than the loop repeats its frame).
    pub observer: Option<ObserverParameters>,
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
            max_joint_acceleration: JointVector::repeat(f64::INFINITY),
            adaptive_gain: None,
            convergence_error: 1e-4,
            method: ServoMethod::FullMethod,
            control_period_s: None,
            observer: None,
            protect_centroid: true,
        }
    }
}

impl<const N: usize> VisualServo<N> {
    /// Builds the servo: desired image, tasks, controller, law, joint-limit cost, depth estimator.
    ///
    /// # Errors
    /// [`ServoError::InvalidParameter`] (velocity and acceleration limits, convergence threshold, desired depth),
    /// [`ServoError::UnsupportedDepthSource`], [`ServoError::MissingControlPeriod`], and the models' errors (a desired
    /// corner that does not undistort, a feature undefined on the desired image, invalid gains, `μ`, `κ`, `ρ`,
    /// controller or depth parameters).
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
        if let Some(a) = config
            .max_joint_acceleration
            .iter()
            .find(|a| a.is_nan() || **a <= 0.0)
        {
            return Err(invalid(
                "max_joint_acceleration",
                *a,
                "> 0 (rad/s², m/s²; or +∞)",
            ));
        }
        let e = config.convergence_error;
        if !(e.is_finite() && e > 0.0) {
            return Err(invalid("convergence_error", e, "finite and > 0"));
        }
        if config.depth == DepthSource::PreviousPlane {
            return Err(ServoError::UnsupportedDepthSource);
        }
        if let Some(period) = config.control_period_s {
            if !(period.is_finite() && period > 0.0 && period <= 1.0) {
                return Err(invalid("control_period_s", period, "in (0, 1] s"));
            }
        }
        let bounded_law = config.method.bounded_law(config.controller.hard_limit_rule);
        let full_method = config.method == ServoMethod::FullMethod;
        let bounds = match (bounded_law, config.control_period_s) {
            (None, _) => None,
            (Some(_), None) => return Err(ServoError::MissingControlPeriod),
            (Some(law), Some(period)) => {
                if !(period.is_finite() && period > 0.0 && period <= 1.0) {
                    return Err(invalid("control_period_s", period, "in (0, 1] s"));
                }
                let limits = JointLimits::new(
                    *config.chain.lower_limits(),
                    *config.chain.upper_limits(),
                    config.activation_ratio,
                )?;
                let bounds = SnsBounds::new(limits, config.max_joint_velocity, period)
                    .and_then(|bounds| bounds.with_max_acceleration(config.max_joint_acceleration))
                    .map_err(|e| ServoError::Law(e.into()))?;
                Some((law, bounds))
            }
        };
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
                if full_method {
                    tasks.push(image_points_task(&desired, gains[3], config.interaction)?);
                }
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
        // SNS and the QP cascade run as in the study: the truncated pseudo-inverse of D2, no removal, no braking and
        // no lock (the box keeps the limits).
        let stack = StackParameters {
            velocity_inverse: if full_method {
                config.controller.velocity_inverse()
            } else {
                VelocityInverse::Truncated
            },
            ..StackParameters::default()
        };
        let boxed = bounded_law.is_some();
        let parameters = ControllerParameters {
            allow_removal: full_method && config.controller.allow_removal,
            braking_rate: if boxed {
                f64::INFINITY
            } else {
                config.controller.braking_rate
            },
            lock_band: if boxed {
                0.0
            } else {
                config.controller.lock_band
            },
            ..config.controller
        };
        let law = ControlLaw::with_stack_parameters(stack, mu, config.avoidance_gain)?;
        let protected: &[usize] = if full_method && config.protect_centroid && tasks.len() > 1 {
            &[0]
        } else {
            &[]
        };
        let limits = JointLimits::new(
            *config.chain.lower_limits(),
            *config.chain.upper_limits(),
            config.activation_ratio,
        )?;
        let mut controller = StackController::new(parameters, &values)?
            .with_protected_tasks(protected)?
            .with_joint_limits(limits.clone())?
            .with_goal_error(config.convergence_error)?;
        if full_method && matches!(config.tasks, TaskChoice::Sequence { .. }) {
            controller = controller.with_reserve_task()?;
        }
        if let Some((law, bounds)) = bounds {
            controller = controller.with_bounded_law(law, bounds)?;
        }
        let estimator = config.depth.estimator(4)?;
        let intrinsics = &config.camera.intrinsics;
        let observer = config
            .observer
            .map(|parameters| FeatureObserver::new(parameters, intrinsics.fx(), intrinsics.fy()))
            .transpose()?;
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
            observer,
            target: config.target,
            desired_points,
            motion: MotionLimits {
                max_velocity: config.max_joint_velocity,
                max_acceleration: config.max_joint_acceleration,
                longest_period: config.control_period_s.unwrap_or(0.0),
            },
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
                acceleration_scale: 1.0,
                stopping_clamp: false,
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
