//! One step of saturation in the null space (theory §13) on the paper scene: the Afma6 of `benches/control_loop.rs`
//! with the paper's four tasks stacked (`ServoLoop::paper`, run until every task is stacked), its joint limits and a
//! 10 ms period.
//!
//! * `sns/solve_*`: the SNS solve alone ([`solve_sns`]) of the four levels and the joint-limit gradient as the last
//!   level, in a box that no level reaches (`inactive`: 0.7 rad/s or m/s) and in one that saturates joints (`active`:
//!   each joint's velocity limit half the largest joint velocity of the stack).
//! * `sns/control_step_*`: the whole law step with SNS ([`control_step`] after
//!   [`ControlWorkspace::saturate_in_null_space`]): the box, the stack solve the controller reads, the SNS solve and
//!   the transition kept in the box.
//!
//! Each solve alternates between the tasks and a copy perturbed by one period's change, as in a loop. Run with
//! `cargo bench --bench sns`.

#[path = "common/perturbed.rs"]
mod perturbed;
#[path = "common/servo_loop.rs"]
mod servo_loop;

use criterion::{criterion_group, criterion_main, Criterion};
use perturbed::perturbed;
use servo_loop::{ServoLoop, PERIOD};
use servostack::avoidance::Cost;
use servostack::law::sns::{solve_sns, SnsBounds, SnsWorkspace};
use servostack::law::{control_step, ControlWorkspace, StackChange};
use servostack::math::JointVector;
use servostack::stack::{solve_stack, StackParameters, StackWorkspace};
use std::hint::black_box;

fn sns_step(c: &mut Criterion) {
    let mut servo = ServoLoop::paper();
    servo.settle();
    let q = *servo.q();
    let values = servo.values().to_vec();
    let pair = [values.clone(), perturbed(&values)];
    let order = [0, 1, 2, 3];
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
    let boxes = [
        ("inactive", JointVector::repeat(0.7)),
        ("active", JointVector::repeat(0.5 * stack_velocity.amax())),
    ];
    let mut group = c.benchmark_group("sns");
    for (name, max_velocity) in boxes {
        let bounds = SnsBounds::new(limits.clone(), max_velocity, PERIOD).unwrap();
        let (mut lower, mut upper) = (JointVector::zeros(), JointVector::zeros());
        bounds
            .velocity_box(&q, &JointVector::zeros(), &mut lower, &mut upper)
            .unwrap();
        let mut workspace = SnsWorkspace::with_capacity(8, values.len());
        let mut k = 0;
        group.bench_function(format!("solve_{name}"), |b| {
            b.iter(|| {
                k += 1;
                let solution = solve_sns(
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
        let saturated: usize = workspace
            .solution()
            .levels()
            .iter()
            .map(|l| l.saturated.iter().filter(|&&s| s).count())
            .sum();
        println!("sns/{name}: {saturated} joint saturations over the levels");
        let mut control = ControlWorkspace::new(&values);
        control.saturate_in_null_space(bounds);
        let cost: &dyn Cost<6> = &limits;
        let mut time = 0.0;
        group.bench_function(format!("control_step_{name}"), |b| {
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
    group.finish();
}

criterion_group!(benches, sns_step);
criterion_main!(benches);
