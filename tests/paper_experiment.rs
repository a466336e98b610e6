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
    scenario.run_experiment(experiment, kind).unwrap()
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
    let run = run(RunKind::StackController);
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
