//! The stack controller on synthetic joint-space tasks (theory §6, D3–D7): the task that drives a joint into its limit is
//! the one removed, the limit is not hit, the task comes back, and the velocity is continuous at every event.

use servostack::avoidance::{Cost, CostError, JointLimits};
use servostack::controller::{
    ControllerError, ControllerParameters, EventKind, RemovalCriterion, StackController,
};
use servostack::law::ControlLaw;
use servostack::linalg::{null_space_projector, RankPolicy};
use servostack::math::JointVector;
use servostack::task::{LinearTask, Task, TaskJacobian, TaskValue};

/// Three 1-row tasks on 3 joints: t0 holds joint 2 at 0, t1 drives joint 0 to 1.05 (beyond its hard limit 1), t2
/// drives joint 1 to 0.3.
fn tasks() -> Vec<LinearTask<3>> {
    let row = |c: usize| TaskJacobian::<3>::from_fn(1, |_, k| if k == c { 1.0 } else { 0.0 });
    vec![
        LinearTask::new("hold", row(2), JointVector::zeros(), 1.0).unwrap(),
        LinearTask::new("reach", row(0), JointVector::<3>::new(1.05, 0.0, 0.0), 1.0).unwrap(),
        LinearTask::new("side", row(1), JointVector::<3>::new(0.0, 0.3, 0.0), 1.0).unwrap(),
    ]
}

/// The tasks with their value storage.
fn tasks_and_values() -> (Vec<LinearTask<3>>, Vec<TaskValue<3>>) {
    let tasks = tasks();
    let values = tasks
        .iter()
        .map(|t| TaskValue::for_task(t).unwrap())
        .collect();
    (tasks, values)
}

/// Evaluates every task at `q`.
fn evaluate(tasks: &[LinearTask<3>], values: &mut [TaskValue<3>], q: &JointVector<3>) {
    for (task, value) in tasks.iter().zip(values.iter_mut()) {
        task.evaluate(q, value).unwrap();
    }
}

/// Limits at ±1 on every joint, ρ = 0.1.
fn limits() -> JointLimits<3> {
    JointLimits::new(JointVector::repeat(-1.0), JointVector::repeat(1.0), 0.1).unwrap()
}

struct Run {
    hit: Option<(usize, usize)>,
    events: Vec<(usize, EventKind, usize)>,
    max_jump: f64,
    first_removal_criteria: Vec<(usize, f64)>,
    first_removal_threshold: Option<f64>,
}

/// Runs the three tasks from (0.2, −0.2, 0.1) with the joint-limit cost, 4000 iterations or until a limit is hit.
fn run(parameters: ControllerParameters, kappa: f64) -> Run {
    let (tasks, mut values) = tasks_and_values();
    let limits = limits();
    let law = ControlLaw::with_default_transition(&values, kappa).unwrap();
    let mut controller = StackController::new(parameters, &values).unwrap();
    let cost: Option<&dyn Cost<3>> = Some(&limits);
    let (dt, mut q) = (0.01, JointVector::<3>::new(0.2, -0.2, 0.1));
    let mut previous = JointVector::<3>::zeros();
    let mut max_jump = 0.0f64;
    let mut changed = true; // the first iteration is a change (the first push)
    let mut hit = None;
    for iteration in 0..4000 {
        evaluate(&tasks, &mut values, &q);
        let step = controller
            .step(&law, &values, cost, &q, iteration, iteration as f64 * dt)
            .unwrap();
        if changed {
            max_jump = max_jump.max((step.velocity - previous).norm());
        }
        changed = step.event.is_some();
        previous = step.velocity;
        q += step.velocity * dt;
        if let Some(joint) = limits.violated_joint(&q) {
            hit = Some((joint, iteration));
            break;
        }
    }
    let first_removal = controller.events().iter().find_map(|e| e.removal.as_ref());
    let first_removal_criteria = first_removal
        .map(|r| r.criteria.iter().map(|c| (c.task, c.combined)).collect())
        .unwrap_or_default();
    let first_removal_threshold = first_removal.map(|r| r.threshold);
    Run {
        hit,
        events: controller
            .events()
            .iter()
            .map(|e| (e.iteration, e.kind, e.task))
            .collect(),
        max_jump,
        first_removal_criteria,
        first_removal_threshold,
    }
}

