//! The hardware-loop façade (`servostack::servo`) in small closed loops: the simulated robot moves by the velocity the
//! façade returns, and the pixels the façade reads are made by the true (distorted) camera from the simulated robot.

use crate::counting_allocator::allocations_during;
use nalgebra::{Isometry3, Point2};
use servostack::avoidance::JointLimits;
use servostack::camera::{BrownConrady, CalibratedCamera, CameraIntrinsics};
use servostack::controller::{ControllerParameters, EventKind, HardLimitRule};
use servostack::depth::DepthSource;
use servostack::math::JointVector;
use servostack::robot::{builtin, KinematicsWorkspace};
use servostack::scenario::{Experiment, Scenario};
use servostack::servo::{
    AdaptiveGain, Corners, DesiredImage, ServoConfig, ServoError, ServoMethod, ServoOutput,
    TaskChoice, VisualServo,
};
use servostack::sim::Scene;
use servostack::target::RectangleTarget;
use servostack::visual_task::FourthTask;
use std::path::Path;

/// A lens with visible barrel distortion and some tangential terms (a 320 px radius moves by about 8 px).
fn lens() -> BrownConrady {
    BrownConrady::new(-0.12, 0.03, 4e-4, -3e-4, 0.0).unwrap()
}

pub(crate) fn paper() -> (Scenario, Experiment<6>) {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/scenarios/paper_afma6.toml"
    );
    let scenario = Scenario::from_file(Path::new(path)).unwrap();
    let experiment = scenario.experiment::<6>().unwrap();
    (scenario, experiment)
}

/// The façade's configuration for the paper scenario, with the scenario's gains, `κ`, `ρ` and controller, seen through
/// `camera`.
pub(crate) fn paper_config(
    scenario: &Scenario,
    experiment: &Experiment<6>,
    camera: CalibratedCamera,
) -> ServoConfig<6> {
    let robot = builtin::afma6().unwrap();
    let target = RectangleTarget::new(scenario.target.width_m, scenario.target.height_m).unwrap();
    let mut config = ServoConfig::new(
        robot.chain,
        robot.mount,
        camera,
        target,
        DesiredImage::Pose(experiment.desired_camera_from_target),
    );
    config.tasks = TaskChoice::Sequence {
        gains: scenario.tasks.gains,
        fourth: FourthTask::Auto,
    };
    config.avoidance_gain = scenario.avoidance.gain;
    config.activation_ratio = scenario.avoidance.activation_ratio;
    config.controller = scenario.controller;
    config
}

/// The simulated robot and camera: Euler integration of the velocity sent, pixels through the true camera.
pub(crate) struct Plant {
    scene: Scene<6>,
    camera: CalibratedCamera,
    workspace: KinematicsWorkspace<6>,
    pub(crate) q: JointVector<6>,
    period: f64,
    iteration: usize,
}

impl Plant {
    pub(crate) fn new(
        scene: Scene<6>,
        camera: CalibratedCamera,
        q: JointVector<6>,
        period: f64,
    ) -> Self {
        Self {
            scene,
            camera,
            workspace: KinematicsWorkspace::new(),
            q,
            period,
            iteration: 0,
        }
    }

    pub(crate) fn time(&self) -> f64 {
        self.iteration as f64 * self.period
    }

    /// The true normalised points (undistorted).
    fn normalized(&mut self) -> [Point2<f64>; 4] {
        let view = self.scene.observe(&mut self.workspace, &self.q).unwrap();
        view.points.map(|p| Point2::new(p.x, p.y))
    }

    /// The four corners as the camera measures them (px, distorted).
    pub(crate) fn pixels(&mut self) -> Corners {
        let camera = self.camera;
        self.normalized().map(|p| Some(camera.pixel_of(p.x, p.y)))
    }

    fn normalized_corners(&mut self) -> Corners {
        self.normalized().map(|p| Some((p.x, p.y)))
    }

    /// Moves the robot by `velocity` over one period.
    pub(crate) fn apply(&mut self, velocity: &JointVector<6>) {
        self.q += velocity * self.period;
        self.iteration += 1;
    }

