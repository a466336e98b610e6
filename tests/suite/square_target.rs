//! Square targets (theory D9): the paper's P_x, P_y are undefined on a square seen head-on; the fourth task then uses the
//! side-length ratios, the four tasks still constrain all six DOF at the goal, and the paper's sequence converges on
//! the square-marker scenario.

use nalgebra::{Dyn, OMatrix, U6};
use servostack::feature::{FeatureError, InteractionSource, Observation};
use servostack::scenario::{Experiment, RunKind, Scenario};
use servostack::sim::{Outcome, View};
use servostack::task::TaskError;
use servostack::visual_task::{paper_tasks, paper_tasks_with, FourthTask, VisualTask};
use std::path::Path;

fn scenario() -> Scenario {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/scenarios/square_marker_afma6.toml"
    );
    Scenario::from_file(Path::new(path)).unwrap()
}

/// The scenario's experiment and the camera's view of the target from the goal pose.
fn goal_view(scenario: &Scenario) -> (Experiment<6>, View<6>) {
    let experiment = scenario.experiment::<6>().unwrap();
    let view = experiment
        .scene
        .view_from(&experiment.desired_camera_from_target)
        .unwrap();
    (experiment, view)
}

/// The stacked interaction matrix `[L_1; L_2; L_3; L_4]` (6 × 6) of the tasks on `obs`.
fn stacked_interaction(tasks: &[VisualTask], obs: &Observation<'_>) -> OMatrix<f64, Dyn, U6> {
    let rows: usize = tasks.iter().map(|t| t.feature().dim()).sum();
    let mut l = OMatrix::<f64, Dyn, U6>::zeros(rows);
    let mut first = 0;
    for task in tasks {
        let dim = task.feature().dim();
        task.feature()
            .interaction(obs, InteractionSource::Exact, l.rows_mut(first, dim))
            .unwrap();
        first += dim;
    }
    l
}

#[test]
fn square_seen_head_on_needs_the_replacement_and_keeps_full_rank() {
    let scenario = scenario();
    let (experiment, view) = goal_view(&scenario);
    let desired = view.observation().unwrap();
    let depth = experiment.desired_camera_from_target.translation.z;
    // The paper's tasks are undefined there (D9).
    let paper = paper_tasks(&desired, depth, depth, [0.5; 4], InteractionSource::Exact);
    assert!(matches!(
        paper,
        Err(TaskError::Feature {
            source: FeatureError::IsotropicMoments { .. },
            ..
        })
    ));
    assert_eq!(
        FourthTask::Auto.resolve(&desired).unwrap(),
        FourthTask::SideRatios
    );
    let tasks = paper_tasks_with(
        &desired,
        depth,
        depth,
        [0.5; 4],
        InteractionSource::Exact,
        FourthTask::Auto,
    )
    .unwrap();
    let l = stacked_interaction(&tasks, &desired);
    assert_eq!(l.nrows(), 6);
    let singular = l.clone().svd(false, false).singular_values;
    let (min, max) = (singular.min(), singular.max());
    println!("head-on square: stacked L singular values {singular:?}");
    assert!(min > 1e-2 * max, "rank-deficient: {singular:?}");
}

/// The paper's rectangle keeps the paper's features under Auto.
#[test]
fn auto_keeps_the_paper_features_on_a_rectangle() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/scenarios/paper_afma6.toml"
    );
    let scenario = Scenario::from_file(Path::new(path)).unwrap();
    let (_, view) = goal_view(&scenario);
    let desired = view.observation().unwrap();
    assert_eq!(
        FourthTask::Auto.resolve(&desired).unwrap(),
        FourthTask::PaperInvariants
    );
}

#[test]
fn square_marker_scenario_converges_with_the_full_method() {
    let scenario = scenario();
    let run = scenario.run::<6>(RunKind::FullMethod).unwrap();
    println!(
        "square marker: {:?} after {} iterations, {} events, min margin {:.3}",
        run.outcome,
        run.records.len(),
        run.events.len(),
        run.min_normalized_margin()
    );
    assert_eq!(run.outcome, Outcome::Converged);
    assert_eq!(
        run.stacked_at_end(),
        ["centroid", "angle", "area", "third_order"]
    );
    assert!(run.min_normalized_margin() > 0.0);
    assert!(run.max_velocity_jump() <= 1e-9);
}
