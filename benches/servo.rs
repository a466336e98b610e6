//! The façade's per-period call (`VisualServo::step`) on the peer scene (docs/peer_scene.md): Afma6, 600 px camera
//! with Brown–Conrady distortion, the 0.2 × 0.1 m target seen head-on at 0.5 m from `q_d`, start `q_d + Δq`, the paper's
//! sequence with joint-limit avoidance and velocity limits. One period = undistortion of four pixels, depths,
//! kinematics and `cVe eJe`, the four tasks, the stack controller, saturation and feedback.
//!
//! The pixels and joint positions of a closed-loop episode ([`EPISODE`] periods at 100 Hz) are recorded once; each
//! timed run replays them into a fresh servo (built outside the timing), so only `step` is timed.
//!
//! Run with `cargo bench --bench servo` (`-- --quick` for a short run).

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::Isometry3;
use servostack::camera::{BrownConrady, CalibratedCamera, CameraIntrinsics};
use servostack::math::JointVector;
use servostack::robot::{builtin, KinematicsWorkspace};
use servostack::servo::{Corners, DesiredImage, ServoConfig, VisualServo};
use servostack::sim::Scene;
use servostack::target::RectangleTarget;
use std::hint::black_box;
use std::time::{Duration, Instant};

/// Periods per recorded episode.
const EPISODE: usize = 1000;
/// Control period (s).
const PERIOD: f64 = 0.01;

struct Peer {
    config: ServoConfig<6>,
    /// `(time, pixels, q)` of each period of the recorded episode.
    episode: Vec<(f64, Corners, JointVector<6>)>,
}

fn peer() -> Peer {
    let robot = builtin::afma6().expect("afma6");
    let intrinsics =
        CameraIntrinsics::new(600.0, 600.0, 320.0, 240.0, 640.0, 480.0).expect("intrinsics");
    let target = RectangleTarget::new(0.2, 0.1).expect("target");
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
    .expect("scene");
    let camera = CalibratedCamera {
        intrinsics,
        distortion: BrownConrady::new(-0.12, 0.03, 4e-4, -3e-4, 0.0).expect("lens"),
    };
    let mut config = ServoConfig::new(
        robot.chain,
        robot.mount,
        camera,
        target,
        DesiredImage::Pose(goal),
    );
    config.max_joint_velocity = JointVector::repeat(0.2);
    // Record one closed-loop episode.
    let mut servo = VisualServo::new(config.clone()).expect("servo");
    let mut workspace = KinematicsWorkspace::new();
    let mut q = desired_q + JointVector::from([0.05, -0.04, -0.10, 0.25, -0.18, 0.12]);
    let mut episode = Vec::with_capacity(EPISODE);
    for k in 0..EPISODE {
        let view = scene.observe(&mut workspace, &q).expect("view");
        let pixels = view.points.map(|p| Some(camera.pixel_of(p.x, p.y)));
        let time = k as f64 * PERIOD;
        let output = servo.step(time, &pixels, &q).expect("step");
        episode.push((time, pixels, q));
        q += output.velocity * PERIOD;
    }
    Peer { config, episode }
}

fn servo_step(c: &mut Criterion) {
    let peer = peer();
    c.bench_function("servo_step_peer_scene", |b| {
        b.iter_custom(|iterations| {
            let mut total = Duration::ZERO;
            let mut done = 0;
            while done < iterations {
                let mut servo = VisualServo::new(peer.config.clone()).expect("servo");
                let count = (iterations - done).min(EPISODE as u64) as usize;
                let start = Instant::now();
                for (time, pixels, q) in &peer.episode[..count] {
                    let output = servo.step(*time, black_box(pixels), q).expect("step");
                    black_box(output.velocity);
                }
                total += start.elapsed();
                done += count as u64;
            }
            total
        });
    });
}

criterion_group!(benches, servo_step);
criterion_main!(benches);
