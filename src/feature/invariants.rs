//! Third-order features: the paper's `P_x, P_y` (task e4, \[M40\]–\[M41\], (F36), D9) and ViSP's invariants.

use super::moments::Orientation;
use super::{
    AreaNormalization, Feature, FeatureError, InteractionRow, InteractionSource, Moments,
    Observation,
};

/// Task e4 of the paper: `s = (P_x, P_y)` \[M40\] (F36), 2 rows (`ωx` against `υy`, `ωy` against `υx`):
///
/// ```text
/// c1 = μ20 − μ02,  s1 = 2μ11,  c2 = μ03 − 3μ21,  s2 = μ30 − 3μ12,  c3 = c1² − s1²,  s3 = 2 s1 c1
/// I1 = c1² + s1²,  I3 = μ20 + μ02,  K = I1 I3^{3/2}
/// P_x = a_n (c2 c3 + s2 s3) / K,   P_y = a_n (s2 c3 − c2 s3) / K
/// ```
///
/// Interaction: exact \[M41\] (chain rule from \[M35\]) for every [`InteractionSource`]. The paper takes this matrix
/// from Chaumette 2004, which is not available to us, so `PaperApprox` deliberately uses the exact form (the `a_n`
/// inside is evaluated exactly too). For `Desired`, pass the desired observation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperInvariants {
    normalization: AreaNormalization,
}

impl PaperInvariants {
    /// The features with the normalisation `(Z*, a*)` of their `a_n` factor.
    pub fn new(normalization: AreaNormalization) -> Self {
        Self { normalization }
    }

    /// `(P_x, L_{P_x})` and `(P_y, L_{P_y})` (exact whatever the source).
    fn evaluate(
        &self,
        obs: &Observation<'_>,
        _source: InteractionSource,
    ) -> Result<[(f64, InteractionRow); 2], FeatureError> {
        let m = obs.moments()?;
        let Orientation {
            c1,
            s1,
            i1,
            i3,
            l_c1,
            l_s1,
            l_i1,
            l_i3,
        } = m.orientation_terms()?;
        let (a_n, _) = self.normalization.evaluate(m)?;
        let (c2, s2, l_c2, l_s2) = m.third_order_terms();
        let c3 = c1 * c1 - s1 * s1;
        let s3 = 2.0 * s1 * c1;
        let k = i1 * i3 * i3.sqrt();
        let nx = c2 * c3 + s2 * s3;
        let ny = s2 * c3 - c2 * s3;
        let (px, py) = (a_n * nx / k, a_n * ny / k);
        // [M41]
        let l_c3 = l_c1 * (2.0 * c1) - l_s1 * (2.0 * s1);
        let l_s3 = (l_c1 * s1 + l_s1 * c1) * 2.0;
        let l_nx = l_c2 * c3 + l_c3 * c2 + l_s2 * s3 + l_s3 * s2;
        let l_ny = l_s2 * c3 + l_c3 * s2 - l_c2 * s3 - l_s3 * c2;
        let l_log = l_i1 / i1 + l_i3 * (2.0 / i3);
        Ok([
            (px, l_nx * (a_n / k) - l_log * px),
            (py, l_ny * (a_n / k) - l_log * py),
        ])
    }
}

impl Feature for PaperInvariants {
    fn name(&self) -> &'static str {
        "P_x, P_y"
    }
    fn dim(&self) -> usize {
        2
    }
    fn is_angle(&self, _row: usize) -> bool {
        false
    }
    fn min_points(&self) -> usize {
        2
    }
    writes_from_one_evaluation!(Self::evaluate);
}

