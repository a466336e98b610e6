//! Bad input to the foundation (tasks, stack, law, costs) gives a clear error variant, never a panic or a NaN.

use nalgebra::DVector;
use servostack::avoidance::{Cost, CostError, JointLimits};
use servostack::law::{control_step, ControlLaw, ControlWorkspace, LawError, StackChange};
use servostack::linalg::{
    null_space_projector, ColumnSvd, LinalgError, RankPolicy, VelocityInverse,
};
use servostack::math::JointVector;
use servostack::stack::{solve_stack, StackError, StackParameters, StackWorkspace};
use servostack::task::{TaskError, TaskJacobian, TaskValue};

use crate::law_fixture::step_first_task;

fn task(rows: usize) -> TaskValue<6> {
    let jacobian = TaskJacobian::<6>::from_fn(rows, |r, c| if r == c { 1.0 } else { 0.1 });
    TaskValue::from_parts("t", DVector::repeat(rows, 0.1), jacobian, 1.0).unwrap()
}

/// A step of task 0 alone with the stack unchanged: the velocity sent.
fn step(
    law: &ControlLaw,
    workspace: &mut ControlWorkspace<6>,
    tasks: &[TaskValue<6>],
    q: &JointVector<6>,
    time: f64,
) -> Result<JointVector<6>, LawError> {
    step_first_task(law, workspace, tasks, q, time, StackChange::Unchanged)
        .map(|out| *out.velocity())
}

#[test]
fn non_finite_configuration() {
    let tasks = [task(2)];
    let law = ControlLaw::new(5.0, 0.1).unwrap();
    let mut ws = ControlWorkspace::new(&tasks);
    let mut q = JointVector::<6>::zeros();
    q[3] = f64::NAN;
    assert!(matches!(
        step(&law, &mut ws, &tasks, &q, 0.0),
        Err(LawError::NonFiniteConfiguration { joint: 3, value }) if value.is_nan()
    ));
    let limits =
        JointLimits::new(JointVector::repeat(-1.0), JointVector::repeat(1.0), 0.1).unwrap();
    assert!(matches!(
        limits.value(&q),
        Err(CostError::NonFiniteConfiguration { joint: 3, value }) if value.is_nan()
    ));
}

#[test]
fn non_finite_task_error_or_jacobian() {
    for what in ["error", "jacobian"] {
        let mut tasks = [task(2), task(1)];
        let (error, jacobian) = tasks[1].parts_mut();
        if what == "error" {
            error[0] = f64::INFINITY;
        } else {
            jacobian[(0, 5)] = f64::NAN;
        }
        let mut ws = StackWorkspace::new(&tasks);
        let err = solve_stack(&StackParameters::default(), &mut ws, &tasks, &[0, 1]).unwrap_err();
        // The error names the level, the task and the offending entry with its value.
        let expected_entry = if what == "error" { (0, 0) } else { (0, 5) };
        match err {
            StackError::NonFiniteTask {
                level: 1,
                task: 1,
                what: found,
                row,
                column,
                value,
            } => {
                assert_eq!(found, what);
                assert_eq!((row, column), expected_entry);
                assert!(if what == "error" {
                    value == f64::INFINITY
                } else {
                    value.is_nan()
                });
            }
            other => panic!("unexpected error {other:?}"),
        }
        assert!(err.to_string().contains(&format!(
            "{what} entry ({}, {})",
            expected_entry.0, expected_entry.1
        )));
    }
}

