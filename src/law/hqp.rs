//! The hierarchical QP cascade: the task stack as lexicographic least squares under hard joint bounds
//! ([theory §14](crate::theory#s14); Kanoun, Lamiraux & Wieber, *Kinematic control of redundant manipulators:
//! generalizing the task-priority framework to inequality task*, IEEE T-RO 27(4), 2011; the form of OpenSoT, TSID and
//! the Stack of Tasks).
//!
//! The hard constraints are the box `[q̇^lo, q̇^hi]` of
//! [`SnsBounds::velocity_box`](super::sns::SnsBounds::velocity_box), the same as SNS's: joint positions
//! `q_min ≤ q + q̇ Δt ≤ q_max` and velocity limits (and acceleration limits when given). Below them, level `k` (the
//! tasks in stack order, then the joint-space target `J = I` with `ẋ = q̇*`, the law's avoidance term `−κ∇h`, or
//! `q̇* = 0` without one) solves
//!
//! ```text
//! q̇*_k = argmin ‖J_k q̇ − ẋ_k‖² + δ² ‖q̇ − q̇*_{k−1}‖²     ẋ_k = −λ_k e_k
//!         s.t.  q̇^lo ≤ q̇ ≤ q̇^hi,   J_j q̇ = J_j q̇*_j  for every j < k
//! ```
//!
//! (`δ` the stack's damping, [`VelocityInverse::Damped`], `0` for the truncated inverse). The equalities that keep
//! the levels above are eliminated rather than handed to the solver: `q̇ = q̇*_{k−1} + Z_{k−1} z` with `Z_{k−1}` an
//! orthonormal basis of the range of the stack's projector `P_{k−1}` ([\[M8\]](crate::theory#m8), its rank
//! decisions), so the QP of level `k` has `r = rank P_{k−1}` variables and the box as its only constraints:
//!
//! ```text
//! min_z ½ zᵀ (Z̃ᵀZ̃ + δ² I) z + zᵀ Z̃ᵀ (J_k q̇*_{k−1} − ẋ_k)      Z̃ = J_k Z_{k−1}
//! s.t.  Z_{k−1} z ≤ q̇^hi − q̇*_{k−1},   −Z_{k−1} z ≤ q̇*_{k−1} − q̇^lo     (rows of infinite bounds left out)
//! ```
//!
//! solved by Clarabel (an interior-point solver, [`HqpParameters::tolerance`]). Keeping `J_j q̇` exactly (to rounding)
//! instead of to the solver's tolerance is what makes the cascade agree with the stack to `10⁻⁹` and more. The joints
//! whose bound a level's optimum presses on (a positive multiplier) sit on it at every optimum of that level: the
//! levels below hold them there (their directions leave `P_k`), so that the next QP's feasible set keeps an interior
//! for the solver.
//!
//! First, unless [`HqpParameters::closed_form_first`] is off, each level tries the stack's own step
//! `q̇*_{k−1} + (J_k P_{k−1})⁺ (ẋ_k − J_k q̇*_{k−1})` (the unconstrained minimiser in `z`, as the stack inverts it): when
//! it lies in the box it is an optimum of the QP and the solver is not called. With no bound active the cascade is
//! therefore the stack law `q̇_n + P_n q̇*` ([\[M14\]](crate::theory#m14)) exactly; the QP itself agrees with it to the
//! solver's accuracy (`tests/suite/hqp.rs`). The result is clamped into the box last, which changes it by the solver's
//! tolerance at most unless no velocity of the levels could stay inside (`q` already past a limit).
//!
//! Allocation: the closed-form levels allocate nothing; each QP allocates (Clarabel's problem data and factorisation
//! are built per solve).

use super::sns::{
    check_box_and_target, joint_target_terms, task_of, task_terms, widened, workspace_buffers,
    BoxSolver, BoxedLaw, Level, SnsError,
};
use crate::linalg::{symmetrize, ColumnSvd, RankPolicy, VelocityInverse};
use crate::math::{JointMatrix, JointVector};
use crate::stack::{check_order, checked_task, StackError, StackParameters};
use crate::task::{TaskJacobian, TaskValue};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use nalgebra::{DMatrix, DVector};

