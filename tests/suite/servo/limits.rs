//! Limits through the façade: joint-velocity limits scale the velocity uniformly and keep its direction, the velocity
//! sent is fed back so that it stays continuous at stack changes while saturated, the servo brakes before a hard limit
//! (theory D25) and before the border of the image, and slides along a hard limit with the joint locked (D26).

use super::{
    assert_fed_back_at_change, distorted_camera, paper, paper_config, run_loop, Plant,
    RaisedWristLimit,
};
use nalgebra::Isometry3;
use servostack::camera::{CalibratedCamera, CameraIntrinsics};
use servostack::controller::ControllerParameters;
use servostack::feature::point_interaction;
use servostack::math::JointVector;
use servostack::robot::builtin;
use servostack::servo::{DesiredImage, ServoConfig, ServoOutput, TaskChoice, VisualServo};
use servostack::sim::Scene;
use servostack::target::RectangleTarget;
use servostack::visual_task::FourthTask;

fn limited_velocity() -> JointVector<6> {
    // m/s for the three prismatic joints, rad/s for the three revolute ones.
    JointVector::from([0.02, 0.02, 0.02, 0.05, 0.05, 0.05])
}

/// With joint-velocity limits, every velocity sent is within them and parallel to the controller's (uniform scaling),
/// the limits are active, and the servo still converges.
#[test]
fn velocity_limits_are_respected_with_the_direction_kept() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let mut config = paper_config(&scenario, &experiment, camera);
    let max = limited_velocity();
    config.max_joint_velocity = max;
    let mut servo = VisualServo::new(config).unwrap();
    let mut plant = Plant::new(experiment.scene.clone(), camera, experiment.start, 0.01);
    let mut scaled = 0;
    let outputs = run_loop(&mut servo, &mut plant, 20_000, |output, _| {
        for i in 0..6 {
            assert!(
                output.velocity[i].abs() <= max[i] * (1.0 + 1e-12),
                "joint {i}: {} > {}",
                output.velocity[i],
                max[i]
            );
        }
        let (sent, raw) = (output.velocity, output.unscaled_velocity);
        if raw.norm() > 0.0 {
            let cosine = sent.dot(&raw) / (sent.norm() * raw.norm());
            assert!((cosine - 1.0).abs() <= 1e-12, "cosine {cosine}");
            assert!(((sent - raw * output.scale).norm()) <= 1e-15 * raw.norm());
        }
        assert!(output.scale > 0.0 && output.scale <= 1.0);
        assert_eq!(output.scaled, output.scale < 1.0);
        if output.scaled {
            scaled += 1;
        }
    });
    assert!(
        scaled > 100,
        "the limits were active at {scaled} periods only"
    );
    let last = outputs.last().unwrap();
    assert!(
        last.converged,
        "not converged under velocity limits: {last:?}"
    );
}

/// Continuity of the velocity *sent* at stack changes while saturated: pushes every transition (ε_add out of reach),
/// tight limits. Since the sent velocity is fed back, the controller's velocity at a change equals the velocity sent
/// at the period before (it would equal the controller's *unscaled* one without the feedback, which the limits made
/// larger), so the sent velocity does not jump at a change: its step there is no larger than a step without change.
#[test]
fn the_sent_velocity_is_fed_back_and_stays_continuous_at_stack_changes() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let mut config = paper_config(&scenario, &experiment, camera);
    config.max_joint_velocity = limited_velocity() * 0.5;
    config.controller = ControllerParameters {
        settle_velocity: 1e3, // push as soon as n_settle/μ has passed
        settle_velocity_with_removal: 1e3,
        ..scenario.controller
    };
    let mut servo = VisualServo::new(config).unwrap();
    let mut plant = Plant::new(experiment.scene.clone(), camera, experiment.start, 0.01);
    let outputs = run_loop(&mut servo, &mut plant, 600, |_, _| {});
    let changes: Vec<usize> = outputs
        .iter()
        .filter(|o| o.event.is_some() && o.iteration > 0)
        .map(|o| o.iteration)
        .collect();
    assert!(changes.len() >= 3, "changes at {changes:?}");
    let steps: Vec<f64> = outputs
        .windows(2)
        .map(|w| (w[1].velocity - w[0].velocity).norm())
        .collect();
    let mut saturated_changes = 0;
    for &k in &changes {
        let (before, at) = (&outputs[k - 1], &outputs[k]);
        assert_eq!(at.iteration, k);
        if before.scaled {
            saturated_changes += 1;
            // Without the feedback the controller would blend from `before.unscaled_velocity`, which differs.
            assert!((before.unscaled_velocity - before.velocity).norm() > 1e-6);
        }
        // q̇(τ⁺) = q̇_sent(τ⁻): the controller's velocity at the change is the one the robot received.
        assert_fed_back_at_change(before, at);
        // The sent velocity's step at the change is no larger than the steps around it without a change.
        let jump = steps[k - 1];
        let around = steps[k.saturating_sub(6)..k - 1]
            .iter()
            .copied()
            .fold(0.0, f64::max);
        assert!(
            jump <= around + 1e-12,
            "change at {k}: jump {jump} > {around}"
        );
    }
    assert!(
        saturated_changes >= 2,
        "only {saturated_changes} changes happened while the limits were active"
    );
}