#[test]
fn zero_rows_and_inconsistent_sizes() {
    assert!(matches!(
        TaskValue::<6>::new("empty", 0, 1.0),
        Err(TaskError::ZeroRows { .. })
    ));
    assert!(matches!(
        TaskValue::<6>::from_parts("t", DVector::zeros(3), TaskJacobian::zeros(2), 1.0),
        Err(TaskError::DimensionMismatch {
            what: "jacobian",
            expected: 3,
            found: 2,
            ..
        })
    ));
    let tasks = [task(2)];
    let mut ws = StackWorkspace::new(&tasks);
    assert_eq!(
        solve_stack(&StackParameters::default(), &mut ws, &tasks, &[1]).unwrap_err(),
        StackError::UnknownTask {
            level: 0,
            task: 1,
            available: 1
        }
    );
    // A workspace sized for 2-row tasks and 1 level.
    let mut small = StackWorkspace::<6>::with_capacity(2, 1);
    let big = [task(3)];
    assert_eq!(
        solve_stack(&StackParameters::default(), &mut small, &big, &[0]).unwrap_err(),
        StackError::CapacityExceeded {
            what: "task rows",
            found: 3,
            capacity: 2
        }
    );
    let two = [task(1), task(1)];
    assert_eq!(
        solve_stack(&StackParameters::default(), &mut small, &two, &[0, 1]).unwrap_err(),
        StackError::CapacityExceeded {
            what: "levels",
            found: 2,
            capacity: 1
        }
    );
    let mut svd = ColumnSvd::<6>::default();
    let mut work = TaskJacobian::<6>::from_fn(2, |r, c| if r == c { 1.0 } else { 0.0 });
    svd.decompose(&mut work, &RankPolicy::default()).unwrap();
    let mut out = JointVector::<6>::zeros();
    assert_eq!(
        svd.solve(
            &work,
            &DVector::zeros(3),
            VelocityInverse::Truncated,
            &mut out
        ),
        Err(LinalgError::DimensionMismatch {
            what: "right-hand side",
            expected: 2,
            found: 3
        })
    );
    let mut wrong_work = TaskJacobian::<6>::zeros(3);
    assert!(matches!(
        null_space_projector(
            &TaskJacobian::<6>::zeros(2),
            &mut wrong_work,
            &RankPolicy::default()
        ),
        Err(LinalgError::DimensionMismatch { .. })
    ));
}

#[test]
fn invalid_gains_and_parameters() {
    for mu in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            ControlLaw::new(mu, 0.1),
            Err(LawError::InvalidTransitionGain { .. })
        ));
    }
    for kappa in [-0.1, f64::NAN] {
        assert!(matches!(
            ControlLaw::new(1.0, kappa),
            Err(LawError::InvalidAvoidanceGain { .. })
        ));
    }
    let damped = StackParameters {
        velocity_inverse: VelocityInverse::Damped { damping: f64::NAN },
        ..Default::default()
    };
    assert!(matches!(
        ControlLaw::with_stack_parameters(damped, 1.0, 0.0),
        Err(LawError::Stack(StackError::Parameters(
            LinalgError::InvalidDamping { .. }
        )))
    ));
    assert!(matches!(
        ControlLaw::with_default_transition::<6>(&[], 0.0),
        Err(LawError::InvalidTransitionGain { mu }) if mu == 0.0
    ));
    for rho in [0.0, 0.5, 0.7, -0.2] {
        assert_eq!(
            JointLimits::<6>::new(JointVector::repeat(-1.0), JointVector::repeat(1.0), rho),
            Err(CostError::InvalidActivationRatio { rho })
        );
    }
}

#[test]
fn time_must_be_finite_and_not_go_back() {
    let tasks = [task(2)];
    let law = ControlLaw::new(5.0, 0.0).unwrap();
    let mut ws = ControlWorkspace::new(&tasks);
    let q = JointVector::<6>::zeros();
    step_first_task(&law, &mut ws, &tasks, &q, 2.0, StackChange::Changed).unwrap();
    assert_eq!(
        step(&law, &mut ws, &tasks, &q, 1.0),
        Err(LawError::InvalidTime {
            time: 1.0,
            switch_time: 2.0
        })
    );
    assert!(matches!(
        step(&law, &mut ws, &tasks, &q, f64::NAN),
        Err(LawError::InvalidTime { time, switch_time: 2.0 }) if time.is_nan()
    ));
    // A failed step leaves the law usable: the next valid step is finite.
    assert!(step(&law, &mut ws, &tasks, &q, 2.5)
        .unwrap()
        .iter()
        .all(|v| v.is_finite()));
}

/// A huge gradient (a user cost gone wrong) must not turn into a NaN velocity silently.
#[test]
fn non_finite_result_is_an_error() {
    struct Exploding;
    impl Cost<6> for Exploding {
        fn value(&self, _: &JointVector<6>) -> Result<f64, CostError> {
            Ok(f64::MAX)
        }
        fn value_and_gradient(
            &self,
            _: &JointVector<6>,
            g: &mut JointVector<6>,
        ) -> Result<f64, CostError> {
            g.fill(f64::MAX);
            Ok(f64::MAX)
        }
    }
    let tasks = [task(1)];
    let law = ControlLaw::new(5.0, 10.0).unwrap();
    let mut ws = ControlWorkspace::new(&tasks);
    let result = control_step(
        &law,
        &mut ws,
        &tasks,
        &[0],
        Some(&Exploding),
        &JointVector::zeros(),
        0.0,
        StackChange::Changed,
    );
    assert_eq!(result.unwrap_err(), LawError::NonFiniteVelocity);
}
