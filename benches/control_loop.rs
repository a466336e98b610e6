//! The whole control step on the Afma6 peer scene and its parts, plus the scaling of the stack solve.
//!
//! * `step/*`: one full iteration of the servo loop (kinematics, projection, features, tasks, law or controller, Euler)
//!   for the paper's four stacked tasks under the stack controller (joint-limit avoidance, continuity, prediction and
//!   criteria at every step), the classical six-row task under the controller, and the peer variants A, B, C, CL; in
//!   episodes of at most 1000 steps from `q0` (the reset and the pushes of the stack untimed), as the peer protocol.
//! * `sequencing/*`: the same loops' steps from `q0` until every task is stacked, the pushes included: while the
//!   sequence is incomplete the controller also solves the stack with the next task added at every step (the early
//!   push's trial law, D28), beside the prediction and criteria of the steady steps.
//! * `parts/*`: kinematics, observation of the target (kinematics + camera pose + projection + plane + `cVe eJe`),
//!   moments, the four paper tasks evaluated (features, `L`, `J = L cVe eJe`), the stack solve of 1–4 paper levels,
//!   the control law alone, and the controller step (law + prediction + criteria) on evaluated tasks.
//! * `scaling/*`: the stack solve against the number of levels and the number of joints N (6, 7, 12), on synthetic
//!   tasks. Every stack solve alternates between the tasks and a copy perturbed by one control period's change, so
//!   that warm-started decompositions start from a nearby matrix, as in a loop, not from the same one.
//!
//! Run with `cargo bench --bench control_loop`.

#[path = "common/perturbed.rs"]
mod perturbed;
#[path = "common/servo_loop.rs"]
mod servo_loop;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use nalgebra::DVector;
use perturbed::perturbed;
use servo_loop::{ServoLoop, Variant};
use servostack::avoidance::Cost;
use servostack::controller::{ControllerParameters, StackController};
use servostack::law::{control_step, ControlWorkspace, StackChange};
use servostack::robot::KinematicsWorkspace;
use servostack::sim::View;
use servostack::stack::{solve_stack, StackParameters, StackWorkspace};
use servostack::task::{Task, TaskJacobian, TaskValue};
use servostack::visual_task::VisualContext;
use std::hint::black_box;
use std::time::{Duration, Instant};

/// Timed steps per episode of the `step/*` benchmarks.
const EPISODE: u64 = 1000;

fn steps(c: &mut Criterion) {
    let mut group = c.benchmark_group("step");
    let loops = [
        ("paper_four_tasks_controller", ServoLoop::paper()),
        ("paper_full_method", ServoLoop::paper_full_method()),
        ("classical_controller", ServoLoop::classical()),
        ("peer_A", ServoLoop::peer(Variant::A)),
        ("peer_B", ServoLoop::peer(Variant::B)),
        ("peer_C", ServoLoop::peer(Variant::C)),
        ("peer_CL", ServoLoop::peer(Variant::CL)),
    ];
    for (name, mut servo) in loops {
        // Episodes as in the peer protocol: from q0 (once every task is stacked), at most EPISODE timed steps, the
        // reset untimed. A loop left running would converge and stop changing, flattering the warm-started SVDs.
        group.bench_function(name, |b| {
            b.iter_custom(|iterations| {
                let (mut total, mut done) = (Duration::ZERO, 0);
                while done < iterations {
                    servo.reset();
                    servo.settle();
                    let steps = (iterations - done).min(EPISODE);
                    let start = Instant::now();
                    for _ in 0..steps {
                        servo.step();
                    }
                    total += start.elapsed();
                    done += steps;
                }
                total
            })
        });
        black_box(servo.error_norm());
    }
    group.finish();
}

/// The steps of the sequencing phase: from `q0` (the reset untimed) until every task is stacked.
fn sequencing(c: &mut Criterion) {
    let mut group = c.benchmark_group("sequencing");
    let loops = [
        ("paper_four_tasks_controller", ServoLoop::paper()),
        ("paper_full_method", ServoLoop::paper_full_method()),
    ];
    for (name, mut servo) in loops {
        let complete = |servo: &ServoLoop| servo.controller().is_none_or(|c| c.is_complete());
        servo.reset();
        let mut steps_to_stack = 0;
        while !complete(&servo) {
            servo.step();
            steps_to_stack += 1;
        }
        assert!(
            steps_to_stack > 1,
            "{name}: stacking the sequence must take steps"
        );
        group.bench_function(name, |b| {
            b.iter_custom(|iterations| {
                let (mut total, mut done) = (Duration::ZERO, 0);
                while done < iterations {
                    servo.reset();
                    let start = Instant::now();
                    while done < iterations && !complete(&servo) {
                        servo.step();
                        done += 1;
                    }
                    total += start.elapsed();
                }
                total
            })
        });
        black_box(servo.error_norm());
    }
    group.finish();
}