    /// The camera pose error against the pose at `goal` (mm, deg).
    pub(crate) fn pose_error(&mut self, goal: &JointVector<6>) -> (f64, f64) {
        let mount = builtin::afma6().unwrap().mount;
        let chain = self.scene.chain().clone();
        let now = mount.base_from_camera(
            chain
                .kinematics(&mut self.workspace, &self.q)
                .unwrap()
                .base_from_tip(),
        );
        let want = mount.base_from_camera(
            chain
                .kinematics(&mut self.workspace, goal)
                .unwrap()
                .base_from_tip(),
        );
        let error = want.inverse() * now;
        (
            error.translation.vector.norm() * 1e3,
            error.rotation.angle().to_degrees(),
        )
    }
}

pub(crate) fn distorted_camera(scene: &Scene<6>) -> CalibratedCamera {
    CalibratedCamera {
        intrinsics: *scene.intrinsics(),
        distortion: lens(),
    }
}

/// Runs the closed loop for at most `max_steps` periods (stopping at convergence), checking every output with `check`;
/// returns the outputs.
pub(crate) fn run_loop(
    servo: &mut VisualServo<6>,
    plant: &mut Plant,
    max_steps: usize,
    mut check: impl FnMut(&ServoOutput<6>, &Plant),
) -> Vec<ServoOutput<6>> {
    let mut outputs = Vec::with_capacity(max_steps);
    for _ in 0..max_steps {
        let pixels = plant.pixels();
        let output = *servo.step(plant.time(), &pixels, &plant.q).unwrap();
        check(&output, plant);
        outputs.push(output);
        if output.converged {
            break;
        }
        plant.apply(&output.velocity);
        assert!(
            plant.scene.limits().violated_joint(&plant.q).is_none(),
            "joint limit at {} s",
            plant.time()
        );
    }
    outputs
}

/// The paper scenario through a distorted camera: the façade undistorts the measured pixels, the full method removes and
/// puts back tasks as needed, stays inside the joint limits and converges to the goal pose. With the paper's settling
/// threshold for the pushes, so that the removal happens (on this unsaturated path the full method's earlier pushes,
/// D5, reach the goal without removing anything).
#[test]
fn converges_on_the_paper_scenario_with_a_distorted_camera() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let mut config = paper_config(&scenario, &experiment, camera);
    config.controller.settle_velocity_with_removal = config.controller.settle_velocity;
    let mut servo = VisualServo::new(config).unwrap();
    let mut plant = Plant::new(experiment.scene.clone(), camera, experiment.start, 0.01);
    let outputs = run_loop(&mut servo, &mut plant, 10_000, |output, _| {
        assert!(output.velocity.iter().all(|v| v.is_finite()));
        assert!(!output.scaled, "no velocity limit was set");
    });
    let last = outputs.last().unwrap();
    assert!(last.converged, "not converged: {last:?}");
    assert_eq!(last.stacked(), &[0, 1, 2, 3]);
    let (mm, deg) = plant.pose_error(&experiment.desired_joints);
    assert!(mm < 1.0 && deg < 0.05, "pose error {mm} mm, {deg}°");
    // The scenario's story: a_n (task 2) was removed on the way and put back.
    let events = servo.controller().events();
    assert!(
        events
            .iter()
            .any(|e| e.kind == EventKind::Remove && e.task == 2),
        "{events:?}"
    );
}

/// No depth known in advance: the façade estimates the target's pose from the four measured corners at each period
/// ([`DepthSource::TargetPose`]) and still reaches the goal pose within the limits.
#[test]
fn converges_on_the_paper_scenario_with_depths_from_the_measured_corners() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let mut config = paper_config(&scenario, &experiment, camera);
    config.depth = DepthSource::TargetPose;
    let mut servo = VisualServo::new(config).unwrap();
    let mut plant = Plant::new(experiment.scene.clone(), camera, experiment.start, 0.01);
    let outputs = run_loop(&mut servo, &mut plant, 10_000, |_, _| {});
    assert!(outputs.last().unwrap().converged);
    let (mm, deg) = plant.pose_error(&experiment.desired_joints);
    assert!(mm < 1.0 && deg < 0.05, "pose error {mm} mm, {deg}°");
}

