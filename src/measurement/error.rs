//! The errors of the measurement model ([`MeasurementError`]): invalid parameters, and invalid inputs to a period.

use crate::camera::CameraError;
use crate::depth::DepthError;

/// Errors of the measurement model. Each variant carries the offending values.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeasurementError {
    /// A parameter is out of range.
    #[error("measurement parameter `{name}` = {value} is invalid: {expected}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is expected.
        expected: &'static str,
    },
    /// The number of points differs from the one the model was built for.
    #[error("{got} points, expected {expected}")]
    PointCountMismatch {
        /// Expected count.
        expected: usize,
        /// Count given.
        got: usize,
    },
    /// A true image point is NaN or infinite, or at or behind the camera.
    #[error("true image point {index} is invalid: ({x}, {y}), depth {depth} m")]
    InvalidPoint {
        /// Index of the point.
        index: usize,
        /// Normalised abscissa.
        x: f64,
        /// Normalised ordinate.
        y: f64,
        /// Depth (m).
        depth: f64,
    },
    /// The camera twist has a NaN or infinite component.
    #[error("camera twist is not finite: {twist:?}")]
    NonFiniteTwist {
        /// The twist `(υ, ω)`.
        twist: [f64; 6],
    },
    /// The time of a call is not after the previous one (or is not finite).
    #[error("time {time} s is not after the previous measurement at {previous} s")]
    TimeNotIncreasing {
        /// The previous call's time (s).
        previous: f64,
        /// This call's time (s).
        time: f64,
    },
    /// Undistortion of a delivered pixel through the nominal camera failed.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// The depths used for prediction are unusable.
    #[error(transparent)]
    Depth(#[from] DepthError),
}
