//! The stack controller's step with the composed avoidance cost (joint limits, three obstacles, visibility) allocates
//! nothing while the obstacle cost is active (the model/workspace split).

use crate::obstacle_fixture as fixture;

use crate::counting_allocator::allocations_during;
use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use servostack::avoidance::Cost;
use servostack::camera::CameraIntrinsics;
use servostack::controller::{ControllerParameters, StackController};
use servostack::feature::InteractionSource;
use servostack::law::ControlLaw;
use servostack::math::JointVector;
use servostack::robot::{builtin, KinematicsWorkspace};
use servostack::sim::Scene;
use servostack::target::RectangleTarget;
use servostack::task::{Task, TaskValue};
use servostack::visual_task::{paper_tasks, VisualContext};

#[test]
fn controller_step_with_obstacles_and_visibility_allocates_nothing() {
    let robot = builtin::afma6().unwrap();
    let intrinsics = CameraIntrinsics::new(800.0, 800.0, 320.0, 240.0, 640.0, 480.0).unwrap();
    let c_from_o = Isometry3::from_parts(
        Vector3::new(0.0, 0.0, 0.5).into(),
        UnitQuaternion::from_euler_angles(0.0, 20f64.to_radians(), 0.0),
    );
    let scene = Scene::with_target_seen_from(
        robot.chain,
        robot.mount,
        intrinsics,
        RectangleTarget::new(0.2, 0.1).unwrap(),
        &fixture::reference_q(),
        &c_from_o,
        0.1,
    )
    .unwrap()
    .with_obstacles(fixture::obstacle_cost(0.15));
    // A wide image band, and the facing term of D27 from 10° (the camera sees the target 20° off its normal): both active.
    let visibility = scene.visibility_cost(200.0, Some(10.0)).unwrap();
    let q = fixture::reference_q();
    let image_only = scene
        .visibility_cost(200.0, None)
        .unwrap()
        .value(&q)
        .unwrap();
    assert!(image_only > 0.0 && visibility.value(&q).unwrap() > image_only);
    let scene = scene.with_visibility(visibility);
    let desired_view = scene.view_from(&c_from_o).unwrap();
    let desired = desired_view.observation().unwrap();
    let tasks = paper_tasks(&desired, 0.5, 0.5, [0.5; 4], InteractionSource::Exact).unwrap();
    let mut values: Vec<TaskValue<6>> = tasks
        .iter()
        .map(TaskValue::for_task::<VisualContext<'_, 6>, _>)
        .collect::<Result<_, _>>()
        .unwrap();
    let cost = scene.avoidance_cost();
    let law = ControlLaw::new(5.0, 1.0).unwrap();
    let parameters = ControllerParameters {
        removal_threshold: Some(scene.limits().default_removal_threshold()),
        ..ControllerParameters::default()
    };
    let mut controller = StackController::new(parameters, &values).unwrap();
    let mut workspace = KinematicsWorkspace::new();
    let mut q =
        fixture::reference_q() + JointVector::<6>::new(0.02, -0.02, -0.03, 0.05, -0.05, 0.05);
    let (mut quiet_steps, mut active_steps) = (0, 0);
    for iteration in 0..400 {
        let mut step = None;
        let allocations = allocations_during(|| {
            let view = scene.observe(&mut workspace, &q).unwrap();
            let observation = view.observation().unwrap();
            let context = VisualContext {
                observation: &observation,
                camera_jacobian: &view.camera_jacobian,
            };
            for (task, value) in tasks.iter().zip(values.iter_mut()) {
                task.evaluate(&context, value).unwrap();
            }
            let time = iteration as f64 * 0.01;
            step = Some(
                controller
                    .step(
                        &law,
                        &values,
                        Some(&cost as &dyn Cost<6>),
                        &q,
                        iteration,
                        time,
                    )
                    .unwrap(),
            );
        });
        let step = step.unwrap();
        // A stack change logs an event (which may allocate); every other step must not.
        if step.event.is_none() && iteration > 0 {
            assert_eq!(allocations, 0, "iteration {iteration}");
            quiet_steps += 1;
            if scene.obstacles().unwrap().value(&q).unwrap() > 0.0 {
                active_steps += 1;
            }
        }
        q += step.velocity * 0.01;
    }
    assert!(quiet_steps > 300, "{quiet_steps} steps without event");
    assert!(
        active_steps > 300,
        "obstacle cost active on {active_steps} steps only"
    );
}