/// Errors of the QP cascade.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HqpError {
    /// The solver tolerance must be finite, within `[1e-14, 1e-3]`.
    #[error("QP tolerance {tolerance} must be finite, within [1e-14, 1e-3]")]
    InvalidTolerance {
        /// The tolerance given.
        tolerance: f64,
    },
    /// The iteration budget of the solver must be at least 1.
    #[error("the QP solver needs at least one iteration")]
    NoIterations,
    /// The box or the joint-space target is invalid (the same checks as SNS's).
    #[error(transparent)]
    Bounds(#[from] SnsError),
    /// The task stack is invalid (unknown or repeated task, non-finite task data, capacity) or its algebra failed.
    #[error(transparent)]
    Stack(#[from] StackError),
    /// The filtered inverse of D30 has no QP form (its damping depends on each singular value): the cascade takes the
    /// truncated or the damped inverse.
    #[error(
        "the QP cascade takes the truncated or the damped inverse, not the filtered one (D30)"
    )]
    FilteredInverse,
    /// Clarabel could not set up the QP of a level, or its solution was not finite. (A QP it stops short of solving
    /// leaves the level at the velocity of the levels above: [`LevelSolve::Kept`].)
    #[error("the QP of level {level} was not solved: {status} after {iterations} iterations")]
    Solver {
        /// The level (0-based; the number of tasks for the joint-space target).
        level: usize,
        /// Clarabel's status, as it prints it.
        status: String,
        /// The iterations it made.
        iterations: u32,
    },
}

/// The solver settings of the cascade.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HqpParameters {
    /// Clarabel's tolerances (absolute and relative duality gap, feasibility); its reduced tolerances, which an
    /// *almost solved* status meets, are `√tolerance`, at most `10⁻⁵`.
    pub tolerance: f64,
    /// The iteration budget of each QP.
    pub max_iterations: u32,
    /// Whether a level first tries the stack's closed-form step and calls the solver only when it leaves the box.
    pub closed_form_first: bool,
}

impl Default for HqpParameters {
    /// Tolerance `10⁻¹¹` (the QP then agrees with the stack to about `10⁻¹⁰` with no bound active; at `10⁻¹⁰`, to
    /// `10⁻⁸`), 50 iterations (the QPs of `benches/hqp.rs` take 6 to 10), closed form first.
    fn default() -> Self {
        Self {
            tolerance: 1e-11,
            max_iterations: 50,
            closed_form_first: true,
        }
    }
}

impl HqpParameters {
    /// Checks the tolerance and the budget.
    ///
    /// # Errors
    /// [`HqpError::InvalidTolerance`], [`HqpError::NoIterations`].
    pub fn validate(&self) -> Result<(), HqpError> {
        if !(1e-14..=1e-3).contains(&self.tolerance) {
            return Err(HqpError::InvalidTolerance {
                tolerance: self.tolerance,
            });
        }
        if self.max_iterations == 0 {
            return Err(HqpError::NoIterations);
        }
        Ok(())
    }

    fn settings(&self) -> DefaultSettings<f64> {
        let reduced = self.tolerance.sqrt().min(1e-5);
        DefaultSettingsBuilder::default()
            .verbose(false)
            .max_iter(self.max_iterations)
            .tol_gap_abs(self.tolerance)
            .tol_gap_rel(self.tolerance)
            .tol_feas(self.tolerance)
            .reduced_tol_gap_abs(reduced)
            .reduced_tol_gap_rel(reduced)
            .reduced_tol_feas(reduced)
            .build()
            .unwrap_or_default()
    }
}

/// How a level of the cascade was solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LevelSolve {
    /// The stack's closed-form step lay in the box (or the levels above left no freedom).
    ClosedForm,
    /// By the QP.
    Qp {
        /// Clarabel's iterations.
        iterations: u32,
    },
    /// The QP was not solved (Clarabel stopped short of its reduced tolerances: insufficient progress, its iteration
    /// budget): the level keeps `q̇*_{k−1}`, the velocity of the levels above, which lies in the box and keeps their
    /// optima. A control loop goes on with a velocity that serves every level above; this level is not improved.
    Kept {
        /// Clarabel's iterations.
        iterations: u32,
    },
}

