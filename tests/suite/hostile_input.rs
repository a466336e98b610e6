//! One test per finding of hostile input (issue 14): each input was once accepted, aborted the process or gave a
//! non-finite number inside `Ok`; each is now a named error or a finite result.

use nalgebra::DVector;
use servostack::avoidance::{Cost, CostError, JointLimits};
use servostack::controller::{ControllerError, ControllerParameters, StackController};
use servostack::law::{control_step, ControlLaw, ControlWorkspace, LawError, StackChange};
use servostack::math::JointVector;
use servostack::report::{ErrorChain, RunSummary};
use servostack::robot::{builtin, KinematicsWorkspace, RobotError, SerialChain, MAX_URDF_DEPTH};
use servostack::scenario::{RunKind, Scenario, ScenarioError, MAX_SCENARIO_DEPTH};
use servostack::sim::{Outcome, SimError, SimulationParameters};
use servostack::stack::{solve_stack, StackError, StackParameters, StackWorkspace};
use servostack::task::{TaskError, TaskJacobian, TaskValue};

const UR5E_SCENARIO: &str = include_str!("../../assets/scenarios/ur5e.toml");

/// Runs `f` on a thread with the 2 MiB stack of spawned threads (a stack overflow there aborts the test binary).
pub(crate) fn on_2_mib_thread<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> T {
    std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(f)
        .unwrap()
        .join()
        .unwrap()
}

/// The rail7 URDF with its first movable joint's `from` replaced by `to`.
fn rail7_with(from: &str, to: &str) -> String {
    assert!(builtin::RAIL7_URDF.contains(from), "{from}");
    builtin::RAIL7_URDF.replacen(from, to, 1)
}

fn load_rail7(xml: &str) -> Result<SerialChain<7>, RobotError> {
    SerialChain::<7>::from_urdf_str(xml, "rail7_base", "rail7_tool")
}

#[test]
fn deeply_nested_urdf_is_refused_before_parsing() {
    // 30,000 levels aborted the process on the main thread, 4,000 on a 2 MiB thread.
    let deep = rail7_with(
        "<link name=\"rail7_base\"/>",
        &format!("{}{}", "<link>".repeat(30_000), "</link>".repeat(30_000)),
    );
    let error = on_2_mib_thread(move || load_rail7(&deep).unwrap_err());
    assert!(
        matches!(error, RobotError::UrdfTooDeep { depth, limit, line: 8 } if depth == MAX_URDF_DEPTH + 1 && limit == MAX_URDF_DEPTH),
        "{error:?}"
    );
    // At the limit the parser runs (and rejects the unknown nesting or not, but returns) on a 2 MiB thread.
    let at_limit = rail7_with(
        "<link name=\"rail7_base\"/>",
        &format!(
            "<link name=\"rail7_base\"/>{}{}",
            "<link>".repeat(MAX_URDF_DEPTH - 1),
            "</link>".repeat(MAX_URDF_DEPTH - 1)
        ),
    );
    let result = on_2_mib_thread(move || load_rail7(&at_limit));
    assert!(!matches!(result, Err(RobotError::UrdfTooDeep { .. })));
}

#[test]
fn deeply_nested_scenario_is_refused_before_parsing() {
    let deep = format!(
        "{UR5E_SCENARIO}\ndeep = {}1{}\n",
        "[".repeat(100_000),
        "]".repeat(100_000)
    );
    let error = on_2_mib_thread(move || Scenario::from_toml_str(&deep, None).unwrap_err());
    assert!(
        matches!(error, ScenarioError::TooDeep { depth, .. } if depth == MAX_SCENARIO_DEPTH + 1),
        "{error}"
    );
}

#[test]
fn huge_axis_is_normalised_without_overflow() {
    // |axis|² overflowed to ∞ and the "unit" axis came out as zeros.
    let chain = load_rail7(&rail7_with(
        "<axis xyz=\"1 0 0\"/>",
        "<axis xyz=\"1e200 1e200 1e200\"/>",
    ))
    .unwrap();
    let axis = chain.joints()[0].axis().into_inner();
    let third = 1.0 / 3f64.sqrt();
    assert!(
        (axis - nalgebra::Vector3::repeat(third)).norm() < 1e-15,
        "{axis}"
    );
    // Small components are a direction too; all below 1e−12 is zero.
    let small = load_rail7(&rail7_with(
        "<axis xyz=\"1 0 0\"/>",
        "<axis xyz=\"0 2e-12 0\"/>",
    ))
    .unwrap();
    assert_eq!(
        small.joints()[0].axis().into_inner(),
        nalgebra::Vector3::y()
    );
    assert!(matches!(
        load_rail7(&rail7_with(
            "<axis xyz=\"1 0 0\"/>",
            "<axis xyz=\"1e-13 0 0\"/>"
        )),
        Err(RobotError::ZeroAxis { .. })
    ));
}

