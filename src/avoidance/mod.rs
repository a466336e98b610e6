//! Avoidance by the projected gradient of a cost ([theory §4](crate::theory#s4), [\[M16\]](crate::theory#m16)–[\[M18\]](crate::theory#m18), [(F17)](crate::theory#f17)–[(F19)](crate::theory#f19)).
//!
//! An "obstacle" is any scalar cost `h(q) ≥ 0` (a potential: zero where the robot is safe, growing towards danger)
//! with its gradient `∇h = (∂h/∂q)ᵀ`. The avoidance term of the control law ([`crate::law`]) is `−κ P^A_n ∇h`: the
//! steepest descent of `h`, projected onto the joint directions that the whole task stack leaves free, so that it never
//! disturbs a stacked task. The stack controller also predicts `h` ahead in time to decide when to remove a task
//! ([theory §6.2](crate::theory#s6-2)).
//!
//! Costs implement [`Cost`]. This module provides
//!
//! * the joint-limit cost of Chaumette & Marchand ([`JointLimits`], [\[M19\]](crate::theory#m19)–[\[M21\]](crate::theory#m21));
//! * the obstacle cost ([`ObstacleCost`]): link collision shapes (from the URDF `<collision>` elements,
//!   [`LinkColliders`]) against world obstacles ([`Obstacle`]), zero beyond an influence distance;
//! * the visibility cost ([`VisibilityCost`]): zero while every target point is inside the image with a margin;
//! * their sum ([`CompositeCost`]), which also tells which term dominates (for the controller's event log).
//!
//! The geometry (parry3d-f64) stays behind [`collision`]; every public type here speaks nalgebra.

pub mod collision;
mod composite;
mod joint_limits;
pub mod mesh;
mod motion_limits;
pub mod obstacles;
pub mod visibility;

pub use collision::{Collider, Geometry, Proximity};
pub use composite::CompositeCost;
pub use joint_limits::{braking_speed, stopping_speed, JointLimits};
pub use mesh::{MeshPaths, MAX_COLLADA_DEPTH, MAX_MESH_BYTES};
pub use motion_limits::{image_braking_scale, MotionLimits, ShapedVelocity};
pub use obstacles::{ClosestPair, LinkColliders, Obstacle, ObstacleCost, ObstaclePair};
pub use visibility::VisibilityCost;

use crate::math::JointVector;
use crate::robot::RobotError;

