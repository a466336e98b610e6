//! Named errors of the façade: bad pixels, joints and times, corners that give no target pose and a non-positive
//! estimated depth are named errors that leave no trace (the next good call continues exactly as without the bad one),
//! and invalid configurations are named errors at construction.

use super::{distorted_camera, paper, paper_config, Plant};
use servostack::controller::HardLimitRule;
use servostack::depth::DepthSource;
use servostack::servo::{
    ServoConfig, ServoError, ServoMethod, ServoOutput, TaskChoice, VisualServo,
};
use servostack::visual_task::FourthTask;

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