#[test]
fn urdf_numbers_beyond_physical_ranges_are_named() {
    // An origin near 1e308 gave kinematics Ok with an infinite pose; limits of ±1e308 a NaN cost.
    let cases = [
        (
            "<origin xyz=\"0 0 0.1\"/>",
            "<origin xyz=\"0 0 1e308\"/>",
            "origin xyz",
            1e308,
        ),
        (
            "<origin xyz=\"0 0 0.1\"/>",
            "<origin xyz=\"0 0 0.1\" rpy=\"0 -5e3 0\"/>",
            "origin rpy",
            -5e3,
        ),
        (
            "lower=\"-1.0\" upper=\"1.0\"",
            "lower=\"-1e308\" upper=\"1e308\"",
            "limit",
            -1e308,
        ),
    ];
    for (from, to, field, value) in cases {
        match load_rail7(&rail7_with(from, to)) {
            Err(RobotError::OutOfRange {
                joint,
                field: f,
                value: v,
                ..
            }) => {
                assert_eq!((joint.as_str(), f, v), ("rail7_rail", field, value));
            }
            other => panic!("{to}: expected OutOfRange, got {other:?}"),
        }
    }
    let error = load_rail7(&rail7_with(cases[0].0, cases[0].1)).unwrap_err();
    assert_eq!(
        error.to_string(),
        "joint \"rail7_rail\": origin xyz = 1e308 is out of range: expected finite, within ±1000 m"
    );
}

#[test]
fn kinematics_never_return_a_non_finite_pose() {
    let chain = builtin::rail7().unwrap().chain;
    let mut workspace = KinematicsWorkspace::new();
    // Finite positions at the top of the range: the two prismatic joints would add up beyond f64::MAX.
    let q = JointVector::<7>::repeat(f64::MAX);
    match chain.kinematics(&mut workspace, &q) {
        Err(RobotError::OutOfRange {
            field: "position",
            value,
            ..
        }) => assert_eq!(value, f64::MAX),
        Err(other) => panic!("expected OutOfRange, got {other:?}"),
        Ok(state) => panic!("Ok with pose {:?}", state.base_from_tip()),
    }
    // At the edge of the accepted coordinates, every joint at ±1e100 (the prismatic ones adding up, the revolute ones
    // any angle): the pose and both Jacobians are finite without being checked.
    for sign in [1.0, -1.0] {
        let state = chain
            .kinematics(&mut workspace, &JointVector::<7>::repeat(sign * 1e100))
            .unwrap();
        assert!(state
            .base_from_tip()
            .translation
            .vector
            .iter()
            .all(|v| v.is_finite()));
        assert!(state.base_jacobian().iter().all(|v| v.is_finite()));
        assert!(state.tip_jacobian().iter().all(|v| v.is_finite()));
    }
    // Ordinary positions are unaffected.
    assert!(chain
        .kinematics(&mut workspace, &JointVector::zeros())
        .is_ok());
}

#[test]
fn joint_limit_cost_is_an_error_rather_than_nan() {
    let (lo, hi) = (
        JointVector::<2>::repeat(-1e308),
        JointVector::<2>::repeat(1e308),
    );
    assert!(matches!(
        JointLimits::new(lo, hi, 0.1),
        Err(CostError::InvalidLimits { joint: 0, .. })
    ));
    let limits = JointLimits::new(
        JointVector::<2>::repeat(-1.0),
        JointVector::<2>::repeat(1.0),
        0.1,
    )
    .unwrap();
    let mut gradient = JointVector::<2>::zeros();
    // Far beyond the limits, δ² overflows: an error naming the cost, not Ok(∞).
    let q = JointVector::<2>::new(0.0, 1e200);
    match limits.value_and_gradient(&q, &mut gradient) {
        Err(CostError::NonFiniteCost { cost, value, .. }) => {
            assert_eq!(cost, "joint_limits");
            assert!(value.is_infinite());
        }
        other => panic!("expected NonFiniteCost, got {other:?}"),
    }
    assert!(matches!(
        limits.value(&q),
        Err(CostError::NonFiniteCost { .. })
    ));
}