/// One level of a cascade solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HqpLevel {
    /// The task index at this level; `None` for the joint-space target.
    pub task: Option<usize>,
    /// How it was solved.
    pub solve: LevelSolve,
    /// Its residual `‖J_k q̇*_k − ẋ_k‖` (`‖q̇ − q̇*‖` for the joint-space target), which the levels below keep.
    pub residual: f64,
}

/// The result of [`solve_hqp`].
#[derive(Debug, Clone, PartialEq)]
pub struct HqpSolution<const N: usize> {
    velocity: JointVector<N>,
    levels: Vec<HqpLevel>,
    clamped: f64,
}

impl<const N: usize> HqpSolution<N> {
    /// The joint velocity, inside the box.
    pub fn velocity(&self) -> &JointVector<N> {
        &self.velocity
    }

    /// Per level, highest priority first (the joint-space target last).
    pub fn levels(&self) -> &[HqpLevel] {
        &self.levels
    }

    /// The largest change the final clamp into the box made to a joint velocity: the solver's tolerance, more only
    /// when no level could keep a joint inside.
    pub fn clamped(&self) -> f64 {
        self.clamped
    }
}

/// Storage for [`solve_hqp`], sized once for the largest task and the number of levels. The QPs allocate their own.
#[derive(Debug, Clone)]
pub struct HqpWorkspace<const N: usize> {
    limited: TaskJacobian<N>,
    desired: DVector<f64>,
    coupling: DVector<f64>,
    /// One decomposition per level (warm-started from the previous step's), for `J_k P_{k−1}`.
    svds: Vec<ColumnSvd<N>>,
    /// The decomposition of `P_{k−1}` whose kept vectors are the basis `Z_{k−1}`.
    basis_svd: ColumnSvd<N>,
    projector: JointMatrix<N>,
    settings: DefaultSettings<f64>,
    closed_form_first: bool,
    solution: HqpSolution<N>,
}

impl<const N: usize> HqpWorkspace<N> {
    /// A workspace for tasks of at most `max_rows` rows and stacks of at most `max_levels` levels, solving with
    /// `parameters`.
    ///
    /// # Errors
    /// Invalid parameters ([`HqpParameters::validate`]).
    pub fn with_capacity(
        max_rows: usize,
        max_levels: usize,
        parameters: &HqpParameters,
    ) -> Result<Self, HqpError> {
        parameters.validate()?;
        let rows = max_rows.max(1);
        Ok(Self {
            limited: TaskJacobian::zeros(rows),
            desired: DVector::zeros(rows),
            coupling: DVector::zeros(rows),
            svds: vec![ColumnSvd::default(); max_levels],
            basis_svd: ColumnSvd::default(),
            projector: JointMatrix::identity(),
            settings: parameters.settings(),
            closed_form_first: parameters.closed_form_first,
            solution: HqpSolution {
                velocity: JointVector::zeros(),
                levels: Vec::with_capacity(max_levels + 1),
                clamped: 0.0,
            },
        })
    }

    /// The result of the last solve (unspecified after a failed one).
    pub fn solution(&self) -> &HqpSolution<N> {
        &self.solution
    }
}