/// Corners that give no target pose (three of them collinear) are a named error that leaves no trace.
#[test]
fn corners_without_a_target_pose_are_a_named_error_and_leave_no_trace() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let config = || {
        let mut config = paper_config(&scenario, &experiment, camera);
        config.depth = DepthSource::TargetPose;
        config
    };
    bad_calls_leave_no_trace(config, 200, true, |servo, plant, k, _| {
        if k % 50 != 0 {
            return None;
        }
        let mut corners = plant.normalized_corners();
        // Corner 2 halfway between corners 0 and 1 (still in the image).
        let (Some(a), Some(b)) = (corners[0], corners[1]) else {
            unreachable!("the plant measures every corner")
        };
        corners[2] = Some((0.5 * (a.0 + b.0), 0.5 * (a.1 + b.1)));
        let error = servo
            .step_normalized(plant.time(), &corners, &plant.q)
            .unwrap_err();
        assert!(matches!(error, ServoError::TargetPose(_)), "{error}");
        Some(error)
    });
}

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
        let gap = (at.unscaled_velocity - before.velocity).norm();
        assert!(
            gap <= 1e-12 * (1.0 + before.velocity.norm()),
            "change at {k}: gap {gap}"
        );
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

/// ViSP's `vpAdaptiveGain::initStandard(λ0, λ∞, λ'0)`: `λ(x) = a e^{−b x} + c`, `a = λ0 − λ∞`, `b = λ'0 / a`, `c = λ∞`.
#[test]
fn adaptive_gain_matches_visp_formula() {
    let gain = AdaptiveGain::new(4.0, 0.4, 30.0).unwrap();
    let (a, b, c) = (3.6, 30.0 / 3.6, 0.4);
    for x in [0.0, 0.05, 1.0] {
        let visp = a * f64::exp(-b * x) + c;
        assert!(
            (gain.value(x) - visp).abs() <= 1e-15,
            "λ({x}) = {}, ViSP {visp}",
            gain.value(x)
        );
    }
    assert_eq!(gain.value(0.0), 4.0);
    assert!((gain.value(1e3) - 0.4).abs() < 1e-15);
    // Constant and invalid gains.
    assert_eq!(AdaptiveGain::new(0.7, 0.7, 5.0).unwrap().value(0.3), 0.7);
    assert!(matches!(
        AdaptiveGain::new(0.0, 0.4, 30.0),
        Err(ServoError::InvalidParameter { .. })
    ));
    assert!(matches!(
        AdaptiveGain::new(0.4, 4.0, 30.0),
        Err(ServoError::InvalidParameter { .. })
    ));
    // A gain growing with the error: λ'(0) < 0 (the derivative at 0 is −λ'(0) > 0).
    let growing = AdaptiveGain::new(0.1, 0.5, -2.0).unwrap();
    let (a, b, c) = (-0.4, -2.0 / -0.4, 0.5);
    for x in [0.0, 0.2, 3.0] {
        assert!((growing.value(x) - (a * f64::exp(-b * x) + c)).abs() <= 1e-15);
    }
    assert!(growing.value(0.2) > growing.value(0.0));
    assert!(matches!(
        AdaptiveGain::new(4.0, 0.4, f64::NAN),
        Err(ServoError::InvalidParameter { .. })
    ));
}

/// The servo applies the adaptive gain to each task at its error: `λ_i = λ(‖e_i‖∞)` (checked on the one-row tasks,
/// where `‖e_i‖∞ = ‖e_i‖`), and the run still converges.
#[test]
fn the_servo_uses_the_adaptive_gain_of_each_task_error() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let mut config = paper_config(&scenario, &experiment, camera);
    let gain = AdaptiveGain::new(0.6, 0.4, 2.0).unwrap();
    config.adaptive_gain = Some(gain);
    let mut servo = VisualServo::new(config).unwrap();
    let mut plant = Plant::new(experiment.scene.clone(), camera, experiment.start, 0.01);
    let mut distinct = false;
    let outputs = run_loop(&mut servo, &mut plant, 10_000, |output, _| {
        for task in [1, 2] {
            let expected = gain.value(output.task_errors[task]);
            assert!((output.task_gains[task] - expected).abs() <= 1e-15);
        }
        distinct |= (output.task_gains[1] - output.task_gains[2]).abs() > 1e-3;
    });
    assert!(distinct, "the gains never differed between tasks");
    assert!(outputs.last().unwrap().converged);
}

