//! Visual features of a planar point target and their interaction matrices ([theory §7](crate::theory#s7), [D8](crate::theory#d8)–[D10](crate::theory#d10)).
//!
//! A visual feature `s` is a function of the observed image points; its **interaction matrix** `L_s`
//! (`dim × 6`) gives its rate under a camera velocity screw `v = (υ, ω)` expressed in the camera frame `c`
//! (linear part first, m/s and rad/s): `ṡ = L_s v` ([theory §0](crate::theory#s0), [§7](crate::theory#s7)). A visual task later builds its Jacobian as
//! `J = L_s · cVe · eJe` \[M42\] (F29).
//!
//! # Data flow (no repeated work, no allocation)
//!
//! 1. [`Observation::new`] validates the observed [`ImagePoint`]s (and the target plane when known). The centroid
//!    and the centred moments `μ_ij` up to order 3 with their interaction rows ([`Moments`], \[M30\],
//!    \[M34\]–\[M35\]) are computed **once per point set**, at the first [`Observation::moments`] call (features that
//!    read the points only never pay for them).
//! 2. Each [`Feature`] reads that observation and writes its value into a caller-provided `&mut [f64]`
//!    ([`Feature::value`]) and its interaction matrix into caller-provided rows of an `OMatrix<f64, Dyn, U6>`
//!    ([`Feature::interaction`], type [`InteractionRows`]), or both in one call ([`Feature::value_and_interaction`],
//!    which a control step uses: the terms the value and the rows share are computed once). Nothing allocates on the
//!    heap in any of these calls.
//! 3. [`Feature::error`] gives `e = s − s*` (F28) with angle rows wrapped into `(−π, π]` ([`crate::math::wrap_angle`],
//!    D8).
//!
//! # Depths
//!
//! Every exact interaction matrix is the chain rule \[M29\] over the point rows \[M28\], which need the inverse depth
//! `1/Z_k` of each point. When a [`TargetPlane`] is given to [`Observation::new`], `1/Z_k = A x_k + B y_k + C`
//! ([theory §7.1](crate::theory#s7-1)); otherwise the depth stored in each [`ImagePoint`] is used. Both are exact for a planar target, so no
//! feature *requires* the plane: the per-point depths of [`ImagePoint`] always suffice.
//!
//! # Interaction sources (D10)
//!
//! [`InteractionSource::Exact`] evaluates the exact matrix on the observation passed in (the current one).
//! [`InteractionSource::Desired`] is the same exact formula, evaluated on the **desired** observation: the caller
//! passes the desired observation to [`Feature::interaction`] (once; the result is constant).
//! [`InteractionSource::PaperApprox`] uses the paper's approximate forms with a priori depths, parameters of the
//! features: (F31) for the centroid ([`Centroid::a_priori_depth`]), (F32)/\[M33\] for the diagonal angle, (F35)/\[M39\]
//! for `a_n`. Features without an approximate form in the paper use their exact matrix for `PaperApprox`; each one
//! says so in its docs (notably `P_x, P_y`, whose matrix the paper takes from Chaumette 2004, not available to us).
//!
//! # Features
//!
//! | feature | rows | theory |
//! |---|---|---|
//! | [`Point`], [`AllPoints`] | 2, 2N | \[M28\] |
//! | [`Centroid`] | 2 (x_g, y_g) | \[M30\], \[M31\], (F31) |
//! | [`DiagonalAngle`] | 1 (angle) | \[M32\], \[M33\] (F32), D8 |
//! | [`CentredMoment`] | 1 | \[M34\]–\[M35\] (F33) |
//! | [`AreaNormalized`] | 1 (a_n) | \[M37\]–\[M39\] (F34)–(F35) |
//! | [`PaperInvariants`] | 2 (P_x, P_y) | \[M40\]–\[M41\] (F36), D9 |
//! | [`SideRatios`] | 2 (r_x, r_y) | replaces `P_x, P_y` for square targets (chain rule over \[M28\]) |
//! | [`NormalizedCentroid`] | 2 (x_n, y_n) | ViSP, [peer scene variant B](crate::theory::peer_scene#variant-b) |
//! | [`MomentOrientation`] | 1 (angle) | ViSP, [peer scene variant B](crate::theory::peer_scene#variant-b) |
//! | [`VispInvariants`] | 2 (P_x, P_y) | ViSP `vpMomentCInvariant`, [theory §7.6](crate::theory#s7-6) |
//! | [`VispMoments`] | 6 | the four ViSP features above in one pass, variant B |
//! | [`FeatureSet`] | sum | stacked features: the paper's four tasks, §7.7, variant B |
//!
//! ```
//! use nalgebra::{Dyn, OMatrix, U6};
//! use servostack::camera::ImagePoint;
//! use servostack::feature::{AreaNormalization, Feature, FeatureSet, InteractionSource, Observation};
//!
//! // Desired image: a 0.2 m × 0.1 m rectangle, fronto-parallel at Z* = 0.5 m (the peer scene).
//! let desired = [(-0.2, -0.1), (0.2, -0.1), (0.2, 0.1), (-0.2, 0.1)].map(|(x, y)| ImagePoint::new(x, y, 0.5));
//! let desired = Observation::new(&desired, None)?;
//! let set = FeatureSet::visp_moments(AreaNormalization::from_desired(&desired, 0.5)?);
//!
//! // Storage allocated once, before the control loop.
//! let mut s = vec![0.0; set.dim()];
//! let mut s_star = vec![0.0; set.dim()];
//! let mut e = vec![0.0; set.dim()];
//! let mut l = OMatrix::<f64, Dyn, U6>::zeros(set.dim());
//! set.value(&desired, &mut s_star)?;
//!
//! // In the loop: current points, then value, matrix and error, without allocation.
//! let current = [(-0.21, -0.09), (0.19, -0.11), (0.2, 0.12), (-0.2, 0.1)].map(|(x, y)| ImagePoint::new(x, y, 0.52));
//! let current = Observation::new(&current, None)?;
//! set.value(&current, &mut s)?;
//! set.interaction(&current, InteractionSource::Exact, l.rows_mut(0, set.dim()))?;
//! set.error(&s, &s_star, &mut e)?;
//! assert!((s_star[2] - 0.5).abs() < 1e-12); // a_n = Z* at the desired pose
//! # Ok::<(), servostack::feature::FeatureError>(())
//! ```