/// Solves the stack `order` of `tasks` (highest priority first), then the joint-space target (`joint_target`, or `0`),
/// as the lexicographic cascade in the box `[lower, upper]` (module docs), with the parameters the workspace was made
/// with.
///
/// # Errors
/// An invalid order, non-finite task data or target, a box that is not an interval ([`SnsError::InvalidBox`] inside
/// [`HqpError::Bounds`]), invalid stack parameters, a failed decomposition, a QP the solver did not solve
/// ([`HqpError::Solver`]). After an error the workspace's solution is unspecified.
#[allow(clippy::too_many_arguments)]
pub fn solve_hqp<'w, const N: usize>(
    parameters: &StackParameters,
    workspace: &'w mut HqpWorkspace<N>,
    tasks: &[TaskValue<N>],
    order: &[usize],
    joint_target: Option<&JointVector<N>>,
    lower: &JointVector<N>,
    upper: &JointVector<N>,
) -> Result<&'w HqpSolution<N>, HqpError> {
    parameters.validate()?;
    check_order(order, tasks.len(), workspace.svds.len())?;
    check_box_and_target(lower, upper, joint_target)?;
    workspace.projector.fill_with_identity();
    workspace.solution.velocity.fill(0.0);
    workspace.solution.levels.clear();
    let rest = JointVector::zeros();
    let target = joint_target.unwrap_or(&rest);
    let mut free = N; // rank of P_{k−1}
    let capacity = workspace.limited.nrows();
    let damping = match parameters.velocity_inverse {
        VelocityInverse::Truncated => 0.0,
        VelocityInverse::Damped { damping } => damping,
        VelocityInverse::Filtered { .. } => return Err(HqpError::FilteredInverse),
    };
    let task_levels = order.iter().enumerate().map(|(level, &index)| {
        let task = checked_task(tasks, level, index, capacity)?;
        Ok::<_, HqpError>((level, Level::Task(index, task)))
    });
    let target_level = std::iter::once(Ok((order.len(), Level::JointTarget(target))));
    let box_ = VelocityBox { lower, upper };
    for item in task_levels.chain(target_level) {
        let (level, kind) = item?;
        let solved = solve_level(
            parameters, damping, workspace, level, kind, &box_, &mut free,
        )?;
        workspace.solution.levels.push(solved);
    }
    let solution = &mut workspace.solution;
    let mut clamped: f64 = 0.0;
    for i in 0..N {
        let inside = solution.velocity[i].clamp(lower[i], upper[i]);
        clamped = clamped.max((inside - solution.velocity[i]).abs());
        solution.velocity[i] = inside;
    }
    solution.clamped = clamped;
    Ok(solution)
}

/// The velocity box of a solve.
struct VelocityBox<'a, const N: usize> {
    lower: &'a JointVector<N>,
    upper: &'a JointVector<N>,
}

impl<const N: usize> VelocityBox<'_, N> {
    /// Whether `v` lies in the box, to the relative tolerance of SNS's iterations.
    fn contains(&self, v: &JointVector<N>) -> bool {
        (0..N).all(|i| widened(self.lower[i], -1.0) <= v[i] && v[i] <= widened(self.upper[i], 1.0))
    }
}

/// One level of [`solve_hqp`]: the closed form, or the QP in the range of `P_{k−1}`; then `P_k`.
#[allow(clippy::too_many_arguments)]
fn solve_level<const N: usize>(
    parameters: &StackParameters,
    damping: f64,
    workspace: &mut HqpWorkspace<N>,
    level: usize,
    kind: Level<'_, N>,
    box_: &VelocityBox<'_, N>,
    free: &mut usize,
) -> Result<HqpLevel, HqpError> {
    let above = workspace.solution.velocity;
    let terms = match kind {
        Level::Task(_, task) => task_terms(
            parameters,
            workspace_buffers(
                &mut workspace.limited,
                &mut workspace.desired,
                &mut workspace.coupling,
            ),
            &mut workspace.svds[level],
            task,
            &workspace.projector,
            &above,
            level,
        )?,
        Level::JointTarget(target) => joint_target_terms(&workspace.projector, target, &above),
    };
    let closed_form = terms.base + terms.scaled;
    let (velocity, solve, held) =
        if *free == 0 || workspace.closed_form_first && box_.contains(&closed_form) {
            (closed_form, LevelSolve::ClosedForm, [false; N])
        } else {
            solve_level_qp(workspace, level, kind, &above, damping, box_, *free)?
        };
    workspace.solution.velocity = velocity;
    // P_k, as the stack computes it: a lower level keeps J_k q̇ (the joint-space target leaves no freedom).
    match kind {
        Level::Task(..) => {
            let svd = &workspace.svds[level];
            *free = free.saturating_sub(svd.rank());
            if *free == 0 {
                workspace.projector.fill(0.0);
            } else {
                svd.subtract_row_space_projector(&mut workspace.projector);
            }
        }
        Level::JointTarget(_) => {
            *free = 0;
            workspace.projector.fill(0.0);
        }
    }
    // The bounds the level's optimum presses on (positive multiplier) hold at every optimum of the level: the levels
    // below keep them as equalities, which leaves their QPs a feasible set with an interior.
    for joint in (0..N).filter(|&i| held[i]) {
        let pivot = workspace.projector[(joint, joint)];
        if *free == 0 || pivot <= HELD_PIVOT_FLOOR {
            continue;
        }
        let direction = workspace.projector.column(joint).clone_owned();
        workspace
            .projector
            .ger(-1.0 / pivot, &direction, &direction, 1.0);
        symmetrize(&mut workspace.projector);
        *free -= 1;
    }
    let residual = match kind {
        // Row by row: J_k q̇ + λ e, without a vector of the task's size.
        Level::Task(_, task) => task
            .jacobian()
            .row_iter()
            .zip(task.error().iter())
            .map(|(row, e)| (row.dot(&velocity.transpose()) + task.gain() * e).powi(2))
            .sum::<f64>()
            .sqrt(),
        Level::JointTarget(target) => (velocity - target).norm(),
    };
    Ok(HqpLevel {
        task: task_of(kind),
        solve,
        residual,
    })
}

