//! Fuzz cases of the hardware-loop façade ([`VisualServo`]): a seeded sequence of control periods on the paper's
//! scene through a distorted camera, each period's frame good or corrupted (non-finite, huge, missing, swapped or
//! off-image corners; repeated, backward, non-finite or far-future times; non-finite, huge or out-of-range joints),
//! the simulated robot moved by every velocity the façade returns.

use super::{finite, Verdict};
use crate::camera::{BrownConrady, CalibratedCamera, CameraIntrinsics};
use crate::math::JointVector;
use crate::robot::{builtin, KinematicsWorkspace};
use crate::scenario::Scenario;
use crate::servo::{Corners, DesiredImage, ServoConfig, TaskChoice, VisualServo};
use crate::target::RectangleTarget;
use crate::visual_task::FourthTask;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

/// Control periods per sequence.
pub const SERVO_PERIODS: usize = 40;

const PAPER: &str = include_str!("../../assets/scenarios/paper_afma6.toml");

/// Runs the sequence of `seed`; `Err` names the first non-finite value returned inside an `Ok`.
pub(super) fn check_servo(seed: u64) -> Verdict {
    match servo_steps(seed) {
        Ok(Ok(())) => Verdict::Accepted,
        Ok(Err(error)) => Verdict::Rejected(error),
        Err(what) => Verdict::NonFinite(what),
    }
}

/// `Ok(Err(message))` when the set-up itself is refused (it never is for the shipped scene).
fn servo_steps(seed: u64) -> Result<Result<(), String>, String> {
    let mut rng = StdRng::seed_from_u64(seed);
    let setup = || -> Result<_, Box<dyn std::error::Error>> {
        let scenario = Scenario::from_toml_str(PAPER, None)?;
        let experiment = scenario.experiment::<6>()?;
        let robot = builtin::afma6()?;
        let camera = CalibratedCamera {
            intrinsics: CameraIntrinsics::new(800.0, 800.0, 320.0, 240.0, 640.0, 480.0)?,
            distortion: BrownConrady::new(-0.12, 0.03, 4e-4, -3e-4, 0.0)?,
        };
        let target = RectangleTarget::new(scenario.target.width_m, scenario.target.height_m)?;
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
        config.controller = scenario.controller;
        Ok((VisualServo::new(config)?, experiment, camera))
    };
    let (mut servo, experiment, camera) = match setup() {
        Ok(parts) => parts,
        Err(error) => return Ok(Err(error.to_string())),
    };
    let mut workspace = KinematicsWorkspace::new();
    let mut q = experiment.start;
    let period = 0.01;
    let mut time = 0.0;
    for _ in 0..SERVO_PERIODS {
        time += period;
        let Ok(view) = experiment.scene.observe(&mut workspace, &q) else {
            return Ok(Ok(()));
        };
        let mut corners: Corners = view.points.map(|p| Some(camera.pixel_of(p.x, p.y)));
        let (mut t, mut joints) = (time, q);
        if rng.random_bool(0.4) {
            corrupt(&mut rng, &mut corners, &mut t, &mut joints);
        }
        if let Ok(output) = servo.step(t, &corners, &joints) {
            finite("velocity", output.velocity.as_slice())?;
            finite("unscaled velocity", output.unscaled_velocity.as_slice())?;
            finite("error norm", &[output.error_norm, output.scale])?;
            q += output.velocity * period;
        }
    }
    Ok(Ok(()))
}

/// One corruption of a period's inputs.
fn corrupt(rng: &mut StdRng, corners: &mut Corners, time: &mut f64, q: &mut JointVector<6>) {
    const VALUES: [f64; 8] = [
        f64::NAN,
        f64::INFINITY,
        -f64::INFINITY,
        1e308,
        -1e308,
        1e-308,
        -5.0,
        1e6,
    ];
    let value = VALUES[rng.random_range(0..VALUES.len())];
    let index = rng.random_range(0..4);
    match rng.random_range(0..8) {
        0 => corners[index] = corners[index].map(|(u, _)| (u, value)),
        1 => corners[index] = None,
        2 => corners.swap(index, (index + 1) % 4),
        3 => corners[index] = corners[index].map(|(u, v)| (u + 700.0, v - 500.0)),
        4 => *time = value,
        5 => *time -= rng.random_range(0.0..0.05),
        6 => *time += 1e9,
        _ => q[rng.random_range(0..6)] = value,
    }
}
