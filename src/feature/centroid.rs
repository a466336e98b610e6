//! Centroid features: the paper's task e1 (\[M30\]–\[M31\], (F30)–(F31)) and ViSP's normalised centroid.

use super::{
    depth_parameter, point_interaction, AreaNormalization, Feature, FeatureError, InteractionRow,
    InteractionRows, InteractionSource, Moments, Observation,
};

/// Task e1 of the paper: the centroid `s = (x_g, y_g)` of the image points, \[M30\] (F30).
///
/// Interaction matrix:
/// * [`InteractionSource::Exact`] / `Desired`: `L_{x_g} = (1/N) Σ L_{x_k}`, `L_{y_g} = (1/N) Σ L_{y_k}` (\[M29\]; with
///   the plane model this is \[M31\], ViSP `vpFeatureMomentGravityCenter`).
/// * [`InteractionSource::PaperApprox`]: (F31), the rows \[M28\] of a single point at `(x_g, y_g)` with the a priori
///   depth `Z_g`. Even for a fronto-parallel target at `Z_g` this differs from the exact rows in `ωx`, `ωy` by the
///   normalised moments `n11 = μ11/N`, `n20 = μ20/N`, `n02 = μ02/N` (\[M31\]); the `υ` part is then exact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Centroid {
    z_g: f64,
}

impl Centroid {
    /// The centroid feature with the a priori depth `Z_g` (m) used by [`InteractionSource::PaperApprox`].
    ///
    /// # Errors
    /// [`FeatureError::InvalidParameter`] unless `Z_g` is within [`DEPTH_M`](crate::bounds::DEPTH_M).
    pub fn new(a_priori_depth: f64) -> Result<Self, FeatureError> {
        Ok(Self {
            z_g: depth_parameter("Z_g", a_priori_depth)?,
        })
    }

    /// The a priori depth `Z_g` (m) of (F31).
    pub fn a_priori_depth(&self) -> f64 {
        self.z_g
    }
}

impl Feature for Centroid {
    fn name(&self) -> &'static str {
        "centroid"
    }
    fn dim(&self) -> usize {
        2
    }
    fn is_angle(&self, _row: usize) -> bool {
        false
    }
    fn min_points(&self) -> usize {
        1
    }
    fn write_value(&self, obs: &Observation<'_>, s: &mut [f64]) -> Result<(), FeatureError> {
        let m = obs.moments()?;
        super::write_values(s, &[m.xg(), m.yg()]);
        Ok(())
    }
    fn write_interaction(
        &self,
        obs: &Observation<'_>,
        source: InteractionSource,
        l: InteractionRows<'_>,
    ) -> Result<(), FeatureError> {
        let m = obs.moments()?;
        let (lx, ly) = match source {
            InteractionSource::PaperApprox => point_interaction(m.xg(), m.yg(), 1.0 / self.z_g),
            InteractionSource::Exact | InteractionSource::Desired => {
                (*m.interaction_xg(), *m.interaction_yg())
            }
        };
        super::write_rows(l, &[lx, ly]);
        Ok(())
    }
}

/// ViSP's normalised centroid ([peer scene variant B](crate::theory::peer_scene#variant-b), `vpFeatureMomentCentered`-based `x_n, y_n`):
/// `s = (x_n, y_n) = (a_n x_g, a_n y_g)` with `a_n = Z* sqrt(a*/a)` \[M37\].
///
/// Interaction: exact product rule `L_{x_n} = a_n L_{x_g} + x_g L_{a_n}` (likewise y) with the exact rows of
/// [`super::Moments`] and [`AreaNormalization`]. The paper has no approximate form: `PaperApprox` is exact too.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalizedCentroid {
    normalization: AreaNormalization,
}

impl NormalizedCentroid {
    /// The normalised centroid with the area normalisation `(Z*, a*)`.
    pub fn new(normalization: AreaNormalization) -> Self {
        Self { normalization }
    }

    /// `(x_n, L_{x_n})` and `(y_n, L_{y_n})` (exact whatever the source).
    fn evaluate(
        &self,
        obs: &Observation<'_>,
        _source: InteractionSource,
    ) -> Result<[(f64, InteractionRow); 2], FeatureError> {
        let m = obs.moments()?;
        let (a_n, l_an) = self.normalization.evaluate(m)?;
        Ok(Self::pairs(m, a_n, &l_an))
    }

    /// `(x_n, L_{x_n})` and `(y_n, L_{y_n})` from `a_n` and `L_{a_n}` already at hand.
    pub(super) fn pairs(
        m: &Moments,
        a_n: f64,
        l_an: &InteractionRow,
    ) -> [(f64, InteractionRow); 2] {
        [
            (a_n * m.xg(), m.interaction_xg() * a_n + l_an * m.xg()),
            (a_n * m.yg(), m.interaction_yg() * a_n + l_an * m.yg()),
        ]
    }
}

impl Feature for NormalizedCentroid {
    fn name(&self) -> &'static str {
        "normalised centroid"
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

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn centroid_exact_matches_camera_motion(pose in tilted_pose_strategy(), plane in any::<bool>()) {
            Scene::new(pose, rectangle(0.2, 0.14)).check_exact(&Centroid::new(0.8).unwrap(), plane);
        }

