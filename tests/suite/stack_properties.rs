//! Properties of the task stack, the continuity term and the projected-gradient avoidance on random stacks
//! (theory \[M8\], \[M14\], \[M15\]/D1, \[M18\]), for N = 6 and N = 7.

use nalgebra::{DMatrix, DVector, Dyn, OMatrix};
use proptest::prelude::*;
use servostack::avoidance::{Cost, JointLimits};
use servostack::law::{control_step, ControlLaw, ControlWorkspace, StackChange};
use servostack::linalg::{ColumnSvd, RankPolicy, VelocityInverse};
use servostack::math::{JointMatrix, JointVector};
use servostack::stack::{solve_stack, StackParameters, StackWorkspace};
use servostack::task::{TaskJacobian, TaskValue};

use crate::law_fixture::step_first_task;

/// Random task values with the given row counts; entries in [−1, 1], gains in [0.2, 2] (also the SNS tests').
pub(crate) fn random_tasks<const N: usize>(data: &[f64], rows: &[usize]) -> Vec<TaskValue<N>> {
    let mut cursor = data.iter().copied().cycle();
    rows.iter()
        .enumerate()
        .map(|(i, &m)| {
            let jacobian = TaskJacobian::<N>::from_fn(m, |_, _| cursor.next().unwrap());
            let error = DVector::from_fn(m, |_, _| cursor.next().unwrap());
            let gain = 1.1 + 0.9 * cursor.next().unwrap();
            TaskValue::from_parts(&format!("t{i}"), error, jacobian, gain).unwrap()
        })
        .collect()
}

/// The augmented Jacobian `[J_1; …; J_k]` of the first `k` tasks, as a dense matrix.
fn augmented<const N: usize>(tasks: &[TaskValue<N>], k: usize) -> DMatrix<f64> {
    let rows: usize = tasks[..k].iter().map(TaskValue::rows).sum();
    let mut out = DMatrix::zeros(rows, N);
    let mut row = 0;
    for task in &tasks[..k] {
        out.view_mut((row, 0), (task.rows(), N))
            .copy_from(task.jacobian());
        row += task.rows();
    }
    out
}

/// The singular values and left singular vectors of `Jᵀ` (tall) by nalgebra's own SVD, an implementation independent
/// of servostack's Jacobi SVD. (nalgebra's SVD of the *wide* `J` is only accurate to about 1e−9 in `J P`: the tall
/// transpose is the accurate route.)
fn reference_row_space(a: &DMatrix<f64>) -> Vec<nalgebra::DVector<f64>> {
    if a.nrows() == 0 {
        return Vec::new();
    }
    let svd = a.transpose().svd(true, false);
    let tol = (1e-6 * svd.singular_values.max()).max(1e-12);
    let u = svd.u.unwrap();
    (0..svd.singular_values.len())
        .filter(|&k| svd.singular_values[k] > tol)
        .map(|k| u.column(k).into_owned())
        .collect()
}

fn reference_rank(a: &DMatrix<f64>) -> usize {
    reference_row_space(a).len()
}

/// `I − J⁺J`, from an orthonormal basis of the row space of `J`.
fn reference_projector<const N: usize>(a: &DMatrix<f64>) -> DMatrix<f64> {
    let mut p = DMatrix::identity(N, N);
    for v in reference_row_space(a) {
        p -= &v * v.transpose();
    }
    p
}

fn to_dense<const N: usize>(p: &JointMatrix<N>) -> DMatrix<f64> {
    DMatrix::from_iterator(N, N, p.iter().copied())
}

fn solve<const N: usize>(
    tasks: &[TaskValue<N>],
    order: &[usize],
) -> (JointVector<N>, JointMatrix<N>, Vec<usize>) {
    let mut ws = StackWorkspace::new(tasks);
    let solution = solve_stack(&StackParameters::default(), &mut ws, tasks, order).unwrap();
    let ranks = solution.levels().iter().map(|l| l.rank).collect();
    (*solution.velocity(), *solution.projector(), ranks)
}

