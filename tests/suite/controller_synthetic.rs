//! The stack controller on synthetic joint-space tasks (theory §6, D1, D3–D7, D13, D14, D28): the task that drives a
//! joint into its limit is the one removed, the limit is not hit, the task comes back, and the velocity is continuous
//! at every event.
//!
//! The tests are split by theme:
//! - [`removal`]: which task is removed and when (§6.2, §6.3, D3, D4, D6);
//! - [`fallback`]: how a removed task comes back, the fallback, the last resort and the hold (§6.4, D7, D13), and the
//!   paper's literal rule;
//! - [`steps`]: the continuity at every change (D1, D14), the early push (D28) and the contract of a step.
//!
//! This file holds what they share: the three tasks on three joints, the joint limits, the closed-loop [`Run`], the
//! continuity check, and the zero gradient of the flat stand-in costs.

/// `Cost::value_and_gradient` for a cost that is flat wherever it is defined: a zero gradient and the cost's `value`.
macro_rules! flat_value_and_gradient {
    () => {
        fn value_and_gradient(
            &self,
            q: &JointVector<3>,
            gradient: &mut JointVector<3>,
        ) -> Result<f64, CostError> {
            gradient.fill(0.0);
            self.value(q)
        }
    };
}

mod fallback;
mod removal;
mod steps;

use crate::counting_allocator::allocations_during;
use servostack::avoidance::{Cost, JointLimits};
use servostack::controller::{ControllerParameters, ControllerStatus, EventKind, StackController};
use servostack::law::ControlLaw;
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
fn evaluate<T: Task<3, JointVector<3>>>(
    tasks: &[T],
    values: &mut [TaskValue<3>],
    q: &JointVector<3>,
) {
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
    first_removal_criteria: Vec<(usize, f64)>,
    first_removal_threshold: Option<f64>,
    fallback_report: Option<(f64, f64)>,
    /// Per removal, in order: the predicted cost that triggered it and the horizon of that prediction (s).
    removal_predictions: Vec<(f64, f64)>,
    /// Per re-insertion (not fallback), in order: the prediction it was judged on and the threshold it passed.
    reinsertion_predictions: Vec<(f64, f64)>,
    /// Per iteration: the velocity sent `q̇_k` and the law `u_k` it was blended from.
    sent: Vec<JointVector<3>>,
    laws: Vec<JointVector<3>>,
    mu: f64,
    /// The controller's status at the end, and whether it says it held.
    status: ControllerStatus,
    held: bool,
    /// Heap allocations made by the controller's steps that changed nothing in the stack.
    allocations_without_event: usize,
}

impl Run {
    /// The iteration of the first event of `kind` for `task`.
    fn first(&self, kind: EventKind, task: usize) -> Option<usize> {
        self.events
            .iter()
            .find(|&&(_, k, t)| k == kind && t == task)
            .map(|e| e.0)
    }

    /// The number of events of `kind`.
    fn count(&self, kind: EventKind) -> usize {
        self.events.iter().filter(|e| e.1 == kind).count()
    }

    /// No limit was hit before the first fallback (or in the whole run without one): the removals kept the limits.
    fn assert_limits_kept_until_fallback(&self) {
        let kept_until = self
            .events
            .iter()
            .find(|e| e.1 == EventKind::Fallback)
            .map_or(self.sent.len(), |e| e.0);
        assert!(
            self.hit.is_none_or(|(_, k)| k >= kept_until),
            "events {:?}, hit {:?}",
            self.events,
            self.hit
        );
    }
}

/// Runs the three tasks from (0.2, −0.2, 0.1) with the joint-limit cost, 4000 iterations or until a limit is hit.
fn run(parameters: ControllerParameters, kappa: f64) -> Run {
    run_tasks(
        tasks(),
        JointVector::<3>::new(0.2, -0.2, 0.1),
        parameters,
        kappa,
        4000,
    )
}

/// Runs `tasks` from `start` with the joint-limit cost, `iterations` periods of 10 ms or until a limit is hit.
fn run_tasks<T: Task<3, JointVector<3>>>(
    tasks: Vec<T>,
    start: JointVector<3>,
    parameters: ControllerParameters,
    kappa: f64,
    iterations: usize,
) -> Run {
    run_guarded(tasks, start, parameters, kappa, None, iterations)
}

