//! Setup the control law's tests share (`hqp`, `sns`, `foundation_errors`, `stack_properties`): limits and one-row
//! tasks on three joints, the two-level stack driven across a stack change in a box, a step with a projection the
//! bounded methods have no counterpart for, and a step of the first task alone.

use nalgebra::{DVector, Vector3};
use servostack::avoidance::{Cost, JointLimits};
use servostack::law::{
    control_step, AvoidanceProjection, ControlLaw, ControlOutput, ControlWorkspace, LawError,
    StackChange,
};
use servostack::math::JointVector;
use servostack::task::{TaskJacobian, TaskValue};

/// Limits at ±1 on three joints, ρ = 0.1.
pub(crate) fn limits3() -> JointLimits<3> {
    JointLimits::new(Vector3::repeat(-1.0), Vector3::repeat(1.0), 0.1).unwrap()
}

/// A one-row task on three joints with gain 1: the Jacobian row `row` and the error `error`.
pub(crate) fn one_row_task(name: &str, error: f64, row: [f64; 3]) -> TaskValue<3> {
    TaskValue::from_parts(
        name,
        DVector::from_vec(vec![error]),
        TaskJacobian::<3>::from_row_slice(&row),
        1.0,
    )
    .unwrap()
}

/// Two tasks on three joints: index 0 is "b" (one row), index 1 is "a" (full rank, asking 0.45 on joint 0 alone).
pub(crate) fn one_row_and_full_rank_tasks() -> [TaskValue<3>; 2] {
    let jacobian =
        TaskJacobian::<3>::from_row_slice(&[1.0, 0.2, 0.0, 0.0, 1.0, 0.3, 0.1, 0.0, 1.0]);
    let first =
        TaskValue::from_parts("a", DVector::from_vec(vec![0.9, -0.4, 0.5]), jacobian, 0.5).unwrap();
    let second = one_row_task("b", -0.3, [0.0, 1.0, 1.0]);
    [second, first]
}

/// Steps the law (λ = 10, no cost, `q = 0`) 100 periods of 0.01 s, task 1 alone then tasks 0 and 1 from step 50;
/// checks that every velocity sent is within `max` and that at the change it is continuous while the law jumps.
pub(crate) fn step_across_a_stack_change(
    workspace: &mut ControlWorkspace<3>,
    tasks: &[TaskValue<3>],
    max: f64,
) {
    let law = ControlLaw::new(10.0, 0.0).unwrap();
    let q = Vector3::zeros();
    let mut last = Vector3::zeros();
    for step in 0..100 {
        let (order, change): (&[usize], _) = match step {
            0 => (&[1], StackChange::Changed),
            1..50 => (&[1], StackChange::Unchanged),
            50 => (&[0, 1], StackChange::Changed),
            _ => (&[0, 1], StackChange::Unchanged),
        };
        let time = 0.01 * (step + 1) as f64;
        let out = control_step(&law, workspace, tasks, order, None, &q, time, change).unwrap();
        assert!(
            out.velocity().amax() <= max,
            "step {step}: {}",
            out.velocity()
        );
        if step == 50 {
            assert!(
                (out.velocity() - last).norm() < 1e-12,
                "{} vs {last}",
                out.velocity()
            );
            assert!((out.law() - last).norm() > 1e-3);
        }
        last = *out.velocity();
    }
}

/// The error of a first step of task 0 with the VISP avoidance projection and the cost of [`limits3`], at `q = 0`.
pub(crate) fn visp_projection_step_error(
    control: &mut ControlWorkspace<3>,
    tasks: &[TaskValue<3>],
) -> LawError {
    let law = ControlLaw::new(10.0, 0.5)
        .unwrap()
        .with_avoidance_projection(AvoidanceProjection::VISP)
        .unwrap();
    let limits = limits3();
    let cost: &dyn Cost<3> = &limits;
    control_step(
        &law,
        control,
        tasks,
        &[0],
        Some(cost),
        &Vector3::zeros(),
        0.0,
        StackChange::Changed,
    )
    .unwrap_err()
}

/// One step of `law` with task 0 alone and no cost.
pub(crate) fn step_first_task<'w, const N: usize>(
    law: &ControlLaw,
    workspace: &'w mut ControlWorkspace<N>,
    tasks: &[TaskValue<N>],
    q: &JointVector<N>,
    time: f64,
    change: StackChange,
) -> Result<&'w ControlOutput<N>, LawError> {
    control_step(law, workspace, tasks, &[0], None, q, time, change)
}
