//! The paper's claim, on the shipped reference scenario (theory §9, D12): the classical law and the push-only stacks fail
//! on a joint limit, each at the stage the paper reports, and the full method converges within the limits after
//! removing the a_n task during the fourth task and putting it back. Asserted from the scenario file, with the default
//! exact interaction matrices.

use servostack::controller::EventKind;
use servostack::scenario::{Experiment, RunKind, Scenario};
use servostack::sim::{Outcome, Run};
use std::sync::OnceLock;

fn scenario() -> &'static (Scenario, Experiment<6>) {
    static SCENARIO: OnceLock<(Scenario, Experiment<6>)> = OnceLock::new();
    SCENARIO.get_or_init(|| {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/assets/scenarios/paper_afma6.toml"
        );
        let scenario = Scenario::from_file(std::path::Path::new(path)).unwrap();
        let experiment = scenario.experiment::<6>().unwrap();
        (scenario, experiment)
    })
}

fn run(kind: RunKind) -> Run<6> {
    let (scenario, experiment) = scenario();
    experiment.run(&scenario.settings(), kind).unwrap()
}

/// Asserts that the run ends with the four tasks stacked and never left the limits.
fn assert_every_task_stacked_within_the_limits(run: &Run<6>) {
    assert_eq!(
        run.stacked_at_end(),
        ["centroid", "angle", "area", "third_order"]
    );
    assert!(run.min_normalized_margin() >= 0.0);
}

/// The names of the tasks stacked at the iteration where the run stopped on a joint limit.
fn stacked_at_hit(run: &Run<6>) -> Vec<&str> {
    match &run.outcome {
        Outcome::JointLimit { stacked, .. } => stacked
            .iter()
            .map(|&i| run.task_names[i].as_str())
            .collect(),
        other => panic!("expected a joint limit, got {other:?}"),
    }
}

fn pushes(run: &Run<6>) -> Vec<&str> {
    run.events_of(EventKind::Push)
        .map(|e| run.task_names[e.task].as_str())
        .collect()
}

#[test]
fn classical_law_reaches_a_joint_limit() {
    let run = run(RunKind::Classical);
    assert_eq!(stacked_at_hit(&run), ["full"]);
}

#[test]
fn stack_without_avoidance_hits_the_limit_during_the_third_task() {
    let run = run(RunKind::Stack);
    assert_eq!(stacked_at_hit(&run), ["centroid", "angle", "area"]);
    assert_eq!(pushes(&run), ["centroid", "angle", "area"]);
    assert!(run.max_velocity_jump() <= 1e-9);
}

#[test]
fn stack_with_gradient_survives_the_third_task_and_fails_in_the_fourth() {
    let run = run(RunKind::StackGradient);
    assert_eq!(
        stacked_at_hit(&run),
        ["centroid", "angle", "area", "third_order"]
    );
    assert_eq!(pushes(&run), ["centroid", "angle", "area", "third_order"]);
    assert_eq!(run.events_of(EventKind::Remove).count(), 0);
    assert!(run.max_velocity_jump() <= 1e-9);
}

#[test]
fn full_method_removes_a_n_during_the_fourth_task_puts_it_back_and_converges() {
    let run = run(RunKind::FullMethod);
    assert_eq!(run.outcome, Outcome::Converged);
    assert!(run.min_normalized_margin() > 0.0, "left the limits");
    assert!(
        run.max_velocity_jump() <= 1e-9,
        "jump {}",
        run.max_velocity_jump()
    );
    let fourth_pushed = run
        .events_of(EventKind::Push)
        .find(|e| run.task_names[e.task] == "third_order")
        .expect("the fourth task is pushed")
        .iteration;
    let first_removal = run
        .events_of(EventKind::Remove)
        .next()
        .expect("a task is removed");
    assert_eq!(run.task_names[first_removal.task], "area");
    assert!(
        first_removal.iteration > fourth_pushed,
        "removed before the fourth task was pushed"
    );
    let report = first_removal.removal.as_ref().expect("a removal report");
    assert!(report.predicted_cost > report.threshold);
    // The criteria of every stacked task are logged, and a_n has the best (largest) combined score.
    let best = report
        .criteria
        .iter()
        .max_by(|a, b| a.combined.total_cmp(&b.combined))
        .unwrap();
    assert_eq!(run.task_names[best.task], "area");
    let reinsertion = run
        .events_of(EventKind::Reinsert)
        .next()
        .expect("a_n is put back");
    assert_eq!(run.task_names[reinsertion.task], "area");
    assert!(reinsertion.iteration > first_removal.iteration);
    assert_eq!(
        run.stacked_at_end(),
        ["centroid", "angle", "area", "third_order"]
    );
}

