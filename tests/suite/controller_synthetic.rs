//! The stack controller on synthetic joint-space tasks (theory §6, D3–D7): the task that drives a joint into its limit is
//! the one removed, the limit is not hit, the task comes back, and the velocity is continuous at every event.

use crate::counting_allocator::allocations_during;
use nalgebra::DVector;
use servostack::avoidance::{CompositeCost, Cost, CostError, JointLimits};
use servostack::controller::{
    ControllerError, ControllerParameters, ControllerStatus, DecisionRule, EventKind,
    RemovalCriterion, StackController,
};
use servostack::law::ControlLaw;
use servostack::linalg::{null_space_projector, RankPolicy};
use servostack::math::JointVector;
use servostack::task::{LinearTask, Task, TaskError, TaskJacobian, TaskValue};

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
    assert_continuous_at_events(&run, 0.01);
}

/// D13: by default the fallback comes at the first refused re-insertion test; with `stall_timeout` set, the refused
/// task waits that long first (the same run until then: the controller is deterministic).
#[test]
fn the_fallback_comes_at_the_first_refusal_unless_a_stall_timeout_is_set() {
    let first_fallback = |stall_timeout: f64| {
        let run = run(
            ControllerParameters {
                hold_before_limit: false,
                stall_timeout,
                ..Default::default()
            },
            1.0,
        );
        let at = run
            .events
            .iter()
            .find(|e| e.1 == EventKind::Fallback)
            .map(|e| e.0)
            .expect("a fallback");
        let (_, removed_for) = run.fallback_report.expect("a fallback report");
        (at, removed_for)
    };
    let (at_once, out_at_once) = first_fallback(0.0);
    let (after_wait, out_after_wait) = first_fallback(2.0);
    assert!(out_after_wait >= 2.0, "out for {out_after_wait} s");
    // The wait starts at the first refusal, which the default run falls back at: 2 s = 200 periods later.
    assert!(
        (200..=202).contains(&(after_wait - at_once)),
        "{at_once} then {after_wait}"
    );
    assert!((out_after_wait - out_at_once - 2.0).abs() < 0.025);
}

/// "reach" wants joint 0 beyond its hard limit: no configuration achieves it within the limits. The robust rule
/// removes it once (the task whose motion points into the limit), pushes the next task while it is out, refuses it
/// while the prediction with it back exceeds the threshold, and at that refusal falls back to the stack with
/// gradient (D13) — logged with the prediction that refused it. When the fallback's law is about to cross the limit,
/// the last resort takes "reach" out once more, and it comes back (without the test) only after its dwell, doubled by
/// the second removal; then it stays (one last resort per task), and the limit is reached as push-only does. No
/// re-insertion by the test, and the limit is never hit while the task is out.
#[test]
fn an_unachievable_task_is_removed_then_the_controller_falls_back_with_last_resort_removals() {
    // Without the hold (the test below), to see where the fallback's law goes.
    let parameters = ControllerParameters {
        hold_before_limit: false,
        ..Default::default()
    };
    let run = run(parameters, 1.0);
    let removals: Vec<(usize, usize)> = run
        .events
        .iter()
        .filter(|e| e.1 == EventKind::Remove)
        .map(|e| (e.0, e.2))
        .collect();
    let fallbacks: Vec<(usize, usize)> = run
        .events
        .iter()
        .filter(|e| e.1 == EventKind::Fallback)
        .map(|e| (e.0, e.2))
        .collect();
    assert!(
        removals.iter().all(|&(_, task)| task == 1),
        "events: {:?}",
        run.events
    );
    assert!(fallbacks.iter().all(|&(_, task)| task == 1));
    assert_eq!(removals.len(), 2, "events: {:?}", run.events);
    // The second removal is the last resort: after the first fallback, for a prediction past the hard limit one
    // transition time ahead (1/μ, longer than the removal horizon T of the first).
    assert!(removals[1].0 > fallbacks[0].0);
    let (first_cost, first_horizon) = run.removal_predictions[0];
    let (last_resort_cost, last_resort_horizon) = run.removal_predictions[1];
    assert!(first_cost.is_finite() && first_horizon == parameters.prediction_horizon);
    assert_eq!(last_resort_cost, f64::INFINITY);
    assert!(last_resort_horizon >= 1.0 / run.mu - 1e-12 && last_resort_horizon > first_horizon);
    assert_eq!(fallbacks.len(), removals.len());
    // "side" (task 2) is pushed while "reach" is out.
    assert!(run
        .events
        .iter()
        .any(|&(k, kind, task)| kind == EventKind::Push && task == 2 && k > removals[0].0));
    assert!(!run.events.iter().any(|e| e.1 == EventKind::Reinsert));
    let (predicted, removed_for) = run.fallback_report.expect("a fallback");
    assert!(predicted > parameters.reinsertion_ratio * limits().default_removal_threshold());
    // The first return is tested only once the task's dwell is over.
    assert!(
        removed_for >= parameters.reinsertion_dwell,
        "out for {removed_for} s"
    );
    // After the first, a return waits at least the doubled dwell T_dwell · 2^{k−1} of the k-th removal.
    for (k, (&(removed, _), &(back, _))) in removals.iter().zip(&fallbacks).enumerate().skip(1) {
        let out_for = (back - removed) as f64 * 0.01;
        let dwell = parameters.reinsertion_dwell * f64::from(1u32 << k);
        assert!(out_for >= dwell - 1e-9, "removal {k}: out {out_for} s");
    }
    // The removed task scored highest: its motion is aligned with ∇h (joint 0 upwards), the others are orthogonal.
    let best = run
        .first_removal_criteria
        .iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap();
    assert_eq!(best.0, 1);
    // The limit is kept while "reach" is out and until its last return; then it is reached as push-only does.
    assert!(!run.held);
    let last_back = fallbacks.last().unwrap().0;
    assert!(run
        .hit
        .is_some_and(|(joint, k)| joint == 0 && k > last_back));
    assert_continuous_at_events(&run, 0.01);
}

