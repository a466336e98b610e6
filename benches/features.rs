//! Visual features from four points: the paper's four tasks with their exact interaction matrices (theory §7).
//!
//! Run with `cargo bench --bench features`.

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::{Dyn, Isometry3, OMatrix, Point3, Translation3, UnitQuaternion, Vector3, U6};
use servostack::camera::ImagePoint;
use servostack::feature::{
    AreaNormalization, Centroid, DiagonalAngle, Feature, FeatureSet, InteractionSource, Observation,
};
use servostack::target::TargetPlane;
use std::hint::black_box;

/// The 0.2 m × 0.1 m rectangle of the peer scene (docs/peer_scene.md) seen from `c_from_o`: image points and plane.
fn project(c_from_o: &Isometry3<f64>) -> ([ImagePoint; 4], TargetPlane) {
    let corners = [(-0.1, -0.05), (0.1, -0.05), (0.1, 0.05), (-0.1, 0.05)];
    let points = corners.map(|(x, y)| {
        let p = c_from_o * Point3::new(x, y, 0.0);
        ImagePoint::new(p.x / p.z, p.y / p.z, p.z)
    });
    let n = c_from_o.rotation * Vector3::z();
    let d = n.dot(&c_from_o.translation.vector);
    (
        points,
        TargetPlane {
            a: n.x / d,
            b: n.y / d,
            c: n.z / d,
        },
    )
}

fn features(c: &mut Criterion) {
    let desired_pose = Isometry3::translation(0.0, 0.0, 0.5);
    let (desired, _) = project(&desired_pose);
    let desired = Observation::new(&desired, None).expect("desired observation");
    let normalization = AreaNormalization::from_desired(&desired, 0.5).expect("normalisation");
    let tasks = FeatureSet::paper_tasks(
        Centroid::new(0.5).expect("Z_g"),
        DiagonalAngle::default(),
        normalization,
    );
    let visp = FeatureSet::visp_moments(normalization);

    let current_pose = Isometry3::from_parts(
        Translation3::new(0.03, -0.02, 0.6),
        UnitQuaternion::from_euler_angles(0.2, -0.15, 0.3),
    );
    let (points, plane) = project(&current_pose);
    let mut s = [0.0; 6];
    let mut l = OMatrix::<f64, Dyn, U6>::zeros(6);

    c.bench_function("observation (moments to order 3 with rows)", |b| {
        b.iter(|| Observation::new(black_box(&points), None).map(|o| o.moments().map(|m| m.xg())))
    });
    c.bench_function("paper four tasks, exact L, from four points", |b| {
        b.iter(|| -> Result<(), servostack::feature::FeatureError> {
            let obs = Observation::new(black_box(&points), None)?;
            let mut first = 0;
            for task in &tasks {
                let dim = task.dim();
                task.value(&obs, &mut s[first..first + dim])?;
                task.interaction(&obs, InteractionSource::Exact, l.rows_mut(first, dim))?;
                first += dim;
            }
            Ok(())
        })
    });
    c.bench_function("paper four tasks, exact L, plane model", |b| {
        b.iter(|| -> Result<(), servostack::feature::FeatureError> {
            let obs = Observation::new(black_box(&points), Some(black_box(&plane)))?;
            let mut first = 0;
            for task in &tasks {
                let dim = task.dim();
                task.value(&obs, &mut s[first..first + dim])?;
                task.interaction(&obs, InteractionSource::Exact, l.rows_mut(first, dim))?;
                first += dim;
            }
            Ok(())
        })
    });
    c.bench_function("ViSP variant B vector (6 rows), exact L", |b| {
        b.iter(|| -> Result<(), servostack::feature::FeatureError> {
            let obs = Observation::new(black_box(&points), None)?;
            visp.value(&obs, &mut s)?;
            visp.interaction(&obs, InteractionSource::Exact, l.rows_mut(0, 6))
        })
    });
    black_box((&s, &l));
}

criterion_group!(benches, features);
criterion_main!(benches);
