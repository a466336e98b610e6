//! The real-time path allocates nothing on the heap (the model/workspace split): the steady-state control step, the
//! features, the kinematics, the camera and the projection. Counted per thread by a global allocator.

use crate::counting_allocator::allocations_during;
use crate::servo_loop::{ServoLoop, Variant};
use nalgebra::{Dyn, OMatrix, Point3, SMatrix, U6};
use servostack::avoidance::{Cost, JointLimits};
use servostack::camera::{project_points, ImagePoint};
use servostack::feature::{
    AreaNormalization, Centroid, DiagonalAngle, Feature, FeatureSet, InteractionSource, Observation,
};
use servostack::law::sns::SnsBounds;
use servostack::law::{control_step, ControlLaw, ControlWorkspace, StackChange};
use servostack::math::JointVector;
use servostack::robot::{builtin, KinematicsWorkspace};
use servostack::target::RectangleTarget;
use servostack::task::{LinearTask, Task, TaskJacobian, TaskValue};

#[test]
fn the_counter_sees_allocations() {
    assert!(allocations_during(|| drop(std::hint::black_box(vec![1u8; 16]))) >= 1);
}

/// Four levels (2, 1, 1, 2 rows) on N = 6 with joint-limit avoidance, the stack changing along the way: after the first
/// steps, evaluating the tasks and running the control step allocates nothing.
#[test]
fn steady_state_stack_solve_with_avoidance_allocates_nothing() {
    linear_stack_allocates_nothing(None);
}

/// The same with saturation in the null space, the velocity limits active at the start: allocation-free too, and every
/// step stays inside the joint limits.
#[test]
fn steady_state_sns_step_allocates_nothing() {
    let limits =
        JointLimits::new(JointVector::repeat(-0.5), JointVector::repeat(0.5), 0.1).unwrap();
    let bounds = SnsBounds::new(limits, JointVector::repeat(0.2), 0.01).unwrap();
    linear_stack_allocates_nothing(Some(bounds));
}

fn linear_stack_allocates_nothing(saturation: Option<SnsBounds<6>>) {
    let rows = [2usize, 1, 1, 2];
    let tasks: Vec<LinearTask<6>> = rows
        .iter()
        .enumerate()
        .map(|(i, &m)| {
            let matrix =
                TaskJacobian::<6>::from_fn(m, |r, c| ((7 * i + 3 * r + c) as f64 * 0.61).sin());
            let target = JointVector::<6>::from_fn(|c, _| 0.1 * (c as f64) - 0.2);
            LinearTask::new(&format!("t{i}"), matrix, target, 0.8).unwrap()
        })
        .collect();
    let mut values: Vec<TaskValue<6>> = tasks
        .iter()
        .map(|t| TaskValue::for_task(t).unwrap())
        .collect();
    let limits =
        JointLimits::new(JointVector::repeat(-0.5), JointVector::repeat(0.5), 0.1).unwrap();
    let law = ControlLaw::with_default_transition(&values, 0.5).unwrap();
    let mut workspace = ControlWorkspace::new(&values);
    let saturating = saturation.is_some();
    if let Some(bounds) = saturation {
        workspace.saturate_in_null_space(bounds);
    }
    let mut order: Vec<usize> = Vec::with_capacity(tasks.len());
    let mut q = JointVector::<6>::from_fn(|c, _| 0.38 - 0.15 * c as f64);
    let dt = 0.01;
    let mut run = |from: usize, to: usize, order: &mut Vec<usize>| {
        for step in from..to {
            let mut change = StackChange::Unchanged;
            if step % 50 == 0 && step / 50 < tasks.len() {
                order.push(step / 50);
                change = StackChange::Changed;
            }
            if step == 260 {
                order.remove(2); // a removal, as the stack controller does
                change = StackChange::Changed;
            }
            for (task, value) in tasks.iter().zip(values.iter_mut()) {
                task.evaluate(&q, value).unwrap();
            }
            let cost: Option<&dyn Cost<6>> = Some(&limits);
            let out = control_step(
                &law,
                &mut workspace,
                &values,
                order,
                cost,
                &q,
                step as f64 * dt,
                change,
            )
            .unwrap();
            q += out.velocity() * dt;
            if saturating {
                assert!(out.velocity().amax() <= 0.2, "{}", out.velocity());
                assert!(limits.violated_joint(&q).is_none(), "{q}");
            }
        }
    };
    run(0, 5, &mut order); // warm-up
    let allocations = allocations_during(|| run(5, 1500, &mut order));
    assert_eq!(allocations, 0);
    assert_eq!(order, vec![0, 1, 3]);
    // The run really servoed: the stacked linear tasks (all zero at the common target) converged.
    let final_error: f64 = order.iter().map(|&i| values[i].error().norm()).sum();
    assert!(final_error < 1e-3, "final error {final_error}");
}

/// 1000 steady-state iterations of a whole servo loop (kinematics, projection, features, tasks, law or controller,
/// Euler step: the code the `peer` and `control_loop` benches time) allocate nothing, and the loop servos.
fn assert_servo_loop_allocates_nothing(mut servo: ServoLoop, name: &str) {
    servo.settle();
    for _ in 0..5 {
        servo.step();
    }
    let initial_error = servo.error_norm();
    let allocations = allocations_during(|| {
        for _ in 0..1000 {
            servo.step();
        }
    });
    assert_eq!(
        allocations, 0,
        "{name}: {allocations} allocations in 1000 steps"
    );
    let error = servo.error_norm();
    assert!(
        error.is_finite() && error < initial_error,
        "{name}: error {initial_error} -> {error}"
    );
}