/// A removed task is tested for re-insertion only once the stack has settled and its dwell has passed (D7). Until then
/// the controller's status says that it has not been tested — no sentinel value in place of a prediction — with the
/// stack velocity it waits on; once refused, the status carries the prediction and the threshold it exceeded.
#[test]
fn a_removed_task_reports_no_test_until_it_is_tested() {
    let (tasks, mut values) = tasks_and_values();
    let limits = limits();
    let law = ControlLaw::with_default_transition(&values, 1.0).unwrap();
    let mut controller = StackController::new(ControllerParameters::default(), &values).unwrap();
    let cost: Option<&dyn Cost<3>> = Some(&limits);
    let (dt, mut q) = (0.01, JointVector::<3>::new(0.2, -0.2, 0.1));
    let (mut removed, mut refused) = (None, None);
    for iteration in 0..4000 {
        evaluate(&tasks, &mut values, &q);
        let step = controller
            .step(&law, &values, cost, &q, iteration, iteration as f64 * dt)
            .unwrap();
        q += step.velocity * dt;
        let status = controller.status();
        if removed.is_none() && step.event == Some(EventKind::Remove) {
            // Just removed, with the robot still moving: not tested yet.
            match status {
                ControllerStatus::Reinserting {
                    task: 1,
                    last_test: None,
                    stack_velocity_norm,
                } => assert!(stack_velocity_norm > 0.0 && stack_velocity_norm.is_finite()),
                other => panic!("after the removal: {other:?}"),
            }
            removed = Some(iteration);
        }
        if let ControllerStatus::Reinserting {
            task: 1,
            last_test: Some(test),
            ..
        } = status
        {
            refused = Some((iteration, test));
            break;
        }
    }
    let removed = removed.expect("the unachievable task is removed");
    let (tested, test) = refused.expect("its re-insertion is tested and refused");
    assert!(tested > removed);
    assert!(test.threshold > 0.0 && test.threshold.is_finite());
    assert!(test.predicted_cost > test.threshold, "{test:?}");
}

