//! Centred moments (\[M34\]–\[M35\], (F33)) and the normalised area `a_n` (\[M37\]–\[M39\], (F34)–(F35)).

use super::{
    depth_parameter, positive_parameter, Feature, FeatureError, InteractionRow, InteractionRows,
    InteractionSource, Moments, Observation,
};

/// One centred moment `s = μ_ij` (\[M34\], no `1/N` factor), `i + j ≤ 3`, with its exact row \[M35\].
/// The paper has no approximate form: every [`InteractionSource`] uses \[M35\].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CentredMoment {
    i: usize,
    j: usize,
}

impl CentredMoment {
    /// The moment `μ_ij` (powers `i` of `x − x_g`, `j` of `y − y_g`).
    ///
    /// # Errors
    /// [`FeatureError::UnsupportedMomentOrder`] when `i + j > 3`.
    pub fn new(i: usize, j: usize) -> Result<Self, FeatureError> {
        if i + j > 3 {
            return Err(FeatureError::UnsupportedMomentOrder { i, j });
        }
        Ok(Self { i, j })
    }

    fn get(&self, m: &Moments) -> Result<(f64, InteractionRow), FeatureError> {
        let unsupported = FeatureError::UnsupportedMomentOrder {
            i: self.i,
            j: self.j,
        };
        Ok((
            m.mu(self.i, self.j).ok_or(unsupported.clone())?,
            *m.interaction_mu(self.i, self.j).ok_or(unsupported)?,
        ))
    }
}

impl Feature for CentredMoment {
    fn name(&self) -> &'static str {
        "centred moment"
    }
    fn dim(&self) -> usize {
        1
    }
    fn is_angle(&self, _row: usize) -> bool {
        false
    }
    fn min_points(&self) -> usize {
        1
    }
    fn write_value(&self, obs: &Observation<'_>, s: &mut [f64]) -> Result<(), FeatureError> {
        let (mu, _) = self.get(obs.moments()?)?;
        super::write_values(s, &[mu]);
        Ok(())
    }
    fn write_interaction(
        &self,
        obs: &Observation<'_>,
        _source: InteractionSource,
        l: InteractionRows<'_>,
    ) -> Result<(), FeatureError> {
        let (_, row) = self.get(obs.moments()?)?;
        super::write_rows(l, &[row]);
        Ok(())
    }
}

/// The normalisation of the second-order size: `a_n = Z* sqrt(a*/a)`, `a = μ20 + μ02` \[M37\] (F34), with the desired
/// depth `Z*` (m) and the desired size `a*` (value of `a` in the desired image). Shared by [`AreaNormalized`],
/// [`super::PaperInvariants`] and [`super::NormalizedCentroid`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AreaNormalization {
    z_star: f64,
    a_star: f64,
}

impl AreaNormalization {
    /// From the desired depth `Z*` (m) and desired size `a*` (`μ20 + μ02` of the desired image, no `1/N`).
    ///
    /// # Errors
    /// [`FeatureError::InvalidParameter`] unless `Z*` is within [`DEPTH_M`](crate::bounds::DEPTH_M) and `a*` is
    /// finite and `> 0`.
    pub fn new(z_star: f64, a_star: f64) -> Result<Self, FeatureError> {
        Ok(Self {
            z_star: depth_parameter("Z*", z_star)?,
            a_star: positive_parameter("a*", a_star)?,
        })
    }

    /// From the desired observation (its `a*`) and the desired depth `Z*` (m).
    ///
    /// # Errors
    /// [`FeatureError::DegenerateArea`] when the desired points coincide; [`FeatureError::InvalidParameter`] for `Z*`.
    pub fn from_desired(desired: &Observation<'_>, z_star: f64) -> Result<Self, FeatureError> {
        let (a_star, _) = desired.moments()?.size()?;
        Self::new(z_star, a_star)
    }

    /// Desired depth `Z*` (m).
    pub fn z_star(&self) -> f64 {
        self.z_star
    }

    /// Desired size `a*`.
    pub fn a_star(&self) -> f64 {
        self.a_star
    }