/// Below this, a diagonal entry of `P_k` means the joint no longer moves in the levels below: holding it is void.
const HELD_PIVOT_FLOOR: f64 = 1e-9;

/// A bound counts as pressed on at a QP's optimum when its slack is below this (relative to the bound) and its
/// multiplier above it (relative to the largest): far above the solver's tolerance, far below a multiplier that
/// matters.
const ACTIVE_THRESHOLD: f64 = 1e-7;

/// The QP of a level in the coordinates `z` of `Z_{k−1}` (module docs); returns `q̇*_{k−1} + Z z` and the joints whose
/// bound the optimum presses on.
#[allow(clippy::too_many_arguments)]
fn solve_level_qp<const N: usize>(
    workspace: &mut HqpWorkspace<N>,
    level: usize,
    kind: Level<'_, N>,
    above: &JointVector<N>,
    damping: f64,
    box_: &VelocityBox<'_, N>,
    free: usize,
) -> Result<(JointVector<N>, LevelSolve, [bool; N]), HqpError> {
    // Z: the right singular vectors of P_{k−1} with singular value 1 (a projector's are 0 or 1 up to rounding, which
    // the default rank policy separates).
    let mut work = workspace.projector;
    workspace
        .basis_svd
        .decompose(&mut work, &RankPolicy::default())
        .map_err(|source| StackError::Linalg { level, source })?;
    let svd = &workspace.basis_svd;
    let columns: Vec<usize> = (0..N).filter(|&k| svd.is_kept(k)).take(free).collect();
    let basis = DMatrix::from_fn(N, columns.len(), |i, j| {
        svd.right_vectors()[(i, columns[j])]
    });
    // Z̃ = J_k Z and the linear term Z̃ᵀ (J_k q̇*_{k−1} − ẋ_k); for the joint-space target J = I.
    let (limited, offset) = match kind {
        Level::Task(_, task) => {
            let jacobian = DMatrix::from_fn(task.rows(), N, |i, j| task.jacobian()[(i, j)]);
            let mut offset = task.jacobian() * above;
            offset.axpy(task.gain(), task.error(), 1.0);
            (&jacobian * &basis, offset)
        }
        Level::JointTarget(target) => (
            basis.clone(),
            DVector::from_iterator(N, (above - target).iter().copied()),
        ),
    };
    let mut hessian = limited.tr_mul(&limited);
    for d in 0..hessian.nrows() {
        hessian[(d, d)] += damping * damping;
    }
    let linear = limited.tr_mul(&offset);
    // The box rows: Z_i z ≤ hi_i − q̇_i and −Z_i z ≤ q̇_i − lo_i, finite bounds only.
    let mut rows: Vec<(f64, usize, f64)> = Vec::with_capacity(2 * N);
    for i in 0..N {
        if box_.upper[i].is_finite() {
            rows.push((1.0, i, box_.upper[i] - above[i]));
        }
        if box_.lower[i].is_finite() {
            rows.push((-1.0, i, above[i] - box_.lower[i]));
        }
    }
    let constraints = DMatrix::from_fn(rows.len(), columns.len(), |r, j| {
        rows[r].0 * basis[(rows[r].1, j)]
    });
    let bounds: Vec<f64> = rows.iter().map(|r| r.2).collect();
    let cones = [SupportedConeT::NonnegativeConeT(rows.len())];
    let mut solver = DefaultSolver::new(
        &upper_triangle(&hessian),
        linear.as_slice(),
        &dense(&constraints),
        &bounds,
        &cones,
        workspace.settings.clone(),
    )
    .map_err(|error| HqpError::Solver {
        level,
        status: error.to_string(),
        iterations: 0,
    })?;
    solver.solve();
    let solution = &solver.solution;
    let solved = matches!(
        solution.status,
        SolverStatus::Solved | SolverStatus::AlmostSolved
    );
    if !solved {
        return Ok((
            *above,
            LevelSolve::Kept {
                iterations: solution.iterations,
            },
            [false; N],
        ));
    }
    let z = DVector::from_column_slice(&solution.x);
    let step = &basis * z;
    if step.iter().any(|v| !v.is_finite()) {
        return Err(HqpError::Solver {
            level,
            status: format!("{:?}", solution.status),
            iterations: solution.iterations,
        });
    }
    let velocity = above + JointVector::from_iterator(step.iter().copied());
    let largest = solution.z.iter().copied().fold(0.0, f64::max);
    let mut held = [false; N];
    for ((&(_, joint, bound), &slack), &multiplier) in rows.iter().zip(&solution.s).zip(&solution.z)
    {
        if slack <= ACTIVE_THRESHOLD * (1.0 + bound.abs())
            && multiplier > ACTIVE_THRESHOLD * (1.0 + largest)
        {
            held[joint] = true;
        }
    }
    Ok((
        velocity,
        LevelSolve::Qp {
            iterations: solution.iterations,
        },
        held,
    ))
}