/// The three `write_*` methods of [`Feature`] for a feature of `K` rows whose values and interaction rows come out of
/// one evaluation, `$evaluate(&self, &Observation, InteractionSource) -> Result<[(f64, InteractionRow); K],
/// FeatureError>`: [`Feature::write_value`] keeps the values (of the exact form; the value does not depend on the
/// source), [`Feature::write_interaction`] the rows, and [`Feature::write_value_and_interaction`] writes both from one
/// evaluation.
macro_rules! writes_from_one_evaluation {
    ($evaluate:path) => {
        fn write_value(
            &self,
            obs: &super::Observation<'_>,
            s: &mut [f64],
        ) -> Result<(), super::FeatureError> {
            let pairs = $evaluate(self, obs, super::InteractionSource::Exact)?;
            super::write_values(s, &pairs.map(|(value, _)| value));
            Ok(())
        }
        fn write_interaction(
            &self,
            obs: &super::Observation<'_>,
            source: super::InteractionSource,
            l: super::InteractionRows<'_>,
        ) -> Result<(), super::FeatureError> {
            let pairs = $evaluate(self, obs, source)?;
            super::write_rows(l, &pairs.map(|(_, row)| row));
            Ok(())
        }
        fn write_value_and_interaction(
            &self,
            obs: &super::Observation<'_>,
            source: super::InteractionSource,
            s: &mut [f64],
            l: super::InteractionRows<'_>,
        ) -> Result<(), super::FeatureError> {
            super::write_pairs(s, l, &$evaluate(self, obs, source)?);
            Ok(())
        }
    };
}

mod angle;
mod area;
mod centroid;
mod invariants;
mod moments;
mod point;
mod set;
mod sides;
#[cfg(test)]
pub(crate) mod testutil;

