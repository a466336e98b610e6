//! The obstacle scenario of the `obstacle_avoidance` example (assets/scenarios/obstacle_afma6.toml): the classical law
//! and the stack with projected gradient collide, the full method reaches the goal without collision and without
//! losing the target, also when the links' shapes are STL meshes; scenario errors name their field.

use servostack::controller::EventKind;
use servostack::scenario::{RunKind, Scenario, ScenarioError};
use servostack::sim::Outcome;

const SCENARIO: &str = include_str!("../../assets/scenarios/obstacle_afma6.toml");

fn scenario() -> Scenario {
    Scenario::from_toml_str(SCENARIO, None).unwrap()
}

#[test]
fn classical_and_stack_gradient_collide_the_full_method_avoids() {
    obstacle_story(&scenario());
}

/// The same story on the gantry whose link shapes are STL meshes (binary and ASCII), read as convex hulls.
#[test]
fn the_story_holds_with_stl_mesh_link_geometry() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/scenarios/obstacle_mesh_afma6.toml"
    );
    let scenario = Scenario::from_file(std::path::Path::new(path)).unwrap();
    assert_eq!(scenario.joint_count().unwrap(), 6);
    obstacle_story(&scenario);
}

/// Classical and stack-with-gradient runs collide with the ball; the full method converges without collision, the
/// target in the image, its removals triggered by the obstacle cost and undone.
fn obstacle_story(scenario: &Scenario) {
    let experiment = scenario.experiment::<6>().unwrap();
    for kind in [RunKind::Classical, RunKind::StackGradient] {
        let run = experiment.run(&scenario.settings(), kind).unwrap();
        match &run.outcome {
            Outcome::Collision {
                obstacle, distance, ..
            } => {
                assert_eq!(obstacle, "ball");
                assert!(*distance <= 0.0);
            }
            other => panic!("{}: {other:?}", kind.name()),
        }
        assert!(run.min_obstacle_distance().unwrap() <= 0.0);
    }
    let run = experiment
        .run(&scenario.settings(), RunKind::FullMethod)
        .unwrap();
    assert_eq!(run.outcome, Outcome::Converged);
    let min_distance = run.min_obstacle_distance().unwrap();
    assert!(min_distance > 0.0, "min obstacle distance {min_distance}");
    // Every iteration's distance is recorded, and every target point stayed in the image.
    let intrinsics = experiment.scene.intrinsics();
    for record in &run.records {
        assert!(record.obstacle_distance.unwrap() >= min_distance);
        assert!(intrinsics.all_in_field_of_view(&record.image, 0.0));
    }
    // The removals made because the avoidance was predicted to fail were triggered by the obstacle cost (a removal
    // that lets a removed task come back, a swap, names that task instead), and every removed task came back.
    let removals: Vec<_> = run.events_of(EventKind::Remove).collect();
    assert!(!removals.is_empty());
    for removal in &removals {
        let report = removal.removal.as_ref().unwrap();
        if report.swapped_for.is_none() {
            assert_eq!(report.cost, "obstacles");
        }
    }
    assert_eq!(run.events_of(EventKind::Reinsert).count(), removals.len());
    println!("full method: min obstacle distance {min_distance:.4} m");
}

fn invalid_field(text: &str) -> String {
    match Scenario::from_toml_str(text, None)
        .unwrap()
        .experiment::<6>()
    {
        Err(ScenarioError::Invalid { field, .. }) => field,
        other => panic!("expected an invalid field, got {other:?}"),
    }
}

#[test]
fn obstacle_errors_name_their_field() {
    assert_eq!(
        invalid_field(&SCENARIO.replace("\"afma6_wrist_1\"", "\"afma6_elbow\"")),
        "obstacles[0].links"
    );
    assert_eq!(
        invalid_field(&SCENARIO.replace(
            "influence_distance_m = 0.06",
            "influence_distance_m = -0.06"
        )),
        "obstacles[0].influence_distance_m"
    );
    assert_eq!(
        invalid_field(&SCENARIO.replace("radius_m = 0.03", "radius_m = 0.0")),
        "obstacles[0].shape"
    );
    assert_eq!(
        invalid_field(&SCENARIO.replace("margin_px = 60.0", "margin_px = 300.0")),
        "visibility.margin_px"
    );
    // A shape the format does not know is a syntax error naming it.
    let text = SCENARIO.replace(
        "{ sphere = { radius_m = 0.03 } }",
        "{ mesh = { file = \"ball.stl\" } }",
    );
    assert!(matches!(
        Scenario::from_toml_str(&text, None),
        Err(ScenarioError::Syntax(e)) if e.to_string().contains("mesh")
    ));
}
