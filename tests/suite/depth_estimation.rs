//! The online depth estimator in a closed-loop simulation written here: a camera moving with a known twist in front of
//! a planar four-point target, the points projected by `camera::project_points` at 30 Hz. After the first second of
//! motion every estimate is within 5 % of the true depth.

use nalgebra::{Isometry3, Point2, Translation3, UnitQuaternion, Vector3, Vector6};
use servostack::camera::{project_points, CalibratedCamera, CameraIntrinsics, ImagePoint};
use servostack::depth::{assign_depths, DepthError, DepthEstimator, Depths};
use servostack::target::RectangleTarget;

/// The camera moved by the twist `(υ, ω)` (camera frame) held for `dt`: points move as `Ẋ = −υ − ω × X`, so the
/// object pose in the new camera frame is `exp(v dt)⁻¹ · c_from_o`.
fn moved(c_from_o: &Isometry3<f64>, twist: &Vector6<f64>, dt: f64) -> Isometry3<f64> {
    let motion = Isometry3::new(
        Vector3::new(twist[0], twist[1], twist[2]) * dt,
        Vector3::new(twist[3], twist[4], twist[5]) * dt,
    );
    motion.inverse() * c_from_o
}

/// The twist at time t (s): a translation with a varying direction and a slow rotation (camera frame).
fn twist_at(t: f64) -> Vector6<f64> {
    Vector6::new(
        0.06 * (1.3 * t).cos(),
        -0.04 + 0.02 * (0.7 * t).sin(),
        -0.05,
        0.05 * (0.9 * t).sin(),
        0.08,
        -0.1,
    )
}

/// Runs the loop for `duration` s: control at 500 Hz (the twist is integrated finely), camera frames at 30 Hz; the
/// estimator gets each frame with the mean twist applied since the previous one. Returns the largest relative error
/// of the depth estimates over the frames after `check_after` s, and the largest at the end.
fn run(
    noise_px: Option<(f64, u64)>,
    initial_depth: f64,
    memory: f64,
    window_frames: usize,
    duration: f64,
    check_after: f64,
) -> (f64, f64, usize) {
    let target = RectangleTarget::new(0.2, 0.14).unwrap();
    let intrinsics = CameraIntrinsics::new(600.0, 600.0, 320.0, 240.0, 640.0, 480.0).unwrap();
    let camera = CalibratedCamera::pinhole(intrinsics);
    let mut c_from_o = Isometry3::from_parts(
        Translation3::new(0.03, -0.02, 0.8),
        UnitQuaternion::from_euler_angles(0.3, -0.25, 0.4),
    );
    let mut estimator = DepthEstimator::new(4, initial_depth, memory, window_frames).unwrap();
    let control_dt = 0.002;
    let frame_every = 1.0 / 30.0;
    let mut next_frame = 0.0;
    let mut twist_sum = Vector6::zeros();
    let mut twist_time = 0.0;
    let mut projected = [ImagePoint::default(); 4];
    let mut measured = [Point2::origin(); 4];
    let mut assigned = [ImagePoint::default(); 4];
    let (mut worst_after, mut worst_end) = (0.0_f64, 0.0_f64);
    let mut rejected = 0usize;
    let mut uniform = lcg(noise_px.map_or(1, |(_, seed)| seed));
    let steps = (duration / control_dt).round() as usize;
    for step in 0..=steps {
        let t = step as f64 * control_dt;
        if t + 1e-12 >= next_frame {
            next_frame += frame_every;
            project_points(&c_from_o, target.points(), &mut projected).unwrap();
            for (m, p) in measured.iter_mut().zip(&projected) {
                let (mut u, mut v) = camera.pixel_of(p.x, p.y);
                if let Some((amplitude, _)) = noise_px {
                    u += amplitude * (2.0 * uniform() - 1.0);
                    v += amplitude * (2.0 * uniform() - 1.0);
                }
                let (x, y) = camera.normalized_of(u, v).unwrap();
                *m = Point2::new(x, y);
            }
            let mean_twist = if twist_time > 0.0 {
                twist_sum / twist_time
            } else {
                Vector6::zeros()
            };
            match estimator.update(t, &measured, &mean_twist) {
                Ok(_) => {}
                // Noise larger than the motion: the update is rejected and the previous depths kept.
                Err(DepthError::NonPositiveDepth { .. }) => rejected += 1,
                Err(other) => panic!("{other}"),
            }
            assign_depths(
                Depths::Estimated(estimator.depths()),
                &measured,
                &mut assigned,
            )
            .unwrap();
            let worst = assigned
                .iter()
                .zip(&projected)
                .map(|(e, truth)| ((e.depth - truth.depth) / truth.depth).abs())
                .fold(0.0, f64::max);
            if t >= check_after {
                worst_after = worst_after.max(worst);
            }
            worst_end = worst;
            twist_sum = Vector6::zeros();
            twist_time = 0.0;
        }
        let twist = twist_at(t);
        c_from_o = moved(&c_from_o, &twist, control_dt);
        twist_sum += twist * control_dt;
        twist_time += control_dt;
    }
    (worst_after, worst_end, rejected)
}