pub use angle::{DiagonalAngle, MomentOrientation};
pub use area::{AreaNormalization, AreaNormalized, CentredMoment};
pub use centroid::{Centroid, NormalizedCentroid};
pub use invariants::{PaperInvariants, VispInvariants};
pub use moments::Moments;
pub use point::{AllPoints, Point};
pub use set::{BoxedFeature, FeatureSet, VispMoments};
pub use sides::SideRatios;

use crate::camera::ImagePoint;
use crate::math::wrap_angle;
use crate::target::TargetPlane;
use nalgebra::{Dyn, MatrixViewMut, RowVector6, U1, U6};

/// One row of an interaction matrix: the partial derivatives of a scalar feature with respect to the camera twist
/// `(υx, υy, υz, ωx, ωy, ωz)` in the camera frame ([theory §0](crate::theory#s0)).
pub type InteractionRow = RowVector6<f64>;

/// Caller-provided storage for the rows of an interaction matrix: a mutable view of `dim` consecutive rows of an
/// `OMatrix<f64, Dyn, U6>` (obtained with `matrix.rows_mut(first_row, dim)`; a static `SMatrix<f64, R, 6>` gives one
/// with `matrix.as_view_mut::<Dyn, U6, U1, Dyn>()`). Features write into it without allocating.
pub type InteractionRows<'a> = MatrixViewMut<'a, f64, Dyn, U6, U1, Dyn>;

/// Relative tolerance below which a size-like quantity is treated as zero: `a = μ20 + μ02` against
/// `Σ (x_k² + y_k²)`, a diagonal length against the magnitude of its end points, and `I1` against `I3²` (D9).
pub const RELATIVE_TOLERANCE: f64 = 1e-10;

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

/// Where the interaction matrix is evaluated ([D10](crate::theory#d10), [§8](crate::theory#s8)).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Default, Hash, serde::Serialize, serde::Deserialize,
)]
pub enum InteractionSource {
    /// Exact matrix (chain rule \[M29\] and the closed forms of §7) at the observation passed in, normally the current
    /// one, with its exact depths.
    #[default]
    Exact,
    /// The paper's approximate forms with a priori depths: (F31), (F32)/\[M33\], (F35)/\[M39\]. Features without such a
    /// form use their exact matrix (stated in each feature's docs).
    PaperApprox,
    /// The exact matrix evaluated at the desired pose: pass the **desired** observation to
    /// [`Feature::interaction`]. The matrix is constant; compute it once.
    Desired,
}

/// Validated image points with their inverse depths and their moments, computed once and read by every feature
/// ([theory §7.1](crate::theory#s7-1), [§7.4](crate::theory#s7-4)).
#[derive(Debug, Clone)]
pub struct Observation<'a> {
    points: &'a [ImagePoint],
    plane: Option<TargetPlane>,
    /// Computed at the first [`Observation::moments`] call, so that features that read the points only (e.g.
    /// [`AllPoints`]) do not pay for them; kept even when they overflowed (`moments()` then fails).
    moments: std::cell::OnceCell<Moments>,
}

