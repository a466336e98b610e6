//! The hierarchical QP cascade (theory §14): the stack's velocity when no bound is active, through the closed form and
//! through the QP alone; with bounds active, every joint inside its box and each level's residual the least any
//! velocity in the box allows while keeping the levels above, against a brute-force enumeration of active sets;
//! continuity of the law at a stack change; clear errors for bad input; and the method on the limit scenarios.

use nalgebra::{DMatrix, DVector, Vector3};
use proptest::prelude::*;
use servostack::law::hqp::{
    solve_hqp, HqpError, HqpParameters, HqpSolution, HqpWorkspace, LevelSolve,
};
use servostack::law::sns::{SnsBounds, SnsError};
use servostack::law::{ControlWorkspace, LawError};
use servostack::linalg::VelocityInverse;
use servostack::math::JointVector;
use servostack::scenario::{RunKind, Scenario};
use servostack::sim::Outcome;
use servostack::stack::{solve_stack, StackParameters, StackWorkspace};
use servostack::task::TaskValue;

use crate::law_fixture::{
    limits3, one_row_and_full_rank_tasks, one_row_task, step_across_a_stack_change,
    visp_projection_step_error,
};
use crate::stack_properties::random_tasks;

fn hqp<const N: usize>(
    parameters: &HqpParameters,
    tasks: &[TaskValue<N>],
    target: Option<&JointVector<N>>,
    lower: &JointVector<N>,
    upper: &JointVector<N>,
) -> HqpSolution<N> {
    let max_rows = tasks.iter().map(TaskValue::rows).max().unwrap_or(1);
    let mut workspace = HqpWorkspace::with_capacity(max_rows, tasks.len(), parameters).unwrap();
    let order: Vec<usize> = (0..tasks.len()).collect();
    solve_hqp(
        &StackParameters::default(),
        &mut workspace,
        tasks,
        &order,
        target,
        lower,
        upper,
    )
    .unwrap()
    .clone()
}