    /// `a_n` \[M37\] and its exact row `L_{a_n} = −(a_n / (2a)) (L_{μ20} + L_{μ02})` (from \[M35\]).
    ///
    /// # Errors
    /// [`FeatureError::DegenerateArea`] when `a` vanishes.
    pub fn evaluate(&self, m: &Moments) -> Result<(f64, InteractionRow), FeatureError> {
        let (a, l_a) = m.size()?;
        Ok(self.of_size(a, &l_a))
    }

    /// `a_n` and `L_{a_n}` as [`Self::evaluate`], from the size `a > 0` and its row `L_a` already at hand.
    pub(super) fn of_size(&self, a: f64, l_a: &InteractionRow) -> (f64, InteractionRow) {
        let a_n = self.z_star * (self.a_star / a).sqrt();
        (a_n, l_a * (-a_n / (2.0 * a)))
    }
}

/// Task e3 of the paper: the normalised area `s = a_n = Z* sqrt(a*/a)` \[M37\] (F34), 1 row (mostly `υz`).
///
/// Interaction:
/// * [`InteractionSource::Exact`] / `Desired`: `L_{a_n} = −(a_n/(2a)) (L_{μ20} + L_{μ02})` by the chain rule from
///   \[M35\] (equal to the plane closed form \[M38\], checked in the tests).
/// * [`InteractionSource::PaperApprox`]: (F35) \[M39\], `[0, 0, −1, −a_n ε1, a_n ε2, 0]` with
///   `ε1 = y_g + (y_g μ02 + x_g μ11 + μ21 + μ03)/a`, `ε2 = x_g + (x_g μ20 + y_g μ11 + μ12 + μ30)/a`, exact for a
///   fronto-parallel target with `a_n = Z` (the a priori depth is the `Z*` of the normalisation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AreaNormalized {
    normalization: AreaNormalization,
}

impl AreaNormalized {
    /// The feature with the normalisation `(Z*, a*)`.
    pub fn new(normalization: AreaNormalization) -> Self {
        Self { normalization }
    }

    /// `a_n` and its row in the form `source` asks for.
    fn evaluate(
        &self,
        obs: &Observation<'_>,
        source: InteractionSource,
    ) -> Result<[(f64, InteractionRow); 1], FeatureError> {
        let m = obs.moments()?;
        let (a_n, l_an) = self.normalization.evaluate(m)?;
        Ok([(a_n, Self::row(m, a_n, l_an, source)?)])
    }

    /// The row of `a_n` in the form `source` asks for, from `a_n` and its exact row `l_an` ([`AreaNormalization`]).
    pub(super) fn row(
        m: &Moments,
        a_n: f64,
        l_an: InteractionRow,
        source: InteractionSource,
    ) -> Result<InteractionRow, FeatureError> {
        Ok(match source {
            InteractionSource::PaperApprox => {
                let (eps1, eps2) = epsilons(m)?;
                InteractionRow::new(0.0, 0.0, -1.0, -a_n * eps1, a_n * eps2, 0.0)
            }
            InteractionSource::Exact | InteractionSource::Desired => l_an,
        })
    }
}

impl Feature for AreaNormalized {
    fn name(&self) -> &'static str {
        "a_n"
    }
    fn dim(&self) -> usize {
        1
    }
    fn is_angle(&self, _row: usize) -> bool {
        false
    }
    fn min_points(&self) -> usize {
        2
    }
    writes_from_one_evaluation!(Self::evaluate);
}