impl<'a> Observation<'a> {
    /// Validates `points` (normalised coordinates and depths in the camera frame) and the optional target plane
    /// `1/Z = A x + B y + C` (1/m, camera frame), then computes the [`Moments`] of the point set. Allocates nothing.
    ///
    /// The inverse depth of point k is `A x_k + B y_k + C` when `plane` is given, `1/Z_k` otherwise.
    ///
    /// # Errors
    /// [`FeatureError::TooFewPoints`] for an empty slice; [`FeatureError::NonFinitePoint`] /
    /// [`FeatureError::NonFinitePlane`] for NaN or infinite inputs (every field is checked, even the depths that a
    /// plane makes unused); [`FeatureError::PointBehindCamera`] when a depth in use is `≤ 0`;
    /// [`FeatureError::PlaneBehindCamera`] when the plane gives `1/Z ≤ 0` at a point. (Overflowing moments are reported
    /// by [`Observation::moments`].)
    pub fn new(
        points: &'a [ImagePoint],
        plane: Option<&TargetPlane>,
    ) -> Result<Self, FeatureError> {
        if points.is_empty() {
            return Err(FeatureError::TooFewPoints {
                feature: "observation",
                needed: 1,
                got: 0,
            });
        }
        if let Some(p) = plane {
            if !(p.a.is_finite() && p.b.is_finite() && p.c.is_finite()) {
                return Err(FeatureError::NonFinitePlane {
                    a: p.a,
                    b: p.b,
                    c: p.c,
                });
            }
        }
        for (index, p) in points.iter().enumerate() {
            if !(p.x.is_finite() && p.y.is_finite() && p.depth.is_finite()) {
                return Err(FeatureError::NonFinitePoint {
                    index,
                    x: p.x,
                    y: p.y,
                    depth: p.depth,
                });
            }
            match plane {
                Some(plane) => {
                    let inverse_depth = plane.inverse_depth(p.x, p.y);
                    if !(inverse_depth > 0.0 && inverse_depth.is_finite()) {
                        return Err(FeatureError::PlaneBehindCamera {
                            index,
                            inverse_depth,
                        });
                    }
                }
                None if p.depth <= 0.0 => {
                    return Err(FeatureError::PointBehindCamera {
                        index,
                        depth: p.depth,
                    })
                }
                None => {}
            }
        }
        Ok(Self {
            points,
            plane: plane.copied(),
            moments: std::cell::OnceCell::new(),
        })
    }

    /// The observed points.
    pub fn points(&self) -> &'a [ImagePoint] {
        self.points
    }

    /// The target plane, when one was given.
    pub fn plane(&self) -> Option<&TargetPlane> {
        self.plane.as_ref()
    }

    /// The moments of the point set, computed once, at the first call, and shared by every feature afterwards.
    ///
    /// # Errors
    /// [`FeatureError::NonFiniteResult`] when the moments overflow (coordinates beyond about 1e75).
    pub fn moments(&self) -> Result<&Moments, FeatureError> {
        let moments = self.moments.get_or_init(|| {
            Moments::compute(self.points, |p| inverse_depth(self.plane.as_ref(), p))
        });
        if moments.is_finite() {
            Ok(moments)
        } else {
            Err(FeatureError::NonFiniteResult { feature: "moments" })
        }
    }

    /// Number of observed points (at least 1).
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Always `false`: an observation has at least one point.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Inverse depth `1/Z_k` (1/m) of point `k` (plane model when known), or `None` when `k` is out of range.
    pub fn inverse_depth(&self, k: usize) -> Option<f64> {
        self.points
            .get(k)
            .map(|p| inverse_depth(self.plane.as_ref(), p))
    }

    /// The image point k and its interaction rows `(L_x, L_y)` \[M28\], or `None` when `k` is out of range.
    fn point_rows(&self, k: usize) -> Option<(ImagePoint, InteractionRow, InteractionRow)> {
        let p = self.points.get(k)?;
        let (lx, ly) = point_interaction(p.x, p.y, inverse_depth(self.plane.as_ref(), p));
        Some((*p, lx, ly))
    }
}

/// Inverse depth of a validated point: plane model when known, `1/Z` otherwise.
fn inverse_depth(plane: Option<&TargetPlane>, p: &ImagePoint) -> f64 {
    match plane {
        Some(plane) => plane.inverse_depth(p.x, p.y),
        None => 1.0 / p.depth,
    }
}

/// Interaction rows of an image point `(x, y)` with inverse depth `ζ = 1/Z` (1/m), [\[M28\]](crate::theory#m28):
///
/// ```text
/// L_x = [ −ζ   0   xζ   xy      −(1+x²)   y ]
/// L_y = [  0  −ζ   yζ   1+y²    −xy      −x ]
/// ```
pub fn point_interaction(x: f64, y: f64, inverse_depth: f64) -> (InteractionRow, InteractionRow) {
    let z = inverse_depth;
    (
        InteractionRow::new(-z, 0.0, x * z, x * y, -(1.0 + x * x), y),
        InteractionRow::new(0.0, -z, y * z, 1.0 + y * y, -x * y, -x),
    )
}

