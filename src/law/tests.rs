use super::*;
use crate::avoidance::JointLimits;
use crate::task::TaskJacobian;
use nalgebra::{DVector, Vector3};

/// A full-rank 3-row task on 3 joints with a large error, and joint 1 deep in its activation band.
fn full_rank_case() -> ([TaskValue<3>; 1], JointLimits<3>, Vector3<f64>) {
    let jacobian =
        TaskJacobian::<3>::from_row_slice(&[1.0, 0.2, 0.0, 0.0, 1.0, 0.3, 0.1, 0.0, 1.0]);
    let task =
        TaskValue::from_parts("t", DVector::from_vec(vec![0.9, -0.4, 0.5]), jacobian, 0.5).unwrap();
    let limits = JointLimits::new(Vector3::repeat(-1.0), Vector3::repeat(1.0), 0.1).unwrap();
    ([task], limits, Vector3::new(0.0, 0.95, 0.0))
}

fn law_of(
    projection: AvoidanceProjection,
    case: &([TaskValue<3>; 1], JointLimits<3>, Vector3<f64>),
) -> (Vector3<f64>, Vector3<f64>) {
    let (tasks, limits, q) = case;
    let law = ControlLaw::new(10.0, 0.5)
        .unwrap()
        .with_avoidance_projection(projection)
        .unwrap();
    let mut workspace = ControlWorkspace::new(tasks);
    let cost: &dyn Cost<3> = limits;
    let law_velocity = *control_step(
        &law,
        &mut workspace,
        tasks,
        &[0],
        Some(cost),
        q,
        1.0,
        StackChange::Unchanged,
    )
    .unwrap()
    .law();
    (
        law_velocity,
        law_velocity - workspace.stack_solution().velocity(),
    )
}

/// D16: with a full-rank task the kernel projector is zero, the norm-preserving one is not, and its avoidance term
/// is orthogonal to `Jᵀe`: it leaves `d‖e‖²/dt = 2 eᵀ J q̇` to the task.
#[test]
fn norm_preserving_projection_acts_without_changing_the_error_norm_rate() {
    let case = full_rank_case();
    let (_, kernel) = law_of(AvoidanceProjection::Kernel, &case);
    assert_eq!(kernel.norm(), 0.0);
    let (_, large) = law_of(AvoidanceProjection::VISP, &case);
    assert!(large.norm() > 1e-3, "avoidance {large}");
    let task = &case.0[0];
    let rate = task.error().dot(&(task.jacobian() * large));
    assert!(rate.abs() < 1e-15, "eᵀ J (avoidance) = {rate}");
    // Below the lower bound of the sigmoid, the kernel projector alone: zero again.
    let far = AvoidanceProjection::NormPreserving {
        lower: 2.0,
        upper: 3.0,
    };
    assert_eq!(law_of(far, &case).1.norm(), 0.0);
}