/// The same unachievable task with `hold_before_limit` (an option, off by default since the lock of D26): where the
/// run above reaches the limit once its last resorts are spent, the controller drops every task instead (D13 hold),
/// the law is the avoidance alone, and the limit is kept to the end of the 40 s. Without the hold the same run crosses
/// it (the test above).
#[test]
fn holding_keeps_the_limit_an_unachievable_task_would_cross() {
    let parameters = ControllerParameters {
        hold_before_limit: true,
        ..ControllerParameters::default()
    };
    let run = run(parameters, 1.0);
    assert_eq!(run.hit, None, "events: {:?}", run.events);
    let holds: Vec<usize> = run
        .events
        .iter()
        .filter(|e| e.1 == EventKind::Hold)
        .map(|e| e.0)
        .collect();
    assert_eq!(holds.len(), 1, "events: {:?}", run.events);
    // The hold comes after the fallback and the last resorts: "reach" removed twice, back after its dwell.
    let hold = holds[0];
    assert!(run.first(EventKind::Fallback, 1).is_some_and(|k| k < hold));
    let removals_before = run
        .events
        .iter()
        .filter(|e| e.1 == EventKind::Remove && e.0 < hold)
        .count();
    assert_eq!(removals_before, 2, "events: {:?}", run.events);
    // Nothing is pushed, removed or put back after it, and the controller says so.
    assert_eq!(run.events.last().map(|e| e.1), Some(EventKind::Hold));
    assert!(matches!(run.status, ControllerStatus::Held { task: 0, .. }) && run.held);
    // The avoidance alone brings the robot to rest inside the limits.
    let last = run.sent.last().copied().unwrap_or_default();
    assert!(last.norm() < 1e-3, "velocity at the end {last:?}");
    assert_continuous_at_events(&run, 0.01);
}

/// A guard that keeps joint 0 above 0.85 (`g = max(0, 0.85 − q_0)²`), inside the upper activation band of the
/// limits (0.8 to 1): the stand-in for the visibility of the target.
struct FloorOnJointZero;

impl FloorOnJointZero {
    const FLOOR: f64 = 0.85;
}

impl Cost<3> for FloorOnJointZero {
    fn value(&self, q: &JointVector<3>) -> Result<f64, CostError> {
        Ok((Self::FLOOR - q[0]).max(0.0).powi(2))
    }
    fn value_and_gradient(
        &self,
        q: &JointVector<3>,
        gradient: &mut JointVector<3>,
    ) -> Result<f64, CostError> {
        gradient.fill(0.0);
        gradient[0] = -2.0 * (Self::FLOOR - q[0]).max(0.0);
        self.value(q)
    }
}

/// D7 guard relief, on the unachievable task: once "reach" is out, the avoidance gradient takes joint 0 down through
/// the band, below the guard's floor. The guard's prediction rises, and "reach" (whose return lowers it) comes back
/// at once — while the robot still moves, without waiting for it to settle, before any fallback — judged on the
/// guard: its prediction with the task back below the one without (here from about 10⁻⁹: any rise). The same run
/// without the guard has no re-insertion at all (previous test). Each removal still counts: the task leaves at most
/// `max_removals` times.
#[test]
fn a_task_comes_back_when_its_absence_is_predicted_to_raise_the_guard() {
    let parameters = ControllerParameters::default();
    let run = run_guarded(
        tasks(),
        JointVector::<3>::new(0.2, -0.2, 0.1),
        parameters,
        1.0,
        Some(&FloorOnJointZero),
        4000,
    );
    let removal = run
        .events
        .iter()
        .find(|e| e.1 == EventKind::Remove)
        .copied()
        .expect("a removal");
    assert_eq!(removal.2, 1, "events: {:?}", run.events);
    let relief = run
        .events
        .iter()
        .find(|e| e.1 == EventKind::Reinsert)
        .copied()
        .expect("a re-insertion by the guard");
    assert_eq!(relief.2, 1);
    assert!(relief.0 > removal.0);
    // The robot is still moving: a settled re-insertion (D7) would wait for ‖q̇_n‖ < settle_velocity.
    let moving = run.sent[relief.0 - 1].norm();
    assert!(moving > 10.0 * parameters.settle_velocity, "‖q̇‖ = {moving}");
    assert!(!run
        .events
        .iter()
        .any(|e| e.1 == EventKind::Fallback && e.0 < relief.0));
    let (with_task, without_task) = run.reinsertion_predictions[0];
    assert!(
        without_task > 0.0 && with_task < without_task,
        "guard predicted {with_task} with the task, {without_task} without"
    );
    let removals = run
        .events
        .iter()
        .filter(|e| e.1 == EventKind::Remove)
        .count();
    assert!(
        removals <= parameters.max_removals as usize,
        "events: {:?}",
        run.events
    );
    assert_continuous_at_events(&run, 0.01);
}