/// A visual feature: a function `s` (`dim` rows) of the observed image points, with its interaction matrix
/// `L_s` (`dim × 6`, `ṡ = L_s v`, twist `(υ, ω)` of the camera in the camera frame) and its error `s − s*` (F28).
///
/// Implementors provide [`Feature::write_value`] and [`Feature::write_interaction`]; callers use the checked
/// [`Feature::value`], [`Feature::interaction`] and [`Feature::error`], which validate the point count and the
/// storage size and reject non-finite results. No method allocates.
pub trait Feature {
    /// Short name, used in errors and logs.
    fn name(&self) -> &'static str;

    /// Number of rows of `s`.
    fn dim(&self) -> usize;

    /// Whether row `row` is an angle (rad), whose error is wrapped into `(−π, π]` (D8).
    fn is_angle(&self, row: usize) -> bool;

    /// Minimum number of image points the feature needs.
    fn min_points(&self) -> usize;

    /// Writes `s` into `s` (length [`Feature::dim`], checked by the caller). Unchecked entry point for implementors;
    /// call [`Feature::value`].
    ///
    /// # Errors
    /// Feature-specific degeneracies ([`FeatureError::DegenerateArea`], ...).
    fn write_value(&self, obs: &Observation<'_>, s: &mut [f64]) -> Result<(), FeatureError>;

    /// Writes `L_s` into `l` ([`Feature::dim`] rows, checked by the caller). Unchecked entry point for implementors;
    /// call [`Feature::interaction`].
    ///
    /// # Errors
    /// Feature-specific degeneracies.
    fn write_interaction(
        &self,
        obs: &Observation<'_>,
        source: InteractionSource,
        l: InteractionRows<'_>,
    ) -> Result<(), FeatureError>;

    /// Writes `s` and `L_s` together (sizes checked by the caller). Unchecked entry point for implementors; call
    /// [`Feature::value_and_interaction`]. The default calls [`Feature::write_value`] then
    /// [`Feature::write_interaction`]; a feature whose value and rows share intermediate terms (a segment, `a_n`, the
    /// second-order terms) overrides it to compute them once. It must write exactly what the two calls write.
    ///
    /// # Errors
    /// As [`Feature::write_value`] and [`Feature::write_interaction`].
    fn write_value_and_interaction(
        &self,
        obs: &Observation<'_>,
        source: InteractionSource,
        s: &mut [f64],
        l: InteractionRows<'_>,
    ) -> Result<(), FeatureError> {
        self.write_value(obs, s)?;
        self.write_interaction(obs, source, l)
    }

    /// Computes the feature value `s` into caller-provided storage of length [`Feature::dim`].
    ///
    /// # Errors
    /// [`FeatureError::TooFewPoints`], [`FeatureError::WrongDimension`], the feature's degeneracies, and
    /// [`FeatureError::NonFiniteResult`] on overflow.
    fn value(&self, obs: &Observation<'_>, s: &mut [f64]) -> Result<(), FeatureError> {
        check_points(self, obs)?;
        check_dim(self, s.len())?;
        self.write_value(obs, s)?;
        check_finite_value(self, s)
    }

    /// Computes the interaction matrix `L_s` into [`Feature::dim`] caller-provided rows (see [`InteractionRows`]),
    /// evaluated on `obs` with the form chosen by `source` (D10). For [`InteractionSource::Desired`], `obs` must be
    /// the desired observation.
    ///
    /// # Errors
    /// As [`Feature::value`].
    fn interaction(
        &self,
        obs: &Observation<'_>,
        source: InteractionSource,
        mut l: InteractionRows<'_>,
    ) -> Result<(), FeatureError> {
        check_points(self, obs)?;
        check_dim(self, l.nrows())?;
        self.write_interaction(obs, source, l.rows_mut(0, self.dim()))?;
        check_finite_rows(self, &l)
    }

    /// [`Feature::value`] and [`Feature::interaction`] in one call, with the same checks and the same results, the
    /// shared terms computed once.
    ///
    /// # Errors
    /// As [`Feature::value`] and [`Feature::interaction`].
    fn value_and_interaction(
        &self,
        obs: &Observation<'_>,
        source: InteractionSource,
        s: &mut [f64],
        mut l: InteractionRows<'_>,
    ) -> Result<(), FeatureError> {
        check_points(self, obs)?;
        check_dim(self, s.len())?;
        check_dim(self, l.nrows())?;
        self.write_value_and_interaction(obs, source, s, l.rows_mut(0, self.dim()))?;
        check_finite_value(self, s)?;
        check_finite_rows(self, &l)
    }

    /// The task error `e = s − s*` (F28) into `e`, with angle rows wrapped into `(−π, π]` (D8, as ViSP's
    /// `vpFeatureMomentAlpha::error`). All three slices have length [`Feature::dim`].
    ///
    /// # Errors
    /// [`FeatureError::WrongDimension`]; [`FeatureError::NonFiniteValue`] for a NaN or infinite `s` or `s*`.
    fn error(&self, s: &[f64], s_star: &[f64], e: &mut [f64]) -> Result<(), FeatureError> {
        for len in [s.len(), s_star.len(), e.len()] {
            check_dim(self, len)?;
        }
        for (row, ((e, &s), &s_star)) in e.iter_mut().zip(s).zip(s_star).enumerate() {
            for value in [s, s_star] {
                if !value.is_finite() {
                    return Err(FeatureError::NonFiniteValue {
                        feature: self.name(),
                        row,
                        value,
                    });
                }
            }
            *e = if self.is_angle(row) {
                wrap_angle(s - s_star)
            } else {
                s - s_star
            };
        }
        Ok(())
    }
}

fn check_points<F: Feature + ?Sized>(
    feature: &F,
    obs: &Observation<'_>,
) -> Result<(), FeatureError> {
    if obs.len() < feature.min_points() {
        return Err(FeatureError::TooFewPoints {
            feature: feature.name(),
            needed: feature.min_points(),
            got: obs.len(),
        });
    }
    Ok(())
}

fn check_finite_value<F: Feature + ?Sized>(feature: &F, s: &[f64]) -> Result<(), FeatureError> {
    if crate::math::all_finite_slice(s) {
        Ok(())
    } else {
        Err(FeatureError::NonFiniteResult {
            feature: feature.name(),
        })
    }
}

fn check_finite_rows<F: Feature + ?Sized>(
    feature: &F,
    l: &InteractionRows<'_>,
) -> Result<(), FeatureError> {
    // Column by column on contiguous slices: nalgebra's entry iterator over a strided view is slow.
    if l.column_iter()
        .all(|column| crate::math::all_finite_slice(column.as_slice()))
    {
        Ok(())
    } else {
        Err(FeatureError::NonFiniteResult {
            feature: feature.name(),
        })
    }
}

fn check_dim<F: Feature + ?Sized>(feature: &F, got: usize) -> Result<(), FeatureError> {
    if got != feature.dim() {
        return Err(FeatureError::WrongDimension {
            feature: feature.name(),
            expected: feature.dim(),
            got,
        });
    }
    Ok(())
}

/// Checks that a feature parameter is finite and strictly positive.
fn positive_parameter(name: &'static str, value: f64) -> Result<f64, FeatureError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(FeatureError::InvalidParameter {
            name,
            value,
            expected: "finite and strictly positive",
        })
    }
}

