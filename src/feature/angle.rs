//! Angle features: the paper's diagonal angle (task e2, \[M32\]–\[M33\], (F32), D8) and ViSP's moment orientation.

use super::moments::Orientation;
use super::{
    Feature, FeatureError, InteractionRow, InteractionSource, Observation, RELATIVE_TOLERANCE,
};

/// Task e2 of the paper: the angle of the directed image segment from point `from` to point `to` (one diagonal of
/// the rectangle), `s = α = atan2(y_b − y_a, x_b − x_a)` in `(−π, π]` (rad), 1 row, mostly `ωz`.
/// Default: the diagonal from point 0 to point 2 (D8). The error is wrapped into `(−π, π]`.
///
/// With `l` the segment length, `(x_c, y_c)` its midpoint, `ζ = 1/Z` of its end points and
/// `k_α = y_c cos α − x_c sin α`:
/// * [`InteractionSource::Exact`] / `Desired`: \[M32\]
///   `[(ζ_b−ζ_a) sin α/l, −(ζ_b−ζ_a) cos α/l, (ζ_b−ζ_a) k_α/l, sin α k_α, −cos α k_α, −1]`.
/// * [`InteractionSource::PaperApprox`]: \[M33\] (F32), the same with `ζ_a = ζ_b` (segment parallel to the image
///   plane): zero `υ` part, identical `ω` part.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DiagonalAngle {
    from: usize,
    to: usize,
}

impl Default for DiagonalAngle {
    /// The diagonal from point 0 to point 2 (D8).
    fn default() -> Self {
        Self { from: 0, to: 2 }
    }
}

impl DiagonalAngle {
    /// The segment from point `from` to point `to` (0-based indices).
    ///
    /// # Errors
    /// [`FeatureError::SameEndPoints`] when `from == to`.
    pub fn new(from: usize, to: usize) -> Result<Self, FeatureError> {
        if from == to {
            return Err(FeatureError::SameEndPoints { from, to });
        }
        Ok(Self { from, to })
    }

    /// The end points `(a, b)` of the segment.
    pub fn end_points(&self) -> (usize, usize) {
        (self.from, self.to)
    }

    /// `α` and its interaction row in the form `source` asks for (the struct's documentation), with
    /// `sin α = Δy/l`, `cos α = Δx/l` read off the segment.
    fn evaluate(
        &self,
        obs: &Observation<'_>,
        source: InteractionSource,
    ) -> Result<[(f64, InteractionRow); 1], FeatureError> {
        let too_few = || FeatureError::TooFewPoints {
            feature: self.name(),
            needed: self.min_points(),
            got: obs.len(),
        };
        let a = obs.points().get(self.from).ok_or_else(too_few)?;
        let b = obs.points().get(self.to).ok_or_else(too_few)?;
        let (dx, dy) = (b.x - a.x, b.y - a.y);
        // `hypot` (slow, overflow-safe) only where the plain sum of squares leaves the normal range.
        let squared = dx * dx + dy * dy;
        let length = if squared.is_normal() {
            squared.sqrt()
        } else {
            dx.hypot(dy)
        };
        let magnitude = a.x.abs() + a.y.abs() + b.x.abs() + b.y.abs();
        if length == 0.0 || length <= RELATIVE_TOLERANCE * magnitude {
            return Err(FeatureError::DegenerateSegment {
                from: self.from,
                to: self.to,
                length,
            });
        }
        let (sin, cos) = (dy / length, dx / length);
        let (xc, yc) = (0.5 * (a.x + b.x), 0.5 * (a.y + b.y));
        let k = yc * cos - xc * sin;
        let dz = match source {
            InteractionSource::PaperApprox => 0.0,
            InteractionSource::Exact | InteractionSource::Desired => {
                let zeta = |k| obs.inverse_depth(k).ok_or_else(too_few);
                (zeta(self.to)? - zeta(self.from)?) / length
            }
        };
        Ok([(
            dy.atan2(dx),
            InteractionRow::new(dz * sin, -dz * cos, dz * k, sin * k, -cos * k, -1.0),
        )])
    }
}

impl Feature for DiagonalAngle {
    fn name(&self) -> &'static str {
        "diagonal angle"
    }
    fn dim(&self) -> usize {
        1
    }
    fn is_angle(&self, _row: usize) -> bool {
        true
    }
    fn min_points(&self) -> usize {
        self.from.max(self.to).saturating_add(1)
    }
    writes_from_one_evaluation!(Self::evaluate);
}