/// D26: the full-rank task drives joint 1 (q = 0.95) towards its upper limit 1. Once joint 1 is within the lock band
/// the law holds it still, with either projection, and solves the task on the other two joints; the step that
/// locks it starts a transition from the last velocity (`q̇(τ⁺) = q̇(τ⁻)`); a joint the law moves away from its
/// limit is not locked; bands outside `(0, 0.5)` are refused.
#[test]
fn a_joint_pressed_into_its_limit_is_locked_and_the_transition_restarts() {
    #[allow(clippy::too_many_arguments)]
    fn step(
        law: &ControlLaw,
        workspace: &mut ControlWorkspace<3>,
        tasks: &[TaskValue<3>],
        cost: Option<&dyn Cost<3>>,
        q: Vector3<f64>,
        time: f64,
        change: StackChange,
    ) -> ControlOutput<3> {
        control_step(law, workspace, tasks, &[0], cost, &q, time, change)
            .unwrap()
            .clone()
    }
    let (tasks, limits, _) = full_rank_case();
    let at_limit = Vector3::new(0.0, 1.0 - 1e-3, 0.0);
    for projection in [AvoidanceProjection::Kernel, AvoidanceProjection::VISP] {
        let law = ControlLaw::new(10.0, 0.5)
            .unwrap()
            .with_avoidance_projection(projection)
            .unwrap();
        let mut workspace = ControlWorkspace::new(&tasks);
        workspace.lock_at_limits(limits.clone(), 1e-3).unwrap();
        let cost: Option<&dyn Cost<3>> = Some(&limits);
        let inside = Vector3::new(0.0, 0.95, 0.0);
        // Away from the limit: nothing locked; the law drives joint 1 up.
        let free = step(
            &law,
            &mut workspace,
            &tasks,
            cost,
            inside,
            0.01,
            StackChange::Changed,
        );
        assert!(free.law()[1] > 0.0, "{:?}", free.law());
        let settled = step(
            &law,
            &mut workspace,
            &tasks,
            cost,
            inside,
            10.0,
            StackChange::Unchanged,
        );
        assert_eq!(workspace.locked_joints(), &[false; 3]);
        // Within 1e−3 of its range (2e−3) from the limit: locked.
        let locked = step(
            &law,
            &mut workspace,
            &tasks,
            cost,
            at_limit,
            10.01,
            StackChange::Unchanged,
        );
        assert_eq!(workspace.locked_joints(), &[false, true, false]);
        assert_eq!(locked.law()[1], 0.0);
        assert!((locked.law() - settled.law()).norm() > 0.1);
        // The transition restarted: the velocity is the last one, not the new law.
        assert!((locked.velocity() - settled.velocity()).norm() < 1e-12);
        // The task in least squares on joints 0 and 2: the residual of J q̇_n = −λ e is orthogonal to their columns.
        let jacobian = tasks[0].jacobian();
        let residual = jacobian * workspace.stack_solution().velocity() + tasks[0].error() * 0.5;
        for column in [0, 2] {
            assert!(jacobian.column(column).dot(&residual).abs() < 1e-12);
        }
    }
    // Driven away from the limit, the joint is not locked.
    let task = &tasks[0];
    let reversed =
        [TaskValue::from_parts("t", -task.error(), task.jacobian().clone(), 0.5).unwrap()];
    let law = ControlLaw::new(10.0, 0.0).unwrap();
    let mut workspace = ControlWorkspace::new(&reversed);
    workspace.lock_at_limits(limits.clone(), 1e-3).unwrap();
    let away = step(
        &law,
        &mut workspace,
        &reversed,
        None,
        at_limit,
        0.01,
        StackChange::Changed,
    );
    assert!(away.law()[1] < 0.0);
    assert_eq!(workspace.locked_joints(), &[false; 3]);
    for band in [0.0, -1e-3, 0.5, f64::NAN] {
        assert!(matches!(
            workspace.lock_at_limits(limits.clone(), band),
            Err(LawError::InvalidLockBand { .. })
        ));
    }
}

#[test]
fn norm_preserving_projection_is_checked() {
    for (lower, upper) in [
        (0.5, 0.5),
        (-0.1, 0.7),
        (0.1, f64::INFINITY),
        (f64::NAN, 1.0),
    ] {
        let projection = AvoidanceProjection::NormPreserving { lower, upper };
        let law = ControlLaw::new(10.0, 0.5)
            .unwrap()
            .with_avoidance_projection(projection);
        assert!(
            matches!(law, Err(LawError::InvalidProjectionBounds { .. })),
            "{lower} .. {upper}"
        );
    }
    let (tasks, limits, q) = full_rank_case();
    let two = [tasks[0].clone(), tasks[0].clone()];
    let law = ControlLaw::new(10.0, 0.5)
        .unwrap()
        .with_avoidance_projection(AvoidanceProjection::VISP)
        .unwrap();
    let mut workspace = ControlWorkspace::new(&two);
    let cost: &dyn Cost<3> = &limits;
    let result = control_step(
        &law,
        &mut workspace,
        &two,
        &[0, 1],
        Some(cost),
        &q,
        0.0,
        StackChange::Changed,
    );
    assert_eq!(
        result.unwrap_err(),
        LawError::NormPreservingNeedsOneLevel { levels: 2 }
    );
}