/// A small deterministic uniform generator in [0, 1) (the test needs no statistical quality, only reproducibility).
fn lcg(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[test]
fn estimates_are_within_five_percent_after_one_second() {
    // Start from a depth 50 % too far; frame-to-frame and 10-frame baselines.
    for window in [1, 10] {
        let (worst_after, worst_end, rejected) = run(None, 1.2, 0.5, window, 4.0, 1.0);
        println!(
            "noise-free, {window}-frame baseline: worst relative depth error after 1 s {worst_after:.2e}, at 4 s \
             {worst_end:.2e}"
        );
        assert!(worst_after < 0.05, "{worst_after}");
        assert_eq!(rejected, 0);
    }
}

/// With ±0.5 px uniform pixel noise the image motion comes from noisy frames. Over a baseline of 10 frames and with a
/// 1 s memory every estimate is within 5 % after the first second, for each of three noise seeds (measured: 1.0–1.4 %
/// worst), and the baseline beats frame-to-frame differences (measured with 1 frame: 3.0–3.4 %).
#[test]
fn estimates_stay_within_five_percent_with_half_a_pixel_of_noise() {
    for seed in [7, 8, 9] {
        let (baseline, end, rejected) = run(Some((0.5, seed)), 0.5, 1.0, 10, 4.0, 1.0);
        let (frame_to_frame, _, _) = run(Some((0.5, seed)), 0.5, 1.0, 1, 4.0, 1.0);
        println!(
            "±0.5 px, seed {seed}: worst relative depth error after 1 s {baseline:.2e} (1-frame baseline \
             {frame_to_frame:.2e}), at 4 s {end:.2e}, {rejected} rejected updates"
        );
        assert!(baseline < 0.05, "seed {seed}: {baseline}");
        assert!(
            baseline < 0.6 * frame_to_frame,
            "seed {seed}: {baseline} vs {frame_to_frame}"
        );
    }
}

/// With ±2 px (the noise level) and a 20-frame baseline the estimates stay within 10 % after the first second
/// (measured: 3.7–6.3 % worst, with at most one early update rejected as non-positive).
#[test]
fn estimates_stay_within_ten_percent_with_two_pixels_of_noise() {
    for seed in [7, 8, 9] {
        let (worst, end, rejected) = run(Some((2.0, seed)), 0.5, 1.0, 20, 4.0, 1.0);
        println!(
            "±2 px, seed {seed}: worst relative depth error after 1 s {worst:.2e}, at 4 s {end:.2e}, {rejected} \
             rejected updates"
        );
        assert!(worst < 0.10, "seed {seed}: {worst}");
    }
}