/// The QP alone at every level: the solver is called even when the closed form fits.
fn qp_only() -> HqpParameters {
    HqpParameters {
        closed_form_first: false,
        ..HqpParameters::default()
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, failure_persistence: None, ..ProptestConfig::default() })]

    /// A box ten times wider than the stack's velocity (and at least 1): the cascade is the stack plus `P^A_n q̇*`, to
    /// 1e−9 relative, both with the closed form first (no QP called) and with the QP alone at every level.
    #[test]
    fn without_active_bounds_the_cascade_is_the_stack(
        data in proptest::collection::vec(-1.0f64..1.0, 60),
        target in proptest::collection::vec(-1.0f64..1.0, 6),
        full in proptest::bool::ANY,
    ) {
        // Four rows leave two directions to the joint-space target; six leave none.
        let rows: &[usize] = if full { &[2, 1, 1, 2] } else { &[2, 1, 1] };
        let tasks = random_tasks::<6>(&data, rows);
        let order: Vec<usize> = (0..rows.len()).collect();
        let mut stack = StackWorkspace::new(&tasks);
        let solution = solve_stack(&StackParameters::default(), &mut stack, &tasks, &order).unwrap();
        let target = JointVector::<6>::from_column_slice(&target);
        for joint_target in [None, Some(&target)] {
            let expected = solution.velocity() + joint_target.map_or(JointVector::zeros(), |t| solution.projector() * t);
            let scale = expected.amax().max(1.0);
            let wide = JointVector::<6>::repeat(10.0 * scale);
            for parameters in [HqpParameters::default(), qp_only()] {
                let result = hqp(&parameters, &tasks, joint_target, &(-wide), &wide);
                let error = (result.velocity() - expected).amax() / scale;
                prop_assert!(error < 1e-9, "closed form first: {}, error {error:e}: {} vs {expected}", parameters.closed_form_first, result.velocity());
                prop_assert_eq!(result.clamped(), 0.0);
                let closed = result.levels().iter().filter(|l| l.solve == LevelSolve::ClosedForm).count();
                if parameters.closed_form_first {
                    prop_assert_eq!(closed, result.levels().len());
                }
            }
        }
    }

    /// A box around zero, often active, on four joints: no joint leaves it, and each level's residual is the least any
    /// velocity in the box allows while keeping the levels above at the optimum the reference found for them
    /// ([`reference_cascade`], by enumeration of active sets).
    #[test]
    fn with_active_bounds_each_level_is_optimal_and_no_joint_leaves_its_box(
        data in proptest::collection::vec(-1.0f64..1.0, 30),
        box_data in proptest::collection::vec(0.05f64..0.6, 8),
        target in proptest::collection::vec(-0.5f64..0.5, 4),
        two_rows_first in proptest::bool::ANY,
    ) {
        let rows: &[usize] = if two_rows_first { &[2, 1] } else { &[1, 1] };
        let tasks = random_tasks::<4>(&data, rows);
        let lower = JointVector::<4>::from_fn(|i, _| -box_data[i]);
        let upper = JointVector::<4>::from_fn(|i, _| box_data[4 + i]);
        let target = JointVector::<4>::from_column_slice(&target);
        let mut levels: Vec<(DMatrix<f64>, DVector<f64>)> = tasks
            .iter()
            .map(|t| (DMatrix::from_fn(t.rows(), 4, |i, j| t.jacobian()[(i, j)]), -t.error() * t.gain()))
            .collect();
        levels.push((DMatrix::identity(4, 4), DVector::from_column_slice(target.as_slice())));
        let reference = reference_cascade(&levels, lower.as_slice(), upper.as_slice());
        for parameters in [HqpParameters::default(), qp_only()] {
            let result = hqp(&parameters, &tasks, Some(&target), &lower, &upper);
            let v = result.velocity();
            prop_assert!((0..4).all(|i| lower[i] <= v[i] && v[i] <= upper[i]), "{v}");
            prop_assert!(result.clamped() < 1e-8, "clamped by {}", result.clamped());
            let x = DVector::from_column_slice(v.as_slice());
            for (k, ((j, desired), (optimum, image))) in levels.iter().zip(&reference).enumerate() {
                let residual = (j * &x - desired).norm_squared();
                // Never worse than the lexicographic optimum. It may be lower by what the levels above are allowed
                // to miss their own optimum (their images within 1e−6, checked below): a lower level gains from
                // that slack at first order (seen: 1.1e−7 below the reference on level 1).
                prop_assert!(residual < optimum + 1e-7, "level {k}: residual² {residual}, least {optimum}");
                prop_assert!(residual > optimum - 1e-6, "level {k}: residual² {residual} below the least {optimum}");
                prop_assert!((j * &x - image).amax() < 1e-6, "level {k}: J q̇ = {} , reference {image}", j * &x);
            }
        }
    }
}

/// The lexicographic optimum by brute force, for a few joints: per level `(J_k, ẋ_k)`, the least `‖J_k q̇ − ẋ_k‖²`
/// over the velocities in the box `[lower, upper]` that keep `J_j q̇ = w_j` for the levels above, and the image
/// `w_k = J_k q̇` of an optimum. Each choice of every joint free, at its lower or at its upper bound gives an affine set;
/// the minimiser of least norm of the level's residual on it is a candidate, kept if it lies in the box. The least
/// candidate is the optimum: a vertex of the (bounded) set of optima is the unique minimiser on the affine set of its
/// own active bounds, so it is among the candidates, and every candidate in the box is feasible.
fn reference_cascade(
    levels: &[(DMatrix<f64>, DVector<f64>)],
    lower: &[f64],
    upper: &[f64],
) -> Vec<(f64, DVector<f64>)> {
    let n = lower.len();
    let mut kept: Vec<(DVector<f64>, f64)> = Vec::new();
    let mut out = Vec::new();
    for (j, desired) in levels {
        let mut best: Option<(f64, DVector<f64>)> = None;
        for code in 0..3usize.pow(n as u32) {
            let digit = |i: usize| (code / 3usize.pow(i as u32)) % 3;
            let mut rows: Vec<(DVector<f64>, f64)> = kept.clone();
            for i in 0..n {
                let bound = match digit(i) {
                    0 => continue,
                    1 => lower[i],
                    _ => upper[i],
                };
                rows.push((
                    DVector::from_fn(n, |c, _| f64::from(u8::from(c == i))),
                    bound,
                ));
            }
            let Some(x) = least_norm_on_affine(&rows, j, desired, n) else {
                continue;
            };
            if (0..n).all(|i| x[i] >= lower[i] - 1e-10 && x[i] <= upper[i] + 1e-10) {
                let value = (j * &x - desired).norm_squared();
                if best.as_ref().is_none_or(|(b, _)| value < *b) {
                    best = Some((value, x));
                }
            }
        }
        let (value, x) =
            best.expect("the box is never empty and contains the optima of the levels above");
        let image = j * &x;
        for r in 0..j.nrows() {
            kept.push((j.row(r).transpose(), image[r]));
        }
        out.push((value, image));
    }
    out
}