/// As [`run_tasks`], with a `guard` cost given to the controller (D6 (d), D7's guard relief).
fn run_guarded<T: Task<3, JointVector<3>>>(
    tasks: Vec<T>,
    start: JointVector<3>,
    parameters: ControllerParameters,
    kappa: f64,
    guard: Option<&dyn Cost<3>>,
    iterations: usize,
) -> Run {
    let mut values: Vec<TaskValue<3>> = tasks
        .iter()
        .map(|t| TaskValue::for_task(t).unwrap())
        .collect();
    let limits = limits();
    let law = ControlLaw::with_default_transition(&values, kappa).unwrap();
    let mut controller = StackController::new(parameters, &values).unwrap();
    let cost: Option<&dyn Cost<3>> = Some(&limits);
    let (dt, mut q) = (0.01, start);
    let (mut sent, mut laws) = (Vec::new(), Vec::new());
    let mut hit = None;
    let mut allocations_without_event = 0;
    for iteration in 0..iterations {
        evaluate(&tasks, &mut values, &q);
        let events_before = controller.events().len();
        let mut result = None;
        let allocations = allocations_during(|| {
            result = Some(controller.step_guarded(
                &law,
                &values,
                cost,
                guard,
                &q,
                iteration,
                iteration as f64 * dt,
            ));
        });
        let step = result.unwrap().unwrap();
        if controller.events().len() == events_before {
            allocations_without_event += allocations;
        }
        sent.push(step.velocity);
        laws.push(*controller.law_workspace().last_output().law());
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
    let fallback_report = controller
        .events()
        .iter()
        .find(|e| e.kind == EventKind::Fallback)
        .and_then(|e| e.reinsertion)
        .map(|r| (r.predicted_cost, r.removed_for));
    let removal_predictions = controller
        .events()
        .iter()
        .filter_map(|e| e.removal.as_ref())
        .map(|r| (r.predicted_cost, r.horizon))
        .collect();
    let reinsertion_predictions = controller
        .events()
        .iter()
        .filter(|e| e.kind == EventKind::Reinsert)
        .filter_map(|e| e.reinsertion)
        .map(|r| (r.predicted_cost, r.threshold))
        .collect();
    Run {
        hit,
        removal_predictions,
        reinsertion_predictions,
        events: controller
            .events()
            .iter()
            .map(|e| (e.iteration, e.kind, e.task))
            .collect(),
        first_removal_criteria,
        first_removal_threshold,
        fallback_report,
        sent,
        laws,
        mu: law.transition_gain(),
        status: controller.status(),
        held: controller.is_held(),
        allocations_without_event,
    }
}

/// D14: at a change made at iteration `k`, the velocity sent does not jump, `q̇_k = q̇_{k−1}`; and at `k + 1` the
/// transition of D1, started once at `k`, gives exactly
/// `q̇_{k+1} − q̇_k = (u_{k+1} − u_k) + (1 − e^{−μΔt}) (u_k − q̇_{k−1})`: a ramp whose first step is a fraction
/// `1 − e^{−μΔt}` of the law's jump. Without the transition term `q̇_k = u_k` jumps; with the transition restarted at
/// `k + 1` too (a double switch) the velocity is held, `q̇_{k+1} = q̇_k`, and the identity fails.
fn assert_continuous_at_events(run: &Run, dt: f64) {
    let ramp = 1.0 - (-run.mu * dt).exp();
    for &(k, kind, task) in &run.events {
        // (A change at k + 1 starts its own transition from q̇_k, checked as its own event.)
        let changed_next = run.events.iter().any(|e| e.0 == k + 1);
        if k == 0 || k + 1 >= run.sent.len() || changed_next {
            continue;
        }
        let before = run.sent[k - 1];
        let law_jump = (run.laws[k] - before).norm();
        let jump = (run.sent[k] - before).norm();
        assert!(
            jump <= 1e-12 * (1.0 + law_jump),
            "{kind:?} {task} at {k}: jump {jump:e}"
        );
        let expected = (run.laws[k + 1] - run.laws[k]) + (run.laws[k] - before) * ramp;
        let step = run.sent[k + 1] - run.sent[k];
        assert!(
            (step - expected).norm() <= 1e-9 * (1.0 + law_jump),
            "{kind:?} {task} at {k}: step {step:?}, expected {expected:?} (law jump {law_jump:e})"
        );
    }
}