/// The upper triangle of a symmetric matrix, in Clarabel's compressed columns.
fn upper_triangle(matrix: &DMatrix<f64>) -> CscMatrix<f64> {
    let n = matrix.ncols();
    let mut colptr = Vec::with_capacity(n + 1);
    let (mut rowval, mut nzval) = (Vec::new(), Vec::new());
    colptr.push(0);
    for j in 0..n {
        for i in 0..=j {
            rowval.push(i);
            nzval.push(matrix[(i, j)]);
        }
        colptr.push(rowval.len());
    }
    CscMatrix::new(n, n, colptr, rowval, nzval)
}

/// A dense matrix in Clarabel's compressed columns.
fn dense(matrix: &DMatrix<f64>) -> CscMatrix<f64> {
    let (m, n) = matrix.shape();
    let colptr = (0..=n).map(|j| j * m).collect();
    let rowval = (0..n).flat_map(|_| 0..m).collect();
    CscMatrix::new(m, n, colptr, rowval, matrix.as_slice().to_vec())
}

/// The cascade as the control law's solver ([`crate::law::ControlWorkspace::solve_as_hierarchical_qp`]).
pub(crate) type HqpLaw<const N: usize> = BoxedLaw<N, HqpWorkspace<N>>;

impl<const N: usize> BoxSolver<N> for HqpWorkspace<N> {
    type Error = HqpError;

    fn solve_in_box(
        &mut self,
        parameters: &StackParameters,
        tasks: &[TaskValue<N>],
        order: &[usize],
        joint_target: Option<&JointVector<N>>,
        lower: &JointVector<N>,
        upper: &JointVector<N>,
    ) -> Result<JointVector<N>, HqpError> {
        solve_hqp(parameters, self, tasks, order, joint_target, lower, upper)
            .map(|solution| *solution.velocity())
    }
}