#[test]
fn push_only_with_avoidance_hits_the_limit() {
    let run = run(
        ControllerParameters {
            allow_removal: false,
            ..Default::default()
        },
        1.0,
    );
    assert_eq!(run.hit.map(|(joint, _)| joint), Some(0));
    assert!(run
        .events
        .iter()
        .all(|&(_, kind, _)| kind == EventKind::Push));
}

#[test]
fn controller_removes_the_blocking_task_and_puts_it_back() {
    let run = run(ControllerParameters::default(), 1.0);
    assert_eq!(run.hit, None, "events: {:?}", run.events);
    let removals: Vec<usize> = run
        .events
        .iter()
        .filter(|e| e.1 == EventKind::Remove)
        .map(|e| e.2)
        .collect();
    assert!(!removals.is_empty(), "no removal: {:?}", run.events);
    assert!(
        removals.iter().all(|&task| task == 1),
        "removed {removals:?}"
    );
    assert!(run
        .events
        .iter()
        .any(|&(_, kind, task)| kind == EventKind::Reinsert && task == 1));
    // The removed task scored highest: its motion is aligned with ∇h (joint 0 upwards), the others are orthogonal.
    let best = run
        .first_removal_criteria
        .iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap();
    assert_eq!(best.0, 1);
    assert!(run.max_jump < 1e-12, "velocity jump {:e}", run.max_jump);
}

#[test]
fn every_criterion_picks_the_blocking_task() {
    for criterion in [
        RemovalCriterion::NormalizedDirection,
        RemovalCriterion::KernelProjection,
    ] {
        let run = run(
            ControllerParameters {
                criterion,
                ..Default::default()
            },
            1.0,
        );
        assert_eq!(run.hit, None);
        let first_removal = run
            .events
            .iter()
            .find(|e| e.1 == EventKind::Remove)
            .unwrap();
        assert_eq!(first_removal.2, 1, "{criterion:?}");
    }
}

/// The criteria against independent computations: `C2_i = ‖(I − J_i⁺J_i) g‖` from the kernel projector, and
/// `C1'_i = −(J_i⁺ e_i)ᵀ g / ‖J_i⁺ e_i‖` for a task with a non-trivial Jacobian.
#[test]
fn criteria_match_their_definitions() {
    let j = TaskJacobian::<3>::from_row_slice(&[1.0, 2.0, 0.5, 0.0, 1.0, -1.0]);
    let task =
        LinearTask::new("two", j.clone(), JointVector::<3>::new(0.3, -0.2, 0.1), 1.0).unwrap();
    let mut value = TaskValue::for_task(&task).unwrap();
    let q = JointVector::<3>::new(0.95, -0.93, 0.0); // two joints in their activation bands
    task.evaluate(&q, &mut value).unwrap();
    let values = [value];
    let limits = limits();
    let law = ControlLaw::new(10.0, 0.5).unwrap();
    let mut controller = StackController::new(ControllerParameters::default(), &values).unwrap();
    controller
        .step(&law, &values, Some(&limits as &dyn Cost<3>), &q, 0, 0.0)
        .unwrap();
    let criteria = controller.criteria()[0];
    let mut g = JointVector::<3>::zeros();
    limits.value_and_gradient(&q, &mut g).unwrap();
    let mut work = j.clone();
    let kernel = null_space_projector(&j, &mut work, &RankPolicy::default()).unwrap();
    assert!((criteria.c2 - (kernel * g).norm()).abs() < 1e-12);
    assert!((criteria.c2.powi(2) + criteria.c2_prime.powi(2) - g.norm_squared()).abs() < 1e-14);
    let pinv = servostack::linalg::pseudo_inverse(&j, &RankPolicy::default()).unwrap();
    let direction = pinv * values[0].error();
    assert!((criteria.c1 + direction.dot(&g)).abs() < 1e-12);
    assert!((criteria.c1_normalized - criteria.c1 / direction.norm()).abs() < 1e-12);
    assert!(
        (criteria.combined - (criteria.c1_normalized + criteria.c2_prime) / g.norm()).abs() < 1e-12
    );
}

