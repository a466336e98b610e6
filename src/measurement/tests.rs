//! Tests of the measurement model over whole runs: frames, noise statistics, latency, prediction, distortion and
//! intrinsics error, and the errors of invalid parameters and inputs.

use super::*;
use crate::camera::{CameraIntrinsics, ImagePoint};
use crate::depth::{DepthError, Depths};
use approx::assert_relative_eq;
use nalgebra::Vector6;

fn intrinsics() -> CameraIntrinsics {
    CameraIntrinsics::new(600.0, 610.0, 320.0, 240.0, 640.0, 480.0).unwrap()
}

/// A square of four points whose image slides along x at 0.1 /s: x_k(t) = x_k(0) + 0.1 t.
fn sliding(t: f64) -> [ImagePoint; 4] {
    [(-0.1, -0.1), (0.1, -0.1), (0.1, 0.1), (-0.1, 0.1)]
        .map(|(x, y)| ImagePoint::new(x + 0.1 * t, y, 0.5))
}

const STILL: Vector6<f64> = Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);

#[test]
fn default_is_the_exact_instantaneous_camera() {
    let parameters = MeasurementParameters::default();
    assert!(parameters.is_exact());
    let mut model = MeasurementModel::new(&parameters, intrinsics(), 4, 0.01).unwrap();
    for step in 0..5 {
        let t = 0.01 * step as f64;
        let truth = sliding(t);
        let m = model
            .measure(t, &truth, &STILL, Depths::Constant(0.5))
            .unwrap();
        assert!(m.fresh);
        assert_eq!(m.frame_time, t);
        for (n, p) in m.normalized.iter().zip(&truth) {
            assert!((n.x - p.x).abs() < 1e-15 && (n.y - p.y).abs() < 1e-15);
        }
        // Pixels by hand: u = 320 + 600 x, v = 240 + 610 y.
        assert_relative_eq!(
            m.pixels[2].x,
            320.0 + 600.0 * (0.1 + 0.1 * t),
            epsilon = 1e-12
        );
        assert_relative_eq!(m.pixels[2].y, 240.0 + 61.0, epsilon = 1e-12);
    }
    let noisy = MeasurementParameters {
        pixel_noise_sigma_px: 0.1,
        ..parameters
    };
    assert!(!noisy.is_exact());
}

/// Noise statistics over 20 000 coordinates: uniform stays in ±a with variance a²/3; Gaussian has variance σ².
/// The same seed gives the same noise, another seed another.
#[test]
fn pixel_noise_has_its_distribution_and_is_seeded() {
    let deviations = |parameters: &MeasurementParameters| -> Vec<f64> {
        let mut model = MeasurementModel::new(parameters, intrinsics(), 4, 0.01).unwrap();
        let truth = sliding(0.0);
        let exact: Vec<(f64, f64)> = truth
            .iter()
            .map(|p| model.true_camera().pixel_of(p.x, p.y))
            .collect();
        let mut out = Vec::new();
        for step in 0..2500 {
            let m = model
                .measure(0.01 * step as f64, &truth, &STILL, Depths::Constant(0.5))
                .unwrap();
            for (p, e) in m.pixels.iter().zip(&exact) {
                out.extend([p.x - e.0, p.y - e.1]);
            }
        }
        out
    };
    let moments = |d: &[f64]| {
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        (
            mean,
            d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / d.len() as f64,
        )
    };
    let uniform = MeasurementParameters {
        pixel_noise_uniform_px: 2.0,
        seed: 11,
        ..Default::default()
    };
    let d = deviations(&uniform);
    assert!(d.iter().all(|v| v.abs() <= 2.0 + 1e-9));
    let (mean, variance) = moments(&d);
    // Standard error of the mean: √(4/3 / 20000) ≈ 0.008.
    assert!(mean.abs() < 0.04, "{mean}");
    assert!((variance - 4.0 / 3.0).abs() < 0.05, "{variance}");
    assert_eq!(d, deviations(&uniform));
    assert_ne!(
        d,
        deviations(&MeasurementParameters {
            seed: 12,
            ..uniform
        })
    );
    let gaussian = MeasurementParameters {
        pixel_noise_sigma_px: 1.5,
        seed: 3,
        ..Default::default()
    };
    let (mean, variance) = moments(&deviations(&gaussian));
    assert!(mean.abs() < 0.05, "{mean}");
    assert!((variance.sqrt() - 1.5).abs() < 0.03, "{}", variance.sqrt());
}

