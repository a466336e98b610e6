//! The per-cycle calls of the real-camera path allocate nothing: undistortion of measured pixels,
//! the measurement model (noise, slower camera, latency, prediction), the depth estimator and the depth assignment.

use crate::counting_allocator::allocations_during;
use nalgebra::{Point2, Vector6};
use servostack::camera::{BrownConrady, CalibratedCamera, CameraIntrinsics, ImagePoint};
use servostack::depth::{assign_depths, DepthEstimator, Depths};
use servostack::measurement::{BetweenFrames, MeasurementModel, MeasurementParameters};

#[test]
fn measurement_depth_and_undistortion_allocate_nothing() {
    let intrinsics = CameraIntrinsics::new(600.0, 600.0, 320.0, 240.0, 640.0, 480.0).unwrap();
    let parameters = MeasurementParameters {
        pixel_noise_uniform_px: 0.2,
        pixel_noise_sigma_px: 0.1,
        seed: 3,
        camera_rate_hz: Some(30.0),
        latency_frames: 1,
        between_frames: BetweenFrames::Predict,
        intrinsics_error_fraction: 0.05,
        distortion_coefficients: [-0.2, 0.05, 0.001, 0.001, 0.0],
        ..Default::default()
    };
    let dt = 0.002;
    let mut model = MeasurementModel::new(&parameters, intrinsics, 4, dt).unwrap();
    let mut estimator = DepthEstimator::new(4, 0.6, 1.0, 10).unwrap();
    let camera = CalibratedCamera {
        intrinsics,
        distortion: BrownConrady::new(-0.2, 0.05, 0.001, 0.001, 0.0).unwrap(),
    };
    // A camera translating along x at 0.05 m/s in front of points at Z = 0.5 m: ẋ = −0.1 /s.
    let twist = Vector6::new(0.05, 0.0, 0.0, 0.0, 0.0, 0.0);
    let mut measured = [Point2::origin(); 4];
    let mut image = [ImagePoint::default(); 4];
    let truth = |t: f64| {
        [(-0.2, -0.1), (0.2, -0.1), (0.2, 0.1), (-0.2, 0.1)]
            .map(|(x, y)| ImagePoint::new(x - 0.1 * t, y, 0.5))
    };
    let mut cycle = |step: usize| {
        let t = step as f64 * dt;
        let m = model
            .measure(t, &truth(t), &twist, Depths::Estimated(estimator.depths()))
            .unwrap();
        measured.copy_from_slice(m.normalized);
        let fresh = m.fresh;
        let (u, v) = camera.pixel_of(0.3, -0.2);
        std::hint::black_box(camera.normalized_of(u, v).unwrap());
        if fresh {
            estimator.update(t, &measured, &twist).unwrap();
        }
        assign_depths(Depths::Estimated(estimator.depths()), &measured, &mut image).unwrap();
    };
    for step in 0..50 {
        cycle(step);
    }
    let allocations = allocations_during(|| {
        for step in 50..300 {
            cycle(step);
        }
    });
    assert_eq!(allocations, 0);
}
