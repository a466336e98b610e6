//! D23: a reserve task takes the place of the last task of the sequence when the stack has achieved its tasks at a
//! false equilibrium; D24: earlier, as soon as the complete stack drives the reserve task's error up. Synthetic
//! joint-space tasks on three joints: the sequence's second task, `s = q₁²` with `s* = 0.25`, is achieved at
//! `q₁ = ±0.5`, and from a negative start it settles at −0.5; the reserve task, `q₁` with desired value 0.5, is
//! achieved at the goal only. From `q₁ = −0.8` the second task moves `q₁` up, towards the reserve's goal, until it
//! stops at −0.5 (D23's case); from `q₁ = −0.3` it moves `q₁` down, away from it (D24's case).

use crate::counting_allocator::allocations_during;
use servostack::controller::{ControllerError, ControllerParameters, EventKind, StackController};
use servostack::law::ControlLaw;
use servostack::math::JointVector;
use servostack::task::{LinearTask, Task, TaskError, TaskJacobian, TaskValue};

/// `e = q₁² − 0.25`, `J = [0, 2 q₁, 0]`: two solutions, as the paper's features have at other poses than the goal.
struct Ambiguous;

impl Task<3, JointVector<3>> for Ambiguous {
    fn name(&self) -> &str {
        "ambiguous"
    }
    fn rows(&self) -> usize {
        1
    }
    fn gain(&self) -> f64 {
        1.0
    }
    fn evaluate(&self, q: &JointVector<3>, out: &mut TaskValue<3>) -> Result<(), TaskError> {
        let (error, jacobian) = out.parts_mut();
        error[0] = q[1] * q[1] - 0.25;
        jacobian.fill(0.0);
        jacobian[(0, 1)] = 2.0 * q[1];
        Ok(())
    }
}

fn row(joint: usize) -> TaskJacobian<3> {
    TaskJacobian::<3>::from_fn(1, |_, k| if k == joint { 1.0 } else { 0.0 })
}

/// The sequence (hold joint 0 at 0.2, the ambiguous task) and, with `reserve`, the reserve task `q₁ → 0.5`.
fn tasks(reserve: bool) -> Vec<Box<dyn Task<3, JointVector<3>>>> {
    let mut tasks: Vec<Box<dyn Task<3, JointVector<3>>>> = vec![
        Box::new(
            LinearTask::new("hold", row(0), JointVector::<3>::new(0.2, 0.0, 0.0), 1.0).unwrap(),
        ),
        Box::new(Ambiguous),
    ];
    if reserve {
        tasks.push(Box::new(
            LinearTask::new("reserve", row(1), JointVector::<3>::new(0.0, 0.5, 0.0), 1.0).unwrap(),
        ));
    }
    tasks
}

struct Outcome {
    q: JointVector<3>,
    events: Vec<(usize, EventKind, usize)>,
    stacked: Vec<usize>,
    sent: Vec<JointVector<3>>,
    /// Heap allocations made by the controller's steps once the whole sequence was pushed (the escape tests run there).
    allocations_after_pushes: usize,
}

/// Runs the tasks from `q₁ = −0.8` for 30 s (10 ms periods), no avoidance cost.
fn run(reserve: bool, parameters: ControllerParameters) -> Outcome {
    run_from(-0.8, reserve, parameters)
}

/// Runs the tasks from `q = (0, q₁, 0)` for 30 s (10 ms periods), no avoidance cost.
fn run_from(q1: f64, reserve: bool, parameters: ControllerParameters) -> Outcome {
    let tasks = tasks(reserve);
    let mut values: Vec<TaskValue<3>> = tasks
        .iter()
        .map(|t| TaskValue::for_task(t.as_ref()).unwrap())
        .collect();
    let law = ControlLaw::with_default_transition(&values, 0.0).unwrap();
    let mut controller = StackController::new(parameters, &values).unwrap();
    if reserve {
        controller = controller.with_reserve_task().unwrap();
    }
    let (dt, mut q) = (0.01, JointVector::<3>::new(0.0, q1, 0.0));
    let mut sent = Vec::with_capacity(3000);
    let mut allocations_after_pushes = 0;
    for iteration in 0..3000 {
        for (task, value) in tasks.iter().zip(values.iter_mut()) {
            task.evaluate(&q, value).unwrap();
        }
        let pushed_all = controller.is_complete();
        let mut step = None;
        let allocations = allocations_during(|| {
            step = Some(controller.step(&law, &values, None, &q, iteration, iteration as f64 * dt));
        });
        if pushed_all {
            allocations_after_pushes += allocations;
        }
        let step = step.unwrap().unwrap();
        sent.push(step.velocity);
        q += step.velocity * dt;
    }
    Outcome {
        q,
        events: controller
            .events()
            .iter()
            .map(|e| (e.iteration, e.kind, e.task))
            .collect(),
        stacked: controller.stacked().to_vec(),
        sent,
        allocations_after_pushes,
    }
}

