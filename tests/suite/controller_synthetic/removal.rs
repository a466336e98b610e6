//! Which task the stack controller removes, and when (theory §6.2, §6.3, D3, D4, D6): without removals the limit is
//! hit; with them, every criterion picks the task whose motion points into the limit, the criteria match their
//! definitions, the threshold defaults to the cost's, and a removal is triggered by a prediction past a hard limit
//! whatever the threshold, after a singular push, by a prediction that loses the target, and one transition ahead
//! for a joint the threshold cannot see or sees too late.

use super::{
    assert_continuous_at_events, evaluate, limits, run, run_tasks, tasks, tasks_and_values,
};
use servostack::avoidance::{CompositeCost, Cost, CostError, JointLimits};
use servostack::controller::{ControllerParameters, EventKind, RemovalCriterion, StackController};
use servostack::law::ControlLaw;
use servostack::linalg::{null_space_projector, RankPolicy};
use servostack::math::JointVector;
use servostack::task::{LinearTask, Task, TaskJacobian, TaskValue};

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
    flat_value_and_gradient!();
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