/// \[M8\] equals `I − J^A⁺ J^A` at every level; the levels' ranks add up as the augmented ranks do.
fn projector_recursion_is_exact<const N: usize>(
    data: &[f64],
    rows: &[usize],
) -> Result<(), TestCaseError> {
    let tasks = random_tasks::<N>(data, rows);
    for k in 0..=tasks.len() {
        let order: Vec<usize> = (0..k).collect();
        let (_, projector, ranks) = solve(&tasks, &order);
        prop_assert!((projector * projector - projector).amax() < 1e-10);
        prop_assert_eq!(projector, projector.transpose());
        // Against the reference when J^A is well conditioned (σ_min ≥ 1e−4, condition ≲ 3e4): near the rank threshold
        // any projector is sensitive (error ~ ε·cond) and two correct SVDs may decide the rank differently.
        let a = augmented(&tasks, k);
        let unambiguous = k == 0 || a.clone().svd(false, false).singular_values.min() >= 1e-4;
        if unambiguous {
            let diff = (to_dense(&projector) - reference_projector::<N>(&a)).amax();
            prop_assert!(diff < 1e-10, "level {k}: |P − P_ref| = {diff:e}");
            prop_assert_eq!(ranks.iter().sum::<usize>(), reference_rank(&a));
        }
    }
    Ok(())
}

/// Adding a lower level leaves `J_i q̇` unchanged for every higher level; compatible levels are achieved exactly.
fn lower_levels_never_disturb_higher<const N: usize>(
    data: &[f64],
    rows: &[usize],
) -> Result<(), TestCaseError> {
    let tasks = random_tasks::<N>(data, rows);
    let total: usize = rows.iter().sum();
    let mut previous: Option<JointVector<N>> = None;
    for k in 1..=tasks.len() {
        let order: Vec<usize> = (0..k).collect();
        let (velocity, _, _) = solve(&tasks, &order);
        prop_assert!(velocity.iter().all(|v| v.is_finite()));
        if let Some(before) = previous {
            // Exact in exact arithmetic; in floating point the residue scales with the size of the new level's step.
            let step = (velocity - before).norm();
            for task in &tasks[..k - 1] {
                let change = (task.jacobian() * (velocity - before)).amax();
                prop_assert!(
                    change < 1e-9 * step.max(1.0),
                    "higher task disturbed by {change:e} (step {step:e})"
                );
            }
        }
        // Compatible stacks (independent rows, Σm ≤ N) are realised exactly. Random stacks are independent almost
        // surely but can be nearly singular, where the rank policy rightly truncates and rounding grows with the
        // velocity: the claim is checked when the augmented Jacobian is well conditioned (smallest singular value
        // ≥ 1e−3, by nalgebra's own SVD), with a tolerance relative to ‖q̇‖.
        let well_conditioned = augmented(&tasks, k).svd(false, false).singular_values.min() >= 1e-3;
        if total <= N && well_conditioned {
            let tolerance = 1e-9 * velocity.norm().max(1.0);
            for task in &tasks[..k] {
                let achieved = task.jacobian() * velocity + task.error() * task.gain();
                prop_assert!(
                    achieved.amax() < tolerance,
                    "task not achieved: {:e}",
                    achieved.amax()
                );
            }
        }
        previous = Some(velocity);
    }
    Ok(())
}

/// The recursion \[M8\] with one SVD per level and nothing else: the reference for the certified paths that skip it.
fn svd_only_recursion<const N: usize>(
    tasks: &[TaskValue<N>],
    order: &[usize],
) -> (JointVector<N>, JointMatrix<N>, Vec<usize>) {
    let policy = RankPolicy::default();
    let mut velocity = JointVector::<N>::zeros();
    let mut projector = JointMatrix::<N>::identity();
    let mut ranks = Vec::new();
    for &index in order {
        let task = &tasks[index];
        let r = -task.error() * task.gain() - task.jacobian() * velocity;
        let mut limited = task.jacobian() * projector;
        let mut svd = ColumnSvd::<N>::default();
        svd.decompose_with_scale(&mut limited, &policy, task.jacobian().norm())
            .unwrap();
        let mut step = JointVector::<N>::zeros();
        svd.solve(&limited, &r, VelocityInverse::Truncated, &mut step)
            .unwrap();
        velocity += step;
        svd.subtract_row_space_projector(&mut projector);
        ranks.push(svd.rank());
    }
    (velocity, projector, ranks)
}

