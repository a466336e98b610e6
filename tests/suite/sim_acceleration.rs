//! Acceleration limits in the simulation (`[simulation] max_prismatic_acceleration_m_s2` and
//! `max_revolute_acceleration_rad_s2`, theory D31): the velocity sent is shaped as the servo façade shapes it, so every
//! change from one period to the next stays within `a_i Δt` through whole runs (pushes, removals, re-insertions), the
//! runs still converge, the run's summary reports the largest change, and bad values are refused by name.
//!
//! Without acceleration limits (the default, `+∞`) the runs are those of before: the exact figures of the paper's runs
//! (`paper_experiment`), of the README (`readme`) and of the event stories (`scenarios`) are unchanged.

use servostack::prelude::*;
use servostack::scenario::ScenarioError;
use servostack::sim::SimError;

fn load(file: &str) -> Scenario {
    Scenario::from_file(format!(
        "{}/assets/scenarios/{file}",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap()
}

/// Near an industrial arm's: 1 m/s² on the Afma6's three prismatic (gantry) axes, 3 rad/s² on its three revolute
/// joints.
fn with_industrial_limits(mut scenario: Scenario) -> Scenario {
    scenario.simulation.max_prismatic_acceleration_m_s2 = 1.0;
    scenario.simulation.max_revolute_acceleration_rad_s2 = 3.0;
    scenario
}

/// `a_i Δt` per joint of the Afma6 (three prismatic joints, then three revolute ones).
fn allowance(scenario: &Scenario) -> [f64; 6] {
    let s = &scenario.simulation;
    let (p, r) = (
        s.max_prismatic_acceleration_m_s2 * s.period,
        s.max_revolute_acceleration_rad_s2 * s.period,
    );
    [p, p, p, r, r, r]
}

/// Checks every sent step of `run` against `a_i Δt (1 + 1e−12)` (from rest); returns the largest
/// `|Δq̇_i| / (a_i Δt)` and the largest `|Δq̇_i|`.
fn check_steps(run: &Run<6>, allowance: &[f64; 6]) -> (f64, f64) {
    let mut previous = JointVector::<6>::zeros();
    let (mut ratio, mut step): (f64, f64) = (0.0, 0.0);
    for record in run.records.iter().filter(|r| r.sent) {
        for i in 0..6 {
            let change = (record.velocity[i] - previous[i]).abs();
            assert!(
                change <= allowance[i] * (1.0 + 1e-12),
                "iteration {}: joint {i} changed by {change} > a Δt = {}",
                record.iteration,
                allowance[i]
            );
            ratio = ratio.max(change / allowance[i]);
            step = step.max(change);
        }
        previous = record.velocity;
    }
    (ratio, step)
}

/// The paper's scenario (100 Hz, a removal and its re-insertion) with the limits of an industrial arm: the velocity
/// sent never changes by more than `a_i Δt` in a period, the limit is reached (the start from rest, and the stack
/// changes, ask for more), the run reports that largest change, and it still converges with its removal.
#[test]
fn the_paper_run_keeps_within_the_acceleration_limits_and_converges() {
    let scenario = with_industrial_limits(load("paper_afma6.toml"));
    let run = scenario.run::<6>(RunKind::FullMethod).unwrap();
    assert_eq!(run.outcome, Outcome::Converged, "{:?}", run.outcome);
    for kind in [EventKind::Push, EventKind::Remove] {
        assert!(run.events_of(kind).next().is_some(), "no {kind:?}");
    }
    let (ratio, step) = check_steps(&run, &allowance(&scenario));
    assert!(
        ratio > 0.99,
        "the limits never acted: largest ratio {ratio}"
    );
    assert_eq!(run.max_acceleration_ratio(), ratio);
    assert_eq!(run.max_joint_velocity_step(), step);

    // Without the limits the same run changes its velocity by more than `a_i Δt` in a period, and reports no ratio.
    let free = load("paper_afma6.toml")
        .run::<6>(RunKind::FullMethod)
        .unwrap();
    assert_eq!(free.max_acceleration_ratio(), 0.0);
    let mut previous = JointVector::<6>::zeros();
    let mut free_ratio: f64 = 0.0;
    for record in free.records.iter().filter(|r| r.sent) {
        for (i, a) in allowance(&scenario).iter().enumerate() {
            free_ratio = free_ratio.max((record.velocity[i] - previous[i]).abs() / a);
        }
        previous = record.velocity;
    }
    assert!(free_ratio > 1.5, "{free_ratio}: the limits are not needed");
    println!("largest change per period against a Δt: {ratio} with the limits, {free_ratio} without; largest step {step}");
}

/// The real-camera scenario (500 Hz control, a 30 Hz camera one frame late, calibration errors) under the same limits:
/// within them at every period, and still converging near the goal.
#[test]
fn the_real_camera_run_keeps_within_the_acceleration_limits_and_converges() {
    let scenario = with_industrial_limits(load("paper_afma6_real_camera.toml"));
    let run = scenario.run::<6>(RunKind::FullMethod).unwrap();
    assert_eq!(run.outcome, Outcome::Converged, "{:?}", run.outcome);
    let (ratio, _) = check_steps(&run, &allowance(&scenario));
    assert!(
        ratio > 0.99,
        "the limits never acted: largest ratio {ratio}"
    );
    assert_eq!(run.max_acceleration_ratio(), ratio);
}

/// SNS and the QP cascade, whose box bounds the speed towards a hard limit by the distance a held velocity needs to
/// stop under the acceleration limit (theory D31, `avoidance::stopping_speed`), on the paper scenario under the same
/// limits: no run crosses a joint limit (with `√(2ad)`, the continuous-time bound, both crossed joint 2's), and every
/// change of the velocity sent stays within `a_i Δt`.
#[test]
fn boxed_laws_keep_the_joint_limits_under_acceleration_limits() {
    let scenario = with_industrial_limits(load("paper_afma6.toml"));
    for kind in [RunKind::Sns, RunKind::Hqp] {
        let run = scenario.run::<6>(kind).unwrap();
        assert!(
            !matches!(run.outcome, Outcome::JointLimit { .. }),
            "{kind:?}: {:?}",
            run.outcome
        );
        check_steps(&run, &allowance(&scenario));
    }
}

/// A limit of zero, a negative or a NaN one, and a finite one beyond `bounds::ACCELERATION_PER_S2`, is refused with
/// the field named, before any run; `+∞` is no limit.
#[test]
fn invalid_acceleration_limits_are_named() {
    let names = [
        "max_prismatic_acceleration_m_s2",
        "max_revolute_acceleration_rad_s2",
    ];
    for field in names {
        for value in [0.0, -1.0, f64::NAN, f64::NEG_INFINITY, 1e7] {
            let mut scenario = load("paper_afma6.toml");
            let s = &mut scenario.simulation;
            match field {
                "max_prismatic_acceleration_m_s2" => s.max_prismatic_acceleration_m_s2 = value,
                _ => s.max_revolute_acceleration_rad_s2 = value,
            }
            match scenario.experiment::<6>() {
                Err(ScenarioError::Simulation(SimError::InvalidParameter { name, .. })) => {
                    assert_eq!(name, field, "{field} = {value}")
                }
                other => panic!("{field} = {value}: {:?}", other.map(|_| ())),
            }
        }
    }
    let mut unlimited = load("paper_afma6.toml");
    unlimited.simulation.max_revolute_acceleration_rad_s2 = f64::INFINITY;
    unlimited.simulation.max_prismatic_acceleration_m_s2 = f64::INFINITY;
    assert!(unlimited.simulation.validate().is_ok());
}

/// The limits are read from the scenario's `[simulation]` table; absent, there is none.
#[test]
fn acceleration_limits_are_read_from_the_scenario() {
    let path = format!(
        "{}/assets/scenarios/paper_afma6.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(path).unwrap();
    let paper = Scenario::from_toml_str(&text, None).unwrap();
    assert_eq!(
        paper.simulation.max_revolute_acceleration_rad_s2,
        f64::INFINITY
    );
    assert_eq!(
        paper.simulation.max_prismatic_acceleration_m_s2,
        f64::INFINITY
    );
    let limited = text.replace(
        "[simulation]\n",
        "[simulation]\nmax_prismatic_acceleration_m_s2 = 1.5\nmax_revolute_acceleration_rad_s2 = 2.5\n",
    );
    let limited = Scenario::from_toml_str(&limited, None).unwrap();
    assert_eq!(limited.simulation.max_prismatic_acceleration_m_s2, 1.5);
    assert_eq!(limited.simulation.max_revolute_acceleration_rad_s2, 2.5);
    let misspelt = text.replace(
        "[simulation]\n",
        "[simulation]\nmax_revolute_acceleration = 2.5\n",
    );
    assert!(Scenario::from_toml_str(&misspelt, None).is_err());
}
