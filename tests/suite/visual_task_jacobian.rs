//! The task Jacobian of visual tasks on a real robot: `J = L cVe eJe` (theory \[M42\]) matches central finite differences
//! of the task error `e(q) = s(q) − s*` through the whole chain (kinematics, camera mount, projection, features).

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use servostack::camera::CameraIntrinsics;
use servostack::feature::InteractionSource;
use servostack::math::JointVector;
use servostack::robot::{builtin, KinematicsWorkspace};
use servostack::sim::Scene;
use servostack::target::RectangleTarget;
use servostack::task::{Task, TaskValue};
use servostack::visual_task::{classical_task, paper_tasks, VisualContext, VisualTask};

/// The peer scene (docs/peer_scene.md) with a tilted desired pose: Afma6, 0.2 × 0.1 m target 0.5 m ahead at q_d.
fn scene() -> (Scene<6>, Isometry3<f64>, JointVector<6>) {
    let robot = builtin::afma6().unwrap();
    let desired_q = JointVector::<6>::new(0.0, 0.0, 0.0, 0.0, 0.3, 0.0);
    let cd_from_o = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, 0.5),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.3),
    );
    let intrinsics = CameraIntrinsics::new(800.0, 800.0, 320.0, 240.0, 640.0, 480.0).unwrap();
    let target = RectangleTarget::new(0.2, 0.1).unwrap();
    let scene = Scene::with_target_seen_from(
        robot.chain,
        robot.mount,
        intrinsics,
        target,
        &desired_q,
        &cd_from_o,
        0.1,
    )
    .unwrap();
    (scene, cd_from_o, desired_q)
}

/// Evaluates `task` at `q` into a fresh value.
fn evaluate(scene: &Scene<6>, task: &VisualTask, q: &JointVector<6>) -> TaskValue<6> {
    let mut workspace = KinematicsWorkspace::new();
    let view = scene.observe(&mut workspace, q).unwrap();
    let observation = view.observation().unwrap();
    let context = VisualContext {
        observation: &observation,
        camera_jacobian: &view.camera_jacobian,
    };
    let mut value = TaskValue::for_task::<VisualContext<'_, 6>, _>(task).unwrap();
    task.evaluate(&context, &mut value).unwrap();
    value
}

/// Largest relative difference between `J` and central differences of `e(q)`.
fn jacobian_error(scene: &Scene<6>, task: &VisualTask, q: &JointVector<6>) -> f64 {
    let value = evaluate(scene, task, q);
    let h = 1e-6;
    let mut worst: f64 = 0.0;
    for j in 0..6 {
        let (mut plus, mut minus) = (*q, *q);
        plus[j] += h;
        minus[j] -= h;
        let numeric = (evaluate(scene, task, &plus).error()
            - evaluate(scene, task, &minus).error())
            / (2.0 * h);
        let analytic = value.jacobian().column(j);
        let scale = 1.0 + analytic.amax();
        worst = worst.max((numeric - analytic).amax() / scale);
    }
    worst
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, failure_persistence: None, ..ProptestConfig::default() })]

    /// The classical task (all six features) and each of the paper's four tasks, at random configurations around the
    /// desired one (every point stays in front of the camera there).
    #[test]
    fn task_jacobians_match_finite_differences(offset in proptest::collection::vec(-1.0..1.0f64, 6)) {
        let (scene, cd_from_o, desired_q) = scene();
        let scale = JointVector::<6>::new(0.05, 0.05, 0.05, 0.2, 0.2, 0.2);
        let q = desired_q + JointVector::<6>::from_column_slice(&offset).component_mul(&scale);
        let desired_view = scene.view_from(&cd_from_o).unwrap();
        let desired = desired_view.observation().unwrap();
        let mut tasks = paper_tasks(&desired, 0.5, 0.5, [0.5; 4], InteractionSource::Exact).unwrap();
        tasks.push(classical_task(&desired, 0.5, 0.5, 0.5, InteractionSource::Exact).unwrap());
        for task in &tasks {
            let error = jacobian_error(&scene, task, &q);
            prop_assert!(error < 1e-6, "{}: relative error {error:e}", Task::<6, VisualContext<'_, 6>>::name(task));
        }
    }
}

/// At the desired configuration every task error vanishes (the target was placed there), and a `Desired`-source
/// Jacobian equals the exact one.
#[test]
fn errors_vanish_at_the_desired_pose_where_desired_and_exact_jacobians_agree() {
    let (scene, cd_from_o, desired_q) = scene();
    let desired_view = scene.view_from(&cd_from_o).unwrap();
    let desired = desired_view.observation().unwrap();
    let exact = classical_task(&desired, 0.5, 0.5, 0.5, InteractionSource::Exact).unwrap();
    let at_desired = classical_task(&desired, 0.5, 0.5, 0.5, InteractionSource::Desired).unwrap();
    let (a, b) = (
        evaluate(&scene, &exact, &desired_q),
        evaluate(&scene, &at_desired, &desired_q),
    );
    assert!(a.error().amax() < 1e-12, "e = {}", a.error());
    assert!((a.jacobian() - b.jacobian()).amax() < 1e-12);
}

