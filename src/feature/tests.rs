//! Tests across the features: overflow is an error, the one-pass evaluation equals the two calls for every feature,
//! and angle errors are wrapped.

use super::testutil::*;
use super::*;
use crate::camera::ImagePoint;
use proptest::prelude::*;

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