/// ViSP's moment orientation ([peer scene variant B](crate::theory::peer_scene#variant-b)): `s = α = ½ atan2(2 μ11, μ20 − μ02)` (rad, in `(−π/2, π/2]`),
/// 1 row, with the centred moments \[M34\].
///
/// Interaction, exact by the chain rule from \[M35\]: with `c1 = μ20 − μ02`, `s1 = 2μ11`, `I1 = c1² + s1²`,
/// `L_α = (c1 L_{s1} − s1 L_{c1}) / (2 I1)`. The paper has no approximate form: `PaperApprox` is exact too.
/// The orientation is defined modulo π: `α` jumps by π when `μ11` changes sign with `μ20 < μ02`. As in ViSP, the
/// error is wrapped into `(−π, π]` only, so keep the target's main axis away from the image's y axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MomentOrientation;

impl MomentOrientation {
    /// `(α, L_α)` (exact whatever the source).
    fn evaluate(
        &self,
        obs: &Observation<'_>,
        _source: InteractionSource,
    ) -> Result<[(f64, InteractionRow); 1], FeatureError> {
        Ok([Self::pair(&obs.moments()?.orientation_terms()?)])
    }

    /// `(α, L_α)` from the second-order terms `o` already checked anisotropic ([`Orientation::anisotropic`]).
    pub(super) fn pair(o: &Orientation) -> (f64, InteractionRow) {
        (
            0.5 * o.s1.atan2(o.c1),
            (o.l_s1 * o.c1 - o.l_c1 * o.s1) / (2.0 * o.i1),
        )
    }
}