/// A square target seen head-on makes the third-order features undefined (theory D9): building the paper's tasks fails
/// with the feature's own error, values included.
#[test]
fn square_seen_head_on_is_a_feature_error() {
    let square = [(-0.1, -0.1), (0.1, -0.1), (0.1, 0.1), (-0.1, 0.1)]
        .map(|(x, y)| servostack::camera::ImagePoint::new(x, y, 0.5));
    let desired = servostack::feature::Observation::new(&square, None).unwrap();
    let error = paper_tasks(&desired, 0.5, 0.5, [0.5; 4], InteractionSource::Exact).unwrap_err();
    match error {
        servostack::task::TaskError::Feature { name, source } => {
            assert_eq!(name, "third_order");
            assert!(
                matches!(
                    source,
                    servostack::feature::FeatureError::IsotropicMoments { .. }
                ),
                "{source:?}"
            );
        }
        other => panic!("expected a feature error, got {other:?}"),
    }
}

/// The angle row of a stacked feature set is wrapped into `(−π, π]` (D8): with the diagonal at `π − δ` in the desired
/// image and at `−π + δ` in the current one, the task error is `2δ`, not `2δ − 2π`; the centroid rows beside it are
/// plain differences. Fails if the rows' angle flags are misread (e.g. taken from the wrong row of the set).
#[test]
fn the_angle_row_of_a_feature_set_is_wrapped() {
    use servostack::camera::ImagePoint;
    use servostack::feature::{Centroid, DiagonalAngle, FeatureSet, Observation};
    let delta: f64 = 0.05;
    // Point 0 at the origin, point 2 at unit distance along the angle; points 1 and 3 off the diagonal.
    let points_at = |angle: f64, shift: f64| {
        [
            (shift, 0.0),
            (shift + 0.1, -0.2),
            (shift + angle.cos() * 0.3, angle.sin() * 0.3),
            (shift - 0.2, 0.1),
        ]
        .map(|(x, y)| ImagePoint { x, y, depth: 1.0 })
    };
    let desired_points = points_at(std::f64::consts::PI - delta, 0.0);
    let current_points = points_at(-std::f64::consts::PI + delta, 0.02);
    let desired = Observation::new(&desired_points, None).unwrap();
    let current = Observation::new(&current_points, None).unwrap();
    let feature = FeatureSet::new(vec![
        Box::new(Centroid::new(1.0).unwrap()),
        Box::new(DiagonalAngle::new(0, 2).unwrap()),
    ]);
    let task = VisualTask::new(
        "centroid and angle",
        Box::new(feature),
        &desired,
        1.0,
        InteractionSource::Exact,
    )
    .unwrap();
    let camera_jacobian = servostack::math::KinematicJacobian::<6>::identity();
    let context = VisualContext {
        observation: &current,
        camera_jacobian: &camera_jacobian,
    };
    let mut value = TaskValue::for_task::<VisualContext<'_, 6>, _>(&task).unwrap();
    task.evaluate(&context, &mut value).unwrap();
    let error = value.error();
    // x_g, y_g: the means of the four points.
    let mean = |points: &[ImagePoint; 4], pick: fn(&ImagePoint) -> f64| {
        points.iter().map(pick).sum::<f64>() / 4.0
    };
    let expected_x = mean(&current_points, |p| p.x) - mean(&desired_points, |p| p.x);
    let expected_y = mean(&current_points, |p| p.y) - mean(&desired_points, |p| p.y);
    assert!(
        (error[0] - expected_x).abs() < 1e-12,
        "x_g error {}",
        error[0]
    );
    assert!(
        (error[1] - expected_y).abs() < 1e-12,
        "y_g error {}",
        error[1]
    );
    assert!(
        (error[2] - 2.0 * delta).abs() < 1e-12,
        "angle error {}",
        error[2]
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// A view kept across steps and rewritten in place by `observe_into` is what `observe` returns at the new
    /// configuration: nothing of the previous configuration survives.
    #[test]
    fn a_view_rewritten_in_place_is_a_fresh_observation(
        first in proptest::array::uniform6(-0.05..0.05f64),
        second in proptest::array::uniform6(-0.05..0.05f64),
    ) {
        let (scene, _, desired_q) = scene();
        let (q1, q2) = (desired_q + JointVector::from(first), desired_q + JointVector::from(second));
        let mut workspace = KinematicsWorkspace::new();
        let mut view = scene.observe(&mut workspace, &q1).unwrap();
        scene.observe_into(&mut workspace, &q2, &mut view).unwrap();
        let fresh = scene.observe(&mut KinematicsWorkspace::new(), &q2).unwrap();
        prop_assert_eq!(view, fresh);
        // The other way round, from a blank placeholder.
        let mut blank = servostack::sim::View::default();
        scene.observe_into(&mut workspace, &q1, &mut blank).unwrap();
        prop_assert_eq!(blank, scene.observe(&mut workspace, &q1).unwrap());
    }
}