/// Random tasks whose last task's first row is the first task's first row plus `near_repeat` times a fresh row: the
/// last level is conditioned about `1/near_repeat` against the first (1: an ordinary random stack).
fn nearly_repeated_stack<const N: usize>(
    data: &[f64],
    rows: &[usize],
    near_repeat: f64,
) -> Vec<TaskValue<N>> {
    let mut tasks = random_tasks::<N>(data, rows);
    let last = tasks.len() - 1;
    let mut jacobian = tasks[last].jacobian().clone();
    let first_row = tasks[0].jacobian().row(0).into_owned();
    let fresh = jacobian.row(0).into_owned();
    jacobian
        .row_mut(0)
        .copy_from(&(first_row + fresh * near_repeat));
    tasks[last] = TaskValue::from_parts(
        "near repeat",
        tasks[last].error().clone(),
        jacobian,
        tasks[last].gain(),
    )
    .unwrap();
    tasks
}

/// The stack with its closed-form levels of one or two rows (D15) against the SVD at every level, on random stacks and
/// on stacks whose last level nearly repeats a higher one (conditioned from 1 to 10⁸, across the certificate's bound,
/// so both paths and the switch between them are exercised): the same ranks, the same velocity and projector. The
/// level itself agrees with the SVD within 1e−12 (`linalg` tests); through a later ill-conditioned level that
/// rounding grows with the level's conditioning, so the whole stack is compared within a bound that grows with it,
/// which any error of the closed form (a sign, a row, a missed projector update) exceeds by orders of magnitude.
fn closed_form_levels_match_the_svd<const N: usize>(
    data: &[f64],
    rows: &[usize],
    near_repeat: f64,
) -> Result<(), TestCaseError> {
    let tasks = nearly_repeated_stack::<N>(data, rows, near_repeat);
    let order: Vec<usize> = (0..tasks.len()).collect();
    let mut ws = StackWorkspace::new(&tasks);
    let solution = solve_stack(&StackParameters::default(), &mut ws, &tasks, &order).unwrap();
    let (velocity, projector, ranks) = svd_only_recursion(&tasks, &order);
    let levels: Vec<usize> = solution.levels().iter().map(|l| l.rank).collect();
    prop_assert_eq!(&levels, &ranks);
    // Rounding of 1e−16 in a higher level's projector moves a lower level's `J̃⁺` by about 1e−16 ρ², with ρ the largest
    // `‖J_i‖_F / σ_min(J̃_i)` of the stack: the bound scales with it (1e−12 relative for a well-conditioned stack).
    let rho = solution
        .levels()
        .iter()
        .zip(&order)
        .filter_map(|(level, &task)| {
            level
                .smallest_kept_singular_value
                .map(|sigma| tasks[task].jacobian().norm() / sigma)
        })
        .fold(1.0, f64::max);
    let tolerance = 1e-14 * rho * rho;
    let difference = (solution.velocity() - velocity).norm();
    prop_assert!(
        difference <= tolerance * velocity.norm().max(1.0),
        "|q̇ − q̇_svd| = {difference:e}, |q̇| = {:e}, ρ = {rho:e}",
        velocity.norm()
    );
    let projector_difference = (solution.projector() - projector).amax();
    prop_assert!(
        projector_difference <= tolerance,
        "|P − P_svd| = {projector_difference:e}, ρ = {rho:e}"
    );
    // The closed form is taken where it may be: the well-conditioned random stacks have certified small levels.
    if near_repeat == 1.0 {
        prop_assert!(solution.levels().iter().any(|level| level.certified));
    }
    Ok(())
}

