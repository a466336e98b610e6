//! The hardware-loop façade (`servostack::servo`) in small closed loops: the simulated robot moves by the velocity the
//! façade returns, and the pixels the façade reads are made by the true (distorted) camera from the simulated robot.
//!
//! The tests are split by theme:
//! - [`convergence`]: the closed loops reach the goal pose (the paper scenario through a distorted camera, depths from
//!   the corners, adaptive gains, taught pixels, out of a false equilibrium: theory D23, the classical task), and the
//!   steady-state periods allocate nothing;
//! - [`limits`]: joint-velocity limits, the velocity sent fed back at stack changes, braking before a hard limit and
//!   sliding along it (D25, D26);
//! - [`errors`]: bad measurements and configurations are named errors, and a bad call leaves no trace.
//!
//! This file holds what they share, and what `servo_acceleration`, `servo_methods` and `servo_observer` use too: the
//! paper scenario and its configuration, the simulated [`Plant`], the closed loop [`run_loop`], the
//! [`RaisedWristLimit`] setup with its braking check, and the check of the velocity fed back at a stack change.

mod convergence;
mod errors;
mod limits;

use crate::counting_allocator::allocations_during;
use nalgebra::Point2;
use servostack::avoidance::JointLimits;
use servostack::camera::{BrownConrady, CalibratedCamera};
use servostack::math::JointVector;
use servostack::robot::{builtin, KinematicsWorkspace};
use servostack::scenario::{Experiment, Scenario};
use servostack::servo::{Corners, DesiredImage, ServoConfig, ServoOutput, TaskChoice, VisualServo};
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

/// Asserts `q̇(τ⁺) = q̇_sent(τ⁻)` at a stack change: the controller's velocity at `at` is the one sent at `before`.
pub(crate) fn assert_fed_back_at_change(before: &ServoOutput<6>, at: &ServoOutput<6>) {
    let gap = (at.unscaled_velocity - before.velocity).norm();
    assert!(
        gap <= 1e-12 * (1.0 + before.velocity.norm()),
        "change at {}: gap {gap}",
        at.iteration
    );
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

    /// Asserts the braking of D25 on `output` at `q`: every joint keeps `|q̇_i| ≤ ξ d_i`, with `d_i` its distance to the
    /// limit it moves towards and `ξ` this setup's braking rate.
    pub(crate) fn assert_braked(&self, output: &ServoOutput<6>, q: &JointVector<6>) {
        let rate = self.config.controller.braking_rate;
        let (lower, upper) = (self.limits.lower(), self.limits.upper());
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