#[test]
fn peer_variants_allocate_nothing() {
    for variant in Variant::ALL {
        assert_servo_loop_allocates_nothing(ServoLoop::peer(variant), variant.name());
    }
}

#[test]
fn paper_controller_step_allocates_nothing() {
    let servo = ServoLoop::paper();
    assert_servo_loop_allocates_nothing(servo, "paper");
}

#[test]
fn classical_controller_step_allocates_nothing() {
    assert_servo_loop_allocates_nothing(ServoLoop::classical(), "classical");
}

#[test]
fn feature_computations_allocate_nothing() {
    let desired = [(-0.2, -0.1), (0.2, -0.1), (0.2, 0.1), (-0.2, 0.1)]
        .map(|(x, y)| ImagePoint::new(x, y, 0.5));
    let desired = Observation::new(&desired, None).unwrap();
    let n = AreaNormalization::from_desired(&desired, 0.5).unwrap();
    let sets = [
        FeatureSet::paper_full(Centroid::new(0.5).unwrap(), DiagonalAngle::default(), n),
        FeatureSet::visp_moments(n),
    ];
    let current = [(-0.21, -0.09), (0.19, -0.11), (0.2, 0.12), (-0.2, 0.1)]
        .map(|(x, y)| ImagePoint::new(x, y, 0.52));
    let (mut s, mut s_star, mut e) = ([0.0; 6], [0.0; 6], [0.0; 6]);
    let mut l = OMatrix::<f64, Dyn, U6>::zeros(6);
    let allocations = allocations_during(|| {
        for set in &sets {
            set.value(&desired, &mut s_star).unwrap();
            let obs = Observation::new(&current, None).unwrap();
            set.value(&obs, &mut s).unwrap();
            for source in [InteractionSource::Exact, InteractionSource::PaperApprox] {
                set.interaction(&obs, source, l.rows_mut(0, 6)).unwrap();
            }
            set.interaction(&desired, InteractionSource::Desired, l.rows_mut(0, 6))
                .unwrap();
            set.error(&s, &s_star, &mut e).unwrap();
        }
    });
    assert_eq!(allocations, 0);
    assert!(e.iter().any(|v| *v != 0.0), "the features were computed");
}

#[test]
fn kinematics_camera_and_projection_allocate_nothing() {
    let robot = builtin::rail7().unwrap();
    let target = RectangleTarget::new(0.2, 0.1).unwrap();
    let mut ws = KinematicsWorkspace::new();
    let mut image = [ImagePoint::default(); 4];
    let mut point_jacobian = SMatrix::<f64, 3, 7>::zeros();
    let link = robot.chain.link("rail7_cover").unwrap().clone();
    let mut checksum = 0.0;
    let allocations = allocations_during(|| {
        for k in 0..100 {
            let q = JointVector::<7>::from_element(0.01 * k as f64);
            let state = robot.chain.kinematics(&mut ws, &q).unwrap();
            let base_from_camera = robot.mount.base_from_camera(state.base_from_tip());
            let camera_jacobian = robot.mount.camera_jacobian(state.tip_jacobian());
            state
                .point_jacobian(&link, &Point3::new(0.1, 0.2, 0.3), &mut point_jacobian)
                .unwrap();
            // The target 0.5 m in front of the camera.
            let c_from_o = nalgebra::Isometry3::translation(0.0, 0.0, 0.5);
            project_points(&c_from_o, target.points(), &mut image).unwrap();
            checksum += image[0].depth + camera_jacobian[(0, 0)] + base_from_camera.translation.x;
        }
    });
    assert_eq!(allocations, 0);
    assert!(checksum.is_finite());
}

/// The same with a mimic joint (the Afma6 with its coupling): the mimic terms of the Jacobians and of a point
/// Jacobian beyond the mimic joint allocate nothing either.
#[test]
fn kinematics_with_a_mimic_joint_allocate_nothing() {
    let robot = builtin::afma6_coupled().unwrap();
    let mut ws = KinematicsWorkspace::new();
    let mut point_jacobian = SMatrix::<f64, 3, 6>::zeros();
    let link = robot.chain.link("afma6_end_effector").unwrap().clone();
    assert!(!link.mimics().is_empty());
    let mut checksum = 0.0;
    let allocations = allocations_during(|| {
        for k in 0..100 {
            let q = JointVector::<6>::from_element(0.01 * k as f64);
            let state = robot.chain.kinematics(&mut ws, &q).unwrap();
            let pose = state.base_from_link(&link).unwrap();
            state
                .point_jacobian(&link, &Point3::new(0.1, 0.2, 0.3), &mut point_jacobian)
                .unwrap();
            checksum += state.tip_jacobian()[(5, 4)] + point_jacobian[(0, 4)] + pose.translation.x;
        }
    });
    assert_eq!(allocations, 0);
    assert!(checksum.is_finite());
}