#[test]
fn invalid_parameters_and_task_count() {
    let values = [TaskValue::<3>::new("t", 1, 1.0).unwrap()];
    let cases = [
        (
            ControllerParameters {
                settle_velocity: 0.0,
                ..Default::default()
            },
            "settle_velocity",
        ),
        (
            ControllerParameters {
                prediction_horizon: -0.1,
                ..Default::default()
            },
            "prediction_horizon",
        ),
        (
            ControllerParameters {
                removal_threshold: Some(f64::NAN),
                ..Default::default()
            },
            "removal_threshold",
        ),
        (
            ControllerParameters {
                settle_transitions: f64::INFINITY,
                ..Default::default()
            },
            "settle_transitions",
        ),
    ];
    for (parameters, expected) in cases {
        match StackController::new(parameters, &values) {
            Err(ControllerError::InvalidParameter { name, .. }) => assert_eq!(name, expected),
            other => panic!("{expected}: expected InvalidParameter, got {other:?}"),
        }
    }
    let mut controller = StackController::new(ControllerParameters::default(), &values).unwrap();
    let law = ControlLaw::new(1.0, 0.0).unwrap();
    assert_eq!(
        controller
            .step(&law, &[], None, &JointVector::zeros(), 0, 0.0)
            .unwrap_err(),
        ControllerError::TaskCount {
            expected: 1,
            found: 0
        }
    );
}

/// With default parameters (`removal_threshold: None`) the threshold comes from the cost (theory D6: the joint-limit
/// half-band cost): the blocking task is still removed, with that threshold, and the limit not hit.
#[test]
fn default_parameters_take_the_threshold_from_the_cost() {
    let run = run(ControllerParameters::default(), 1.0);
    assert_eq!(run.hit, None);
    assert!(run
        .events
        .iter()
        .any(|&(_, kind, task)| kind == EventKind::Remove && task == 1));
    assert_eq!(
        run.first_removal_threshold,
        Some(limits().default_removal_threshold())
    );
}

/// The first push happens at the first step, with that step's iteration and time (a clock need not start at 0), and
/// it is the only change of that iteration.
#[test]
fn first_push_is_logged_at_the_first_step() {
    let (tasks, mut values) = tasks_and_values();
    let law = ControlLaw::new(10.0, 0.0).unwrap();
    let mut controller = StackController::new(ControllerParameters::default(), &values).unwrap();
    assert!(controller.stacked().is_empty());
    let q = JointVector::<3>::zeros(); // "hold" is already achieved here: a naive rule would push again at once
    evaluate(&tasks, &mut values, &q);
    controller.step(&law, &values, None, &q, 7, 100.0).unwrap();
    assert_eq!(controller.events().len(), 1);
    let first = &controller.events()[0];
    assert_eq!(
        (first.iteration, first.time, first.kind, first.task),
        (7, 100.0, EventKind::Push, 0)
    );
    assert_eq!(controller.stacked(), &[0]);
}

/// A cost that is defined at one configuration only: the law (evaluated there) succeeds, the prediction (elsewhere)
/// fails (reported as an infinite value of joint 0, for the test).
struct DefinedOnlyAt(JointVector<3>);

impl Cost<3> for DefinedOnlyAt {
    fn value(&self, q: &JointVector<3>) -> Result<f64, CostError> {
        if *q == self.0 {
            Ok(0.0)
        } else {
            Err(CostError::NonFiniteConfiguration {
                joint: 0,
                value: f64::INFINITY,
            })
        }
    }
    fn value_and_gradient(
        &self,
        q: &JointVector<3>,
        gradient: &mut JointVector<3>,
    ) -> Result<f64, CostError> {
        gradient.fill(0.0);
        self.value(q)
    }
}

/// A step that fails after the law ran (here, in the prediction) sends nothing: the next change still blends from
/// the velocity actually sent before, which the law's workspace keeps.
#[test]
fn a_failed_step_leaves_the_last_sent_velocity_in_place() {
    let (tasks, mut values) = tasks_and_values();
    let law = ControlLaw::new(10.0, 0.0).unwrap();
    let mut controller = StackController::new(ControllerParameters::default(), &values).unwrap();
    let q = JointVector::<3>::new(0.2, -0.2, 0.4); // "hold" (joint 2 to 0) is stacked first and moves joint 2
    evaluate(&tasks, &mut values, &q);
    controller.step(&law, &values, None, &q, 0, 0.0).unwrap();
    let sent = controller
        .step(&law, &values, None, &q, 1, 0.01)
        .unwrap()
        .velocity;
    assert!(sent.norm() > 0.0);
    let failing = DefinedOnlyAt(q);
    let error = controller
        .step(&law, &values, Some(&failing), &q, 2, 0.02)
        .unwrap_err();
    assert_eq!(
        error,
        ControllerError::Cost(CostError::NonFiniteConfiguration {
            joint: 0,
            value: f64::INFINITY
        })
    );
    assert_eq!(*controller.law_workspace().last_output().velocity(), sent);
}