/// Steps the same loop twice: once clean, once with a bad call before each good one at `bad_at`; each bad call gives
/// the expected error, and the good calls give exactly the clean run's outputs (the memory is kept).
fn bad_calls_leave_no_trace(
    config: impl Fn() -> ServoConfig<6>,
    steps: usize,
    normalized: bool,
    mut bad: impl FnMut(&mut VisualServo<6>, &mut Plant, usize, &ServoOutput<6>) -> Option<ServoError>,
) {
    let (_, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let call = |servo: &mut VisualServo<6>, plant: &mut Plant| {
        let q = plant.q;
        let t = plant.time();
        if normalized {
            let corners = plant.normalized_corners();
            *servo.step_normalized(t, &corners, &q).unwrap()
        } else {
            let corners = plant.pixels();
            *servo.step(t, &corners, &q).unwrap()
        }
    };
    let mut clean = Vec::new();
    let mut servo = VisualServo::new(config()).unwrap();
    let mut plant = Plant::new(experiment.scene.clone(), camera, experiment.start, 0.01);
    for _ in 0..steps {
        let output = call(&mut servo, &mut plant);
        plant.apply(&output.velocity);
        clean.push(output);
    }
    let mut servo = VisualServo::new(config()).unwrap();
    let mut plant = Plant::new(experiment.scene.clone(), camera, experiment.start, 0.01);
    let mut errors = 0;
    for k in 0..steps {
        if k > 0 {
            if let Some(expected) = bad(&mut servo, &mut plant, k, &clean[k - 1]) {
                let _ = expected;
                errors += 1;
            }
        }
        let output = call(&mut servo, &mut plant);
        assert_eq!(output, clean[k], "period {k} differs after a bad call");
        plant.apply(&output.velocity);
    }
    assert!(errors > 0);
}

/// Each bad measurement gives its named error and leaves no trace: NaN pixel, missing corner, pixel outside the image,
/// non-finite joint, time equal to or before the last accepted one.
#[test]
fn bad_pixels_joints_and_times_are_named_errors_and_leave_no_trace() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let config = || paper_config(&scenario, &experiment, camera);
    bad_calls_leave_no_trace(config, 400, false, |servo, plant, k, _| {
        if k % 5 != 0 {
            return None;
        }
        let (t, q) = (plant.time(), plant.q);
        let good = plant.pixels();
        let corner = (k / 5) % 4;
        let error = match (k / 5) % 7 {
            0 => {
                let mut c = good;
                c[corner] = Some((f64::NAN, 100.0));
                let e = servo.step(t, &c, &q).unwrap_err();
                assert!(
                    matches!(e, ServoError::NonFiniteCorner { index, .. } if index == corner),
                    "{e}"
                );
                e
            }
            1 => {
                let mut c = good;
                c[corner] = None;
                let e = servo.step(t, &c, &q).unwrap_err();
                assert_eq!(e, ServoError::MissingCorner { index: corner });
                e
            }
            2 => {
                let mut c = good;
                c[corner] = Some((650.0, 200.0));
                let e = servo.step(t, &c, &q).unwrap_err();
                assert!(
                    matches!(e, ServoError::OutsideImage { index, u, .. } if index == corner && u == 650.0),
                    "{e}"
                );
                let mut c = good;
                c[corner] = Some((300.0, -0.5));
                assert!(matches!(
                    servo.step(t, &c, &q),
                    Err(ServoError::OutsideImage { .. })
                ));
                e
            }
            3 => {
                let mut bad_q = q;
                bad_q[4] = f64::INFINITY;
                let e = servo.step(t, &good, &bad_q).unwrap_err();
                assert!(
                    matches!(e, ServoError::NonFiniteJoint { joint: 4, .. }),
                    "{e}"
                );
                e
            }
            4 => {
                // The last accepted time, again.
                let previous = (plant.iteration - 1) as f64 * plant.period;
                let e = servo.step(previous, &good, &q).unwrap_err();
                assert!(matches!(e, ServoError::TimeNotIncreasing { .. }), "{e}");
                e
            }
            5 => {
                let e = servo.step(t - 1.0, &good, &q).unwrap_err();
                assert!(matches!(e, ServoError::TimeNotIncreasing { .. }), "{e}");
                assert!(matches!(
                    servo.step(f64::NAN, &good, &q),
                    Err(ServoError::TimeNotIncreasing { .. })
                ));
                e
            }
            _ => {
                // Normalised corners: NaN and outside the image.
                let mut n = plant.normalized_corners();
                n[corner] = Some((0.1, f64::NAN));
                let e = servo.step_normalized(t, &n, &q).unwrap_err();
                assert!(matches!(e, ServoError::NonFiniteCorner { .. }), "{e}");
                n[corner] = Some((0.9, 0.0)); // 600 px × 0.9 + 320 > 640
                assert!(matches!(
                    servo.step_normalized(t, &n, &q),
                    Err(ServoError::OutsideImage { .. })
                ));
                e
            }
        };
        Some(error)
    });
}