/// D25 through the façade: the classical task drives the last wrist joint into a raised lower limit. Unbraked, the
/// robot crosses it; braked (the default), every joint moving towards a limit keeps `|q̇_i| ≤ ξ d_i`, the braking
/// acts, and no limit is crossed.
#[test]
fn the_servo_brakes_before_a_hard_limit() {
    let setup = RaisedWristLimit::new();
    assert!(setup.config.controller.braking_rate.is_finite());
    let mut unbraked = setup.config.clone();
    unbraked.controller.braking_rate = f64::INFINITY;
    assert!(
        setup.run(unbraked, &mut |_, _, _, _| {}).0,
        "the classical law no longer reaches the limit"
    );
    let mut braked = 0;
    let (crossed, _) = setup.run(setup.config.clone(), &mut |_, output, q, _| {
        setup.assert_braked(output, q);
        braked += usize::from(output.scaled);
    });
    assert!(!crossed, "a limit was crossed with the braking");
    assert!(braked > 10, "braked at {braked} periods only");
}

/// D26 through the façade: braked at its raised limit, the wrist joint is locked (the default; the step allocates
/// nothing) and the five other joints go on reducing the task error, which ends well below where the braking alone
/// stops the robot; no limit is crossed. Each change of the locked joints starts a transition: the velocity sent
/// never jumps, although the law does at the change.
#[test]
fn the_servo_slides_along_a_hard_limit() {
    let setup = RaisedWristLimit::new();
    assert!(setup.config.controller.lock_band > 0.0);
    let mut braked_only = setup.config.clone();
    braked_only.controller.lock_band = 0.0;
    let (crossed, stopped) = setup.run(braked_only, &mut |_, _, _, _| {});
    assert!(!crossed);
    let mut locked_periods = 0;
    let mut previous: Option<([bool; 6], JointVector<6>)> = None;
    // At the periods where the locked joints change: the largest step of the velocity sent, and of the law.
    let (mut largest_law_jump, mut largest_step): (f64, f64) = (0.0, 0.0);
    let mut allocating_locked_steps = 0;
    let (crossed, slid) = setup.run(
        setup.config.clone(),
        &mut |servo, output, _, allocations| {
            let workspace = servo.controller().law_workspace();
            let locked = output.locked;
            assert_eq!(&locked, workspace.locked_joints());
            locked_periods += usize::from(locked[5]);
            // The lock is part of the real-time step: nothing allocated while it acts.
            allocating_locked_steps += usize::from(locked[5] && allocations > 0);
            assert!(!locked[..5].contains(&true), "{locked:?}");
            if let Some((locked_before, sent_before)) = previous {
                if locked != locked_before {
                    let law = workspace.last_output().law();
                    largest_step = largest_step.max((output.velocity - sent_before).norm());
                    largest_law_jump = largest_law_jump.max((law - sent_before).norm());
                }
            }
            previous = Some((locked, output.velocity));
        },
    );
    assert!(!crossed, "a limit was crossed with the lock");
    assert!(locked_periods > 100, "locked at {locked_periods} periods");
    assert_eq!(allocating_locked_steps, 0);
    assert!(
        slid.error_norm < 0.5 * stopped.error_norm,
        "error {} with the lock, {} stopped by the braking",
        slid.error_norm,
        stopped.error_norm
    );
    assert!(
        largest_law_jump > 0.01 && largest_step < 0.01 * largest_law_jump,
        "largest step {largest_step} for a law jump of {largest_law_jump} at a lock change"
    );
}

