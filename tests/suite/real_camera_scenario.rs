//! The reference scenario through a real camera (a scenario's `[measurement]` and `depth`): a 30 Hz camera one frame
//! late under 500 Hz control, 5 % intrinsics error, a 1 cm / 2° hand-eye error, lens distortion, depths taught at the
//! goal or estimated from the measured corners (the target's pose). The full method reaches the goal pose within the
//! limits; bad measurement fields are named.

use servostack::depth::DepthSource;
use servostack::robot::KinematicsWorkspace;
use servostack::scenario::{RunKind, Scenario, ScenarioError};
use servostack::sim::{Outcome, SimError};
use servostack::study::{standard_families, Study};
use std::path::Path;

fn scenario() -> Scenario {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/scenarios/paper_afma6_real_camera.toml"
    );
    Scenario::from_file(Path::new(path)).unwrap()
}

#[test]
fn full_method_reaches_the_goal_pose_through_a_miscalibrated_slow_camera() {
    reaches_the_goal_pose(&scenario());
}

/// No depth known in advance: each frame's depths come from the target's pose estimated from the four measured
/// corners (a homography through the miscalibrated camera, so about 5 % off).
#[test]
fn full_method_reaches_the_goal_pose_with_depths_from_the_measured_corners() {
    let mut scenario = scenario();
    scenario.depth = Some(DepthSource::TargetPose);
    reaches_the_goal_pose(&scenario);
}

/// ±2 px of pixel noise on top, depths from the measured corners, the feature observer (D32), the side ratios and a
/// gain of 0.03 s⁻¹ at the goal held 45 s, an industrial arm's acceleration limits (`paper_afma6_noisy_camera.toml`):
/// from the scenario's start and from mild starts of the study, the full method settles within 5 mm / 0.5° of the goal
/// pose, inside the joint limits, every change of the velocity sent within `a_i Δt`.
#[test]
fn full_method_reaches_the_goal_pose_through_a_noisy_camera() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/scenarios/paper_afma6_noisy_camera.toml"
    );
    let scenario = Scenario::from_file(Path::new(path)).unwrap();
    reaches_the_goal_pose(&scenario);
    let mild: Vec<_> = standard_families()
        .into_iter()
        .filter(|f| f.name == "mild")
        .collect();
    let study = Study::new(&scenario, mild, 3, 11)
        .unwrap()
        .with_methods(&[RunKind::FullMethod]);
    for draw in &study.run().unwrap().families[0].draws {
        let full = &draw.methods[0];
        assert!(full.converged(), "draw {}: {full:?}", draw.draw);
        // The scenario's acceleration limits (1 m/s², 3 rad/s²) act, and hold at every period.
        assert!(
            full.max_acceleration_ratio > 0.5 && full.max_acceleration_ratio <= 1.0 + 1e-12,
            "draw {}: largest change per period {} × a Δt",
            draw.draw,
            full.max_acceleration_ratio
        );
        let (translation_mm, rotation_deg) = (
            1e3 * full.camera_translation_error,
            full.camera_rotation_error_deg,
        );
        assert!(
            translation_mm < 5.0 && rotation_deg < 0.5,
            "draw {}: {translation_mm} mm, {rotation_deg}°",
            draw.draw
        );
    }
}

fn reaches_the_goal_pose(scenario: &Scenario) {
    let experiment = scenario.experiment::<6>().unwrap();
    let run = experiment
        .run(&scenario.settings(), RunKind::FullMethod)
        .unwrap();
    assert_eq!(run.outcome, Outcome::Converged, "{:?}", run.events);
    assert!(run.min_normalized_margin() > 0.0);
    // The true camera pose against its goal (the run converged on the noise-free task errors).
    let q = run.records.last().unwrap().q;
    let view = experiment
        .scene
        .observe(&mut KinematicsWorkspace::new(), &q)
        .unwrap();
    let error = view.c_from_o * experiment.desired_camera_from_target.inverse();
    let (translation_mm, rotation_deg) = (
        1e3 * error.translation.vector.norm(),
        error.rotation.angle().to_degrees(),
    );
    assert!(
        translation_mm < 5.0 && rotation_deg < 0.5,
        "{translation_mm} mm, {rotation_deg}°"
    );
    println!(
        "real camera: {translation_mm:.2} mm / {rotation_deg:.3}° from the goal, largest velocity step {:.2e} \
         ({:.2} per s²)",
        run.max_velocity_step(),
        run.max_velocity_step() / run.period
    );
    assert!(run.max_velocity_step().is_finite());
}

fn field_of(text: &str) -> String {
    let scenario = Scenario::from_toml_str(text, None).unwrap();
    match scenario.run::<6>(RunKind::FullMethod) {
        Err(ScenarioError::Invalid { field, .. }) => field,
        other => panic!("expected an invalid field, got {other:?}"),
    }
}

#[test]
fn bad_measurement_and_depth_fields_are_named() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/scenarios/paper_afma6_real_camera.toml"
    ))
    .unwrap();
    let bad_intrinsics = text.replace(
        "intrinsics_error_fraction = 0.05",
        "intrinsics_error_fraction = 0.7",
    );
    assert_eq!(field_of(&bad_intrinsics), "measurement");
    let bad_rate = text.replace("camera_rate_hz = 30.0", "camera_rate_hz = -30.0");
    assert_eq!(field_of(&bad_rate), "measurement");
    let bad_depth = text.replace("kind = \"desired\"", "kind = \"constant\"\ndepth_m = -0.5");
    assert_eq!(field_of(&bad_depth), "depth");
    let unknown = text.replace("latency_frames = 1", "latency_frame = 1");
    assert!(Scenario::from_toml_str(&unknown, None).is_err());
}

/// The simulation's velocity saturation must be positive (or infinite): a zero or NaN limit is named.
#[test]
fn invalid_velocity_limits_are_named() {
    for (field, value) in [
        ("max_prismatic_velocity_m_s", 0.0),
        ("max_revolute_velocity_rad_s", f64::NAN),
        ("max_revolute_velocity_rad_s", -1.0),
    ] {
        let mut scenario = scenario();
        match field {
            "max_prismatic_velocity_m_s" => scenario.simulation.max_prismatic_velocity_m_s = value,
            _ => scenario.simulation.max_revolute_velocity_rad_s = value,
        }
        // Checked with the scenario, before any run.
        match scenario.experiment::<6>() {
            Err(ScenarioError::Simulation(SimError::InvalidParameter { name, .. })) => {
                assert_eq!(name, field)
            }
            other => panic!("{field} = {value}: {:?}", other.map(|_| ())),
        }
    }
}