/// The minimiser of least norm of `‖J x − ẋ‖²` on `{x : aᵢᵀ x = bᵢ}` (nalgebra's SVD), or `None` when those equations
/// are inconsistent.
fn least_norm_on_affine(
    rows: &[(DVector<f64>, f64)],
    j: &DMatrix<f64>,
    desired: &DVector<f64>,
    n: usize,
) -> Option<DVector<f64>> {
    let (particular, basis) = if rows.is_empty() {
        (DVector::zeros(n), DMatrix::identity(n, n))
    } else {
        let a = DMatrix::from_fn(rows.len(), n, |r, c| rows[r].0[c]);
        let b = DVector::from_fn(rows.len(), |r, _| rows[r].1);
        let svd = a.clone().svd(true, true);
        let threshold = 1e-9 * svd.singular_values.max().max(1.0);
        let particular = svd.solve(&b, threshold).ok()?;
        if (&a * &particular - &b).amax() > 1e-9 {
            return None;
        }
        // The null space of a: the right singular vectors beyond its rank (completed to n by a square padding).
        let mut padded = DMatrix::zeros(rows.len().max(n), n);
        padded.rows_mut(0, rows.len()).copy_from(&a);
        let full = padded.svd(false, true);
        let v_t = full.v_t?;
        let null: Vec<DVector<f64>> = (0..n)
            .filter(|&k| full.singular_values[k] <= threshold)
            .map(|k| v_t.row(k).transpose())
            .collect();
        let basis = if null.is_empty() {
            DMatrix::zeros(n, 0)
        } else {
            DMatrix::from_columns(&null)
        };
        (particular, basis)
    };
    if basis.ncols() == 0 {
        return Some(particular);
    }
    let limited = j * &basis;
    let step = limited.pseudo_inverse(1e-9).ok()? * (desired - j * &particular);
    Some(particular + basis * step)
}

/// With a full-rank task pushing the joints out of a tight box, the cascade keeps every velocity sent in the box and
/// the stack change continuous: `q̇(τ⁺) = q̇(τ⁻)` when the last velocity lies in the box.
#[test]
fn the_cascade_law_is_continuous_at_a_stack_change_and_stays_in_its_box() {
    let tasks = one_row_and_full_rank_tasks();
    let mut workspace = ControlWorkspace::new(&tasks);
    let max = 0.1;
    let bounds = SnsBounds::new(limits3(), Vector3::repeat(max), 0.01).unwrap();
    workspace
        .solve_as_hierarchical_qp(bounds, &HqpParameters::default())
        .unwrap();
    step_across_a_stack_change(&mut workspace, &tasks, max);
    let solution = workspace.hqp_solution().unwrap();
    // The full-rank task asks 0.45 on joint 0 alone: the box makes its level a QP, whose least residual is not zero.
    let levels = solution.levels();
    assert_eq!(levels.len(), 3);
    assert!(
        matches!(levels[1].solve, LevelSolve::Qp { .. }),
        "{levels:?}"
    );
    assert!(levels[1].residual > 1e-3, "{levels:?}");
}

