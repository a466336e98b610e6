//! One step of the hierarchical QP cascade (theory §14) on the paper scene (the Afma6 of `benches/control_loop.rs` with
//! the paper's four tasks stacked, `ServoLoop::paper` run until every task is stacked) and on the peer scene (the
//! four-point task of `benches/peer.rs`, variant C, ten periods from its start), with the scene's joint limits and a 10 ms period.
//!
//! * `hqp/{scene}/solve_*`: the cascade alone ([`solve_hqp`]): the levels and the joint-limit gradient as the last
//!   level, in a box that no level reaches (`inactive`: 0.7 rad/s or m/s; every level then takes the closed form and
//!   no QP is solved), the same with the QP at every level (`inactive_qp_only`), and in a box that makes levels QPs
//!   (`active`: each joint's velocity limit half the largest joint velocity of the stack).
//! * `hqp/{scene}/control_step_active`: the whole law step ([`control_step`] after
//!   [`ControlWorkspace::solve_as_hierarchical_qp`]) in the active box: the box, the stack solve the controller reads,
//!   the cascade and the transition kept in the box.
//!
//! Each solve alternates between the tasks and a copy perturbed by one period's change, as in a loop. The number of
//! QPs a step solves, and their iterations, are printed. Run with `cargo bench --bench hqp`.

#[path = "common/perturbed.rs"]
mod perturbed;
#[path = "common/servo_loop.rs"]
mod servo_loop;

use criterion::{criterion_group, criterion_main, Criterion};
use perturbed::perturbed;
use servo_loop::{ServoLoop, Variant, PERIOD};
use servostack::avoidance::Cost;
use servostack::law::hqp::{solve_hqp, HqpParameters, HqpWorkspace, LevelSolve};
use servostack::law::sns::SnsBounds;
use servostack::law::{control_step, ControlWorkspace, StackChange};
use servostack::math::JointVector;
use servostack::stack::{solve_stack, StackParameters, StackWorkspace};
use std::hint::black_box;

fn hqp_step(c: &mut Criterion) {
    let mut paper = ServoLoop::paper();
    paper.settle();
    // A few periods in, so that the tasks are evaluated and the law moves.
    let mut peer = ServoLoop::peer(Variant::C);
    for _ in 0..10 {
        peer.step();
    }
    let mut group = c.benchmark_group("hqp");
    for (scene, servo) in [("paper", &paper), ("peer", &peer)] {
        let q = *servo.q();
        let values = servo.values().to_vec();
        let pair = [values.clone(), perturbed(&values)];
        let order: Vec<usize> = (0..values.len()).collect();
        let limits = servo.scene().limits().clone();
        let mut gradient = JointVector::zeros();
        limits.value_and_gradient(&q, &mut gradient).unwrap();
        let target = gradient * -servo.law().avoidance_gain();
        let parameters = StackParameters::default();
        let stack_velocity = *solve_stack(
            &parameters,
            &mut StackWorkspace::new(&values),
            &values,
            &order,
        )
        .unwrap()
        .velocity();
        let qp_only = HqpParameters {
            closed_form_first: false,
            ..HqpParameters::default()
        };
        let cases = [
            ("inactive", 0.7, HqpParameters::default()),
            ("inactive_qp_only", 0.7, qp_only),
            (
                "active",
                0.5 * stack_velocity.amax(),
                HqpParameters::default(),
            ),
        ];
        let max_rows = values.iter().map(|v| v.rows()).max().unwrap();
        for (name, max_velocity, hqp) in cases {
            let bounds =
                SnsBounds::new(limits.clone(), JointVector::repeat(max_velocity), PERIOD).unwrap();
            let (mut lower, mut upper) = (JointVector::zeros(), JointVector::zeros());
            bounds
                .velocity_box(&q, &JointVector::zeros(), &mut lower, &mut upper)
                .unwrap();
            let mut workspace = HqpWorkspace::with_capacity(max_rows, values.len(), &hqp).unwrap();
            let mut k = 0;
            group.bench_function(format!("{scene}/solve_{name}"), |b| {
                b.iter(|| {
                    k += 1;
                    let solution = solve_hqp(
                        &parameters,
                        &mut workspace,
                        black_box(&pair[k % 2]),
                        &order,
                        Some(&target),
                        &lower,
                        &upper,
                    )
                    .unwrap();
                    black_box(solution.velocity()[0])
                })
            });
            let iterations: Vec<u32> = workspace
                .solution()
                .levels()
                .iter()
                .filter_map(|l| match l.solve {
                    LevelSolve::Qp { iterations } | LevelSolve::Kept { iterations } => {
                        Some(iterations)
                    }
                    LevelSolve::ClosedForm => None,
                })
                .collect();
            println!(
                "hqp/{scene}/{name}: {} QPs of {} levels, iterations {iterations:?}",
                iterations.len(),
                workspace.solution().levels().len()
            );
            if name != "active" {
                continue;
            }
            let mut control = ControlWorkspace::new(&values);
            control.solve_as_hierarchical_qp(bounds, &hqp).unwrap();
            let cost: &dyn Cost<6> = &limits;
            let mut time = 0.0;
            group.bench_function(format!("{scene}/control_step_{name}"), |b| {
                b.iter(|| {
                    time += PERIOD;
                    k += 1;
                    let out = control_step(
                        servo.law(),
                        &mut control,
                        black_box(&pair[k % 2]),
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
        }
    }
    group.finish();
}

criterion_group!(benches, hqp_step);
criterion_main!(benches);