        #[test]
        fn normalized_centroid_matches_camera_motion(pose in tilted_pose_strategy(), plane in any::<bool>()) {
            let norm = AreaNormalization::new(0.5, 0.1).unwrap();
            let f = NormalizedCentroid::new(norm);
            let scene = Scene::new(pose, rectangle(0.2, 0.1));
            scene.check_exact(&f, plane);
            // PaperApprox is documented as exact for this feature.
            assert_close(&scene.interaction(&f, InteractionSource::PaperApprox, plane),
                         &scene.interaction(&f, InteractionSource::Exact, plane), 1e-15);
        }

        /// The exact rows equal the closed form \[M31\] with the plane model (ViSP's gravity-centre feature).
        #[test]
        fn centroid_matches_closed_form_m31(pose in tilted_pose_strategy()) {
            let scene = Scene::new(pose, rectangle(0.2, 0.14));
            let (pts, plane) = scene.image();
            let obs = Observation::new(&pts, None).unwrap();
            let m = obs.moments().unwrap();
            let n = pts.len() as f64;
            let (xg, yg) = (m.xg(), m.yg());
            let (n20, n11, n02) = (m.mu(2, 0).unwrap() / n, m.mu(1, 1).unwrap() / n, m.mu(0, 2).unwrap() / n);
            let (a, b) = (plane.a, plane.b);
            let zbar = plane.inverse_depth(xg, yg);
            let mut m31 = Rows::zeros(2);
            m31.row_mut(0).copy_from_slice(&[-zbar, 0.0, xg * zbar + a * n20 + b * n11, xg * yg + n11,
                                             -(1.0 + xg * xg + n20), yg]);
            m31.row_mut(1).copy_from_slice(&[0.0, -zbar, yg * zbar + a * n11 + b * n02, 1.0 + yg * yg + n02,
                                             -(xg * yg + n11), -xg]);
            assert_close(&scene.interaction(&Centroid::new(0.8).unwrap(), InteractionSource::Exact, false),
                         &m31, 1e-12);
        }

        /// (F31) is not exact on a tilted target: the υ part differs from the exact rows.
        #[test]
        fn centroid_approx_differs_when_tilted(pose in tilted_pose_strategy()) {
            let scene = Scene::new(pose, rectangle(0.2, 0.14));
            let f = Centroid::new(pose.translation.z).unwrap();
            let exact = scene.interaction(&f, InteractionSource::Exact, true);
            let approx = scene.interaction(&f, InteractionSource::PaperApprox, true);
            prop_assert!((exact.columns(0, 3) - approx.columns(0, 3)).amax() > 1e-4);
        }
    }

    /// Fronto-parallel target at `Z_g`: (F31) equals the exact υ part; the ω part differs by exactly
    /// `n11`, `n20`, `n02` (\[M31\] with A = B = 0).
    #[test]
    fn centroid_approx_on_fronto_parallel_target() {
        let z = 0.7;
        let scene = Scene::new(pose(0.05, -0.03, z, 0.0, 0.0, 0.4), rectangle(0.2, 0.14));
        let f = Centroid::new(z).unwrap();
        let exact = scene.interaction(&f, InteractionSource::Exact, false);
        let approx = scene.interaction(&f, InteractionSource::PaperApprox, false);
        assert_relative_eq!(
            exact.columns(0, 3).into_owned(),
            approx.columns(0, 3).into_owned(),
            epsilon = 1e-14
        );
        let (pts, _) = scene.image();
        let m = *Observation::new(&pts, None).unwrap().moments().unwrap();
        let n = 4.0;
        let (n20, n11, n02) = (
            m.mu(2, 0).unwrap() / n,
            m.mu(1, 1).unwrap() / n,
            m.mu(0, 2).unwrap() / n,
        );
        assert!(n11.abs() > 1e-4, "rotated rectangle: μ11 ≠ 0");
        let diff = exact - approx;
        assert_relative_eq!(diff[(0, 3)], n11, epsilon = 1e-14);
        assert_relative_eq!(diff[(0, 4)], -n20, epsilon = 1e-14);
        assert_relative_eq!(diff[(1, 3)], n02, epsilon = 1e-14);
        assert_relative_eq!(diff[(1, 4)], -n11, epsilon = 1e-14);
        assert_relative_eq!(diff[(0, 5)], 0.0, epsilon = 1e-14);
        assert_relative_eq!(diff[(1, 5)], 0.0, epsilon = 1e-14);
    }

    #[test]
    fn hand_computed_centroid() {
        let pts = [
            ImagePoint::new(0.1, 0.2, 1.0),
            ImagePoint::new(0.3, -0.2, 2.0),
            ImagePoint::new(-0.1, 0.3, 1.0),
        ];
        let obs = Observation::new(&pts, None).unwrap();
        let mut s = [0.0; 2];
        Centroid::new(1.0).unwrap().value(&obs, &mut s).unwrap();
        assert_relative_eq!(s[0], 0.1, epsilon = 1e-15);
        assert_relative_eq!(s[1], 0.1, epsilon = 1e-15);
    }

    #[test]
    fn bad_a_priori_depth() {
        for z in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                Centroid::new(z),
                Err(FeatureError::InvalidParameter { name: "Z_g", .. })
            ));
        }
    }
}