/// D30: the stack with the filtered inverse (`floor` relative to each level's scale) against the formula, level by
/// level on a dense SVD (nalgebra's, not the crate's): `q̇ += Σ_{σ_k kept} v_k σ_k (u_kᵀ r) / max(σ_k², ε²)`,
/// `ε = floor · max(σ_max(J̃_i), ‖J_i‖_F)`, the projector truncated as in D2. On the same random and nearly repeated
/// stacks as the closed-form test, so that levels fall on both sides of `ε` and both the certified paths and the SVD
/// answer. The filtered gains are at most `1/ε`, so rounding is amplified by at most `min(ρ, 1/floor)²`.
fn filtered_levels_match_their_formula<const N: usize>(
    data: &[f64],
    rows: &[usize],
    near_repeat: f64,
    floor: f64,
) -> Result<(), TestCaseError> {
    let tasks = nearly_repeated_stack::<N>(data, rows, near_repeat);
    let order: Vec<usize> = (0..tasks.len()).collect();
    let parameters = StackParameters {
        velocity_inverse: VelocityInverse::Filtered { floor },
        ..StackParameters::default()
    };
    let mut ws = StackWorkspace::new(&tasks);
    let solution = solve_stack(&parameters, &mut ws, &tasks, &order).unwrap();
    let mut velocity = DVector::<f64>::zeros(N);
    let mut projector = DMatrix::<f64>::identity(N, N);
    let mut rho: f64 = 1.0;
    for task in &tasks {
        let jacobian = DMatrix::from_fn(task.rows(), N, |i, j| task.jacobian()[(i, j)]);
        let error = DVector::from_fn(task.rows(), |i, _| task.error()[i]);
        let r = -error * task.gain() - &jacobian * &velocity;
        let limited = &jacobian * &projector;
        let svd = limited.clone().svd(true, true);
        let (u, v_t) = (svd.u.unwrap(), svd.v_t.unwrap());
        let reference = svd.singular_values.max().max(jacobian.norm());
        let threshold =
            (RankPolicy::DEFAULT_RELATIVE * reference).max(RankPolicy::DEFAULT_ABSOLUTE);
        let epsilon = floor * reference;
        for (k, &sigma) in svd.singular_values.iter().enumerate() {
            if sigma <= threshold {
                continue;
            }
            let v = v_t.row(k).transpose();
            velocity += &v * (sigma * u.column(k).dot(&r) / (sigma * sigma).max(epsilon * epsilon));
            projector -= &v * v.transpose();
            rho = rho.max(jacobian.norm() / sigma.max(epsilon));
        }
    }
    let computed = DVector::from_column_slice(solution.velocity().as_slice());
    let difference = (&computed - &velocity).norm();
    let tolerance = 1e-13 * rho * rho * velocity.norm().max(1.0);
    prop_assert!(
        difference <= tolerance,
        "|q̇ − q̇_formula| = {difference:e}, |q̇| = {:e}, ρ = {rho:e}",
        velocity.norm()
    );
    Ok(())
}

/// D26: a stack solved with some joints locked (`P^A_0 = I − Σ e_i e_iᵀ`) is the stack of the same tasks whose
/// Jacobians lose the locked columns: the same `q̇_n`, zero on the locked joints, and the same `P^A_n` less the locked
/// directions (which the column-less stack leaves free). The reference goes through the unlocked solver, whose first
/// level reads the Jacobian in place.
fn locked_joints_are_the_stack_without_their_columns<const N: usize>(
    data: &[f64],
    rows: &[usize],
    lock: &[bool],
) -> Result<(), TestCaseError> {
    let tasks = random_tasks::<N>(data, rows);
    let locked: [bool; N] = std::array::from_fn(|i| lock[i]);
    let without_columns: Vec<TaskValue<N>> = tasks
        .iter()
        .map(|task| {
            let mut jacobian = task.jacobian().clone();
            for (joint, _) in locked.iter().enumerate().filter(|(_, &l)| l) {
                jacobian.column_mut(joint).fill(0.0);
            }
            TaskValue::from_parts("t", task.error().clone(), jacobian, task.gain()).unwrap()
        })
        .collect();
    let mut workspace = StackWorkspace::new(&tasks);
    workspace.lock_joints(&locked);
    for k in 1..=tasks.len() {
        // Away from the rank threshold, where two correct solvers may truncate differently.
        let reference_matrix = augmented(&without_columns, k);
        let singular_values = reference_matrix.clone().svd(false, false).singular_values;
        let rank = reference_rank(&reference_matrix);
        if singular_values.iter().any(|&s| s > 1e-9 && s < 1e-3) {
            continue;
        }
        let order: Vec<usize> = (0..k).collect();
        let solution =
            solve_stack(&StackParameters::default(), &mut workspace, &tasks, &order).unwrap();
        let (reference_velocity, reference_projector, _) = solve(&without_columns, &order);
        let tolerance = 1e-9 * reference_velocity.norm().max(1.0);
        prop_assert!(
            (solution.velocity() - reference_velocity).amax() < tolerance,
            "level {k}: q̇_n {} against {}",
            solution.velocity(),
            reference_velocity
        );
        let mut expected_projector = reference_projector;
        for (joint, _) in locked.iter().enumerate().filter(|(_, &l)| l) {
            expected_projector[(joint, joint)] -= 1.0;
        }
        prop_assert!((solution.projector() - expected_projector).amax() < 1e-9);
        for (joint, _) in locked.iter().enumerate().filter(|(_, &l)| l) {
            prop_assert_eq!(solution.velocity()[joint], 0.0);
            prop_assert!(solution.projector().row(joint).amax() < 1e-12);
        }
        let levels_rank: usize = solution.levels().iter().map(|l| l.rank).sum();
        prop_assert_eq!(levels_rank, rank);
        prop_assert_eq!(solution.locked_joints(), &locked);
    }
    Ok(())
}