#[test]
fn gains_horizons_and_periods_beyond_physical_ranges_are_named() {
    assert!(matches!(
        ControlLaw::new(1e-300, 0.0),
        Err(LawError::InvalidTransitionGain { mu }) if mu == 1e-300
    ));
    assert!(matches!(
        ControlLaw::new(10.0, 1e308),
        Err(LawError::InvalidAvoidanceGain { .. })
    ));
    assert!(matches!(
        TaskValue::<6>::new("t", 2, 1e308),
        Err(TaskError::InvalidGain { .. })
    ));
    let horizon = ControllerParameters {
        prediction_horizon: 1e308,
        ..ControllerParameters::default()
    };
    assert!(matches!(
        horizon.validate(),
        Err(ControllerError::InvalidParameter {
            name: "prediction_horizon",
            ..
        })
    ));
    let mut scenario = Scenario::from_toml_str(UR5E_SCENARIO, None).unwrap();
    scenario.simulation = SimulationParameters {
        period: 1e308,
        ..scenario.simulation
    };
    match scenario.run::<6>(RunKind::Classical) {
        Err(ScenarioError::Simulation(SimError::InvalidParameter { name, value, .. })) => {
            assert_eq!((name, value), ("period", 1e308));
        }
        other => panic!("expected an invalid period, got {other:?}"),
    }
    // D25: a braking rate above 1/period could not keep a joint from crossing its limit within one period.
    let mut scenario = Scenario::from_toml_str(UR5E_SCENARIO, None).unwrap();
    scenario.controller.braking_rate = 2.0 / scenario.simulation.period;
    match scenario.run::<6>(RunKind::FullMethod) {
        Err(ScenarioError::Simulation(SimError::InvalidParameter { name, .. })) => {
            assert_eq!(name, "controller.braking_rate");
        }
        other => panic!("expected an invalid braking rate, got {other:?}"),
    }
    scenario.controller.braking_rate = f64::NAN;
    assert!(scenario.run::<6>(RunKind::FullMethod).is_err());
    let far = UR5E_SCENARIO.replace(
        "translation_m = [0.0, 0.0, 0.45]",
        "translation_m = [0.0, 0.0, 1e308]",
    );
    let error = Scenario::from_toml_str(&far, None)
        .unwrap()
        .experiment::<6>()
        .unwrap_err();
    assert_eq!(
        error.to_string(),
        "scenario field `desired.camera_from_target.translation_m`: value 2 = 1e308 is out of range: finite, within ±1000 m"
    );
}

fn one_task() -> Vec<TaskValue<6>> {
    let jacobian = TaskJacobian::<6>::from_fn(2, |r, c| if r == c { 1.0 } else { 0.0 });
    vec![TaskValue::from_parts("t", DVector::from_vec(vec![0.1, -0.2]), jacobian, 1.0).unwrap()]
}

#[test]
fn time_must_increase_strictly_across_control_steps() {
    let tasks = one_task();
    let law = ControlLaw::new(10.0, 0.0).unwrap();
    let mut workspace = ControlWorkspace::new(&tasks);
    let q = JointVector::<6>::zeros();
    let mut step = |time, change| {
        control_step(&law, &mut workspace, &tasks, &[0], None, &q, time, change).map(|_| ())
    };
    step(2.0, StackChange::Changed).unwrap();
    step(3.0, StackChange::Unchanged).unwrap();
    // 2.5 is after the last change (τ = 2) and was accepted; a repeated time too.
    for time in [2.5, 3.0] {
        assert_eq!(
            step(time, StackChange::Unchanged),
            Err(LawError::TimeNotIncreasing {
                time,
                previous: 3.0
            })
        );
    }
    // A refused step leaves the clock where it was.
    step(3.1, StackChange::Unchanged).unwrap();
    // The controller steps through the law: the same rule, the same error.
    let mut controller = StackController::new(ControllerParameters::default(), &tasks).unwrap();
    controller.step(&law, &tasks, None, &q, 0, 1.0).unwrap();
    controller.step(&law, &tasks, None, &q, 1, 2.0).unwrap();
    assert!(matches!(
        controller.step(&law, &tasks, None, &q, 2, 1.5),
        Err(ControllerError::Law(LawError::TimeNotIncreasing {
            time: 1.5,
            previous: 2.0
        }))
    ));
}

#[test]
fn duplicate_and_unknown_stack_entries_are_named() {
    let tasks = one_task();
    let mut workspace = StackWorkspace::new(&tasks);
    let parameters = StackParameters::default();
    // `[0, 0]` reported "workspace too small: levels is 2, capacity 1".
    assert_eq!(
        solve_stack(&parameters, &mut workspace, &tasks, &[0, 0]).unwrap_err(),
        StackError::DuplicateTask {
            task: 0,
            first_level: 0,
            level: 1
        }
    );
    assert_eq!(
        solve_stack(&parameters, &mut workspace, &tasks, &[0, 3]).unwrap_err(),
        StackError::UnknownTask {
            level: 1,
            task: 3,
            available: 1
        }
    );
}