fn parts(c: &mut Criterion) {
    let mut servo = ServoLoop::paper();
    servo.settle();
    let q = *servo.q();
    let scene = servo.scene();
    let mut kinematics = KinematicsWorkspace::new();
    let mut group = c.benchmark_group("parts");
    group.bench_function("kinematics", |b| {
        b.iter(|| {
            let state = scene
                .chain()
                .kinematics(&mut kinematics, black_box(&q))
                .unwrap();
            black_box(state.tip_jacobian()[(0, 0)])
        })
    });
    let mut view = View::default();
    group.bench_function("observe", |b| {
        b.iter(|| {
            scene
                .observe_into(&mut kinematics, black_box(&q), &mut view)
                .unwrap();
            black_box(view.points[0].x)
        })
    });
    let view = scene.observe(&mut kinematics, &q).unwrap();
    group.bench_function("observation_moments", |b| {
        b.iter(|| {
            black_box(
                black_box(&view)
                    .observation()
                    .unwrap()
                    .moments()
                    .unwrap()
                    .xg(),
            )
        })
    });
    let observation = view.observation().unwrap();
    let context = VisualContext {
        observation: &observation,
        camera_jacobian: &view.camera_jacobian,
    };
    let mut values = servo.values().to_vec();
    group.bench_function("paper_tasks_evaluate", |b| {
        b.iter(|| {
            for (task, value) in servo.tasks().iter().zip(values.iter_mut()) {
                task.evaluate(black_box(&context), value).unwrap();
            }
        })
    });
    for levels in 1..=values.len() {
        let order: Vec<usize> = (0..levels).collect();
        bench_alternating(
            &mut group,
            BenchmarkId::new("stack_solve_paper", levels),
            &values,
            &order,
        );
    }
    let law = servo.law();
    let cost: &dyn Cost<6> = scene.limits();
    let order = [0, 1, 2, 3];
    let mut workspace = ControlWorkspace::new(&values);
    let mut time = 0.0;
    group.bench_function("control_law_4_levels", |b| {
        b.iter(|| {
            time += 0.01;
            let out = control_step(
                law,
                &mut workspace,
                &values,
                &order,
                Some(cost),
                &q,
                time,
                StackChange::Unchanged,
            )
            .unwrap();
            black_box(out.velocity()[0])
        })
    });
    let parameters = ControllerParameters {
        settle_velocity: 1e3,
        settle_velocity_with_removal: 1e3,
        removal_threshold: Some(1e9),
        ..ControllerParameters::default()
    };
    let mut controller = StackController::new(parameters, &values).unwrap();
    let (mut iteration, mut time) = (0, 0.0);
    while !controller.is_complete() {
        controller
            .step(law, &values, Some(cost), &q, iteration, time)
            .unwrap();
        iteration += 1;
        time += 0.01;
    }
    group.bench_function("controller_step_law_prediction_criteria", |b| {
        b.iter(|| {
            iteration += 1;
            time += 0.01;
            let step = controller
                .step(law, &values, Some(cost), &q, iteration, time)
                .unwrap();
            black_box(step.velocity[0])
        })
    });
    assert!(
        !controller.criteria().is_empty(),
        "the criteria must be computed in this benchmark"
    );
    group.finish();
}

/// Four synthetic levels of `rows` rows each on N joints, deterministic pseudo-random entries.
fn synthetic_tasks<const N: usize>(rows: &[usize]) -> Vec<TaskValue<N>> {
    rows.iter()
        .enumerate()
        .map(|(i, &m)| {
            let jacobian = TaskJacobian::<N>::from_fn(m, |r, c| {
                ((11 * i + 5 * r + 3 * c) as f64 * 0.73).sin()
            });
            let error = DVector::from_fn(m, |r, _| 0.1 * ((i + r) as f64).cos());
            TaskValue::from_parts(&format!("t{i}"), error, jacobian, 0.5).unwrap()
        })
        .collect()
}

/// Solves alternately `tasks` and a copy perturbed by one control period's change, as a control loop does: the
/// warm-started decompositions (levels with at least N rows) then start from a nearby, not an identical, matrix.
fn bench_alternating<const N: usize>(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    id: BenchmarkId,
    tasks: &[TaskValue<N>],
    order: &[usize],
) {
    let pair = [tasks.to_vec(), perturbed(tasks)];
    let mut workspace = StackWorkspace::new(tasks);
    let parameters = StackParameters::default();
    let mut k = 0;
    group.bench_function(id, |b| {
        b.iter(|| {
            k += 1;
            let solution =
                solve_stack(&parameters, &mut workspace, black_box(&pair[k % 2]), order).unwrap();
            black_box(solution.velocity()[0])
        })
    });
}

fn bench_solve<const N: usize>(c: &mut Criterion, group: &str, rows: &[usize], levels: usize) {
    let tasks = synthetic_tasks::<N>(rows);
    let order: Vec<usize> = (0..levels).collect();
    let id = format!(
        "n{N}_rows{}",
        rows[..levels]
            .iter()
            .map(usize::to_string)
            .collect::<Vec<_>>()
            .join("-")
    );
    let mut group = c.benchmark_group(group);
    bench_alternating(&mut group, BenchmarkId::from_parameter(id), &tasks, &order);
    group.finish();
}

fn scaling(c: &mut Criterion) {
    // Against the number of levels: the paper's shape (2, 1, 1, 2) on six joints.
    for levels in 1..=4 {
        bench_solve::<6>(c, "scaling_levels", &[2, 1, 1, 2], levels);
    }
    // Against N: the paper's shape, and one level of N rows (a full-rank square level, the worst case of a level).
    bench_solve::<6>(c, "scaling_joints", &[2, 1, 1, 2], 4);
    bench_solve::<7>(c, "scaling_joints", &[2, 1, 1, 2], 4);
    bench_solve::<12>(c, "scaling_joints", &[2, 1, 1, 2], 4);
    bench_solve::<6>(c, "scaling_joints", &[6], 1);
    bench_solve::<7>(c, "scaling_joints", &[7], 1);
    bench_solve::<12>(c, "scaling_joints", &[12], 1);
    bench_solve::<6>(c, "scaling_joints", &[8], 1);
}

criterion_group!(benches, steps, sequencing, parts, scaling);
criterion_main!(benches);