/// Checks that a depth parameter (m) is within [`DEPTH_M`](crate::bounds::DEPTH_M).
fn depth_parameter(name: &'static str, value: f64) -> Result<f64, FeatureError> {
    let range = crate::bounds::DEPTH_M;
    if range.contains(value) {
        Ok(value)
    } else {
        Err(FeatureError::InvalidParameter {
            name,
            value,
            expected: range.text,
        })
    }
}

/// Writes `rows` into `l` (whose row count the checked caller has matched to `rows.len()`).
fn write_rows(mut l: InteractionRows<'_>, rows: &[InteractionRow]) {
    for (mut dst, src) in l.row_iter_mut().zip(rows) {
        dst.copy_from(src);
    }
}

/// Writes `values` into `s` (whose length the checked caller has matched to `values.len()`).
fn write_values(s: &mut [f64], values: &[f64]) {
    for (dst, src) in s.iter_mut().zip(values) {
        *dst = *src;
    }
}

/// Writes the values and the rows of `pairs` into `s` and `l` (sizes matched by the checked caller).
fn write_pairs(s: &mut [f64], mut l: InteractionRows<'_>, pairs: &[(f64, InteractionRow)]) {
    for ((dst, mut row), (value, src)) in s.iter_mut().zip(l.row_iter_mut()).zip(pairs) {
        *dst = *value;
        row.copy_from(src);
    }
}