#[test]
fn a_run_that_ends_at_once_has_no_nan_in_its_summary() {
    let mut scenario = Scenario::from_toml_str(UR5E_SCENARIO, None).unwrap();
    scenario.simulation.max_iterations = 0;
    let run = scenario.run::<6>(RunKind::Classical).unwrap();
    assert_eq!(run.iterations(), 0);
    assert!(matches!(
        run.outcome,
        Outcome::Stalled { .. } | Outcome::MaxIterations { .. }
    ));
    assert_eq!(run.final_error_norm(), None);
    // The margin of the start configuration, the only one the run had.
    assert!(run.min_normalized_margin().is_finite() && run.min_normalized_margin() > 0.0);
    assert_eq!(run.max_velocity_step(), 0.0);
    let summary = RunSummary::new("classical", &run);
    let json = serde_json::to_value(&summary).unwrap();
    assert!(json["final_error_norm"].is_null());
    assert!(json["min_normalized_margin"].is_f64());
    assert!(json["max_velocity_step"].is_f64());
}

#[test]
fn a_run_out_of_budget_before_its_pushes_names_the_task_it_waited_for() {
    // One iteration: the centroid is pushed at the first, the angle task can never be.
    let mut scenario = Scenario::from_toml_str(UR5E_SCENARIO, None).unwrap();
    scenario.simulation.max_iterations = 1;
    let run = scenario.run::<6>(RunKind::FullMethod).unwrap();
    let Outcome::Stalled { task, reason } = &run.outcome else {
        panic!("expected a stalled run, got {:?}", run.outcome);
    };
    assert_eq!(*task, 1);
    assert!(reason.starts_with("angle was never pushed"), "{reason}");
    // The reason is one sentence for people: the error of every task, no run of blanks left by a line break.
    for name in ["centroid", "angle", "area"] {
        assert!(reason.contains(name), "{reason}");
    }
    assert!(!reason.contains("  "), "{reason:?}");
}

#[test]
fn errors_are_shown_with_field_and_value_not_the_input() {
    // The Debug form of a syntax error holds the whole TOML (the description included); the Display chain names the
    // field and its line only.
    let text = UR5E_SCENARIO.replace("fx = 800.0", "fx = \"800\"");
    let error = Scenario::from_toml_str(&text, None).unwrap_err();
    assert!(format!("{error:?}").contains("coupled joints"));
    let shown = ErrorChain(&error).to_string();
    assert!(shown.contains("fx") && shown.contains("line 14"), "{shown}");
    assert!(!shown.contains("coupled joints"), "{shown}");
    // A wrapper whose message holds its source's is not repeated.
    let wrapped = ScenarioError::Robot(RobotError::UnknownRobot {
        name: "x".into(),
        known: &["afma6"],
    });
    assert_eq!(
        ErrorChain(&wrapped).to_string(),
        "scenario field `robot`: unknown built-in robot \"x\" (known: [\"afma6\"])"
    );
}

/// Cost used to reach the law's velocity-norm check: a gradient whose entries are finite but whose norm overflows.
struct HugeGradient;

impl Cost<6> for HugeGradient {
    fn value(&self, _: &JointVector<6>) -> Result<f64, CostError> {
        Ok(0.0)
    }
    fn value_and_gradient(
        &self,
        _: &JointVector<6>,
        g: &mut JointVector<6>,
    ) -> Result<f64, CostError> {
        g.fill(1e200);
        Ok(0.0)
    }
}

#[test]
fn a_velocity_whose_norm_overflows_is_not_sent() {
    let tasks = one_task();
    let law = ControlLaw::new(10.0, 1e6).unwrap();
    let mut workspace = ControlWorkspace::new(&tasks);
    // The projector leaves 4 free joints: their velocities are −κ·1e200 = −1e206 each, finite, with an infinite norm.
    let result = control_step(
        &law,
        &mut workspace,
        &tasks,
        &[0],
        Some(&HugeGradient),
        &JointVector::zeros(),
        0.0,
        StackChange::Unchanged,
    );
    assert_eq!(result.unwrap_err(), LawError::NonFiniteVelocity);
}

#[test]
fn files_larger_than_the_limits_are_not_read() {
    let dir = std::env::temp_dir().join(format!("servostack-hostile-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // Sparse files: their size is what is checked, before any byte is read.
    let urdf = dir.join("huge.urdf");
    std::fs::File::create(&urdf)
        .unwrap()
        .set_len(servostack::robot::MAX_URDF_BYTES as u64 + 1)
        .unwrap();
    assert!(matches!(
        SerialChain::<6>::from_urdf_file(&urdf, "a", "b"),
        Err(RobotError::UrdfTooLarge { bytes, .. }) if bytes == servostack::robot::MAX_URDF_BYTES as u64 + 1
    ));
    let scenario = dir.join("huge.toml");
    std::fs::File::create(&scenario)
        .unwrap()
        .set_len(servostack::scenario::MAX_SCENARIO_BYTES as u64 + 1)
        .unwrap();
    assert!(matches!(
        Scenario::from_file(&scenario),
        Err(ScenarioError::TooLarge { .. })
    ));
    std::fs::remove_dir_all(&dir).unwrap();
}