/// `(ε1, ε2)` of \[M38\]–\[M39\].
fn epsilons(m: &Moments) -> Result<(f64, f64), FeatureError> {
    let (a, _) = m.size()?;
    let mu = |i, j| m.mu(i, j).unwrap_or(0.0);
    let (xg, yg) = (m.xg(), m.yg());
    Ok((
        yg + (yg * mu(0, 2) + xg * mu(1, 1) + mu(2, 1) + mu(0, 3)) / a,
        xg + (xg * mu(2, 0) + yg * mu(1, 1) + mu(1, 2) + mu(3, 0)) / a,
    ))
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::*;
    use crate::camera::ImagePoint;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    fn moments_of(pts: &[ImagePoint]) -> Moments {
        *Observation::new(pts, None).unwrap().moments().unwrap()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn centred_moments_match_camera_motion(pose in tilted_pose_strategy(), plane in any::<bool>()) {
            let scene = Scene::new(pose, rectangle(0.2, 0.14));
            for (i, j) in [(2, 0), (1, 1), (0, 2), (3, 0), (2, 1), (1, 2), (0, 3)] {
                scene.check_exact(&CentredMoment::new(i, j).unwrap(), plane);
            }
        }

        #[test]
        fn area_normalized_matches_camera_motion(pose in tilted_pose_strategy(), plane in any::<bool>()) {
            let f = AreaNormalized::new(AreaNormalization::new(0.8, 0.05).unwrap());
            Scene::new(pose, rectangle(0.2, 0.14)).check_exact(&f, plane);
        }

        /// The chain rule equals ViSP's plane closed form \[M38\].
        #[test]
        fn area_normalized_matches_closed_form_m38(pose in tilted_pose_strategy()) {
            let scene = Scene::new(pose, rectangle(0.2, 0.14));
            let (pts, plane) = scene.image();
            let norm = AreaNormalization::new(0.8, 0.05).unwrap();
            let m = moments_of(&pts);
            let (a_n, _) = norm.evaluate(&m).unwrap();
            let (a, _) = m.size().unwrap();
            let (eps1, eps2) = epsilons(&m).unwrap();
            let e = |i, j| m.mu(i, j).unwrap() / a;
            let (pa, pb, pc) = (plane.a, plane.b, plane.c);
            let mut m38 = Rows::zeros(1);
            m38.row_mut(0).copy_from_slice(&[
                a_n * (pa * e(2, 0) + pb * e(1, 1)),
                a_n * (pa * e(1, 1) + pb * e(0, 2)),
                -a_n * pc - a_n * (pb * eps1 + pa * eps2),
                -a_n * eps1,
                a_n * eps2,
                0.0,
            ]);
            let f = AreaNormalized::new(norm);
            assert_close(&scene.interaction(&f, InteractionSource::Exact, false), &m38, 1e-12);
        }

        /// (F35) is an approximation on a tilted target: it differs from the exact row.
        #[test]
        fn area_normalized_approx_differs_when_tilted(pose in tilted_pose_strategy()) {
            let scene = Scene::new(pose, rectangle(0.2, 0.14));
            let f = AreaNormalized::new(AreaNormalization::new(0.8, 0.05).unwrap());
            let exact = scene.interaction(&f, InteractionSource::Exact, true);
            let approx = scene.interaction(&f, InteractionSource::PaperApprox, true);
            prop_assert!((exact - approx).amax() > 1e-3);
        }
    }

    /// (F35) equals the exact row for a fronto-parallel target with `a_n = Z`: normalisation from a fronto-parallel
    /// desired image at `Z*`, current image fronto-parallel at another depth, shifted and turned in its plane.
    #[test]
    fn area_normalized_approx_is_exact_fronto_parallel() {
        let desired = rectangle_points_fronto(0.2, 0.14, 0.5);
        let norm = AreaNormalization::from_desired(&Observation::new(&desired, None).unwrap(), 0.5)
            .unwrap();
        let f = AreaNormalized::new(norm);
        let z = 0.9;
        let scene = Scene::new(pose(0.08, -0.05, z, 0.0, 0.0, 0.3), rectangle(0.2, 0.14));
        assert_relative_eq!(scene.value(&f, false)[0], z, epsilon = 1e-12);
        let exact = scene.interaction(&f, InteractionSource::Exact, false);
        let approx = scene.interaction(&f, InteractionSource::PaperApprox, false);
        assert_close(&approx, &exact, 1e-12);
        assert!(
            exact[(0, 3)].abs() > 1e-3 && exact[(0, 4)].abs() > 1e-3,
            "off-centre: ω entries non-zero"
        );
    }

    /// Centred fronto-parallel `w × h` rectangle at depth Z: μ20 = 4 (w/2Z)², μ02 = 4 (h/2Z)², the others vanish;
    /// `a_n = Z*` at the desired depth, and `a_n = Z` at another depth.
    #[test]
    fn hand_computed_rectangle_moments() {
        let (w, h, z) = (0.2, 0.1, 0.5);
        let pts = rectangle_points_fronto(w, h, z);
        let m = moments_of(&pts);
        let (hw, hh) = (w / (2.0 * z), h / (2.0 * z));
        assert_relative_eq!(m.mu(2, 0).unwrap(), 4.0 * hw * hw, epsilon = 1e-15);
        assert_relative_eq!(m.mu(0, 2).unwrap(), 4.0 * hh * hh, epsilon = 1e-15);
        assert_eq!(m.mu(0, 0), Some(4.0));
        for (i, j) in [(1, 0), (0, 1), (1, 1), (3, 0), (2, 1), (1, 2), (0, 3)] {
            assert_relative_eq!(m.mu(i, j).unwrap(), 0.0, epsilon = 1e-16);
        }
        assert_eq!(m.mu(2, 2), None);
        let norm = AreaNormalization::new(z, 4.0 * (hw * hw + hh * hh)).unwrap();
        let f = AreaNormalized::new(norm);
        let mut s = [0.0];
        f.value(&Observation::new(&pts, None).unwrap(), &mut s)
            .unwrap();
        assert_relative_eq!(s[0], z, epsilon = 1e-15);
        let far = rectangle_points_fronto(w, h, 2.0);
        f.value(&Observation::new(&far, None).unwrap(), &mut s)
            .unwrap();
        assert_relative_eq!(s[0], 2.0, epsilon = 1e-14);
        // Exact row at the centred fronto-parallel pose: [0, 0, −1, 0, 0, 0] (M38 with A = B = 0, C = 1/Z, ε = 0).
        let mut l = Rows::zeros(1);
        f.interaction(
            &Observation::new(&pts, None).unwrap(),
            InteractionSource::Exact,
            l.rows_mut(0, 1),
        )
        .unwrap();
        assert_relative_eq!(
            l.row(0).into_owned(),
            InteractionRow::new(0.0, 0.0, -1.0, 0.0, 0.0, 0.0),
            epsilon = 1e-14
        );
    }

    #[test]
    fn coincident_points_are_an_error() {
        let pts = [ImagePoint::new(0.1, 0.2, 1.0); 4];
        let obs = Observation::new(&pts, None).unwrap();
        let f = AreaNormalized::new(AreaNormalization::new(0.5, 0.1).unwrap());
        let mut s = [0.0];
        assert!(
            matches!(f.value(&obs, &mut s), Err(FeatureError::DegenerateArea { a, .. }) if a == 0.0)
        );
        let mut l = Rows::zeros(1);
        assert!(matches!(
            f.interaction(&obs, InteractionSource::PaperApprox, l.rows_mut(0, 1)),
            Err(FeatureError::DegenerateArea { .. })
        ));
        assert!(matches!(
            AreaNormalization::from_desired(&obs, 0.5),
            Err(FeatureError::DegenerateArea { .. })
        ));
        let single = Observation::new(&pts[..1], None).unwrap();
        assert_eq!(
            f.value(&single, &mut s),
            Err(FeatureError::TooFewPoints {
                feature: "a_n",
                needed: 2,
                got: 1
            })
        );
    }

    #[test]
    fn bad_parameters() {
        assert_eq!(
            CentredMoment::new(2, 2),
            Err(FeatureError::UnsupportedMomentOrder { i: 2, j: 2 })
        );
        assert!(matches!(
            AreaNormalization::new(-0.5, 0.1),
            Err(FeatureError::InvalidParameter { name: "Z*", .. })
        ));
        assert!(matches!(
            AreaNormalization::new(0.5, f64::NAN),
            Err(FeatureError::InvalidParameter { name: "a*", .. })
        ));
    }
}