/// The online depth estimator given an image motion opposite to the camera's (noise larger than the motion) would
/// estimate a negative depth: a named error, the estimator keeps its state, and the next good period continues exactly.
#[test]
fn a_non_positive_estimated_depth_is_a_named_error_and_leaves_no_trace() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let config = || {
        let mut config = paper_config(&scenario, &experiment, camera);
        config.depth = DepthSource::Estimated {
            initial_depth_m: 0.5,
            memory_s: 1e-3,
            window_frames: 1,
        };
        config
    };
    let mut seen = 0;
    bad_calls_leave_no_trace(config, 60, true, |servo, plant, k, previous| {
        if k < 20 || k % 10 != 0 {
            return None;
        }
        // The camera twist over the last period, and the image motion it makes at the last points for a depth of
        // −0.1 m (1/Z = −10): b(s, ω) + ρ a(s, υ) with ρ < 0 (depth module docs).
        let v = previous.camera_twist;
        let dt = plant.period;
        plant.iteration -= 1;
        plant.q -= previous.velocity * dt;
        let last = plant.normalized();
        plant.q += previous.velocity * dt;
        plant.iteration += 1;
        let corners = last.map(|p| {
            let (x, y) = (p.x, p.y);
            let a = (-v[0] + x * v[2], -v[1] + y * v[2]);
            let b = (
                x * y * v[3] - (1.0 + x * x) * v[4] + y * v[5],
                (1.0 + y * y) * v[3] - x * y * v[4] - x * v[5],
            );
            let rho = -10.0;
            Some((x + (b.0 + rho * a.0) * dt, y + (b.1 + rho * a.1) * dt))
        });
        let error = servo
            .step_normalized(plant.time(), &corners, &plant.q)
            .unwrap_err();
        assert!(
            matches!(error, ServoError::NonPositiveDepth { depth, .. } if depth <= 0.0),
            "{error}"
        );
        seen += 1;
        Some(error)
    });
    assert!(seen >= 3);
}

/// The peer scene (docs/peer_scene.md): Afma6, 600 px camera, the 0.2 × 0.1 m target at 0.5 m head-on from q_d.
fn peer(depth: DepthSource) -> (VisualServo<6>, Plant) {
    let robot = builtin::afma6().unwrap();
    let intrinsics = CameraIntrinsics::new(600.0, 600.0, 320.0, 240.0, 640.0, 480.0).unwrap();
    let target = RectangleTarget::new(0.2, 0.1).unwrap();
    let desired_q = JointVector::from([0.0, 0.0, 0.0, 0.0, 0.3, 0.0]);
    let goal = Isometry3::translation(0.0, 0.0, 0.5);
    let scene = Scene::with_target_seen_from(
        robot.chain.clone(),
        robot.mount,
        intrinsics,
        target,
        &desired_q,
        &goal,
        0.1,
    )
    .unwrap();
    let camera = CalibratedCamera {
        intrinsics,
        distortion: lens(),
    };
    let mut config = ServoConfig::new(
        robot.chain,
        robot.mount,
        camera,
        target,
        DesiredImage::Pose(goal),
    );
    config.depth = depth;
    config.max_joint_velocity = JointVector::repeat(0.2);
    let start = desired_q + JointVector::from([0.05, -0.04, -0.10, 0.25, -0.18, 0.12]);
    (
        VisualServo::new(config).unwrap(),
        Plant::new(scene, camera, start, 0.01),
    )
}

/// 1000 steady-state periods of the façade (undistortion, depths, kinematics, tasks, controller, saturation, feedback)
/// allocate nothing, from pixels with the desired depths and from normalised points with the online estimator.
#[test]
fn steady_state_periods_allocate_nothing() {
    for (depth, normalized) in [
        (DepthSource::Desired, false),
        (DepthSource::TargetPose, false),
        (
            DepthSource::Estimated {
                initial_depth_m: 0.4,
                memory_s: 1.0,
                window_frames: 10,
            },
            true,
        ),
    ] {
        let (mut servo, mut plant) = peer(depth);
        let step = |servo: &mut VisualServo<6>, plant: &mut Plant| {
            let (t, q) = (plant.time(), plant.q);
            let output = if normalized {
                let corners = plant.normalized_corners();
                *servo.step_normalized(t, &corners, &q).unwrap()
            } else {
                let corners = plant.pixels();
                *servo.step(t, &corners, &q).unwrap()
            };
            plant.apply(&output.velocity);
            output
        };
        for _ in 0..50 {
            step(&mut servo, &mut plant);
        }
        let before = servo.last_output().error_norm;
        let mut last = None;
        let allocations = allocations_during(|| {
            for _ in 0..1000 {
                last = Some(step(&mut servo, &mut plant));
            }
        });
        assert_eq!(allocations, 0, "{depth:?}");
        let last = last.unwrap();
        assert!(
            last.error_norm < 0.5 * before,
            "{before} -> {}",
            last.error_norm
        );
        assert!(
            servo.controller().events().len() >= 2,
            "the stack changed on the way"
        );
    }
}

