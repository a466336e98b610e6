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
//!
//! [`ImagePoint`]: crate::camera::ImagePoint
//! [`TargetPlane`]: crate::target::TargetPlane

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
mod error;
mod invariants;
mod moments;
mod observation;
mod point;
mod set;
mod sides;
#[cfg(test)]
mod tests;
#[cfg(test)]
pub(crate) mod testutil;

pub use angle::{DiagonalAngle, MomentOrientation};
pub use area::{AreaNormalization, AreaNormalized, CentredMoment};
pub use centroid::{Centroid, NormalizedCentroid};
pub use error::FeatureError;
pub use invariants::{PaperInvariants, VispInvariants};
pub use moments::Moments;
pub use observation::Observation;
pub use point::{point_interaction, AllPoints, Point};
pub use set::{BoxedFeature, FeatureSet, VispMoments};
pub use sides::SideRatios;

use crate::math::wrap_angle;
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