/// D14 on the reference scenario: at every change of the full method the velocity sent does not jump, and the next
/// step is the first step of the transition's ramp, at least half of `(1 − e^{−μΔt})` times the law's jump (it is
/// zero if the velocity is held one period — a transition restarted twice — and the whole jump without the term).
#[test]
fn full_method_velocity_ramps_at_every_change() {
    let (scenario, _) = scenario();
    let run = run(RunKind::FullMethod);
    let mu = 10.0 * scenario.tasks.gains.iter().copied().fold(0.0, f64::max);
    let ramp = 1.0 - (-mu * scenario.simulation.period).exp();
    let steps = run.velocity_steps();
    let continuity = run.event_continuity();
    let mut checked = 0;
    for (i, change) in continuity.iter().enumerate() {
        assert!(change.jump <= 1e-9, "{change:?}");
        let next_is_a_change = continuity
            .get(i + 1)
            .is_some_and(|n| n.iteration == change.iteration + 1);
        if change.law_jump > 1e-3 && !next_is_a_change && change.iteration > 0 {
            let first_step = steps[change.iteration + 1];
            assert!(
                first_step >= 0.5 * ramp * change.law_jump,
                "{change:?}: first step {first_step:e}"
            );
            assert!(
                first_step <= 1.5 * ramp * change.law_jump + 1e-2,
                "{change:?}: first step {first_step:e}"
            );
            checked += 1;
        }
    }
    assert!(checked >= 3, "{continuity:?}");
}

/// A change of one parameter of a scenario.
type ScenarioChange = Box<dyn Fn(&mut Scenario)>;

/// The paper's four outcomes do not hang on one value of a tuned parameter: with h_max, κ, ε_add or Z* (the depth of
/// the size feature a_n) moved by ±30 %, the classical law and the two push-only stacks still hit the joint limit,
/// the stack with gradient only after the fourth task is pushed, and the full method still converges within the
/// limits after removing and putting back a task.
#[test]
fn paper_outcomes_hold_with_each_tuned_parameter_moved_thirty_percent() {
    let (base, _) = scenario();
    for factor in [0.7, 1.3] {
        let variants: [(&str, ScenarioChange); 4] = [
            (
                "h_max",
                Box::new(move |s: &mut Scenario| {
                    s.controller.removal_threshold =
                        s.controller.removal_threshold.map(|h| h * factor)
                }),
            ),
            (
                "kappa",
                Box::new(move |s: &mut Scenario| s.avoidance.gain *= factor),
            ),
            (
                "eps_add",
                Box::new(move |s: &mut Scenario| {
                    s.controller.settle_velocity *= factor;
                    s.controller.settle_velocity_with_removal *= factor;
                }),
            ),
            (
                "z_star",
                Box::new(move |s: &mut Scenario| {
                    s.tasks.area_depth_m =
                        Some(factor * s.desired.camera_from_target.translation_m[2])
                }),
            ),
        ];
        for (name, change) in variants {
            let mut scenario = base.clone();
            change(&mut scenario);
            let experiment = scenario.experiment::<6>().unwrap();
            let outcome = |kind| experiment.run(&scenario.settings(), kind).unwrap();
            let label = format!("{name} × {factor}");
            assert_eq!(
                outcome(RunKind::Classical).outcome.name(),
                "joint_limit",
                "{label}"
            );
            let stack = outcome(RunKind::Stack);
            assert_eq!(
                stacked_at_hit(&stack),
                ["centroid", "angle", "area"],
                "{label}"
            );
            let gradient = outcome(RunKind::StackGradient);
            assert_eq!(
                stacked_at_hit(&gradient),
                ["centroid", "angle", "area", "third_order"],
                "{label}"
            );
            let full = outcome(RunKind::FullMethod);
            assert_eq!(full.outcome, Outcome::Converged, "{label}");
            assert!(full.min_normalized_margin() > 0.0, "{label}");
            let removed: Vec<usize> = full.events_of(EventKind::Remove).map(|e| e.task).collect();
            assert!(!removed.is_empty(), "{label}");
            for task in removed {
                assert!(
                    full.events_of(EventKind::Reinsert).any(|e| e.task == task),
                    "{label}: task {task} not put back"
                );
            }
        }
    }
}