/// Desired pixels taught through the camera, with the desired depth, give the same servo as the desired pose they are
/// taught from (same desired points up to the undistortion's tolerance, same velocities) when the depths are the
/// constant `Z*` (taught pixels carry no per-point depth).
#[test]
fn taught_desired_pixels_match_the_desired_pose() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let mut from_pose = paper_config(&scenario, &experiment, camera);
    from_pose.depth = DepthSource::Constant {
        depth_m: experiment.desired_camera_from_target.translation.z,
    };
    let by_pose = VisualServo::new(from_pose.clone()).unwrap();
    let desired = by_pose.desired_points();
    let pixels = desired.map(|p| camera.pixel_of(p.x, p.y));
    let depth_m = experiment.desired_camera_from_target.translation.z;
    let mut taught = from_pose.clone();
    taught.desired = DesiredImage::Pixels { pixels, depth_m };
    let mut by_pixels = VisualServo::new(taught).unwrap();
    for (a, b) in by_pixels.desired_points().iter().zip(desired) {
        assert!((a.x - b.x).abs() < 1e-10 && (a.y - b.y).abs() < 1e-10);
    }
    let mut by_pose = by_pose;
    let mut plant = Plant::new(experiment.scene.clone(), camera, experiment.start, 0.01);
    for _ in 0..300 {
        let (t, q, corners) = (plant.time(), plant.q, plant.pixels());
        let a = *by_pose.step(t, &corners, &q).unwrap();
        let b = *by_pixels.step(t, &corners, &q).unwrap();
        assert!((a.velocity - b.velocity).norm() < 1e-6 * (1.0 + a.velocity.norm()));
        plant.apply(&a.velocity);
    }
    // A taught corner outside the image, a non-positive desired depth: errors at construction.
    let mut bad = from_pose.clone();
    bad.desired = DesiredImage::Pixels {
        pixels: [(-5.0, 10.0), pixels[1], pixels[2], pixels[3]],
        depth_m,
    };
    assert!(matches!(
        VisualServo::new(bad),
        Err(ServoError::OutsideImage { index: 0, .. })
    ));
    let mut bad = from_pose;
    bad.desired = DesiredImage::Pixels {
        pixels,
        depth_m: 0.0,
    };
    assert!(matches!(
        VisualServo::new(bad),
        Err(ServoError::InvalidParameter { .. })
    ));
}