fn data(len: usize) -> impl Strategy<Value = Vec<f64>> {
    proptest::collection::vec(-1.0..1.0f64, len)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn projector_recursion_n6(d in data(120)) {
        projector_recursion_is_exact::<6>(&d, &[2, 1, 1, 2])?;
        projector_recursion_is_exact::<6>(&d, &[8, 2])?;
        projector_recursion_is_exact::<6>(&d, &[3, 4, 2])?;
    }

    #[test]
    fn projector_recursion_n7(d in data(120)) {
        projector_recursion_is_exact::<7>(&d, &[2, 1, 1, 2])?;
        projector_recursion_is_exact::<7>(&d, &[8, 1])?;
    }

    #[test]
    fn closed_form_levels_n6(d in data(120), exponent in 0.0..8.0f64) {
        let near_repeat = if exponent < 1.0 { 1.0 } else { 10f64.powf(-exponent) };
        closed_form_levels_match_the_svd::<6>(&d, &[2, 1, 1, 2], near_repeat)?;
        closed_form_levels_match_the_svd::<6>(&d, &[1, 2, 1, 1], near_repeat)?;
    }

    #[test]
    fn closed_form_levels_n7(d in data(120), exponent in 0.0..8.0f64) {
        closed_form_levels_match_the_svd::<7>(&d, &[2, 1, 1, 2, 1], 10f64.powf(-exponent))?;
    }

    #[test]
    fn filtered_levels_n6(d in data(120), exponent in 0.0..8.0f64, floor_exponent in 2.0..5.0f64) {
        let near_repeat = if exponent < 1.0 { 1.0 } else { 10f64.powf(-exponent) };
        let floor = 10f64.powf(-floor_exponent);
        filtered_levels_match_their_formula::<6>(&d, &[2, 1, 1, 2], near_repeat, floor)?;
        filtered_levels_match_their_formula::<6>(&d, &[1, 2, 1, 1], near_repeat, floor)?;
        filtered_levels_match_their_formula::<6>(&d, &[8, 2], near_repeat, floor)?;
    }

    #[test]
    fn filtered_levels_n7(d in data(120), exponent in 0.0..8.0f64, floor_exponent in 2.0..5.0f64) {
        filtered_levels_match_their_formula::<7>(&d, &[2, 1, 1, 2, 1], 10f64.powf(-exponent), 10f64.powf(-floor_exponent))?;
    }

    #[test]
    fn locked_joints_n6(d in data(120), lock in proptest::collection::vec(proptest::bool::weighted(0.3), 6)) {
        locked_joints_are_the_stack_without_their_columns::<6>(&d, &[2, 1, 1, 2], &lock)?;
        locked_joints_are_the_stack_without_their_columns::<6>(&d, &[8, 2], &lock)?;
    }

    #[test]
    fn locked_joints_n7(d in data(120), lock in proptest::collection::vec(proptest::bool::weighted(0.3), 7)) {
        locked_joints_are_the_stack_without_their_columns::<7>(&d, &[2, 1, 1, 2, 1], &lock)?;
        locked_joints_are_the_stack_without_their_columns::<7>(&d, &[3, 3], &lock)?;
    }

    #[test]
    fn priority_n6(d in data(120)) {
        lower_levels_never_disturb_higher::<6>(&d, &[2, 1, 1, 2])?;
        lower_levels_never_disturb_higher::<6>(&d, &[2, 3, 2, 4])?;
    }

    #[test]
    fn priority_n7(d in data(120)) {
        lower_levels_never_disturb_higher::<7>(&d, &[2, 1, 1, 2, 1])?;
        lower_levels_never_disturb_higher::<7>(&d, &[8, 2])?;
    }

    /// Conflicting stacks: level 2 repeats a combination of level 1's rows plus one new row, level 3 lies entirely in
    /// the row space of levels 1–2. Ranks must be (2, 1, 0), the velocity finite, and level 1 still exact.
    #[test]
    fn conflicting_stack_has_right_ranks(d in data(60), mix in data(4)) {
        let base = random_tasks::<6>(&d, &[2, 1]);
        let j1 = base[0].jacobian().clone();
        let fresh = base[1].jacobian().clone();
        let mut j2 = TaskJacobian::<6>::zeros(2);
        j2.row_mut(0).copy_from(&(j1.row(0) * mix[0] + j1.row(1) * mix[1]));
        j2.row_mut(1).copy_from(&fresh.row(0));
        let mut j3 = TaskJacobian::<6>::zeros(1);
        j3.row_mut(0).copy_from(&(j1.row(0) * mix[2] + fresh.row(0) * mix[3]));
        let tasks = vec![
            base[0].clone(),
            TaskValue::from_parts("t2", DVector::from_vec(vec![0.3, -0.2]), j2, 1.0).unwrap(),
            TaskValue::from_parts("t3", DVector::from_vec(vec![0.5]), j3, 1.0).unwrap(),
        ];
        let mut ws = StackWorkspace::new(&tasks);
        let solution = solve_stack(&StackParameters::default(), &mut ws, &tasks, &[0, 1, 2]).unwrap();
        let ranks: Vec<usize> = solution.levels().iter().map(|l| l.rank).collect();
        prop_assert_eq!(ranks, vec![2, 1, 0]);
        prop_assert!(solution.levels()[0].fully_achievable);
        prop_assert!(!solution.levels()[1].fully_achievable);
        prop_assert!(!solution.levels()[2].fully_achievable);
        prop_assert!(solution.velocity().iter().all(|v| v.is_finite()));
        let level1 = tasks[0].jacobian() * solution.velocity() + tasks[0].error() * tasks[0].gain();
        prop_assert!(level1.amax() < 1e-9);
    }
}