/// A QP the solver stops short of (here its iteration budget of one) leaves the level at the velocity of the levels
/// above: inside the box, and the run goes on. With the default budget the same level is solved and meets its bound.
#[test]
fn a_qp_not_solved_keeps_the_levels_above() {
    let task = one_row_task("x", -0.45, [1.0, 0.0, 0.0]);
    let tasks = [task];
    let (lower, upper) = (Vector3::repeat(-0.1), Vector3::repeat(0.1));
    let solve = |parameters: HqpParameters| {
        let mut workspace = HqpWorkspace::with_capacity(1, 1, &parameters).unwrap();
        solve_hqp(
            &StackParameters::default(),
            &mut workspace,
            &tasks,
            &[0],
            None,
            &lower,
            &upper,
        )
        .unwrap()
        .clone()
    };
    let short = solve(HqpParameters {
        max_iterations: 1,
        ..HqpParameters::default()
    });
    assert!(
        matches!(short.levels()[0].solve, LevelSolve::Kept { .. }),
        "{:?}",
        short.levels()
    );
    assert_eq!(*short.velocity(), Vector3::zeros());
    let solved = solve(HqpParameters::default());
    assert!(matches!(solved.levels()[0].solve, LevelSolve::Qp { .. }));
    assert!(
        (solved.velocity()[0] - 0.1).abs() < 1e-8,
        "{}",
        solved.velocity()
    );
}

#[test]
fn bad_parameters_and_inputs_are_clear_errors() {
    for tolerance in [0.0, 1e-15, 1e-2, f64::NAN, f64::INFINITY] {
        let parameters = HqpParameters {
            tolerance,
            ..HqpParameters::default()
        };
        let err = HqpWorkspace::<3>::with_capacity(1, 1, &parameters).unwrap_err();
        assert!(matches!(err, HqpError::InvalidTolerance { .. }), "{err}");
    }
    let parameters = HqpParameters {
        max_iterations: 0,
        ..HqpParameters::default()
    };
    let err = HqpWorkspace::<3>::with_capacity(1, 1, &parameters).unwrap_err();
    assert_eq!(err, HqpError::NoIterations);
    let task = one_row_task("x", 0.2, [1.0, 0.0, 0.0]);
    let tasks = [task];
    let mut workspace = HqpWorkspace::with_capacity(1, 1, &HqpParameters::default()).unwrap();
    let parameters = StackParameters::default();
    let (lower, upper) = (Vector3::new(-1.0, 0.5, -1.0), Vector3::new(1.0, 0.2, 1.0));
    let err = solve_hqp(
        &parameters,
        &mut workspace,
        &tasks,
        &[0],
        None,
        &lower,
        &upper,
    )
    .unwrap_err();
    assert!(
        matches!(err, HqpError::Bounds(SnsError::InvalidBox { joint: 1, .. })),
        "{err}"
    );
    let filtered = StackParameters {
        velocity_inverse: VelocityInverse::Filtered { floor: 3e-4 },
        ..StackParameters::default()
    };
    let err = solve_hqp(
        &filtered,
        &mut workspace,
        &tasks,
        &[0],
        None,
        &-upper.abs(),
        &upper.abs(),
    )
    .unwrap_err();
    assert_eq!(err, HqpError::FilteredInverse);
    let target = Vector3::new(0.0, f64::NAN, 0.0);
    let err = solve_hqp(
        &parameters,
        &mut workspace,
        &tasks,
        &[0],
        Some(&target),
        &-upper.abs(),
        &upper.abs(),
    )
    .unwrap_err();
    assert!(
        matches!(
            err,
            HqpError::Bounds(SnsError::NonFiniteJointValue { joint: 1, .. })
        ),
        "{err}"
    );
    let err = solve_hqp(
        &parameters,
        &mut workspace,
        &tasks,
        &[3],
        None,
        &-upper.abs(),
        &upper.abs(),
    )
    .unwrap_err();
    assert!(matches!(err, HqpError::Stack(_)), "{err}");
    // The law with the cascade and a projection it has no counterpart for.
    let mut control = ControlWorkspace::new(&tasks);
    let bounds = SnsBounds::new(limits3(), Vector3::repeat(1.0), 0.01).unwrap();
    control
        .solve_as_hierarchical_qp(bounds, &HqpParameters::default())
        .unwrap();
    let err = visp_projection_step_error(&mut control, &tasks);
    assert_eq!(err, LawError::HqpNeedsKernelProjection);
}