/// What a test checks at each period: the corners (normalised, true) and the servo's output.
type PeriodCheck<'a> = dyn FnMut(&[(f64, f64); 4], &ServoOutput<6>) + 'a;

/// D25 at the border of the image through the façade: the classical task at 20 s⁻¹ drives the camera from 0.5 m to
/// 0.21 m of the 0.2 × 0.1 m target, whose image then spans the frame to 34 px of its left and right borders. At that
/// gain the corners would run to the border at four times `ξ` times their distance to it; braked (the default), no
/// corner moves towards a border faster than `ξ` times its distance to it in pixels (its velocity from the twist sent
/// and the depths the servo used, `L_j v`), the braking acts, and the servo converges. Unbraked, the corners run
/// faster than that at many periods.
#[test]
fn the_servo_brakes_before_the_border_of_the_image() {
    let robot = builtin::afma6().unwrap();
    let intrinsics = CameraIntrinsics::new(600.0, 600.0, 320.0, 240.0, 640.0, 480.0).unwrap();
    let camera = CalibratedCamera::pinhole(intrinsics);
    let target = RectangleTarget::new(0.2, 0.1).unwrap();
    let start = JointVector::from([0.0, 0.0, 0.0, 0.0, 0.3, 0.0]);
    let scene = Scene::with_target_seen_from(
        robot.chain.clone(),
        robot.mount,
        intrinsics,
        target,
        &start,
        &Isometry3::translation(0.0, 0.0, 0.5),
        0.1,
    )
    .unwrap();
    let mut config = ServoConfig::new(
        robot.chain,
        robot.mount,
        camera,
        target,
        DesiredImage::Pose(Isometry3::translation(0.0, 0.0, 0.21)),
    );
    config.tasks = TaskChoice::Classical {
        gain: 20.0,
        fourth: FourthTask::Auto,
    };
    let rate = config.controller.braking_rate;
    assert!(config.controller.brake_at_image_border && rate.is_finite());
    let run = |config: ServoConfig<6>, check: &mut PeriodCheck| {
        let mut servo = VisualServo::new(config).unwrap();
        let mut plant = Plant::new(scene.clone(), camera, start, 0.01);
        for _ in 0..2000 {
            let corners = plant.normalized().map(|p| (p.x, p.y));
            let output = *servo.step(plant.time(), &plant.pixels(), &plant.q).unwrap();
            check(&corners, &output);
            if output.converged {
                return true;
            }
            plant.apply(&output.velocity);
        }
        false
    };
    // The periods at which a corner moves towards a border faster than `ξ` times its distance to it.
    let too_fast = |corners: &[(f64, f64); 4], output: &ServoOutput<6>| {
        corners.iter().zip(&output.depths).any(|(&(x, y), &depth)| {
            let (row_x, row_y) = point_interaction(x, y, 1.0 / depth);
            let (u, v) = intrinsics.normalized_to_pixel(x, y);
            let speeds = [
                600.0 * (row_x * output.camera_twist)[0],
                600.0 * (row_y * output.camera_twist)[0],
            ];
            [(speeds[0], u, 640.0), (speeds[1], v, 480.0)]
                .into_iter()
                .any(|(speed, position, extent)| {
                    let room = if speed > 0.0 {
                        extent - position
                    } else {
                        position
                    };
                    speed.abs() > rate * room * (1.0 + 1e-9)
                })
        })
    };
    let (mut braked_fast, mut braked) = (0, 0);
    let converged = run(config.clone(), &mut |corners, output| {
        braked_fast += usize::from(too_fast(corners, output));
        braked += usize::from(output.scaled);
    });
    assert!(converged, "the braked servo did not converge");
    assert_eq!(braked_fast, 0);
    let mut unbraked = config;
    unbraked.controller.brake_at_image_border = false;
    let (mut unbraked_fast, mut unbraked_scaled) = (0, 0);
    assert!(run(unbraked, &mut |corners, output| {
        unbraked_fast += usize::from(too_fast(corners, output));
        unbraked_scaled += usize::from(output.scaled);
    }));
    assert!(
        unbraked_fast > 10,
        "{unbraked_fast} periods too fast unbraked"
    );
    assert!(
        braked > unbraked_scaled + 10,
        "scaled at {braked} periods braked, {unbraked_scaled} unbraked"
    );
}
