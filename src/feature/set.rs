//! Stacked features: the paper's four tasks (§7.2–§7.6), the classical 6-row vector (§7.7) and ViSP's moment vector
//! ([peer scene variant B](crate::theory::peer_scene#variant-b)).

use super::{
    check_dim, check_points, AreaNormalization, AreaNormalized, Centroid, DiagonalAngle, Feature,
    FeatureError, InteractionRow, InteractionRows, InteractionSource, MomentOrientation,
    NormalizedCentroid, Observation, PaperInvariants, VispInvariants,
};

/// A boxed feature that a [`FeatureSet`] can hold and share across threads.
pub type BoxedFeature = Box<dyn Feature + Send + Sync>;

/// Several features stacked in order: `s = (s_1, …, s_m)`, `L = [L_1; …; L_m]`. Itself a [`Feature`], so a task can
/// hold one feature or a set alike. Every feature reads the same [`Observation`] (moments computed once).
/// Construction allocates (the list of features); [`Feature::value`] and [`Feature::interaction`] do not.
pub struct FeatureSet {
    features: Vec<BoxedFeature>,
    dim: usize,
    min_points: usize,
}

impl std::fmt::Debug for FeatureSet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list()
            .entries(self.features.iter().map(|feature| feature.name()))
            .finish()
    }
}

impl FeatureSet {
    /// Stacks `features` in the given order.
    pub fn new(features: Vec<BoxedFeature>) -> Self {
        let dim = features.iter().map(|f| f.dim()).sum();
        let min_points = features.iter().map(|f| f.min_points()).max().unwrap_or(0);
        Self {
            features,
            dim,
            min_points,
        }
    }

    /// The stacked features.
    pub fn features(&self) -> &[BoxedFeature] {
        &self.features
    }

    /// The paper's four tasks, in priority order (§7.2–§7.6):
    /// e1 centroid (2 rows, [`Centroid`]), e2 diagonal angle (1, [`DiagonalAngle`]), e3 `a_n` (1, [`AreaNormalized`]),
    /// e4 `P_x, P_y` (2, [`PaperInvariants`]).
    pub fn paper_tasks(
        centroid: Centroid,
        angle: DiagonalAngle,
        normalization: AreaNormalization,
    ) -> [FeatureSet; 4] {
        [
            Self::new(vec![Box::new(centroid)]),
            Self::new(vec![Box::new(angle)]),
            Self::new(vec![Box::new(AreaNormalized::new(normalization))]),
            Self::new(vec![Box::new(PaperInvariants::new(normalization))]),
        ]
    }

    /// The classical full task (§7.7): `s = (x_g, y_g, α, a_n, P_x, P_y)`, 6 rows, row 2 an angle.
    pub fn paper_full(
        centroid: Centroid,
        angle: DiagonalAngle,
        normalization: AreaNormalization,
    ) -> Self {
        Self::new(vec![
            Box::new(centroid),
            Box::new(angle),
            Box::new(AreaNormalized::new(normalization)),
            Box::new(PaperInvariants::new(normalization)),
        ])
    }

    /// ViSP's moment vector of [peer scene variant B](crate::theory::peer_scene#variant-b): `s = (x_n, y_n, a_n, P_x, P_y, α)` with ViSP's definitions
    /// ([`NormalizedCentroid`], [`AreaNormalized`], [`VispInvariants`], [`MomentOrientation`]); row 5 an angle.
    /// One part, [`VispMoments`], which evaluates the four in one pass over their shared terms.
    pub fn visp_moments(normalization: AreaNormalization) -> Self {
        Self::new(vec![Box::new(VispMoments::new(normalization))])
    }

    /// The feature owning stacked row `row` and the row's index inside it.
    fn locate(&self, row: usize) -> Option<(&BoxedFeature, usize)> {
        let mut first = 0;
        for f in &self.features {
            if row < first + f.dim() {
                return Some((f, row - first));
            }
            first += f.dim();
        }
        None
    }
}

/// ViSP's moment vector `s = (x_n, y_n, a_n, P_x, P_y, α)` of [peer scene variant B](crate::theory::peer_scene#variant-b)
/// as one feature of 6 rows (row 5 an angle, rad): the values and rows of [`NormalizedCentroid`] (`x_n = a_n x_g`,
/// `y_n = a_n y_g`), [`AreaNormalized`] (`a_n = Z* √(a*/a)`, \[M37\]), [`VispInvariants`] (`P_x = I1/I3²`,
/// `P_y = I2/I3²`) and [`MomentOrientation`] (`α = ½ atan2(2μ11, μ20 − μ02)`), the same bits as the four stacked, with
/// what they share computed once: the size `a = I3 = μ20 + μ02` and its row (instead of four times), `a_n` and
/// `L_{a_n}` (a square root and two divisions, instead of twice), and the second-order terms `c1`, `s1`, `I1` with
/// their rows (instead of three times). Errors come in the order of the parts (`a = 0` first, then isotropic moments for `α`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VispMoments {
    normalization: AreaNormalization,
}