/// ViSP's point-based invariants (`vpMomentCInvariant::Px()`, `Py()`, [peer scene variant B](crate::theory::peer_scene#variant-b), [theory §7.6](crate::theory#s7-6)):
/// `s = (P_x, P_y) = (I1/I3², a I2/I3³)` with `I1 = c1² + s1²`, `I2 = c2² + s2²` (\[M40\] notation),
/// `I3 = a = μ20 + μ02` (so `P_y = I2/I3²` for a point set).
///
/// Interaction, exact by the chain rule from \[M35\]: `L = L_X/I3² − 2 s L_{I3}/I3` for `X = I1` and `X = a I2/I3 = I2`,
/// with `L_{I1} = 2c1 L_{c1} + 2s1 L_{s1}` and `L_{I2} = 2c2 L_{c2} + 2s2 L_{s2}`. Defined for a square seen head-on
/// (`P_x = 0`); only coincident points (`a = 0`) are an error. `PaperApprox` is exact too.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct VispInvariants;

impl VispInvariants {
    /// `(P_x, L_{P_x})` and `(P_y, L_{P_y})` (exact whatever the source).
    fn evaluate(
        &self,
        obs: &Observation<'_>,
        _source: InteractionSource,
    ) -> Result<[(f64, InteractionRow); 2], FeatureError> {
        let m = obs.moments()?;
        Ok(Self::pairs(m, &m.second_order_terms()?))
    }

    /// `(P_x, L_{P_x})` and `(P_y, L_{P_y})` from the second-order terms `o` of `m` already at hand.
    pub(super) fn pairs(m: &Moments, o: &Orientation) -> [(f64, InteractionRow); 2] {
        let (c2, s2, l_c2, l_s2) = m.third_order_terms();
        let i2 = c2 * c2 + s2 * s2;
        let l_i2 = l_c2 * (2.0 * c2) + l_s2 * (2.0 * s2);
        let inv_i3_sq = 1.0 / (o.i3 * o.i3);
        let ratio = |x: f64, l_x: InteractionRow| {
            let value = x * inv_i3_sq;
            (value, l_x * inv_i3_sq - o.l_i3 * (2.0 * value / o.i3))
        };
        [ratio(o.i1, o.l_i1), ratio(i2, l_i2)]
    }
}