/// D23 through the façade: a desired view turned by a few degrees (`afma6_false_equilibrium.toml`) at which the paper's
/// features are also achieved 0.11 m from the goal. With the image points in reserve the servo replaces the
/// third-order task by them once its stack has settled there, stays inside the limits and converges at the goal; kept
/// from escaping, it settles at the false equilibrium and, its corners away from their desired positions, never reports
/// convergence.
#[test]
fn the_servo_leaves_a_false_equilibrium_of_the_features() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/scenarios/afma6_false_equilibrium.toml"
    );
    let scenario = Scenario::from_file(Path::new(path)).unwrap();
    let experiment = scenario.experiment::<6>().unwrap();
    let camera = CalibratedCamera {
        intrinsics: *experiment.scene.intrinsics(),
        distortion: BrownConrady::default(),
    };
    let run = |escape_achieved_error: f64| {
        let mut config = paper_config(&scenario, &experiment, camera);
        config.controller.escape_achieved_error = escape_achieved_error;
        // Depths from the corners (exact here) and the scenario's robot limits (ViSP's defaults), as in the study the
        // draw comes from.
        config.depth = DepthSource::TargetPose;
        let s = &scenario.simulation;
        config.max_joint_velocity = JointVector::from([
            s.max_prismatic_velocity_m_s,
            s.max_prismatic_velocity_m_s,
            s.max_prismatic_velocity_m_s,
            s.max_revolute_velocity_rad_s,
            s.max_revolute_velocity_rad_s,
            s.max_revolute_velocity_rad_s,
        ]);
        let mut servo = VisualServo::new(config).unwrap();
        let mut plant = Plant::new(experiment.scene.clone(), camera, experiment.start, 0.01);
        let outputs = run_loop(&mut servo, &mut plant, 8000, |_, _| {});
        let escaped = servo
            .controller()
            .events()
            .iter()
            .any(|e| e.kind == EventKind::Escape && e.task == 4);
        let converged = outputs.last().unwrap().converged;
        (
            escaped,
            converged,
            plant.pose_error(&experiment.desired_joints),
            outputs,
        )
    };
    let (escaped, converged, (mm, deg), _) =
        run(ControllerParameters::default().escape_achieved_error);
    assert!(
        escaped && converged,
        "escaped {escaped}, converged {converged}"
    );
    assert!(mm < 1.0 && deg < 0.1, "pose error {mm} mm, {deg}°");

    // An achievement threshold no stack meets: no escape, the corners still checked.
    let (escaped, converged, (mm, _), outputs) = run(1e-300);
    assert!(!escaped && !converged);
    // The paper's four features did settle: only the corners tell that this is not the goal.
    let last = outputs.last().unwrap();
    assert!(last.task_errors[..4].iter().all(|&e| e < 1e-4), "{last:?}");
    assert!(last.task_errors[4] > 0.01 && mm > 50.0, "{last:?}, {mm} mm");
}

/// The classical task (one level, six features) through the façade servos the peer scene to its goal.
#[test]
fn the_classical_task_converges_on_the_peer_scene() {
    let (_, mut plant) = peer(DepthSource::Desired);
    let robot = builtin::afma6().unwrap();
    let mut config = ServoConfig::new(
        robot.chain,
        robot.mount,
        plant.camera,
        RectangleTarget::new(0.2, 0.1).unwrap(),
        DesiredImage::Pose(Isometry3::translation(0.0, 0.0, 0.5)),
    );
    config.tasks = TaskChoice::Classical {
        gain: 0.5,
        fourth: FourthTask::Auto,
    };
    let mut servo = VisualServo::new(config).unwrap();
    let outputs = run_loop(&mut servo, &mut plant, 5000, |output, _| {
        assert_eq!(output.task_count, 1);
    });
    let last = outputs.last().unwrap();
    assert!(last.converged, "{last:?}");
    let (mm, deg) = plant.pose_error(&JointVector::from([0.0, 0.0, 0.0, 0.0, 0.3, 0.0]));
    assert!(mm < 0.1 && deg < 0.01, "{mm} mm, {deg}°");
}

/// The classical task of the paper scenario through the façade, with the last wrist joint's lower limit raised above
/// its goal (−0.2 rad against −0.397): the task drives that joint into its limit.
pub(crate) struct RaisedWristLimit {
    pub(crate) config: ServoConfig<6>,
    pub(crate) limits: JointLimits<6>,
    scene: Scene<6>,
    camera: CalibratedCamera,
    start: JointVector<6>,
}

impl RaisedWristLimit {
    pub(crate) fn new() -> Self {
        let (scenario, experiment) = paper();
        let camera = distorted_camera(&experiment.scene);
        let mut config = paper_config(&scenario, &experiment, camera);
        config.tasks = TaskChoice::Classical {
            gain: scenario.tasks.classical_gain,
            fourth: FourthTask::Auto,
        };
        let mut lower = *config.chain.lower_limits();
        lower[5] = -0.2;
        let upper = *config.chain.upper_limits();
        config.chain = config.chain.clone().with_limits(lower, upper).unwrap();
        let limits = JointLimits::new(lower, upper, config.activation_ratio).unwrap();
        Self {
            config,
            limits,
            scene: experiment.scene,
            camera,
            start: experiment.start,
        }
    }