impl VispMoments {
    /// The vector with the normalisation `(Z*, a*)` of its `x_n`, `y_n` and `a_n`.
    pub fn new(normalization: AreaNormalization) -> Self {
        Self { normalization }
    }

    /// The six `(value, row)` pairs; the row of `a_n` in the form `source` asks for (the others are exact whatever the
    /// source), as [`AreaNormalized`].
    fn evaluate(
        &self,
        obs: &Observation<'_>,
        source: InteractionSource,
    ) -> Result<[(f64, InteractionRow); 6], FeatureError> {
        let m = obs.moments()?;
        let o = m.second_order_terms()?;
        let (a_n, l_an) = self.normalization.of_size(o.i3, &o.l_i3);
        let [x_n, y_n] = NormalizedCentroid::pairs(m, a_n, &l_an);
        let area = (a_n, AreaNormalized::row(m, a_n, l_an, source)?);
        let [p_x, p_y] = VispInvariants::pairs(m, &o);
        let alpha = MomentOrientation::pair(&o.anisotropic()?);
        Ok([x_n, y_n, area, p_x, p_y, alpha])
    }
}

impl Feature for VispMoments {
    fn name(&self) -> &'static str {
        "ViSP moment vector"
    }
    fn dim(&self) -> usize {
        6
    }
    fn is_angle(&self, row: usize) -> bool {
        row == 5
    }
    fn min_points(&self) -> usize {
        2
    }
    writes_from_one_evaluation!(Self::evaluate);
}

