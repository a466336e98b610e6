//! The errors of the feature module ([`FeatureError`]): invalid observations, degenerate images, invalid parameters
//! and storage of the wrong size.

/// Errors of the feature module. Each variant carries the offending values.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FeatureError {
    /// The feature needs more image points than were observed.
    #[error("feature `{feature}` needs at least {needed} image points, got {got}")]
    TooFewPoints {
        /// Name of the feature.
        feature: &'static str,
        /// Minimum number of points.
        needed: usize,
        /// Number of points observed.
        got: usize,
    },
    /// The feature is defined for an exact number of points (e.g. [`AllPoints`]) and another number was observed.
    ///
    /// [`AllPoints`]: super::AllPoints
    #[error("feature `{feature}` is defined for exactly {expected} image points, got {got}")]
    PointCountMismatch {
        /// Name of the feature.
        feature: &'static str,
        /// Number of points the feature was built for.
        expected: usize,
        /// Number of points observed.
        got: usize,
    },
    /// An image point has a NaN or infinite coordinate or depth.
    #[error("image point {index} is not finite: x = {x}, y = {y}, depth = {depth}")]
    NonFinitePoint {
        /// Index of the point.
        index: usize,
        /// Normalised abscissa.
        x: f64,
        /// Normalised ordinate.
        y: f64,
        /// Depth (m).
        depth: f64,
    },
    /// The target plane has a NaN or infinite coefficient.
    #[error("target plane is not finite: A = {a}, B = {b}, C = {c}")]
    NonFinitePlane {
        /// Coefficient A (1/m).
        a: f64,
        /// Coefficient B (1/m).
        b: f64,
        /// Coefficient C (1/m).
        c: f64,
    },
    /// An image point is at or behind the camera: its depth is not strictly positive.
    #[error("image point {index} is at or behind the camera: depth = {depth} m")]
    PointBehindCamera {
        /// Index of the point.
        index: usize,
        /// Its depth (m).
        depth: f64,
    },
    /// The target plane puts an image point at or behind the camera (or at infinity): `A x + B y + C ≤ 0`.
    #[error("the target plane puts image point {index} at or behind the camera: 1/Z = {inverse_depth} 1/m")]
    PlaneBehindCamera {
        /// Index of the point.
        index: usize,
        /// `A x + B y + C` at that point (1/m).
        inverse_depth: f64,
    },
    /// The two end points of the segment defining an angle coincide in the image (zero length, \[M32\]).
    #[error("segment from point {from} to point {to} has zero length ({length}) in the image: its angle is undefined")]
    DegenerateSegment {
        /// Index of the first end point.
        from: usize,
        /// Index of the second end point.
        to: usize,
        /// Length of the segment in normalised coordinates.
        length: f64,
    },
    /// `a = μ20 + μ02` vanishes (all points coincide in the image), so `a_n`, `P_x`, `P_y` are undefined (\[M37\]).
    #[error("second-order size a = μ20 + μ02 = {a} is zero relative to Σ(x² + y²) = {scale}: the points coincide")]
    DegenerateArea {
        /// `μ20 + μ02`.
        a: f64,
        /// `Σ (x_k² + y_k²)`, the scale of the relative test.
        scale: f64,
    },
    /// `I1 = (μ20 − μ02)² + 4 μ11²` vanishes relative to `I3² = (μ20 + μ02)²`: the second-order moments are
    /// isotropic (a square seen head-on), so the orientation and the paper's `P_x, P_y` are undefined (D9).
    #[error("I1 = {i1} is zero relative to I3² (I3 = {i3}): isotropic moments, e.g. a square seen head-on (D9)")]
    IsotropicMoments {
        /// `I1`.
        i1: f64,
        /// `I3 = μ20 + μ02`.
        i3: f64,
    },
    /// A parameter of a feature is out of its range.
    #[error("parameter `{name}` = {value} must be {expected}")]
    InvalidParameter {
        /// Name of the parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// Its range.
        expected: &'static str,
    },
    /// The two point indices of a segment are equal.
    #[error("a segment needs two distinct points, got {from} and {to}")]
    SameEndPoints {
        /// Index of the first end point.
        from: usize,
        /// Index of the second end point.
        to: usize,
    },
    /// A centred moment `μ_ij` of order `i + j > 3` was requested (orders up to 3 are computed).
    #[error("centred moment μ_{i}{j} has order {} > 3", i + j)]
    UnsupportedMomentOrder {
        /// Power of x.
        i: usize,
        /// Power of y.
        j: usize,
    },
    /// The caller-provided storage does not have the feature's dimension.
    #[error("feature `{feature}` has {expected} rows, storage has {got}")]
    WrongDimension {
        /// Name of the feature.
        feature: &'static str,
        /// The feature's dimension.
        expected: usize,
        /// Rows of the storage.
        got: usize,
    },
    /// A feature value given to [`Feature::error`] is NaN or infinite.
    ///
    /// [`Feature::error`]: super::Feature::error
    #[error("feature `{feature}`, row {row}: value {value} is not finite")]
    NonFiniteValue {
        /// Name of the feature.
        feature: &'static str,
        /// Row.
        row: usize,
        /// The value.
        value: f64,
    },
    /// A computed value or interaction entry overflowed to a non-finite number (extreme input).
    #[error("feature `{feature}` produced a non-finite result")]
    NonFiniteResult {
        /// Name of the feature.
        feature: &'static str,
    },
}