#[cfg(test)]
mod tests {
    use super::testutil::*;
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    #[test]
    fn bad_observations_are_errors() {
        assert_eq!(
            Observation::new(&[], None).err(),
            Some(FeatureError::TooFewPoints {
                feature: "observation",
                needed: 1,
                got: 0
            })
        );
        let mut pts = rectangle_points_fronto(0.2, 0.1, 0.5);
        pts[1].y = f64::NAN;
        assert!(matches!(
            Observation::new(&pts, None),
            Err(FeatureError::NonFinitePoint { index: 1, .. })
        ));
        let mut pts = rectangle_points_fronto(0.2, 0.1, 0.5);
        pts[3].depth = f64::INFINITY;
        assert!(matches!(
            Observation::new(&pts, None),
            Err(FeatureError::NonFinitePoint { index: 3, .. })
        ));
        for depth in [0.0, -0.2] {
            let mut pts = rectangle_points_fronto(0.2, 0.1, 0.5);
            pts[2].depth = depth;
            assert_eq!(
                Observation::new(&pts, None).err(),
                Some(FeatureError::PointBehindCamera { index: 2, depth })
            );
        }
        let pts = rectangle_points_fronto(0.2, 0.1, 0.5);
        let nan_plane = TargetPlane {
            a: 0.0,
            b: f64::NAN,
            c: 2.0,
        };
        assert!(matches!(
            Observation::new(&pts, Some(&nan_plane)),
            Err(FeatureError::NonFinitePlane { .. })
        ));
        // A plane that passes through the camera's field of view behind it: 1/Z = 10 x + 1 is ≤ 0 at x = −0.2.
        let behind = TargetPlane {
            a: 10.0,
            b: 0.0,
            c: 1.0,
        };
        assert_eq!(
            Observation::new(&pts, Some(&behind)).err(),
            Some(FeatureError::PlaneBehindCamera {
                index: 0,
                inverse_depth: -1.0
            })
        );
    }

