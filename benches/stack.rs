//! Criterion benchmarks of the stack solve and the control law, on synthetic tasks (no robot, no camera).

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::DVector;
use servostack::avoidance::{Cost, JointLimits};
use servostack::law::{control_step, ControlLaw, ControlWorkspace, StackChange};
use servostack::math::JointVector;
use servostack::stack::{solve_stack, StackParameters, StackWorkspace};
use servostack::task::{TaskJacobian, TaskValue};
use std::hint::black_box;

/// The paper's stack shape on N joints: levels of 2, 1, 1 and 2 rows, deterministic pseudo-random entries.
fn paper_shaped_tasks<const N: usize>() -> Vec<TaskValue<N>> {
    [2usize, 1, 1, 2]
        .iter()
        .enumerate()
        .map(|(i, &m)| {
            let jacobian =
                TaskJacobian::<N>::from_fn(m, |r, c| ((11 * i + 5 * r + c) as f64 * 0.73).sin());
            let error = DVector::from_fn(m, |r, _| 0.1 * ((i + r) as f64).cos());
            TaskValue::from_parts(&format!("t{i}"), error, jacobian, 0.5).unwrap()
        })
        .collect()
}

fn stack_solve(c: &mut Criterion) {
    let tasks = paper_shaped_tasks::<6>();
    let mut group = c.benchmark_group("stack_solve_n6");
    for levels in 1..=4 {
        let order: Vec<usize> = (0..levels).collect();
        let mut ws = StackWorkspace::new(&tasks);
        group.bench_function(format!("{levels}_levels"), |b| {
            b.iter(|| {
                let solution = solve_stack(
                    &StackParameters::default(),
                    &mut ws,
                    black_box(&tasks),
                    &order,
                )
                .unwrap();
                black_box(solution.velocity()[0])
            })
        });
    }
    group.finish();
}

fn control_law(c: &mut Criterion) {
    let tasks = paper_shaped_tasks::<6>();
    let limits =
        JointLimits::new(JointVector::repeat(-1.0), JointVector::repeat(1.0), 0.1).unwrap();
    let law = ControlLaw::with_default_transition(&tasks, 0.5).unwrap();
    let mut ws = ControlWorkspace::new(&tasks);
    let q = JointVector::<6>::from_fn(|i, _| 0.95 - 0.3 * i as f64);
    let cost: Option<&dyn Cost<6>> = Some(&limits);
    control_step(
        &law,
        &mut ws,
        &tasks,
        &[0, 1, 2, 3],
        cost,
        &q,
        0.0,
        StackChange::Changed,
    )
    .unwrap();
    let mut time = 0.0;
    c.bench_function("control_step_4_levels_with_avoidance_n6", |b| {
        b.iter(|| {
            time += 0.01; // the law's time must increase from step to step
            let out = control_step(
                &law,
                &mut ws,
                black_box(&tasks),
                &[0, 1, 2, 3],
                cost,
                black_box(&q),
                time,
                StackChange::Unchanged,
            )
            .unwrap();
            black_box(out.velocity()[0])
        })
    });
}

criterion_group!(benches, stack_solve, control_law);
criterion_main!(benches);