#[test]
fn without_a_reserve_the_sequence_settles_at_its_false_equilibrium() {
    let out = run(false, ControllerParameters::default());
    assert!((out.q[1] + 0.5).abs() < 1e-3, "{:?}", out.q);
    assert!(out.events.iter().all(|e| e.1 == EventKind::Push));
}

#[test]
fn the_reserve_task_replaces_the_last_task_once_and_reaches_the_goal() {
    let out = run(true, ControllerParameters::default());
    // Joint 1 ends at the goal, where the replaced task is achieved too; the higher task was kept throughout.
    assert!((out.q[1] - 0.5).abs() < 1e-3, "{:?}", out.q);
    assert!((out.q[0] - 0.2).abs() < 1e-3, "{:?}", out.q);
    let escapes: Vec<_> = out
        .events
        .iter()
        .filter(|e| e.1 == EventKind::Escape)
        .collect();
    assert_eq!(escapes.len(), 1, "{:?}", out.events);
    assert_eq!(escapes[0].2, 2, "the event names the reserve task");
    assert_eq!(out.stacked, [0, 2]);
    // Only once the sequence had settled at the false equilibrium: both pushes before it.
    let pushes: Vec<_> = out
        .events
        .iter()
        .filter(|e| e.1 == EventKind::Push)
        .collect();
    assert_eq!(pushes.len(), 2);
    assert!(pushes.iter().all(|p| p.0 < escapes[0].0));
    // The change is continuous (D1): no velocity jump at the escape.
    let k = escapes[0].0;
    assert!((out.sent[k] - out.sent[k - 1]).norm() < 1e-9);
    assert!(
        out.sent[k + 1].norm() > 0.0,
        "the reserve task moves the robot"
    );
}

#[test]
fn no_escape_above_the_reserve_threshold_or_before_the_stack_is_achieved() {
    // The reserve's error at the false equilibrium is 1.0: with a threshold above it, no escape.
    let high = ControllerParameters {
        escape_error: 1.5,
        ..ControllerParameters::default()
    };
    let out = run(true, high);
    assert!(out.events.iter().all(|e| e.1 != EventKind::Escape));
    assert!((out.q[1] + 0.5).abs() < 1e-3);
    // The stacked tasks must be achieved first: an impossible achievement threshold never lets it happen.
    let strict = ControllerParameters {
        escape_achieved_error: 1e-300,
        ..ControllerParameters::default()
    };
    let out = run(true, strict);
    assert!(out.events.iter().all(|e| e.1 != EventKind::Escape));
}

/// The iterations of the events of one kind.
fn iterations_of(out: &Outcome, kind: EventKind) -> Vec<usize> {
    out.events
        .iter()
        .filter(|e| e.1 == kind)
        .map(|e| e.0)
        .collect()
}

/// The lowest `q₁` of a run from `q₁ = start`, integrated from the velocities sent as the run did.
fn lowest_q1(start: f64, out: &Outcome) -> f64 {
    out.sent
        .iter()
        .scan(start, |q1, v| {
            *q1 += v[1] * 0.01;
            Some(*q1)
        })
        .fold(start, f64::min)
}