/// The robot's velocity saturation: every velocity sent stays within the limits — the limits active over many
/// periods — and the velocity sent does not jump at any change of the full method. (That the controller blends from
/// the velocity the robot received is tested on the façade, `tests/suite/servo.rs`, where it is observable.)
#[test]
fn saturated_velocities_stay_within_the_limits_and_continuous() {
    let (base, _) = scenario();
    let mut scenario = base.clone();
    scenario.simulation.max_prismatic_velocity_m_s = 0.02;
    scenario.simulation.max_revolute_velocity_rad_s = 0.05;
    let run = scenario.run::<6>(RunKind::FullMethod).unwrap();
    let mut saturated = 0;
    for record in run.records.iter().filter(|r| r.sent) {
        for (i, v) in record.velocity.iter().enumerate() {
            let max = if i < 3 { 0.02 } else { 0.05 };
            assert!(v.abs() <= max * (1.0 + 1e-12), "joint {i}: {v}");
            saturated += usize::from(v.abs() >= max * (1.0 - 1e-9));
        }
    }
    assert!(
        saturated > 100,
        "the limits were hardly active ({saturated} periods)"
    );
    for change in run.event_continuity() {
        assert!(change.jump <= 1e-9, "{change:?}");
    }
}

/// D22: converged means at the goal pose, not only task errors below the threshold. The reference run ends at its
/// goal; asked for a tolerance below what the `1e−4` threshold on the errors leaves of the pose, the same run ends as
/// `off_goal` with its true distance to the goal, and the check is what decides it.
#[test]
fn the_reference_run_converges_at_its_goal_pose() {
    let (scenario, experiment) = scenario();
    let run = run(RunKind::FullMethod);
    assert_eq!(run.outcome, Outcome::Converged);
    let last = run.last_record().unwrap();
    let view = experiment
        .scene
        .observe(&mut servostack::robot::KinematicsWorkspace::new(), &last.q)
        .unwrap();
    // The camera pose, compared with the desired one independently of the simulation's own check.
    let error = view.c_from_o * experiment.desired_camera_from_target.inverse();
    let (translation, angle) = (error.translation.vector.norm(), error.rotation.angle());
    assert!(
        translation < 1e-3 && angle.to_degrees() < 0.1,
        "{translation} m, {angle} rad"
    );

    let mut strict = scenario.clone();
    strict.simulation.goal_tolerance_m = translation / 2.0;
    let strict_run = experiment
        .run(&strict.settings(), RunKind::FullMethod)
        .unwrap();
    match strict_run.outcome {
        Outcome::OffGoal {
            translation_m,
            rotation_deg,
        } => {
            assert!((translation_m - translation).abs() < 1e-12);
            assert!((rotation_deg - angle.to_degrees()).abs() < 1e-9);
        }
        other => panic!("expected off_goal, got {other:?}"),
    }
    // The same run, iteration for iteration: only its verdict differs.
    assert_eq!(strict_run.iterations(), run.iterations());
}

/// The QP cascade, the second extra row (theory §14): the same pushes as SNS, but the fourth task's level minimises its
/// residual in the box instead of being scaled down, and the run converges with every task stacked, inside the limits.
#[test]
fn hqp_converges_within_the_limits_with_every_task_stacked() {
    let run = run(RunKind::Hqp);
    assert!(
        matches!(run.outcome, Outcome::Converged),
        "{:?}",
        run.outcome
    );
    assert_every_task_stacked_within_the_limits(&run);
}

/// SNS, the extra row of the experiment (not from the paper; theory §13): the same pushes as the stack with gradient,
/// but joint 2 is held on its lower limit instead of passing it, and with no removal the fourth task stays unmet
/// until the budget ends.
#[test]
fn sns_holds_joint_2_on_its_limit_with_the_fourth_task_unmet() {
    let run = run(RunKind::Sns);
    assert!(
        matches!(run.outcome, Outcome::MaxIterations { .. }),
        "{:?}",
        run.outcome
    );
    assert_every_task_stacked_within_the_limits(&run);
    let (_, experiment) = scenario();
    let end = experiment
        .scene
        .limits()
        .normalized(&run.records.last().unwrap().q);
    assert!(end[2] < 1e-6, "{end}");
    assert!(run.final_error_norm().unwrap() > 1e-2);
}