/// Errors of costs.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CostError {
    /// The activation ratio `ρ` of the joint-limit cost must lie in `(0, 1/2)` ([\[M19\]](crate::theory#m19)).
    #[error("activation ratio ρ = {rho} must lie in (0, 1/2)")]
    InvalidActivationRatio {
        /// The ratio given.
        rho: f64,
    },
    /// A joint's limits are neither finite, within [`crate::bounds::JOINT_POSITION`] and ordered (`lower < upper`) nor
    /// `(−∞, +∞)` (an unlimited joint).
    #[error("joint {joint}: limits [{lower}, {upper}] must be finite, within ±1000 (m or rad), with lower < upper, or [-inf, inf] for an unlimited joint")]
    InvalidLimits {
        /// The joint index (0-based).
        joint: usize,
        /// Its lower limit.
        lower: f64,
        /// Its upper limit.
        upper: f64,
    },
    /// The configuration holds a NaN or an infinity.
    #[error("joint {joint} = {value} is not finite")]
    NonFiniteConfiguration {
        /// The first offending joint (0-based).
        joint: usize,
        /// Its value.
        value: f64,
    },
    /// A link's collision geometry is of a kind without a loader (a URDF `<mesh>` in a format other than STL, OBJ or
    /// COLLADA).
    #[error("link {link:?}: unsupported collision geometry {geometry} (supported: box, cylinder, sphere, capsule, STL, OBJ and COLLADA meshes)")]
    UnsupportedGeometry {
        /// The link.
        link: String,
        /// What was found.
        geometry: String,
    },
    /// A mesh file of a link's collision geometry cannot be read (missing, unreadable).
    #[error("link {link:?}: cannot read mesh file {file}: {message}")]
    MeshFile {
        /// The link.
        link: String,
        /// The file the URDF `filename` led to.
        file: String,
        /// The operating system's message.
        message: String,
    },
    /// A mesh file of a link's collision geometry is not a valid mesh of its format, or holds no vertex.
    #[error("link {link:?}: malformed mesh file {file}: {message}")]
    MalformedMesh {
        /// The link.
        link: String,
        /// The file.
        file: String,
        /// What is wrong (the format reader's message).
        message: String,
    },
    /// A mesh file is larger than the limit of its [`MeshPaths`], checked before it is read.
    #[error("link {link:?}: mesh file {file} has {bytes} bytes, above the limit of {limit} (raise it with MeshPaths::with_max_file_bytes)")]
    MeshTooLarge {
        /// The link.
        link: String,
        /// The file.
        file: String,
        /// Its size (bytes; `limit + 1` when the size is known only by reading, as for a pipe).
        bytes: u64,
        /// The limit (bytes).
        limit: usize,
    },
    /// A `package://` mesh URI leads outside its package's directory (a `..` component or an absolute path after the
    /// package name), which [`MeshPaths`] refuses unless told otherwise.
    #[error("link {link:?}: mesh {filename:?} leads outside its package's directory (allow it with MeshPaths::allowing_paths_outside_packages)")]
    PathOutsidePackage {
        /// The link.
        link: String,
        /// The URDF `filename`.
        filename: String,
    },
    /// A `package://` mesh URI names a package that is neither in the package map nor on `ROS_PACKAGE_PATH`.
    #[error("link {link:?}: mesh {filename:?} names package {package:?}, which is neither in the package map nor on ROS_PACKAGE_PATH")]
    UnknownPackage {
        /// The link.
        link: String,
        /// The URDF `filename`.
        filename: String,
        /// The package name.
        package: String,
    },
    /// The points of a convex-hull shape make no convex polyhedron (fewer than three, or all on a line).
    #[error("{owner:?}: the convex hull of {points} points is degenerate (fewer than three points, or all on a line)")]
    DegenerateConvexHull {
        /// The link or obstacle.
        owner: String,
        /// How many points were given.
        points: usize,
    },
    /// A size or pose of a collision shape is not finite, or a size is not > 0.
    #[error("{owner:?}: collision shape {field} = {value} must be finite (and > 0 for a size)")]
    InvalidGeometry {
        /// The link or obstacle.
        owner: String,
        /// The offending field.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// parry has no distance algorithm for this pair of shapes.
    #[error("no distance query between {first:?} and {second:?}")]
    UnsupportedShapePair {
        /// The first shape.
        first: Geometry,
        /// The second shape.
        second: Geometry,
    },
    /// A pair names a link that is not on the robot's chain.
    #[error("unknown link {link:?} (not on the chain from base to tip)")]
    UnknownLink {
        /// The name given.
        link: String,
    },
    /// A pair names a link of the chain that has no collision geometry.
    #[error("link {link:?} has no collision geometry")]
    NoCollisionGeometry {
        /// The link.
        link: String,
    },
    /// A pair names an obstacle that does not exist.
    #[error("unknown obstacle {obstacle:?}")]
    UnknownObstacle {
        /// The name given.
        obstacle: String,
    },
    /// An influence distance is not finite and > 0 (m).
    #[error("pair ({link:?}, {obstacle:?}): influence distance {value} m must be finite and > 0")]
    InvalidInfluenceDistance {
        /// The link.
        link: String,
        /// The obstacle.
        obstacle: String,
        /// The value given.
        value: f64,
    },
    /// The visibility margin must be finite, ≥ 0 and leave a non-empty safe region of the image (px).
    #[error("visibility margin {margin_px} px must be finite, ≥ 0 and < half of the image size ({width} × {height} px)")]
    InvalidMargin {
        /// The margin given (px).
        margin_px: f64,
        /// Image width (px).
        width: f64,
        /// Image height (px).
        height: f64,
    },
    /// A point of the visibility cost is non-finite, or there is none.
    #[error("visibility cost: the target points must be finite and at least one")]
    InvalidTargetPoints,
    /// The facing term of the visibility cost needs a finite centre, a finite non-zero normal and an activation angle
    /// within `[0, 180)` degrees.
    #[error("visibility cost: facing term with activation {activation_deg}° (within [0, 180)), a finite centre and a finite non-zero normal")]
    InvalidFacing {
        /// The activation angle given (degrees).
        activation_deg: f64,
    },
    /// A caller's buffer has the wrong length.
    #[error("{what}: {found} entries, expected {expected}")]
    LengthMismatch {
        /// Which buffer.
        what: &'static str,
        /// The expected length.
        expected: usize,
        /// The length given.
        found: usize,
    },
    /// A target point is at or behind the camera: its projection, hence the visibility cost, is undefined.
    #[error("target point {point} is behind the camera (depth {depth} m)")]
    PointBehindCamera {
        /// The point's index.
        point: usize,
        /// Its depth in the camera frame (m).
        depth: f64,
    },
    /// The cost or its gradient overflowed at a finite configuration (a joint far beyond its range): an error, never
    /// a NaN or infinite cost returned as a value.
    #[error(
        "cost {cost:?} is not finite at this configuration: value {value}, gradient {gradient:?}"
    )]
    NonFiniteCost {
        /// The cost's name ([`Cost::name`]).
        cost: String,
        /// The value computed.
        value: f64,
        /// The gradient computed (empty for [`Cost::value`]).
        gradient: Vec<f64>,
    },
    /// The robot model failed (kinematics or URDF).
    #[error(transparent)]
    Robot(#[from] RobotError),
}