/// A stand-in for the visibility of the target that cannot be evaluated past `q_0 = 0.86`, inside the limit's band and
/// short of where the joint-limit cost reaches `h_max`, as the projection of a target point behind the camera cannot:
/// `CostError::PointBehindCamera` there, 0 elsewhere.
struct BlindPastJointZero;

impl Cost<3> for BlindPastJointZero {
    fn value(&self, q: &JointVector<3>) -> Result<f64, CostError> {
        if q[0] > 0.86 {
            Err(CostError::PointBehindCamera {
                point: 0,
                depth: -0.1,
            })
        } else {
            Ok(0.0)
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
    fn name(&self) -> &str {
        "blind"
    }
}

/// [`BlindPastJointZero`] added to the joint-limit cost by a cost of its own that, unlike [`CompositeCost`], cannot
/// name its dominant term where a point is behind the camera: its `dominant_term` passes the error on.
struct LimitsAndBlind(JointLimits<3>);

impl Cost<3> for LimitsAndBlind {
    fn value(&self, q: &JointVector<3>) -> Result<f64, CostError> {
        Ok(self.0.value(q)? + BlindPastJointZero.value(q)?)
    }
    fn value_and_gradient(
        &self,
        q: &JointVector<3>,
        gradient: &mut JointVector<3>,
    ) -> Result<f64, CostError> {
        Ok(self.0.value_and_gradient(q, gradient)? + BlindPastJointZero.value(q)?)
    }
    fn name(&self) -> &str {
        "limits and blind"
    }
    fn dominant_term(&self, q: &JointVector<3>) -> Result<&str, CostError> {
        self.value(q)?;
        Ok("limits")
    }
    fn default_removal_threshold(&self) -> Option<f64> {
        Cost::default_removal_threshold(&self.0)
    }
}

/// D6: a prediction that takes a target point behind the camera is an infinite cost, and the removal it triggers is
/// made and reported instead of failing the step (the removal report evaluated the cost's terms at the prediction and
/// passed their error on): with a [`CompositeCost`] the term named as the dominant one is the term that could not be
/// evaluated there; with a cost that cannot name it, the cost itself.
#[test]
fn a_prediction_that_loses_the_target_removes_the_task_and_names_the_term() {
    let composite = CompositeCost::new().with(limits()).with(BlindPastJointZero);
    assert_eq!(removal_naming(&composite), "blind");
    assert_eq!(
        removal_naming(&LimitsAndBlind(limits())),
        "limits and blind"
    );
}

/// The three tasks from (0.2, −0.2, 0.1) under `cost` up to the first removal, which must be of "reach" on an
/// infinite prediction; the name of the dominant cost its report gives.
fn removal_naming(cost: &dyn Cost<3>) -> String {
    let (tasks, mut values) = tasks_and_values();
    let law = ControlLaw::with_default_transition(&values, 1.0).unwrap();
    let mut controller = StackController::new(ControllerParameters::default(), &values).unwrap();
    let (dt, mut q) = (0.01, JointVector::<3>::new(0.2, -0.2, 0.1));
    // Up to the removal: the steps before it, and the step that makes it, succeed.
    for iteration in 0..1000 {
        evaluate(&tasks, &mut values, &q);
        let step = controller
            .step(
                &law,
                &values,
                Some(cost),
                &q,
                iteration,
                iteration as f64 * dt,
            )
            .unwrap_or_else(|e| panic!("iteration {iteration}: {e}"));
        if step.event == Some(EventKind::Remove) {
            break;
        }
        q += step.velocity * dt;
    }
    let removal = controller
        .events()
        .iter()
        .find_map(|e| e.removal.as_ref().map(|r| (e.task, r)))
        .expect("a removal");
    assert_eq!(removal.0, 1, "events: {:?}", controller.events());
    assert!(removal.1.predicted_cost.is_infinite());
    removal.1.cost.clone()
}

/// The paper's literal rule on the same tasks: removal and re-insertion at the same threshold, no dwell — the task
/// is removed and put back over and over (the chatter the robust rule removes).
#[test]
fn the_paper_rule_chatters_on_an_unachievable_task() {
    let run = run(
        ControllerParameters {
            rule: DecisionRule::Paper,
            ..Default::default()
        },
        1.0,
    );
    let removals = run
        .events
        .iter()
        .filter(|e| e.1 == EventKind::Remove)
        .count();
    let reinsertions = run
        .events
        .iter()
        .filter(|e| e.1 == EventKind::Reinsert)
        .count();
    assert!(
        removals >= 10 && reinsertions >= 10,
        "events: {:?}",
        run.events
    );
    assert_continuous_at_events(&run, 0.01);
}

proptest::proptest! {
    #![proptest_config(proptest::test_runner::Config::with_cases(48))]

    /// D14 on random stacks: three random one-row tasks on three joints, a random start and avoidance gain, both
    /// decision rules; at every push, removal, re-insertion and fallback the velocity is continuous and the ramp is
    /// the one of D1 started once.
    #[test]
    fn continuity_holds_at_every_change_of_random_stacks(
        rows in proptest::collection::vec(-1.0..1.0f64, 9),
        targets in proptest::collection::vec(-1.2..1.2f64, 3),
        start in proptest::collection::vec(-0.7..0.7f64, 3),
        kappa in 0.0..3.0f64,
        paper in proptest::bool::ANY,
    ) {
        let tasks: Vec<LinearTask<3>> = (0..3)
            .map(|i| {
                let row = TaskJacobian::<3>::from_row_slice(&rows[3 * i..3 * i + 3]);
                let goal = JointVector::<3>::from_fn(|k, _| if k == i { targets[i] } else { 0.0 });
                // The target value of row i is its row times `goal`.
                LinearTask::new(&format!("t{i}"), row, goal, 1.0).unwrap()
            })
            .collect();
        let rule = if paper { DecisionRule::Paper } else { DecisionRule::Robust };
        let parameters = ControllerParameters { rule, ..Default::default() };
        let run = run_tasks(tasks, JointVector::from_column_slice(&start), parameters, kappa, 800);
        assert_continuous_at_events(&run, 0.01);
    }
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
    let braking = [f64::NAN, 0.0, -1.0, f64::NEG_INFINITY].map(|braking_rate| {
        (
            ControllerParameters {
                braking_rate,
                ..Default::default()
            },
            "braking_rate",
        )
    });
    let lock = [f64::NAN, -1e-6, 0.5, f64::INFINITY].map(|lock_band| {
        (
            ControllerParameters {
                lock_band,
                ..Default::default()
            },
            "lock_band",
        )
    });
    let early_push = [f64::NAN, 1.0, 0.5, -1.0].map(|early_push_ratio| {
        (
            ControllerParameters {
                early_push_ratio,
                ..Default::default()
            },
            "early_push_ratio",
        )
    });
    let floor = [f64::NAN, -1e-4, 0.02, f64::INFINITY].map(|singular_value_floor| {
        (
            ControllerParameters {
                singular_value_floor,
                ..Default::default()
            },
            "singular_value_floor",
        )
    });
    let restart = [
        ("restart_rate", [f64::NAN, -1.0, f64::INFINITY]),
        ("restart_centre_band", [0.0, 0.6, f64::NAN]),
        ("restart_timeout", [0.0, -1.0, f64::INFINITY]),
        ("stall_timeout", [-1.0, f64::NAN, f64::INFINITY]),
    ]
    .into_iter()
    .flat_map(|(name, values)| {
        values.map(|value| {
            let mut parameters = ControllerParameters::default();
            match name {
                "restart_rate" => parameters.restart_rate = value,
                "restart_centre_band" => parameters.restart_centre_band = value,
                "stall_timeout" => parameters.stall_timeout = value,
                _ => parameters.restart_timeout = value,
            }
            (parameters, name)
        })
    });
    for (parameters, expected) in cases
        .into_iter()
        .chain(braking)
        .chain(lock)
        .chain(early_push)
        .chain(floor)
        .chain(restart)
    {
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
    assert!(run
        .events
        .iter()
        .any(|&(_, kind, task)| kind == EventKind::Remove && task == 1));
    assert_eq!(
        run.first_removal_threshold,
        Some(limits().default_removal_threshold())
    );
}

/// D6: a prediction beyond a hard limit is a danger whatever `h_max`. With a threshold the joint-limit cost cannot
/// reach (its largest value at a limit is `½ (ρΔq)²/Δq = 0.01` on these joints), "reach" is still removed before
/// joint 0 crosses its limit, because the configuration predicted `T` ahead is outside the limits.
#[test]
fn a_prediction_beyond_a_hard_limit_removes_the_task_whatever_the_threshold() {
    let out_of_reach = ControllerParameters {
        removal_threshold: Some(1.0),
        ..Default::default()
    };
    let run = run(out_of_reach, 1.0);
    let removal_at = run.first(EventKind::Remove, 1).expect("reach removed");
    assert!(
        run.hit.is_none_or(|(_, k)| k > removal_at),
        "events {:?}, hit {:?}",
        run.events,
        run.hit
    );
    // The limit is kept until the fallback (as with a reachable threshold), not hit right after the removal.
    run.assert_limits_kept_until_fallback();
}

/// D6 after a singular push: "lever" (`e = 10⁻³ q_0 + q_2 − 0.3`) is pushed below "hold" (`q_2 → 0`), which leaves it
/// only joint 0 with a Jacobian of 10⁻³: its law asks about 300 rad/s of joint 0. The velocity sent ramps towards
/// it through the transition of D1, and the prediction of the current stack is past joint 0's limit. Removing "lever"
/// must be found to help: the stack without it, changed now, starts its transition from the velocity sent at the
/// previous period — not from the one the current stack sends, which already carries a share of the 300 rad/s and
/// would make every candidate's prediction as bad as the current one's (then nothing is removed and the joint reaches
/// its limit within a few periods of the push).
#[test]
fn a_singular_push_is_undone_before_the_limit() {
    let row = |entries: [f64; 3]| TaskJacobian::<3>::from_fn(1, |_, k| entries[k]);
    let tasks = vec![
        LinearTask::new("hold", row([0.0, 0.0, 1.0]), JointVector::zeros(), 1.0).unwrap(),
        LinearTask::new(
            "lever",
            row([1e-3, 0.0, 1.0]),
            JointVector::<3>::new(0.0, 0.0, 0.3),
            1.0,
        )
        .unwrap(),
    ];
    let run = run_tasks(
        tasks,
        JointVector::<3>::new(0.2, -0.2, 0.05),
        ControllerParameters::default(),
        1.0,
        4000,
    );
    let push = run.first(EventKind::Push, 1).expect("lever pushed");
    let removal = run.first(EventKind::Remove, 1).unwrap_or_else(|| {
        panic!(
            "lever never removed; events {:?}, hit {:?}",
            run.events, run.hit
        )
    });
    assert!(
        removal <= push + 2,
        "pushed at {push}, removed at {removal}"
    );
    run.assert_limits_kept_until_fallback();
}

/// A one-row task given by a function of `q` and two constants `c`: `(e, J)`, gain 1 s⁻¹.
struct FnTask {
    name: &'static str,
    constants: [f64; 2],
    function: fn(&JointVector<3>, [f64; 2]) -> (f64, [f64; 3]),
}

impl Task<3, JointVector<3>> for FnTask {
    fn name(&self) -> &str {
        self.name
    }
    fn rows(&self) -> usize {
        1
    }
    fn gain(&self) -> f64 {
        1.0
    }
    fn evaluate(&self, q: &JointVector<3>, out: &mut TaskValue<3>) -> Result<(), TaskError> {
        let (error, row) = (self.function)(q, self.constants);
        out.set(
            self.name,
            &DVector::from_element(1, error),
            &TaskJacobian::from_fn(1, |_, k| row[k]),
        )
    }
}

/// D28's two tasks. "sum" drives `q0 + q2` to 0.7: alone, its least-norm motion moves `q0` and `q2` together, to 0.35
/// each. "lever", `e = (c − q0) q1 − d`, `J = [−q1, c − q0, 0]` with `c` just above 0.35: at `q1 = 0`, its Jacobian
/// projected into the null space of "sum" is `c − q0` along `q1`, nearly singular where "sum" alone converges; both
/// are achieved at regular configurations too (`q0` below 0.35, `q2 = 0.7 − q0`, `q1 = d/(c − q0)`).
fn sum_and_lever(c: f64, d: f64) -> Vec<FnTask> {
    vec![
        FnTask {
            name: "sum",
            constants: [0.0; 2],
            function: |q, _| (q[0] + q[2] - 0.7, [1.0, 0.0, 1.0]),
        },
        FnTask {
            name: "lever",
            constants: [c, d],
            function: |q, [c, d]| ((c - q[0]) * q[1] - d, [-q[1], c - q[0], 0.0]),
        },
    ]
}

/// Runs [`sum_and_lever`] from `q = 0` for 30 s, pushing "lever" by D28 with `r_push` = [`LEVER_PUSH_RATIO`]
/// (`early`) and only once "sum" has settled (`late`, `r_push = +∞`); `ε_add` 10⁻³: "sum" settles at
/// `|e_sum| < 1.4·10⁻³`, where `c − q0 ≈ c − 0.3493`.
fn early_and_late(c: f64, d: f64) -> (Run, Run) {
    let run = |early_push_ratio| {
        let parameters = ControllerParameters {
            settle_velocity_with_removal: 1e-3,
            early_push_ratio,
            ..ControllerParameters::default()
        };
        run_tasks(
            sum_and_lever(c, d),
            JointVector::zeros(),
            parameters,
            1.0,
            3000,
        )
    };
    (run(LEVER_PUSH_RATIO), run(f64::INFINITY))
}

/// The `r_push` of the lever tests: 4, so that the early push's jump, below `r_push · 0.5` rad/s, sits apart from the
/// settled push's 7–12 rad/s. These tests check D28's mechanism, not its default (16, chosen on the zoo: theory D28),
/// under which this lever's early push may jump by up to 8 rad/s.
const LEVER_PUSH_RATIO: f64 = 4.0;

/// The iteration "lever" was first pushed at, and the law's jump there.
fn lever_push(run: &Run) -> (usize, f64) {
    let k = run.first(EventKind::Push, 1).expect("lever pushed");
    (k, (run.laws[k] - run.laws[k - 1]).norm())
}

/// D28 checked on one early run: "lever" never removed, no limit hit, no allocation in the steps without an event,
/// both tasks achieved at the end.
fn assert_early_run_converges(early: &Run, c: f64, d: f64) {
    assert_eq!(
        early.first(EventKind::Remove, 1),
        None,
        "{:?}",
        early.events
    );
    assert_eq!(early.hit, None);
    // Watching `‖u⁺‖` at every period (a trial stack solve) allocates nothing.
    assert_eq!(early.allocations_without_event, 0);
    let q_end = early
        .sent
        .iter()
        .fold(JointVector::<3>::zeros(), |q, v| q + v * 0.01);
    for task in sum_and_lever(c, d) {
        let error = (task.function)(&q_end, task.constants).0;
        assert!(
            error.abs() < 1e-6,
            "{}: {error} at q = {q_end:?}",
            task.name
        );
    }
}

/// D28 with `c = 0.351`, `d = 0.02`. Pushed once "sum" has settled (`c − q0 ≈ 1.7·10⁻³`), the law of "lever" asks
/// `q1` for about `0.02/1.7·10⁻³ ≈ 12` rad/s. The early push (`r_push` = 4) sends it in while `‖u⁺‖` is within
/// `r_push` times its smallest value, at most the law at the start (0.5 rad/s): a jump below `r_push · 0.5 = 2` rad/s.
#[test]
fn the_next_task_is_pushed_before_its_push_turns_singular() {
    let (c, d) = (0.351, 0.02);
    let (early, late) = early_and_late(c, d);
    let ((early_push, early_jump), (late_push, late_jump)) =
        (lever_push(&early), lever_push(&late));
    assert!(
        early_push < late_push,
        "{:?} / {:?}",
        early.events,
        late.events
    );
    assert!(late_jump > 5.0, "late push: law jump {late_jump}");
    assert!(early_jump < 2.0, "early push: law jump {early_jump}");
    assert_early_run_converges(&early, c, d);
}

proptest::proptest! {
    #![proptest_config(proptest::test_runner::Config::with_cases(32))]

    /// D28 over the family: `c − 0.35` from 5·10⁻⁴ to 2·10⁻³ and `d` from 0.02 to 0.04, so that the settled push asks
    /// for `d/(c − 0.3493)` ≥ 7 rad/s. The early push comes first, with a jump below `r_push · 0.5 = 2` rad/s, and the
    /// run converges as above.
    #[test]
    fn the_early_push_holds_over_lever_geometries(offset in 5e-4..2e-3f64, d in 0.02..0.04f64) {
        let c = 0.35 + offset;
        let (early, late) = early_and_late(c, d);
        let ((early_push, early_jump), (late_push, late_jump)) = (lever_push(&early), lever_push(&late));
        proptest::prop_assert!(early_push < late_push, "{:?} / {:?}", early.events, late.events);
        proptest::prop_assert!(late_jump > 5.0, "late push: law jump {}", late_jump);
        proptest::prop_assert!(early_jump < 2.0, "early push: law jump {}", early_jump);
        assert_early_run_converges(&early, c, d);
    }
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

/// D6, a joint the `h_max` test cannot see: with a threshold above the joint-limit cost at a limit (`½ (ρΔq)²/Δq =
/// 0.01` on these joints), "reach" drives joint 0 fast towards a goal at 2, beyond its limit at 1. A removal decided
/// when the crossing is predicted `T` ahead comes too late (the change needs about `1/μ` to act, and joint 0 crossed
/// its limit five periods after such a removal); decided when it is predicted one transition ahead, as the last resort
/// of D13 does, it keeps the limit until the fallback.
#[test]
fn a_joint_the_threshold_cannot_see_is_watched_one_transition_ahead() {
    let row = |c: usize| TaskJacobian::<3>::from_fn(1, |_, k| if k == c { 1.0 } else { 0.0 });
    let mut tasks = tasks();
    tasks[1] = LinearTask::new("reach", row(0), JointVector::<3>::new(2.0, 0.0, 0.0), 1.0).unwrap();
    let out_of_reach = ControllerParameters {
        removal_threshold: Some(1.0),
        ..Default::default()
    };
    let run = run_tasks(
        tasks,
        JointVector::<3>::new(0.2, -0.2, 0.1),
        out_of_reach,
        1.0,
        4000,
    );
    assert!(run.first(EventKind::Remove, 1).is_some(), "reach removed");
    run.assert_limits_kept_until_fallback();
}

/// D6, a joint the `h_max` test sees, but too late: with every task at gain 0.2 s⁻¹ (so `μ = 2` s⁻¹: a change takes
/// about 0.5 s to act), "reach" drives joint 0 towards a goal at 2, 3 or 4, beyond its limit at 1, entering the band at
/// `0.2 (goal − 0.8)` = 0.24, 0.44, 0.64 rad/s. The `h_max` test fires when the prediction `T` ahead is half-way
/// through the band (0.1 from the limit), and the motion still to come after a removal is about `v/μ`: above `v = 0.1 /
/// (1/μ − T)` (0.22 rad/s) it comes late, and at 0.64 rad/s joint 0 crosses its limit 32 periods after the removal.
/// Watched one transition ahead for a hard limit as well, the limit is kept until the fallback in all three. (Faster
/// still, at 1.04 rad/s, neither keeps it: the prediction one transition ahead covers `1 − e^{−1}` of the motion to
/// come, and a velocity limit, not a removal, is what keeps such a joint.)
#[test]
fn a_fast_joint_is_watched_one_transition_ahead() {
    let row = |c: usize| TaskJacobian::<3>::from_fn(1, |_, k| if k == c { 1.0 } else { 0.0 });
    let slow =
        |name, c, target: JointVector<3>| LinearTask::new(name, row(c), target, 0.2).unwrap();
    for goal in [2.0, 3.0, 4.0] {
        let tasks = vec![
            slow("hold", 2, JointVector::zeros()),
            slow("reach", 0, JointVector::<3>::new(goal, 0.0, 0.0)),
            slow("side", 1, JointVector::<3>::new(0.0, 0.3, 0.0)),
        ];
        let run = run_tasks(
            tasks,
            JointVector::<3>::new(0.2, -0.2, 0.1),
            ControllerParameters::default(),
            1.0,
            4000,
        );
        assert!(
            run.first(EventKind::Remove, 1).is_some(),
            "goal {goal}: reach removed"
        );
        run.assert_limits_kept_until_fallback();
    }
}