/// The cascade as a method of the scenarios, on the two suite scenarios where the classical law ends on a joint limit
/// (the paper scene among them): no run ends on a limit, every configuration stays inside the limits and every velocity
/// sent within the robot's velocity limits.
#[test]
fn hqp_runs_of_the_limit_scenarios_never_pass_a_bound() {
    assert_eq!(RunKind::from_name("hqp"), Some(RunKind::Hqp));
    let assets = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenarios"));
    for file in ["ur5e_limits.toml", "paper_afma6.toml"] {
        let scenario = Scenario::from_file(assets.join(file)).unwrap();
        let run = scenario.run::<6>(RunKind::Hqp).unwrap();
        assert!(
            !matches!(run.outcome, Outcome::JointLimit { .. }),
            "{file}: {:?}",
            run.outcome
        );
        let experiment = scenario.experiment::<6>().unwrap();
        let limits = experiment.scene.limits().clone();
        let joints = experiment.scene.chain().joints();
        let simulation = &scenario.simulation;
        for record in &run.records {
            let normalized = limits.normalized(&record.q);
            assert!(
                normalized.iter().all(|&s| (0.0..=1.0).contains(&s)),
                "{file}, iteration {}: {normalized}",
                record.iteration
            );
        }
        for record in &run.records {
            for (joint, &v) in joints.iter().zip(record.velocity.iter()) {
                let max = if joint.kind().is_rotational() {
                    simulation.max_revolute_velocity_rad_s
                } else {
                    simulation.max_prismatic_velocity_m_s
                };
                assert!(
                    v.abs() <= max,
                    "{file}, iteration {}: {}",
                    record.iteration,
                    record.velocity
                );
            }
        }
    }
}

/// The closed-form levels allocate nothing (what the module docs say): a cascade with no bound active, after a first
/// solve that warms the workspace, makes no heap allocation; one with an active bound does (the QP's).
#[test]
fn a_cascade_without_an_active_bound_allocates_nothing() {
    let data: Vec<f64> = (0..60)
        .map(|i| ((i * 37 % 23) as f64 / 11.5) - 1.0)
        .collect();
    let tasks = random_tasks::<6>(&data, &[2, 1, 1]);
    let target = JointVector::<6>::repeat(0.1);
    let mut workspace = HqpWorkspace::with_capacity(2, 3, &HqpParameters::default()).unwrap();
    let parameters = StackParameters::default();
    let wide = JointVector::<6>::repeat(1e3);
    let mut solve = |lower: &JointVector<6>, upper: &JointVector<6>| {
        solve_hqp(
            &parameters,
            &mut workspace,
            &tasks,
            &[0, 1, 2],
            Some(&target),
            lower,
            upper,
        )
        .unwrap()
        .levels()
        .iter()
        .any(|l| matches!(l.solve, LevelSolve::Qp { .. }))
    };
    assert!(!solve(&-wide, &wide));
    let allocations = crate::counting_allocator::allocations_during(|| {
        assert!(!solve(&-wide, &wide));
    });
    assert_eq!(allocations, 0);
    let tight = JointVector::<6>::repeat(1e-3);
    let allocations = crate::counting_allocator::allocations_during(|| {
        assert!(solve(&-tight, &tight));
    });
    assert!(allocations > 0);
}