/// `value` when it and `gradient` are finite, else [`CostError::NonFiniteCost`] naming `cost`: the last check of a
/// cost before it returns (cheap, and allocation-free unless it fails).
pub(crate) fn checked_cost<const N: usize>(
    cost: &str,
    value: f64,
    gradient: Option<&JointVector<N>>,
) -> Result<f64, CostError> {
    if value.is_finite() && gradient.is_none_or(crate::math::all_finite) {
        Ok(value)
    } else {
        Err(CostError::NonFiniteCost {
            cost: cost.to_owned(),
            value,
            gradient: gradient
                .map(|g| g.iter().copied().collect())
                .unwrap_or_default(),
        })
    }
}

/// A differentiable scalar cost `h(q)` on the joint space, minimised by the projected-gradient term ([\[M16\]](crate::theory#m16)).
///
/// Implementations must be allocation-free and must return an error, never NaN, on bad input.
pub trait Cost<const N: usize> {
    /// The cost `h(q)` (dimensionless or in the cost's own unit; `0` where there is nothing to avoid).
    ///
    /// # Errors
    /// [`CostError::NonFiniteConfiguration`] and cost-specific failures.
    fn value(&self, q: &JointVector<N>) -> Result<f64, CostError>;

    /// The cost `h(q)`, with its gradient `∇h(q) = (∂h/∂q)ᵀ` written into `gradient`.
    ///
    /// # Errors
    /// As [`Cost::value`].
    fn value_and_gradient(
        &self,
        q: &JointVector<N>,
        gradient: &mut JointVector<N>,
    ) -> Result<f64, CostError>;

    /// A short name for logs (`"joint_limits"`, `"obstacles"`, `"visibility"`, ...). Default: `"cost"`.
    fn name(&self) -> &str {
        "cost"
    }

    /// The name of the term that contributes most to `h(q)`, for a cost made of several terms ([`CompositeCost`]);
    /// the cost's own [`Cost::name`] otherwise (the default). The stack controller records it with every removal.
    ///
    /// # Errors
    /// As [`Cost::value`].
    fn dominant_term(&self, q: &JointVector<N>) -> Result<&str, CostError> {
        let _ = q;
        Ok(self.name())
    }

    /// The removal threshold `h_max` the stack controller uses with this cost when none is given ([D6](crate::theory#d6)), in the
    /// cost's unit; `None` (the default) when the cost has no natural one, and then no task is removed unless a
    /// threshold is set explicitly.
    fn default_removal_threshold(&self) -> Option<f64> {
        None
    }

    /// Whether `q` lies where the cost guards against reaching, not merely near it: beyond a hard joint limit for
    /// [`JointLimits`]. The stack controller treats a prediction there as an infinite cost whatever `h_max`
    /// ([D6](crate::theory#d6)). Default: `false`.
    fn forbids(&self, q: &JointVector<N>) -> bool {
        let _ = q;
        false
    }
}

/// A reference to a cost is the same cost (so a [`CompositeCost`] can hold borrowed terms).
impl<const N: usize, C: Cost<N> + ?Sized> Cost<N> for &C {
    fn value(&self, q: &JointVector<N>) -> Result<f64, CostError> {
        (**self).value(q)
    }

    fn value_and_gradient(
        &self,
        q: &JointVector<N>,
        gradient: &mut JointVector<N>,
    ) -> Result<f64, CostError> {
        (**self).value_and_gradient(q, gradient)
    }

    fn name(&self) -> &str {
        (**self).name()
    }

    fn dominant_term(&self, q: &JointVector<N>) -> Result<&str, CostError> {
        (**self).dominant_term(q)
    }

    fn default_removal_threshold(&self) -> Option<f64> {
        (**self).default_removal_threshold()
    }

    fn forbids(&self, q: &JointVector<N>) -> bool {
        (**self).forbids(q)
    }
}

/// How far `s` lies beyond the dead band `[low, high]`: `s − high` above, `s − low` below, 0 inside — the `δ` of the
/// joint-limit cost [\[M20\]](crate::theory#m20), also used by the visibility cost on image coordinates.
pub(crate) fn dead_band(s: f64, low: f64, high: f64) -> f64 {
    if s > high {
        s - high
    } else if s < low {
        s - low
    } else {
        0.0
    }
}

#[cfg(test)]
pub(crate) mod test_support {
    use super::Cost;
    use crate::math::JointVector;

    /// Central finite differences of a cost's value, compared to its analytic gradient; returns the max abs error.
    pub fn gradient_error<const N: usize>(
        cost: &impl Cost<N>,
        q: &JointVector<N>,
        step: f64,
    ) -> f64 {
        let mut analytic = JointVector::<N>::zeros();
        cost.value_and_gradient(q, &mut analytic).unwrap();
        (0..N)
            .map(|i| {
                let mut plus = *q;
                let mut minus = *q;
                plus[i] += step;
                minus[i] -= step;
                let numeric =
                    (cost.value(&plus).unwrap() - cost.value(&minus).unwrap()) / (2.0 * step);
                (numeric - analytic[i]).abs()
            })
            .fold(0.0, f64::max)
    }
}
