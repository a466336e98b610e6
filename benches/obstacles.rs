//! Obstacle cost with gradient for the Afma6 against three obstacles (a sphere, a box, a cylinder; every link with
//! collision geometry paired with each: 12 pairs): with every pair inside its influence distance, and with every
//! pair beyond it (the cut-off query only). Also the visibility cost and the sum with the joint limits.

#[path = "../tests/suite/obstacle_fixture.rs"]
mod fixture;

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::Point3;
use servostack::avoidance::{CompositeCost, Cost, JointLimits, VisibilityCost};
use servostack::camera::CameraIntrinsics;
use servostack::math::JointVector;
use servostack::robot::{builtin, KinematicsWorkspace};
use std::hint::black_box;

fn obstacles(c: &mut Criterion) {
    let q = fixture::reference_q();
    let near = fixture::obstacle_cost(0.15);
    let far = fixture::obstacle_cost(0.001);
    let mut gradient = JointVector::<6>::zeros();
    for (name, cost) in [
        ("12 pairs active", &near),
        ("12 pairs beyond influence", &far),
    ] {
        c.bench_function(&format!("obstacles/afma6/3 obstacles/{name}"), |b| {
            b.iter(|| {
                black_box(
                    cost.value_and_gradient(black_box(&q), &mut gradient)
                        .unwrap(),
                )
            })
        });
    }
    let robot = builtin::afma6().unwrap();
    let mut workspace = KinematicsWorkspace::new();
    let state = robot.chain.kinematics(&mut workspace, &q).unwrap();
    let base_from_camera = robot.mount.base_from_camera(state.base_from_tip());
    let points: Vec<Point3<f64>> = [(-0.1, -0.05), (0.1, -0.05), (0.1, 0.05), (-0.1, 0.05)]
        .iter()
        .map(|&(x, y)| base_from_camera * Point3::new(x, y, 0.5))
        .collect();
    let intrinsics = CameraIntrinsics::new(800.0, 800.0, 320.0, 240.0, 640.0, 480.0).unwrap();
    let visibility = VisibilityCost::new(
        robot.chain.clone(),
        robot.mount,
        &intrinsics,
        &points,
        170.0,
    )
    .unwrap();
    c.bench_function("obstacles/afma6/visibility (4 points, active)", |b| {
        b.iter(|| {
            black_box(
                visibility
                    .value_and_gradient(black_box(&q), &mut gradient)
                    .unwrap(),
            )
        })
    });
    let limits = JointLimits::new(
        *robot.chain.lower_limits(),
        *robot.chain.upper_limits(),
        0.1,
    )
    .unwrap();
    let sum = CompositeCost::new()
        .with(&limits)
        .with(&near)
        .with(&visibility);
    c.bench_function(
        "obstacles/afma6/composite (limits + 12 pairs + visibility)",
        |b| {
            b.iter(|| {
                black_box(
                    sum.value_and_gradient(black_box(&q), &mut gradient)
                        .unwrap(),
                )
            })
        },
    );
}

criterion_group!(benches, obstacles);
criterion_main!(benches);