impl Feature for FeatureSet {
    fn name(&self) -> &'static str {
        "feature set"
    }
    fn dim(&self) -> usize {
        self.dim
    }
    fn is_angle(&self, row: usize) -> bool {
        self.locate(row).is_some_and(|(f, r)| f.is_angle(r))
    }
    fn min_points(&self) -> usize {
        self.min_points
    }
    fn write_value(&self, obs: &Observation<'_>, s: &mut [f64]) -> Result<(), FeatureError> {
        let mut rest = s;
        for f in &self.features {
            let (head, tail) = rest.split_at_mut(f.dim().min(rest.len()));
            f.value(obs, head)?;
            rest = tail;
        }
        Ok(())
    }
    fn write_interaction(
        &self,
        obs: &Observation<'_>,
        source: InteractionSource,
        mut l: InteractionRows<'_>,
    ) -> Result<(), FeatureError> {
        let mut first = 0;
        for f in &self.features {
            let rows = f.dim().min(l.nrows() - first.min(l.nrows()));
            f.interaction(obs, source, l.rows_mut(first, rows))?;
            first += rows;
        }
        Ok(())
    }
    /// The checked call of the trait, without checking again what the parts have checked: each part's own
    /// [`Feature::value_and_interaction`] checks its values and rows finite (the error then names the part), and the
    /// parts' rows are all of the set's.
    fn value_and_interaction(
        &self,
        obs: &Observation<'_>,
        source: InteractionSource,
        s: &mut [f64],
        l: InteractionRows<'_>,
    ) -> Result<(), FeatureError> {
        check_points(self, obs)?;
        check_dim(self, s.len())?;
        check_dim(self, l.nrows())?;
        self.write_value_and_interaction(obs, source, s, l)
    }
    fn write_value_and_interaction(
        &self,
        obs: &Observation<'_>,
        source: InteractionSource,
        s: &mut [f64],
        mut l: InteractionRows<'_>,
    ) -> Result<(), FeatureError> {
        let (mut rest, mut first) = (s, 0);
        for f in &self.features {
            let (head, tail) = rest.split_at_mut(f.dim().min(rest.len()));
            let rows = f.dim().min(l.nrows() - first.min(l.nrows()));
            f.value_and_interaction(obs, source, head, l.rows_mut(first, rows))?;
            (rest, first) = (tail, first + rows);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::*;
    use crate::camera::ImagePoint;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    fn paper_params() -> (Centroid, DiagonalAngle, AreaNormalization) {
        (
            Centroid::new(0.5).unwrap(),
            DiagonalAngle::default(),
            AreaNormalization::new(0.5, 0.2).unwrap(),
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        /// The stacked sets are exact (FD of real camera motion) and their rows are those of the parts, in order.
        #[test]
        fn sets_stack_their_features(pose in tilted_pose_strategy_yaw(-1.0..1.0), plane in any::<bool>()) {
            let (c, a, n) = paper_params();
            let scene = Scene::new(pose, rectangle(0.2, 0.1));
            let full = FeatureSet::paper_full(c, a, n);
            let tasks = FeatureSet::paper_tasks(c, a, n);
            scene.check_exact(&full, plane);
            let visp = FeatureSet::visp_moments(n);
            scene.check_exact(&visp, plane);
            for source in [InteractionSource::Exact, InteractionSource::PaperApprox] {
                let l = scene.interaction(&full, source, plane);
                let mut first = 0;
                for task in &tasks {
                    let part = scene.interaction(task, source, plane);
                    assert_relative_eq!(l.rows(first, task.dim()).into_owned(), part, epsilon = 0.0);
                    first += task.dim();
                }
            }
            let s = scene.value(&full, plane);
            let parts: Vec<f64> = tasks.iter().flat_map(|t| scene.value(t, plane)).collect();
            prop_assert_eq!(s, parts);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// The one-pass ViSP vector writes the same bits as its four parts stacked, for every source, by each entry
        /// point; and its errors come in the parts' order.
        #[test]
        fn visp_vector_is_its_parts(pose in tilted_pose_strategy(), plane in any::<bool>()) {
            let n = AreaNormalization::new(0.5, 0.05).unwrap();
            let parts = FeatureSet::new(vec![
                Box::new(NormalizedCentroid::new(n)),
                Box::new(AreaNormalized::new(n)),
                Box::new(VispInvariants),
                Box::new(MomentOrientation),
            ]);
            let fused = FeatureSet::visp_moments(n);
            let scene = Scene::new(pose, rectangle(0.2, 0.1));
            prop_assert_eq!(scene.value(&fused, plane), scene.value(&parts, plane));
            let (points, target_plane) = scene.image();
            let obs = Observation::new(&points, plane.then_some(&target_plane)).unwrap();
            for source in [InteractionSource::Exact, InteractionSource::PaperApprox, InteractionSource::Desired] {
                prop_assert_eq!(scene.interaction(&fused, source, plane), scene.interaction(&parts, source, plane));
                let one_pass = |f: &FeatureSet| {
                    let (mut s, mut l) = ([0.0; 6], Rows::zeros(6));
                    f.value_and_interaction(&obs, source, &mut s, l.rows_mut(0, 6)).unwrap();
                    (s, l)
                };
                prop_assert_eq!(one_pass(&fused), one_pass(&parts));
            }
        }
    }

    #[test]
    fn visp_vector_errors_in_the_parts_order() {
        let n = AreaNormalization::new(0.5, 0.05).unwrap();
        let fused = FeatureSet::visp_moments(n);
        let mut s = [0.0; 6];
        let same = [ImagePoint::new(0.1, 0.1, 1.0); 3];
        assert!(matches!(
            fused.value(&Observation::new(&same, None).unwrap(), &mut s),
            Err(FeatureError::DegenerateArea { .. })
        ));
        let square = rectangle_points_fronto(0.1, 0.1, 0.5);
        assert!(matches!(
            fused.value(&Observation::new(&square, None).unwrap(), &mut s),
            Err(FeatureError::IsotropicMoments { .. })
        ));
    }

    #[test]
    fn layout_of_the_sets() {
        let (c, a, n) = paper_params();
        let dims: Vec<usize> = FeatureSet::paper_tasks(c, a, n)
            .iter()
            .map(|t| t.dim())
            .collect();
        assert_eq!(dims, [2, 1, 1, 2]);
        let full = FeatureSet::paper_full(c, a, n);
        assert_eq!(full.dim(), 6);
        assert_eq!(
            (0..7).map(|r| full.is_angle(r)).collect::<Vec<_>>(),
            [false, false, true, false, false, false, false]
        );
        assert_eq!(full.min_points(), 3);
        let visp = FeatureSet::visp_moments(n);
        assert_eq!(visp.dim(), 6);
        assert_eq!(
            (0..6).filter(|&r| visp.is_angle(r)).collect::<Vec<_>>(),
            [5]
        );
    }

    /// Variant B at the desired pose of the [peer scene](crate::theory::peer_scene#scene) (rectangle 0.2 × 0.1 m fronto-parallel at 0.5 m): hand values
    /// x_n = y_n = 0, a_n = Z*, P_x = (0.03/0.05)² (I1/I3² with μ20 = 0.16, μ02 = 0.04), P_y = 0, α = 0; the errors
    /// of a set wrap its angle rows only.
    #[test]
    fn visp_vector_at_the_desired_pose() {
        let pts = rectangle_points_fronto(0.2, 0.1, 0.5);
        let obs = Observation::new(&pts, None).unwrap();
        let n = AreaNormalization::from_desired(&obs, 0.5).unwrap();
        assert_relative_eq!(n.a_star(), 0.2, epsilon = 1e-15);
        let set = FeatureSet::visp_moments(n);
        let mut s = [0.0; 6];
        set.value(&obs, &mut s).unwrap();
        let expected = [0.0, 0.0, 0.5, (0.12f64 / 0.2).powi(2), 0.0, 0.0];
        for (v, e) in s.iter().zip(expected) {
            assert_relative_eq!(*v, e, epsilon = 1e-15);
        }
        let mut e = [0.0; 6];
        let shifted = [7.0, 0.0, 0.0, 0.0, 0.0, 7.0];
        set.error(&shifted, &[0.0; 6], &mut e).unwrap();
        assert_eq!(e[0], 7.0);
        assert_relative_eq!(e[5], 7.0 - 2.0 * std::f64::consts::PI, epsilon = 1e-15);
    }

    #[test]
    fn bad_storage_and_values() {
        let (c, a, n) = paper_params();
        let full = FeatureSet::paper_full(c, a, n);
        let pts = rectangle_points_fronto(0.2, 0.1, 0.5);
        let obs = Observation::new(&pts, None).unwrap();
        let mut s = [0.0; 5];
        assert_eq!(
            full.value(&obs, &mut s),
            Err(FeatureError::WrongDimension {
                feature: "feature set",
                expected: 6,
                got: 5
            })
        );
        let mut l = Rows::zeros(7);
        assert!(matches!(
            full.interaction(&obs, InteractionSource::Exact, l.rows_mut(0, 7)),
            Err(FeatureError::WrongDimension {
                expected: 6,
                got: 7,
                ..
            })
        ));
        let mut e = [0.0; 6];
        let bad = [0.0, 0.0, f64::NAN, 0.0, 0.0, 0.0];
        assert!(matches!(
            full.error(&bad, &[0.0; 6], &mut e),
            Err(FeatureError::NonFiniteValue { row: 2, .. })
        ));
        let obs2 = Observation::new(&pts[..2], None).unwrap();
        let mut s6 = [0.0; 6];
        assert!(matches!(
            full.value(&obs2, &mut s6),
            Err(FeatureError::TooFewPoints {
                needed: 3,
                got: 2,
                ..
            })
        ));
    }

    /// The set's one-pass call keeps the checks of the trait: its own storage sizes and point count, and the parts'
    /// finite results, each named by its part.
    #[test]
    fn one_pass_evaluation_is_checked() {
        let (c, a, n) = paper_params();
        let full = FeatureSet::paper_full(c, a, n);
        let pts = rectangle_points_fronto(0.2, 0.1, 0.5);
        let obs = Observation::new(&pts, None).unwrap();
        let source = InteractionSource::Exact;
        let mut rows = Rows::zeros(7);
        let wrong_rows =
            full.value_and_interaction(&obs, source, &mut [0.0; 6], rows.rows_mut(0, 7));
        assert!(matches!(
            wrong_rows,
            Err(FeatureError::WrongDimension {
                feature: "feature set",
                expected: 6,
                got: 7
            })
        ));
        let wrong_values =
            full.value_and_interaction(&obs, source, &mut [0.0; 5], rows.rows_mut(0, 6));
        assert!(matches!(
            wrong_values,
            Err(FeatureError::WrongDimension {
                feature: "feature set",
                expected: 6,
                got: 5
            })
        ));
        let two = Observation::new(&pts[..2], None).unwrap();
        let too_few = full.value_and_interaction(&two, source, &mut [0.0; 6], rows.rows_mut(0, 6));
        assert!(matches!(
            too_few,
            Err(FeatureError::TooFewPoints {
                needed: 3,
                got: 2,
                ..
            })
        ));
        // Points so far apart that the third-order invariants overflow while the moments do not.
        let far = [
            ImagePoint::new(0.0, 0.0, 1.0),
            ImagePoint::new(1e70, 0.0, 1.0),
            ImagePoint::new(0.0, 1e70, 1.0),
        ];
        let far = Observation::new(&far, None).unwrap();
        let invariants = FeatureSet::new(vec![Box::new(VispInvariants)]);
        let mut l = Rows::zeros(2);
        assert_eq!(
            invariants.value_and_interaction(&far, source, &mut [0.0; 2], l.rows_mut(0, 2)),
            Err(FeatureError::NonFiniteResult {
                feature: "ViSP P_x, P_y"
            })
        );
        assert!(full
            .value_and_interaction(&obs, source, &mut [0.0; 6], rows.rows_mut(0, 6))
            .is_ok());
    }
}
