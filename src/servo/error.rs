//! The errors of the façade ([`ServoError`]): invalid configuration at construction, and per period, the measurement
//! errors that leave the servo's memory as it was.

use crate::avoidance::CostError;
use crate::camera::CameraError;
use crate::controller::ControllerError;
use crate::depth::DepthError;
use crate::law::LawError;
use crate::robot::RobotError;
use crate::target::TargetError;
use crate::task::TaskError;

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
    ///
    /// [`DepthSource::PreviousPlane`]: crate::depth::DepthSource::PreviousPlane
    /// [`DepthSource::TargetPose`]: crate::depth::DepthSource::TargetPose
    #[error("depth source `previous_plane` is not supported by the servo façade (use desired, constant, target_pose or estimated)")]
    UnsupportedDepthSource,
    /// Saturation in the null space or the QP cascade asked for ([`ServoMethod`], or the full method's
    /// [`HardLimitRule::SaturateInNullSpace`]) without [`ServoConfig::control_period_s`], which sizes their box (at
    /// construction).
    ///
    /// [`ServoMethod`]: super::ServoMethod
    /// [`ServoConfig::control_period_s`]: super::ServoConfig::control_period_s
    /// [`HardLimitRule::SaturateInNullSpace`]: crate::controller::HardLimitRule::SaturateInNullSpace
    #[error("saturation in the null space and the QP cascade need the control period: set ServoConfig::control_period_s (s), the longest period of your loop")]
    MissingControlPeriod,
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
        ///
        /// [`VisualServo::step_normalized`]: super::VisualServo::step_normalized
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
    /// The feature observer's parameters are out of range (at construction, [`ServoConfig::observer`]).
    ///
    /// [`ServoConfig::observer`]: super::ServoConfig::observer
    #[error(transparent)]
    Observer(#[from] crate::measurement::MeasurementError),
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
    ///
    /// [`DepthSource::TargetPose`]: crate::depth::DepthSource::TargetPose
    #[error("no target pose from the measured corners: {0}")]
    TargetPose(#[from] TargetError),
}

/// A depth error of a period: a non-positive depth is named, the rest passes through.
pub(super) fn depth_error(error: DepthError) -> ServoError {
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