/// Limits around `center` such that every joint sits in an activation band (upper or lower, alternating).
fn active_limits<const N: usize>(center: &JointVector<N>) -> JointLimits<N> {
    let offset = JointVector::<N>::from_fn(|i, _| if i % 2 == 0 { 0.85 } else { 0.15 });
    JointLimits::new(
        center - offset,
        center - offset + JointVector::repeat(1.0),
        0.3,
    )
    .unwrap()
}

/// A random sequence of pushes and removals while integrating `q`. At every change, `q̇(τ⁺) = q̇(τ⁻)`.
fn continuity_at_every_change<const N: usize>(
    d: &[f64],
    rows: &[usize],
    switches: &[(usize, bool)],
    with_avoidance: bool,
) -> Result<(), TestCaseError> {
    let tasks = random_tasks::<N>(d, rows);
    let limits = active_limits(&JointVector::<N>::zeros());
    let cost: Option<&dyn Cost<N>> = if with_avoidance { Some(&limits) } else { None };
    let law = ControlLaw::with_default_transition(&tasks, 0.8).unwrap();
    let mut ws = ControlWorkspace::new(&tasks);
    let dt = 0.01;
    let mut q = JointVector::<N>::zeros();
    let mut order: Vec<usize> = Vec::with_capacity(tasks.len());
    let mut previous = JointVector::<N>::zeros();
    let mut changes = 0;
    for step in 0..400usize {
        let time = step as f64 * dt;
        let mut change = if step == 0 {
            StackChange::Changed
        } else {
            StackChange::Unchanged
        };
        // Two pushes at fixed steps guarantee changes on top of the random ones.
        let forced = (step == 40 || step == 80).then_some(true);
        let random = switches
            .iter()
            .find(|(at, _)| *at == step)
            .map(|&(_, push)| push);
        if let Some(push) = forced.or(random) {
            // Push a task not stacked yet (after a removal, `order.len()` may be one that is).
            let next = (0..tasks.len()).find(|t| !order.contains(t));
            if let (true, Some(next)) = (push, next) {
                order.push(next);
                change = StackChange::Changed;
            } else if !push && !order.is_empty() {
                order.remove(step % order.len());
                change = StackChange::Changed;
            }
        }
        let out = control_step(&law, &mut ws, &tasks, &order, cost, &q, time, change).unwrap();
        let velocity = *out.velocity();
        prop_assert!(velocity.iter().all(|v| v.is_finite()));
        if change == StackChange::Changed {
            changes += 1;
            let jump = (velocity - previous).norm();
            prop_assert!(jump <= 1e-12, "jump {jump:e} at step {step}");
        }
        q += velocity * dt;
        previous = velocity;
    }
    prop_assert!(changes >= 3);
    Ok(())
}