    /// Overflow inside a feature is reported, not returned as a non-finite value.
    #[test]
    fn overflow_is_an_error() {
        let pts = [
            ImagePoint::new(0.0, 0.0, 1.0),
            ImagePoint::new(1e70, 0.0, 1.0),
            ImagePoint::new(0.0, 1e70, 1.0),
        ];
        let obs = Observation::new(&pts, None).unwrap();
        let mut s = [0.0; 2];
        assert_eq!(
            VispInvariants.value(&obs, &mut s),
            Err(FeatureError::NonFiniteResult {
                feature: "ViSP P_x, P_y"
            })
        );
        let huge = [
            ImagePoint::new(1e155, 0.0, 1.0),
            ImagePoint::new(0.0, 0.0, 1.0),
        ];
        assert_eq!(
            Observation::new(&huge, None).unwrap().moments().err(),
            Some(FeatureError::NonFiniteResult { feature: "moments" })
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        /// With the true plane, inverse depths and moments agree with the per-point depths.
        #[test]
        fn plane_and_depths_agree(pose in tilted_pose_strategy()) {
            let (pts, plane) = Scene::new(pose, rectangle(0.2, 0.14)).image();
            let with_plane = Observation::new(&pts, Some(&plane)).unwrap();
            let with_depths = Observation::new(&pts, None).unwrap();
            for (k, p) in pts.iter().enumerate() {
                assert_relative_eq!(with_plane.inverse_depth(k).unwrap(), 1.0 / p.depth, max_relative = 1e-12);
            }
            prop_assert_eq!(with_plane.inverse_depth(4), None);
            let (a, b) = (with_plane.moments().unwrap(), with_depths.moments().unwrap());
            assert_relative_eq!(a.interaction_mu(2, 1).unwrap(), b.interaction_mu(2, 1).unwrap(), max_relative = 1e-10);
        }

        /// `value_and_interaction` gives, bit for bit, what `value` and `interaction` give apart (or the same error),
        /// for every feature, source and depth model, on tilted views and on views where some features degenerate
        /// (a square seen head-on: isotropic moments; points collapsed onto a segment).
        #[test]
        fn the_one_pass_evaluation_equals_the_two_calls(
            pose in tilted_pose_strategy(),
            plane in any::<bool>(),
            shape in 0usize..3,
        ) {
            let normalization = AreaNormalization::new(0.6, 0.04).unwrap();
            let features: Vec<BoxedFeature> = vec![
                Box::new(Centroid::new(0.7).unwrap()),
                Box::new(NormalizedCentroid::new(normalization)),
                Box::new(DiagonalAngle::default()),
                Box::new(DiagonalAngle::new(3, 1).unwrap()),
                Box::new(MomentOrientation),
                Box::new(CentredMoment::new(2, 1).unwrap()),
                Box::new(AreaNormalized::new(normalization)),
                Box::new(PaperInvariants::new(normalization)),
                Box::new(VispInvariants),
                Box::new(SideRatios),
                Box::new(Point::new(2)),
                Box::new(AllPoints::new(4).unwrap()),
                Box::new(FeatureSet::paper_full(Centroid::new(0.7).unwrap(), DiagonalAngle::default(), normalization)),
                Box::new(FeatureSet::visp_moments(normalization)),
            ];
            let object = match shape {
                0 => rectangle(0.2, 0.14),
                1 => rectangle(0.2, 0.2),
                _ => rectangle(0.2, 0.0),
            };
            // The square is seen head-on (turned about the optical axis only).
            let pose = if shape == 1 { testutil::pose(0.01, -0.02, 0.6, 0.0, 0.0, 0.3) } else { pose };
            let scene = Scene::new(pose, object);
            let (points, target_plane) = scene.image();
            let observation = Observation::new(&points, plane.then_some(&target_plane)).unwrap();
            for feature in &features {
                for source in [InteractionSource::Exact, InteractionSource::PaperApprox, InteractionSource::Desired] {
                    let rows = feature.dim();
                    let (mut s_apart, mut l_apart) = (vec![0.0; rows], crate::task::InteractionMatrix::zeros(rows));
                    let apart = feature
                        .value(&observation, &mut s_apart)
                        .and_then(|()| feature.interaction(&observation, source, l_apart.rows_mut(0, rows)));
                    let (mut s_once, mut l_once) = (vec![0.0; rows], crate::task::InteractionMatrix::zeros(rows));
                    let once = feature.value_and_interaction(&observation, source, &mut s_once, l_once.rows_mut(0, rows));
                    prop_assert_eq!(&once, &apart, "{} with {:?}", feature.name(), source);
                    if once.is_ok() {
                        prop_assert_eq!(&s_once, &s_apart, "{}", feature.name());
                        prop_assert_eq!(&l_once, &l_apart, "{} with {:?}", feature.name(), source);
                    }
                }
            }
        }

        /// Errors of angle rows land in (−π, π] and equal s − s* modulo 2π.
        #[test]
        fn angle_errors_are_wrapped(s in -10.0..10.0f64, s_star in -10.0..10.0f64) {
            let mut e = [0.0];
            DiagonalAngle::default().error(&[s], &[s_star], &mut e).unwrap();
            let pi = std::f64::consts::PI;
            prop_assert!(e[0] > -pi && e[0] <= pi);
            let turns = (s - s_star - e[0]) / (2.0 * pi);
            prop_assert!((turns - turns.round()).abs() < 1e-9);
        }
    }
}