/// A 30 Hz camera under 500 Hz control: 30 frames in the first second, each at the first control period at or
/// after n/30 s; points held in between.
#[test]
fn slower_camera_delivers_frames_at_its_rate_and_holds_between() {
    let parameters = MeasurementParameters {
        camera_rate_hz: Some(30.0),
        ..Default::default()
    };
    let dt = 0.002;
    let mut model = MeasurementModel::new(&parameters, intrinsics(), 4, dt).unwrap();
    let mut frame_times = Vec::new();
    for step in 0..500 {
        let t = step as f64 * dt;
        let m = model
            .measure(t, &sliding(t), &STILL, Depths::Constant(0.5))
            .unwrap();
        if m.fresh {
            frame_times.push(t);
        }
        assert_relative_eq!(
            m.normalized[0].x,
            sliding(m.frame_time)[0].x,
            epsilon = 1e-12
        );
    }
    assert_eq!(frame_times.len(), 30);
    for (n, t) in frame_times.iter().enumerate() {
        let due = n as f64 / 30.0;
        assert!(*t >= due - 1e-9 && *t < due + dt, "frame {n} at {t}");
    }
}

/// Latency of two frames: what is delivered was captured two frames earlier (the first frame until then).
#[test]
fn latency_delivers_older_frames() {
    let parameters = MeasurementParameters {
        camera_rate_hz: Some(25.0),
        latency_frames: 2,
        ..Default::default()
    };
    let dt = 0.01;
    let mut model = MeasurementModel::new(&parameters, intrinsics(), 4, dt).unwrap();
    let mut captures = Vec::new();
    for step in 0..100 {
        let t = step as f64 * dt;
        let m = model
            .measure(t, &sliding(t), &STILL, Depths::Constant(0.5))
            .unwrap();
        if step % 4 == 0 {
            captures.push(t);
        }
        let expected_frame = captures.len().saturating_sub(3);
        assert_relative_eq!(m.frame_time, captures[expected_frame], epsilon = 1e-12);
        assert_relative_eq!(
            m.normalized[1].x,
            sliding(m.frame_time)[1].x,
            epsilon = 1e-12
        );
    }
}

/// Prediction between frames follows a camera translating along x (every point moves by ẋ = −υx/Z): the predicted
/// points stay on the truth, the held ones lag.
#[test]
fn prediction_follows_the_known_twist() {
    let twist = Vector6::new(0.05, 0.0, 0.0, 0.0, 0.0, 0.0);
    // x(t) = x(0) − υx t / Z with Z = 0.5.
    let truth = |t: f64| sliding(0.0).map(|p| ImagePoint::new(p.x - 0.1 * t, p.y, 0.5));
    let run = |between_frames| {
        let parameters = MeasurementParameters {
            camera_rate_hz: Some(10.0),
            between_frames,
            ..Default::default()
        };
        let mut model = MeasurementModel::new(&parameters, intrinsics(), 4, 0.01).unwrap();
        let mut worst = 0.0_f64;
        for step in 0..50 {
            let t = step as f64 * 0.01;
            let m = model
                .measure(t, &truth(t), &twist, Depths::Constant(0.5))
                .unwrap();
            worst = worst.max((m.normalized[3].x - truth(t)[3].x).abs());
        }
        worst
    };
    let (held, predicted) = (run(BetweenFrames::Hold), run(BetweenFrames::Predict));
    // Held: up to 9 periods behind, 9 · 0.01 · 0.1 = 0.009.
    assert_relative_eq!(held, 0.009, epsilon = 1e-9);
    assert!(predicted < 1e-12, "{predicted}");
}

/// With distortion and exact intrinsics the controller gets the true points back; with an intrinsics error each
/// nominal parameter is off by exactly ±ε.
#[test]
fn distortion_and_intrinsics_error() {
    let distorted = MeasurementParameters {
        distortion_coefficients: [-0.3, 0.1, 0.001, -0.002, 0.01],
        ..Default::default()
    };
    let mut model = MeasurementModel::new(&distorted, intrinsics(), 4, 0.01).unwrap();
    let truth = sliding(1.0);
    let m = model
        .measure(0.0, &truth, &STILL, Depths::Constant(0.5))
        .unwrap();
    // The pixel is displaced by the lens: x = 0.2 gives x_d ≠ x.
    assert!((m.pixels[1].x - (320.0 + 600.0 * 0.2)).abs() > 1.0);
    for (n, p) in m.normalized.iter().zip(&truth) {
        assert!((n.x - p.x).abs() < 1e-11 && (n.y - p.y).abs() < 1e-11);
    }
    let wrong = MeasurementParameters {
        intrinsics_error_fraction: 0.05,
        seed: 5,
        ..Default::default()
    };
    let model = MeasurementModel::new(&wrong, intrinsics(), 4, 0.01).unwrap();
    let (t, n) = (
        model.true_camera().intrinsics,
        model.nominal_camera().intrinsics,
    );
    for (true_value, nominal) in [
        (t.fx(), n.fx()),
        (t.fy(), n.fy()),
        (t.cx(), n.cx()),
        (t.cy(), n.cy()),
    ] {
        assert_relative_eq!((nominal / true_value - 1.0).abs(), 0.05, epsilon = 1e-12);
    }
}