impl Feature for VispInvariants {
    fn name(&self) -> &'static str {
        "ViSP P_x, P_y"
    }
    fn dim(&self) -> usize {
        2
    }
    fn is_angle(&self, _row: usize) -> bool {
        false
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

    fn norm() -> AreaNormalization {
        AreaNormalization::new(0.8, 0.05).unwrap()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn paper_invariants_match_camera_motion(pose in tilted_pose_strategy(), plane in any::<bool>()) {
            let f = PaperInvariants::new(norm());
            let scene = Scene::new(pose, rectangle(0.2, 0.14));
            scene.check_exact(&f, plane);
            // Documented choice: PaperApprox uses the exact form.
            assert_close(&scene.interaction(&f, InteractionSource::PaperApprox, plane),
                         &scene.interaction(&f, InteractionSource::Exact, plane), 0.0);
        }

        #[test]
        fn visp_invariants_match_camera_motion(pose in tilted_pose_strategy(), plane in any::<bool>()) {
            Scene::new(pose, rectangle(0.2, 0.1)).check_exact(&VispInvariants, plane);
        }
    }

    /// Centred fronto-parallel rectangle: third-order moments vanish, so the paper's `P_x = P_y = 0` and ViSP's
    /// `P_y = 0`, while ViSP's `P_x = I1/I3² = ((w² − h²)/(w² + h²))²` (μ11 = 0).
    #[test]
    fn hand_computed_symmetric_rectangle() {
        let (w, h) = (0.2, 0.1);
        let pts = rectangle_points_fronto(w, h, 0.5);
        let obs = Observation::new(&pts, None).unwrap();
        let mut s = [0.0; 2];
        PaperInvariants::new(norm()).value(&obs, &mut s).unwrap();
        assert_relative_eq!(s[0], 0.0, epsilon = 1e-13);
        assert_relative_eq!(s[1], 0.0, epsilon = 1e-13);
        VispInvariants.value(&obs, &mut s).unwrap();
        let expected = ((w * w - h * h) / (w * w + h * h)).powi(2);
        assert_relative_eq!(s[0], expected, epsilon = 1e-15);
        assert_relative_eq!(s[1], 0.0, epsilon = 1e-15);
    }

    /// A hand-computed asymmetric case: points (0,0), (1,0), (0,1) at unit depth, Z* = 1, a* = a.
    /// x_g = y_g = 1/3; μ20 = μ02 = 2/3, μ11 = −1/3, μ30 = μ03 = 2/9, μ21 = μ12 = −1/9;
    /// c1 = 0, s1 = −2/3, c2 = s2 = 5/9, c3 = −4/9, s3 = 0, I1 = 4/9, I3 = 4/3, a_n = 1,
    /// K = (4/9)(4/3)^{3/2}: P_x = P_y = (−20/81)/K; ViSP P_x = (4/9)/(16/9) = 1/4, P_y = (50/81)/(16/9) = 25/72.
    #[test]
    fn hand_computed_triangle() {
        let pts = [
            ImagePoint::new(0.0, 0.0, 1.0),
            ImagePoint::new(1.0, 0.0, 1.0),
            ImagePoint::new(0.0, 1.0, 1.0),
        ];
        let obs = Observation::new(&pts, None).unwrap();
        let m = obs.moments().unwrap();
        assert_relative_eq!(m.mu(2, 0).unwrap(), 2.0 / 3.0, epsilon = 1e-15);
        assert_relative_eq!(m.mu(1, 1).unwrap(), -1.0 / 3.0, epsilon = 1e-15);
        assert_relative_eq!(m.mu(3, 0).unwrap(), 2.0 / 9.0, epsilon = 1e-15);
        assert_relative_eq!(m.mu(2, 1).unwrap(), -1.0 / 9.0, epsilon = 1e-15);
        let f = PaperInvariants::new(AreaNormalization::new(1.0, 4.0 / 3.0).unwrap());
        let mut s = [0.0; 2];
        f.value(&obs, &mut s).unwrap();
        let k = 4.0 / 9.0 * (4.0f64 / 3.0).powf(1.5);
        assert_relative_eq!(s[0], -20.0 / 81.0 / k, epsilon = 1e-14);
        assert_relative_eq!(s[1], -20.0 / 81.0 / k, epsilon = 1e-14);
        VispInvariants.value(&obs, &mut s).unwrap();
        assert_relative_eq!(s[0], 0.25, epsilon = 1e-15);
        assert_relative_eq!(s[1], 25.0 / 72.0, epsilon = 1e-14);
    }

    /// D9: a square seen head-on has I1 = 0: the paper's P_x, P_y are an error; ViSP's are defined (P_x = 0).
    #[test]
    fn square_head_on_is_an_error() {
        let pts = rectangle_points_fronto(0.1, 0.1, 0.5);
        let obs = Observation::new(&pts, None).unwrap();
        let mut s = [0.0; 2];
        let mut l = Rows::zeros(2);
        let f = PaperInvariants::new(norm());
        assert!(
            matches!(f.value(&obs, &mut s), Err(FeatureError::IsotropicMoments { i1, .. }) if i1 < 1e-30)
        );
        assert!(matches!(
            f.interaction(&obs, InteractionSource::Exact, l.rows_mut(0, 2)),
            Err(FeatureError::IsotropicMoments { .. })
        ));
        VispInvariants.value(&obs, &mut s).unwrap();
        assert_relative_eq!(s[0], 0.0, epsilon = 1e-15);
        // A nearly square rectangle (1e−3 relative side difference) is still accepted.
        let pts = rectangle_points_fronto(0.1, 0.1001, 0.5);
        f.value(&Observation::new(&pts, None).unwrap(), &mut s)
            .unwrap();
        // Coincident points: a = 0 is reported first.
        let same = [ImagePoint::new(0.1, 0.1, 1.0); 3];
        let obs = Observation::new(&same, None).unwrap();
        assert!(matches!(
            f.value(&obs, &mut s),
            Err(FeatureError::DegenerateArea { .. })
        ));
        assert!(matches!(
            VispInvariants.value(&obs, &mut s),
            Err(FeatureError::DegenerateArea { .. })
        ));
    }
}