    /// Runs `config` for up to 3000 periods, calling `check` on each output (with the servo, before the velocity is
    /// applied, and the allocations the step made); returns whether a limit was crossed and the last output.
    pub(crate) fn run(
        &self,
        config: ServoConfig<6>,
        check: &mut dyn FnMut(&VisualServo<6>, &ServoOutput<6>, &JointVector<6>, usize),
    ) -> (bool, ServoOutput<6>) {
        let mut servo = VisualServo::new(config).unwrap();
        let mut plant = Plant::new(self.scene.clone(), self.camera, self.start, 0.01);
        let mut last = None;
        for _ in 0..3000 {
            let pixels = plant.pixels();
            let mut output = None;
            let allocations = allocations_during(|| {
                output = Some(*servo.step(plant.time(), &pixels, &plant.q).unwrap());
            });
            let output = output.unwrap();
            check(&servo, &output, &plant.q, allocations);
            plant.apply(&output.velocity);
            last = Some(output);
            if self.limits.violated_joint(&plant.q).is_some() {
                return (true, output);
            }
        }
        (false, last.unwrap())
    }
}

/// D25 through the façade: the classical task drives the last wrist joint into a raised lower limit. Unbraked, the
/// robot crosses it; braked (the default), every joint moving towards a limit keeps `|q̇_i| ≤ ξ d_i`, the braking
/// acts, and no limit is crossed.
#[test]
fn the_servo_brakes_before_a_hard_limit() {
    let setup = RaisedWristLimit::new();
    let rate = setup.config.controller.braking_rate;
    assert!(rate.is_finite());
    let (lower, upper) = (*setup.limits.lower(), *setup.limits.upper());
    let mut unbraked = setup.config.clone();
    unbraked.controller.braking_rate = f64::INFINITY;
    assert!(
        setup.run(unbraked, &mut |_, _, _, _| {}).0,
        "the classical law no longer reaches the limit"
    );
    let mut braked = 0;
    let (crossed, _) = setup.run(setup.config.clone(), &mut |_, output, q, _| {
        for i in 0..6 {
            let v = output.velocity[i];
            let distance = if v > 0.0 {
                upper[i] - q[i]
            } else {
                q[i] - lower[i]
            };
            assert!(
                v.abs() <= rate * distance * (1.0 + 1e-12),
                "joint {i}: {v} at {distance} from its limit"
            );
        }
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

/// Invalid configurations are named errors at construction.
#[test]
fn invalid_configurations_are_named_errors() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let base = paper_config(&scenario, &experiment, camera);
    let mut config = base.clone();
    config.max_joint_velocity[3] = 0.0;
    assert!(matches!(
        VisualServo::new(config),
        Err(ServoError::InvalidParameter {
            name: "max_joint_velocity",
            ..
        })
    ));
    let mut config = base.clone();
    config.max_joint_velocity[0] = f64::NAN;
    assert!(VisualServo::new(config).is_err());
    let mut config = base.clone();
    config.depth = DepthSource::PreviousPlane;
    assert!(matches!(
        VisualServo::new(config),
        Err(ServoError::UnsupportedDepthSource)
    ));
    // Saturation in the null space and the QP cascade need the period that sizes their box.
    let mut config = base.clone();
    config.controller.hard_limit_rule = HardLimitRule::SaturateInNullSpace;
    assert!(matches!(
        VisualServo::new(config),
        Err(ServoError::MissingControlPeriod)
    ));
    for method in [
        ServoMethod::SaturationInNullSpace,
        ServoMethod::HierarchicalQp,
    ] {
        let mut config = base.clone();
        config.method = method;
        assert!(matches!(
            VisualServo::new(config.clone()),
            Err(ServoError::MissingControlPeriod)
        ));
        for period in [0.0, -0.01, 2.0, f64::NAN, f64::INFINITY] {
            config.control_period_s = Some(period);
            assert!(
                matches!(
                    VisualServo::new(config.clone()),
                    Err(ServoError::InvalidParameter {
                        name: "control_period_s",
                        ..
                    })
                ),
                "{method:?}, period {period}"
            );
        }
    }
    let mut config = base.clone();
    config.depth = DepthSource::Constant { depth_m: -0.5 };
    assert!(matches!(
        VisualServo::new(config),
        Err(ServoError::Depth(_))
    ));
    let mut config = base.clone();
    config.convergence_error = 0.0;
    assert!(VisualServo::new(config).is_err());
    let mut config = base.clone();
    config.avoidance_gain = -1.0;
    assert!(matches!(VisualServo::new(config), Err(ServoError::Law(_))));
    let mut config = base;
    config.tasks = TaskChoice::Sequence {
        gains: [0.5, 0.0, 0.5, 0.5],
        fourth: FourthTask::Auto,
    };
    assert!(matches!(VisualServo::new(config), Err(ServoError::Task(_))));
}