fn switch_times() -> impl Strategy<Value = Vec<(usize, bool)>> {
    proptest::collection::vec((1usize..400, proptest::bool::weighted(0.65)), 3..10)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn continuity_n6(d in data(120), switches in switch_times(), with_avoidance: bool) {
        continuity_at_every_change::<6>(&d, &[2, 1, 1, 2], &switches, with_avoidance)?;
    }

    #[test]
    fn continuity_n7(d in data(120), switches in switch_times(), with_avoidance: bool) {
        continuity_at_every_change::<7>(&d, &[2, 1, 8, 2], &switches, with_avoidance)?;
    }

    /// The avoidance term lives in the kernel of every stacked task: `J_i P^A_n ∇h = 0`.
    #[test]
    fn avoidance_leaves_stacked_tasks_untouched(d in data(120), s in data(7)) {
        let tasks = random_tasks::<7>(&d, &[2, 1, 1]);
        let q = JointVector::<7>::from_column_slice(&s) * 0.1; // inside every activation band
        let limits = active_limits(&JointVector::<7>::zeros());
        let mut gradient = JointVector::<7>::zeros();
        limits.value_and_gradient(&q, &mut gradient).unwrap();
        prop_assert!(gradient.norm() > 0.0);
        let (_, projector, _) = solve(&tasks, &[0, 1, 2]);
        for task in &tasks {
            let disturbance = (task.jacobian() * projector * gradient).amax();
            prop_assert!(disturbance < 1e-12, "J P ∇h = {disturbance:e}");
        }
    }
}

/// After a switch with a constant law, `q̇(t) − u = e^{−μ(t−τ)} (q̇(τ⁻) − u(τ))`.
#[test]
fn transition_decays_exponentially() {
    let j = OMatrix::<f64, Dyn, nalgebra::Const<6>>::from_fn(2, |i, k| ((i * 6 + k) as f64).cos());
    let tasks = [TaskValue::from_parts("c", DVector::from_vec(vec![0.4, -0.1]), j, 0.5).unwrap()];
    let law = ControlLaw::new(5.0, 0.0).unwrap();
    let mut ws = ControlWorkspace::new(&tasks);
    let q = JointVector::<6>::zeros();
    let kick = JointVector::<6>::from_fn(|i, _| 0.1 * i as f64 - 0.2);
    ws.reset(&kick);
    let start = 1.5;
    step_first_task(&law, &mut ws, &tasks, &q, start, StackChange::Changed).unwrap();
    for dt in [0.01, 0.1, 0.3, 1.0] {
        let out = step_first_task(
            &law,
            &mut ws,
            &tasks,
            &q,
            start + dt,
            StackChange::Unchanged,
        )
        .unwrap();
        let expected = (kick - out.law()) * (-5.0 * dt).exp();
        assert!((out.velocity() - out.law() - expected).amax() < 1e-14);
        assert!((out.decay() - (-5.0 * dt).exp()).abs() < 1e-15);
    }
}