impl Feature for MomentOrientation {
    fn name(&self) -> &'static str {
        "moment orientation"
    }
    fn dim(&self) -> usize {
        1
    }
    fn is_angle(&self, _row: usize) -> bool {
        true
    }
    fn min_points(&self) -> usize {
        2
    }
    writes_from_one_evaluation!(Self::evaluate);
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::*;
    use crate::camera::ImagePoint;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn diagonal_angle_matches_camera_motion(pose in tilted_pose_strategy(), plane in any::<bool>(),
                                                diag in 0usize..4) {
            let f = [DiagonalAngle::default(), DiagonalAngle::new(1, 3).unwrap(), DiagonalAngle::new(2, 0).unwrap(),
                     DiagonalAngle::new(0, 1).unwrap()][diag];
            let scene = Scene::new(pose, rectangle(0.2, 0.14));
            scene.check_exact(&f, plane);
            // [M33]: the ω part is exact, the υ part is zero.
            let exact = scene.interaction(&f, InteractionSource::Exact, plane);
            let approx = scene.interaction(&f, InteractionSource::PaperApprox, plane);
            assert_close(&approx.columns(3, 3), &exact.columns(3, 3), 1e-14);
            prop_assert!(approx.columns(0, 3).amax() == 0.0);
        }

        /// Yaw restricted so that `2α` stays away from ±π, where the orientation jumps by π.
        #[test]
        fn moment_orientation_matches_camera_motion(pose in tilted_pose_strategy_yaw(-1.0..1.0),
                                                    plane in any::<bool>()) {
            Scene::new(pose, rectangle(0.2, 0.1)).check_exact(&MomentOrientation, plane);
        }
    }

    /// Tilted about the y axis, the end points of the diagonal are at different depths: \[M33\] misses the υ part.
    #[test]
    fn diagonal_approx_differs_when_tilted() {
        let scene = Scene::new(pose(0.05, 0.02, 0.7, 0.0, 0.4, 0.0), rectangle(0.2, 0.14));
        let f = DiagonalAngle::default();
        let exact = scene.interaction(&f, InteractionSource::Exact, false);
        assert!(exact.columns(0, 3).amax() > 1e-2);
        let approx = scene.interaction(&f, InteractionSource::PaperApprox, false);
        assert_eq!(approx.columns(0, 3).amax(), 0.0);
    }

    /// Fronto-parallel segment (`ζ_a = ζ_b`): \[M33\] equals \[M32\].
    #[test]
    fn diagonal_approx_is_exact_fronto_parallel() {
        let scene = Scene::new(pose(0.05, 0.02, 0.7, 0.0, 0.0, 0.6), rectangle(0.2, 0.14));
        let f = DiagonalAngle::default();
        assert_close(
            &scene.interaction(&f, InteractionSource::PaperApprox, false),
            &scene.interaction(&f, InteractionSource::Exact, false),
            1e-14,
        );
    }

    /// Centred fronto-parallel `w × h` rectangle: the diagonal 0 → 2 goes from (−w/2, −h/2) to (w/2, h/2), so
    /// `α = atan2(h, w)`; the reverse diagonal gives `α − π`, and the error between them wraps to π. ViSP's
    /// orientation of a rectangle wider than tall is 0.
    #[test]
    fn hand_computed_angles() {
        let (w, h) = (0.2, 0.1);
        let pts = rectangle_points_fronto(w, h, 0.5);
        let obs = Observation::new(&pts, None).unwrap();
        let (mut s, mut s_rev, mut e) = ([0.0], [0.0], [0.0]);
        DiagonalAngle::default().value(&obs, &mut s).unwrap();
        assert_relative_eq!(s[0], h.atan2(w), epsilon = 1e-15);
        DiagonalAngle::new(2, 0)
            .unwrap()
            .value(&obs, &mut s_rev)
            .unwrap();
        assert_relative_eq!(s_rev[0], h.atan2(w) - std::f64::consts::PI, epsilon = 1e-15);
        DiagonalAngle::default().error(&s, &s_rev, &mut e).unwrap();
        assert_relative_eq!(e[0], std::f64::consts::PI, epsilon = 1e-12);
        MomentOrientation.value(&obs, &mut s).unwrap();
        assert_eq!(s[0], 0.0);
        // Turned by 0.3 rad in the image plane: both angles turn by 0.3.
        let (c, sn) = (0.3f64.cos(), 0.3f64.sin());
        let turned = pts.map(|p| ImagePoint::new(c * p.x - sn * p.y, sn * p.x + c * p.y, p.depth));
        let obs = Observation::new(&turned, None).unwrap();
        MomentOrientation.value(&obs, &mut s).unwrap();
        assert_relative_eq!(s[0], 0.3, epsilon = 1e-14);
        DiagonalAngle::default().value(&obs, &mut s).unwrap();
        assert_relative_eq!(s[0], h.atan2(w) + 0.3, epsilon = 1e-14);
    }

    #[test]
    fn extreme_segment_lengths_keep_the_exact_row() {
        // The segment's length leaves the range of a plain sum of squares (it overflows at 1e200 and underflows at
        // 1e-170): the row must still be the formula's, sin α and cos α taken from atan2 here.
        for scale in [1.0, 1e200, 1e-170] {
            let (xa, ya, xb, yb) = (0.3 * scale, -0.1 * scale, -0.2 * scale, 0.4 * scale);
            let mut pts = rectangle_points_fronto(0.2, 0.1, 0.5);
            pts[0] = ImagePoint::new(xa, ya, 0.5);
            pts[2] = ImagePoint::new(xb, yb, 0.5);
            let obs = Observation::new(&pts, None).unwrap();
            let mut l = crate::task::InteractionMatrix::zeros(1);
            DiagonalAngle::default()
                .interaction(&obs, InteractionSource::PaperApprox, l.rows_mut(0, 1))
                .unwrap();
            let (sin, cos) = (yb - ya).atan2(xb - xa).sin_cos();
            let k = 0.5 * (ya + yb) * cos - 0.5 * (xa + xb) * sin;
            assert_relative_eq!(l[(0, 3)], sin * k, max_relative = 1e-14);
            assert_relative_eq!(l[(0, 4)], -cos * k, max_relative = 1e-14);
        }
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        assert_eq!(
            DiagonalAngle::new(1, 1),
            Err(FeatureError::SameEndPoints { from: 1, to: 1 })
        );
        let mut pts = rectangle_points_fronto(0.2, 0.1, 0.5);
        pts[2] = pts[0];
        let obs = Observation::new(&pts, None).unwrap();
        let mut s = [0.0];
        assert_eq!(
            DiagonalAngle::default().value(&obs, &mut s),
            Err(FeatureError::DegenerateSegment {
                from: 0,
                to: 2,
                length: 0.0
            })
        );
        let obs2 = Observation::new(&pts[..2], None).unwrap();
        assert_eq!(
            DiagonalAngle::default().value(&obs2, &mut s),
            Err(FeatureError::TooFewPoints {
                feature: "diagonal angle",
                needed: 3,
                got: 2
            })
        );
        // A square seen head-on has isotropic moments: no orientation (D9).
        let square = rectangle_points_fronto(0.1, 0.1, 0.5);
        let obs = Observation::new(&square, None).unwrap();
        assert!(matches!(
            MomentOrientation.value(&obs, &mut s),
            Err(FeatureError::IsotropicMoments { .. })
        ));
    }
}
