//! Forward kinematics + base and end-effector Jacobians (one `SerialChain::kinematics` call) for the six-joint
//! built-in robots, and the eye-in-hand camera Jacobian `cVe · eJe` on top.

use criterion::{criterion_group, criterion_main, Criterion};
use servostack::math::JointVector;
use servostack::robot::{builtin, KinematicsWorkspace};
use std::hint::black_box;

fn kinematics(c: &mut Criterion) {
    let q = JointVector::<6>::new(0.05, -0.04, -0.1, 0.25, 0.12, 0.12);
    for robot in [builtin::afma6().unwrap(), builtin::ur5e().unwrap()] {
        let mut ws = KinematicsWorkspace::new();
        c.bench_function(&format!("kinematics/{}/fk+jacobians", robot.name), |b| {
            b.iter(|| {
                let state = robot.chain.kinematics(&mut ws, black_box(&q)).unwrap();
                black_box(state.tip_jacobian()[(0, 0)] + state.base_jacobian()[(0, 0)])
            })
        });
        c.bench_function(
            &format!("kinematics/{}/fk+jacobians+camera", robot.name),
            |b| {
                b.iter(|| {
                    let state = robot.chain.kinematics(&mut ws, black_box(&q)).unwrap();
                    let base_from_camera = robot.mount.base_from_camera(state.base_from_tip());
                    let camera_jacobian = robot.mount.camera_jacobian(state.tip_jacobian());
                    black_box((base_from_camera, camera_jacobian))
                })
            },
        );
    }
}

criterion_group!(benches, kinematics);
criterion_main!(benches);