#[test]
fn the_reserve_comes_in_as_soon_as_the_stack_drives_its_error_up() {
    // From −0.3 the ambiguous task heads for −0.5, away from the reserve's goal 0.5.
    let early = run_from(-0.3, true, ControllerParameters::default());
    assert!((early.q[1] - 0.5).abs() < 1e-3, "{:?}", early.q);
    let pushes = iterations_of(&early, EventKind::Push);
    let escapes = iterations_of(&early, EventKind::Escape);
    assert_eq!((pushes.len(), escapes.len()), (2, 1), "{:?}", early.events);
    // One transition time (1/μ = 0.1 s with the default μ = 10 · λ) after the push: the law's transient is not judged,
    // and nothing had settled yet (the settled test needs n_settle = 5 transition times).
    let after_push = escapes[0] - pushes[1];
    assert!((10..=12).contains(&after_push), "{:?}", early.events);
    // No velocity jump at the escape (D1), and no heap allocation in the steps that test and make it.
    let k = escapes[0];
    assert!((early.sent[k] - early.sent[k - 1]).norm() < 1e-9);
    assert_eq!(early.allocations_after_pushes, 0);
    // Joint 1 turned back before it got near the false equilibrium.
    assert!(
        lowest_q1(-0.3, &early) > -0.4,
        "{}",
        lowest_q1(-0.3, &early)
    );

    // Without the early escape (r_escape = +∞) the stack first settles at −0.5, and only D23 brings the reserve in.
    let late = run_from(
        -0.3,
        true,
        ControllerParameters {
            escape_growth_rate: f64::INFINITY,
            ..ControllerParameters::default()
        },
    );
    assert!((late.q[1] - 0.5).abs() < 1e-3, "{:?}", late.q);
    assert!(lowest_q1(-0.3, &late) < -0.49, "{}", lowest_q1(-0.3, &late));
    let late_escape = iterations_of(&late, EventKind::Escape);
    assert_eq!(late_escape.len(), 1);
    assert!(
        late_escape[0] > escapes[0] + 100,
        "D23 waits for the settled false equilibrium: {} vs {}",
        late_escape[0],
        escapes[0]
    );
}

#[test]
fn no_early_escape_while_the_stack_drives_the_reserve_towards_its_goal() {
    // From −0.8 the ambiguous task moves q₁ towards 0.5 until it stops at −0.5: the escape comes only once settled
    // there (D23), the same with and without D24.
    let with = run(true, ControllerParameters::default());
    let without = run(
        true,
        ControllerParameters {
            escape_growth_rate: f64::INFINITY,
            ..ControllerParameters::default()
        },
    );
    assert_eq!(with.events, without.events);
    let pushes = iterations_of(&with, EventKind::Push);
    let escapes = iterations_of(&with, EventKind::Escape);
    assert_eq!(escapes.len(), 1);
    assert!(escapes[0] > pushes[1] + 100, "{:?}", with.events);
    // A growth threshold above the rate at which the stack drives the reserve's error up from −0.3 keeps the early
    // escape out too: that rate, u₁/e_r = λ (0.25 − q₁²) / (2 q₁ (q₁ − 0.5)), is 1/3 s⁻¹ at −0.3 and falls towards 0
    // at −0.5.
    let high = run_from(
        -0.3,
        true,
        ControllerParameters {
            escape_growth_rate: 1.0,
            ..ControllerParameters::default()
        },
    );
    let high_escapes = iterations_of(&high, EventKind::Escape);
    assert_eq!(high_escapes.len(), 1);
    assert!(high_escapes[0] > iterations_of(&high, EventKind::Push)[1] + 100);
}

#[test]
fn escape_parameters_and_lists_too_short_are_named() {
    for (name, value) in [
        ("escape_error", f64::NAN),
        ("escape_error", 0.0),
        ("escape_achieved_error", -1.0),
        ("escape_growth_rate", f64::NAN),
        ("escape_growth_rate", -0.1),
    ] {
        let mut parameters = ControllerParameters::default();
        match name {
            "escape_error" => parameters.escape_error = value,
            "escape_growth_rate" => parameters.escape_growth_rate = value,
            _ => parameters.escape_achieved_error = value,
        }
        match parameters.validate() {
            Err(ControllerError::InvalidParameter { name: named, .. }) => assert_eq!(named, name),
            other => panic!("{name} = {value}: {other:?}"),
        }
    }
    let never = ControllerParameters {
        escape_error: f64::INFINITY,
        ..ControllerParameters::default()
    };
    assert!(never.validate().is_ok());
    let one =
        [
            TaskValue::for_task(
                &LinearTask::new("only", row(0), JointVector::zeros(), 1.0).unwrap(),
            )
            .unwrap(),
        ];
    let error = StackController::new(ControllerParameters::default(), &one)
        .unwrap()
        .with_reserve_task()
        .unwrap_err();
    assert!(matches!(
        error,
        ControllerError::InvalidParameter {
            name: "reserve task",
            ..
        }
    ));
}