#[test]
fn invalid_parameters_are_named() {
    let cases: [(&str, MeasurementParameters); 9] = [
        (
            "filter_time_constant_s",
            MeasurementParameters {
                filter_time_constant_s: -0.1,
                ..Default::default()
            },
        ),
        (
            "pixel_noise_uniform_px",
            MeasurementParameters {
                pixel_noise_uniform_px: -1.0,
                ..Default::default()
            },
        ),
        (
            "pixel_noise_sigma_px",
            MeasurementParameters {
                pixel_noise_sigma_px: f64::NAN,
                ..Default::default()
            },
        ),
        (
            "camera_rate_hz",
            MeasurementParameters {
                camera_rate_hz: Some(0.0),
                ..Default::default()
            },
        ),
        (
            "camera_rate_hz",
            MeasurementParameters {
                camera_rate_hz: Some(200.0),
                ..Default::default()
            },
        ),
        (
            "latency_frames",
            MeasurementParameters {
                latency_frames: 5000,
                ..Default::default()
            },
        ),
        (
            "intrinsics_error_fraction",
            MeasurementParameters {
                intrinsics_error_fraction: 0.5,
                ..Default::default()
            },
        ),
        (
            "hand_eye_translation_m",
            MeasurementParameters {
                hand_eye_translation_m: f64::INFINITY,
                ..Default::default()
            },
        ),
        (
            "distortion_coefficients",
            MeasurementParameters {
                distortion_coefficients: [0.0, f64::NAN, 0.0, 0.0, 0.0],
                ..Default::default()
            },
        ),
    ];
    for (name, parameters) in cases {
        match MeasurementModel::new(&parameters, intrinsics(), 4, 0.01) {
            Err(MeasurementError::InvalidParameter { name: found, .. }) => {
                assert_eq!(found, name)
            }
            other => panic!("{name}: {other:?}"),
        }
    }
    assert!(matches!(
        MeasurementModel::new(&MeasurementParameters::default(), intrinsics(), 4, 0.0),
        Err(MeasurementError::InvalidParameter { name: "period", .. })
    ));
    assert!(matches!(
        MeasurementModel::new(&MeasurementParameters::default(), intrinsics(), 0, 0.01),
        Err(MeasurementError::InvalidParameter {
            name: "point_count",
            ..
        })
    ));
}

#[test]
fn bad_measurements_are_named() {
    let predict = MeasurementParameters {
        camera_rate_hz: Some(10.0),
        between_frames: BetweenFrames::Predict,
        ..Default::default()
    };
    let mut model = MeasurementModel::new(&predict, intrinsics(), 4, 0.01).unwrap();
    let truth = sliding(0.0);
    let depths = Depths::Constant(0.5);
    assert_eq!(
        model.measure(0.0, &truth[..3], &STILL, depths).err(),
        Some(MeasurementError::PointCountMismatch {
            expected: 4,
            got: 3
        })
    );
    let mut nan = truth;
    nan[2].x = f64::NAN;
    assert!(matches!(
        model.measure(0.0, &nan, &STILL, depths),
        Err(MeasurementError::InvalidPoint { index: 2, .. })
    ));
    let mut behind = truth;
    behind[1].depth = -0.1;
    assert!(matches!(
        model.measure(0.0, &behind, &STILL, depths),
        Err(MeasurementError::InvalidPoint { index: 1, .. })
    ));
    let mut bad_twist = STILL;
    bad_twist[0] = f64::NAN;
    assert!(matches!(
        model.measure(0.0, &truth, &bad_twist, depths),
        Err(MeasurementError::NonFiniteTwist { .. })
    ));
    model.measure(0.0, &truth, &STILL, depths).unwrap();
    for time in [0.0, -0.01, f64::NAN] {
        assert!(matches!(
            model.measure(time, &truth, &STILL, depths),
            Err(MeasurementError::TimeNotIncreasing { .. })
        ));
    }
    // Between frames, prediction needs usable depths.
    assert!(matches!(
        model.measure(0.01, &truth, &STILL, Depths::Constant(-1.0)),
        Err(MeasurementError::Depth(DepthError::NonPositiveDepth { .. }))
    ));
}
