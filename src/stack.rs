//! The task stack: strict priorities by recursive null-space projection ([theory §2](crate::theory#s2), [\[M14\]](crate::theory#m14), [\[M8\]](crate::theory#m8), [(F6)](crate::theory#f6)–[(F8)](crate::theory#f8), [(F16)](crate::theory#f16)).
//!
//! For an ordered stack of tasks `(e_1, …, e_n)` (index 1 has the highest priority), each with its own gain, the joint
//! velocity that realises `ė_i = −λ_i e_i` as well as the higher levels allow is built level by level:
//!
//! ```text
//! [M14]  q̇_0 = 0,   P^A_0 = I_N
//!        J̃_i  = J_i P^A_{i−1}                                    (limited Jacobian, m_i × N)
//!        q̇_i = q̇_{i−1} + J̃_i⁺ ( −λ_i e_i − J_i q̇_{i−1} )
//! [M8]   P^A_i = P^A_{i−1} − J̃_i⁺ J̃_i                           (Baerlocher–Boulic projector update)
//! ```
//!
//! `P^A_n` is the orthogonal projector onto the kernel of the augmented Jacobian `[J_1; …; J_n]`: the directions left
//! free by the whole stack, where avoidance acts ([`crate::law`], [\[M18\]](crate::theory#m18)). Because `range(J̃_i⁺) ⊂ range(P^A_{i−1})`,
//! a lower level never changes `J_k q̇` for a higher level `k` (up to the rank truncation).
//!
//! Each level is solved by one allocation-free SVD of `J̃_i` ([`crate::linalg::ColumnSvd`]), or without it on one of
//! two certified paths ([D15](crate::theory#d15)): a first level of at least `N` rows certified to have full column
//! rank and to be well conditioned (a square one once its rows are equilibrated), by the normal equations
//! ([`crate::linalg::solve_full_column_rank`]); a level of
//! one or two rows certified to have full row rank and to be well conditioned, in closed form from the `1 × 1` or
//! `2 × 2` matrix `J̃_i J̃_iᵀ` ([`crate::linalg::solve_small_stack_level`]). Both answer only when the SVD's rank decision
//! is certain, and then agree with it to rounding. The velocity term may use
//! damped least squares, the projector update is always the truncated, exact `J̃⁺J̃` ([D2](crate::theory#d2)). The projector is
//! re-symmetrised after each update ([theory §2.1.3](crate::theory#s2-1-3)). The rank threshold of level `i` is relative to the task's own scale
//! `‖J_i‖_F`, not to `σ_max(J̃_i)`: a level whose `J̃_i` is tiny compared with `J_i` conflicts with the higher levels
//! (algorithmic singularity), and its tiny directions must be dropped, not inverted. Per-level [`LevelDiagnostics`] report the rank of `J̃_i`, its
//! smallest kept singular value, and whether the level is fully achievable (`rank J̃_i = m_i`, [theory §2.1.5](crate::theory#s2-1-5)).
//!
//! ```
//! use servostack::stack::{solve_stack, StackParameters, StackWorkspace};
//! use servostack::task::{TaskValue, TaskJacobian};
//! use nalgebra::DVector;
//!
//! // Two 1-row tasks on 3 joints: level 1 wants q̇_0 = −0.5·0.2, level 2 wants q̇_0 + q̇_1 = −0.5·(−0.4).
//! let t1 = TaskValue::<3>::from_parts("a", DVector::from_vec(vec![0.2]), TaskJacobian::from_row_slice(&[1.0, 0.0, 0.0]), 0.5)?;
//! let t2 = TaskValue::<3>::from_parts("b", DVector::from_vec(vec![-0.4]), TaskJacobian::from_row_slice(&[1.0, 1.0, 0.0]), 0.5)?;
//! let tasks = [t1, t2];
//! let mut workspace = StackWorkspace::<3>::new(&tasks);
//! let solution = solve_stack(&StackParameters::default(), &mut workspace, &tasks, &[0, 1])?;
//! assert!((solution.velocity()[0] + 0.1).abs() < 1e-12);
//! assert!((solution.velocity()[0] + solution.velocity()[1] - 0.2).abs() < 1e-12);
//! assert_eq!(solution.levels()[1].rank, 1);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::linalg::{
    mul_rows_and_vector_to, rank_test_threshold, solve_full_column_rank, solve_small_stack_level,
    ColumnSvd, LinalgError, RankPolicy, VelocityInverse, FAST_PATH_CONDITION_BOUND,
};
use crate::math::{JointMatrix, JointVector};
use crate::task::{TaskJacobian, TaskValue};
use nalgebra::DVector;

/// Errors of the stack solve.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StackError {
    /// The stack order names a task index that is not in the task list.
    #[error("stack level {level} names task {task}, but only {available} tasks exist")]
    UnknownTask {
        /// The level (0 = highest priority).
        level: usize,
        /// The task index given.
        task: usize,
        /// The number of tasks in the list.
        available: usize,
    },
    /// The stack order names a task twice: a task is at most one level of a stack.
    #[error("stack levels {first_level} and {level} both name task {task}")]
    DuplicateTask {
        /// The task index.
        task: usize,
        /// The first level naming it (0 = highest priority).
        first_level: usize,
        /// The later level naming it again.
        level: usize,
    },
    /// The task does not fit the workspace (it has more rows, or the stack more levels, than it was sized for).
    #[error("workspace too small: {what} is {found}, capacity {capacity}")]
    CapacityExceeded {
        /// `"task rows"` or `"levels"`.
        what: &'static str,
        /// The size requested.
        found: usize,
        /// The capacity of the workspace.
        capacity: usize,
    },
    /// A task's error or Jacobian holds a NaN or an infinity (the first one, in column-major order).
    #[error(
        "stack level {level} (task {task}): {what} entry ({row}, {column}) = {value} is not finite"
    )]
    NonFiniteTask {
        /// The level (0 = highest priority).
        level: usize,
        /// The task index.
        task: usize,
        /// `"error"` or `"jacobian"`.
        what: &'static str,
        /// The entry's row.
        row: usize,
        /// The entry's column (0 for the error vector).
        column: usize,
        /// The entry (NaN or ±∞).
        value: f64,
    },
    /// The linear algebra failed (see the source).
    #[error("stack level {level}: {source}")]
    Linalg {
        /// The level (0 = highest priority).
        level: usize,
        /// The underlying error.
        source: LinalgError,
    },
    /// Invalid parameters.
    #[error("invalid stack parameters: {0}")]
    Parameters(LinalgError),
}

/// How each level is inverted ([theory §2.1](crate::theory#s2-1), [D2](crate::theory#d2)).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct StackParameters {
    /// Which singular values of `J̃_i` count (relative threshold 1e−6 and an absolute floor by default).
    pub rank_policy: RankPolicy,
    /// The inverse of the velocity term: truncated (default) or damped least squares.
    pub velocity_inverse: VelocityInverse,
}

impl StackParameters {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`StackError::Parameters`] for an invalid damping.
    pub fn validate(&self) -> Result<(), StackError> {
        self.velocity_inverse
            .validate()
            .map_err(StackError::Parameters)
    }
}

/// What one level of the stack achieved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelDiagnostics {
    /// The index of the task at this level in the task list.
    pub task: usize,
    /// The number of rows `m_i` of the task.
    pub rows: usize,
    /// The numerical rank of the limited Jacobian `J̃_i = J_i P^A_{i−1}`.
    pub rank: usize,
    /// The smallest singular value of `J̃_i` kept by the rank policy (`None` at rank 0); for a [`Self::certified`]
    /// level of full column rank, the certificate's lower bound on it, `1/‖L⁻¹‖_F` less rounding, within a factor `√N`
    /// of the exact value (for a square level, a bound for its equilibrated rows mapped back to `J̃_i`, which may be
    /// looser); for a certified level of one or two rows, the value from the closed-form eigenvalue of
    /// `J̃_i J̃_iᵀ` ([D15](crate::theory#d15)).
    pub smallest_kept_singular_value: Option<f64>,
    /// `true` when the level was solved without an SVD on a certified path ([D15](crate::theory#d15)): full column
    /// rank `N` by the normal equations ([`crate::linalg::solve_full_column_rank`]), or one or two rows of full row
    /// rank in closed form ([`crate::linalg::solve_small_stack_level`]); `false` for the SVD.
    pub certified: bool,
    /// `true` when `rank J̃_i = m_i`: every velocity the task asks for is realisable without disturbing the higher
    /// levels ([theory §2.1.5](crate::theory#s2-1-5)). A task with more rows than free joints is never fully achievable.
    pub fully_achievable: bool,
}

/// The result of a stack solve: `q̇_n`, `P^A_n` and per-level diagnostics.
#[derive(Debug, Clone, PartialEq)]
pub struct StackSolution<const N: usize> {
    velocity: JointVector<N>,
    projector: JointMatrix<N>,
    levels: Vec<LevelDiagnostics>,
    locked: [bool; N],
}

impl<const N: usize> StackSolution<N> {
    /// The joints the solve held still ([D26](crate::theory#d26)): `P^A_0 = I − Σ_{i locked} e_i e_iᵀ`, so `q̇_n`
    /// and `P^A_n` are zero on them.
    pub fn locked_joints(&self) -> &[bool; N] {
        &self.locked
    }

    /// The stack velocity `q̇_n` of [\[M14\]](crate::theory#m14) (m/s or rad/s per joint), without transition or avoidance terms.
    pub fn velocity(&self) -> &JointVector<N> {
        &self.velocity
    }

    /// The projector `P^A_n` onto the joint directions left free by the whole stack ([\[M8\]](crate::theory#m8)).
    pub fn projector(&self) -> &JointMatrix<N> {
        &self.projector
    }

    /// Diagnostics, one per level, highest priority first.
    pub fn levels(&self) -> &[LevelDiagnostics] {
        &self.levels
    }

    /// `true` when every level is fully achievable.
    pub fn all_achievable(&self) -> bool {
        self.levels.iter().all(|level| level.fully_achievable)
    }
}

/// Preallocated storage for [`solve_stack`]: sized once for the largest task and the number of tasks, it makes the
/// solve allocation-free.
#[derive(Debug, Clone)]
pub struct StackWorkspace<const N: usize> {
    limited: TaskJacobian<N>,
    residual: DVector<f64>,
    /// One decomposition per level, so that each level's is warm-started from its previous solve.
    svds: Vec<ColumnSvd<N>>,
    /// Per level, whether the certified fast path is worth trying (D15): `false` after an SVD that found the level
    /// rank-deficient or too ill-conditioned for the certificate, so that a level that never qualifies (the moment
    /// task of the peer scene) does not pay for a failed attempt at every step.
    try_certified: Vec<bool>,
    step: JointVector<N>,
    /// The joints held still by the next solves ([`Self::lock_joints`]).
    locked: [bool; N],
    solution: StackSolution<N>,
}

impl<const N: usize> StackWorkspace<N> {
    /// A workspace for stacks built from `tasks`: rows for the largest task, one level per task in the list.
    pub fn new(tasks: &[TaskValue<N>]) -> Self {
        let max_rows = tasks.iter().map(TaskValue::rows).max().unwrap_or(1);
        Self::with_capacity(max_rows, tasks.len())
    }

    /// A workspace for tasks of at most `max_rows` rows and stacks of at most `max_levels` levels.
    pub fn with_capacity(max_rows: usize, max_levels: usize) -> Self {
        Self {
            limited: TaskJacobian::zeros(max_rows.max(1)),
            residual: DVector::zeros(max_rows.max(1)),
            svds: vec![ColumnSvd::default(); max_levels],
            try_certified: vec![true; max_levels],
            step: JointVector::zeros(),
            locked: [false; N],
            solution: StackSolution {
                velocity: JointVector::zeros(),
                projector: JointMatrix::identity(),
                levels: Vec::with_capacity(max_levels),
                locked: [false; N],
            },
        }
    }

    /// The largest task (rows) and the deepest stack (levels) this workspace was sized for.
    pub fn capacity(&self) -> (usize, usize) {
        (self.limited.nrows(), self.svds.len())
    }

    /// The result of the last solve (unspecified after a failed one).
    pub fn solution(&self) -> &StackSolution<N> {
        &self.solution
    }

    /// Holds the joints marked `true` still in the next solves ([D26](crate::theory#d26)): the stack starts from
    /// `P^A_0 = I − Σ_{i locked} e_i e_iᵀ` instead of `I`, so every level, and the avoidance term through `P^A_n`, moves
    /// only the other joints. All `false` (the default) is the stack of [\[M14\]](crate::theory#m14).
    pub fn lock_joints(&mut self, locked: &[bool; N]) {
        self.locked = *locked;
    }

    /// The joints the next solves hold still.
    pub fn locked_joints(&self) -> &[bool; N] {
        &self.locked
    }
}

/// Solves the stack `order` (indices into `tasks`, highest priority first) by [\[M14\]](crate::theory#m14) and [\[M8\]](crate::theory#m8). Allocation-free when the
/// workspace was sized for these tasks. An empty order gives `q̇_n = 0`, `P^A_n = I`.
///
/// # Errors
/// An unknown or repeated task index, a task or stack larger than the workspace, non-finite task data, invalid parameters, or a
/// failed decomposition. After an error, the workspace's solution is unspecified (not returned to the caller).
pub fn solve_stack<'w, const N: usize>(
    parameters: &StackParameters,
    workspace: &'w mut StackWorkspace<N>,
    tasks: &[TaskValue<N>],
    order: &[usize],
) -> Result<&'w StackSolution<N>, StackError> {
    parameters.validate()?;
    check_order(order, tasks.len(), workspace.svds.len())?;
    let StackWorkspace {
        limited,
        residual,
        svds,
        try_certified,
        step,
        locked,
        solution,
    } = workspace;
    solution.velocity.fill(0.0);
    // P^A_0 = I, less the locked joints (D26)
    solution.projector.fill_with_identity();
    solution.locked = *locked;
    let mut free = N; // rank of P^A_i
    for (joint, _) in locked.iter().enumerate().filter(|(_, &l)| l) {
        solution.projector[(joint, joint)] = 0.0;
        free -= 1;
    }
    solution.levels.clear();
    // The certified paths answer only where the SVD path would give the same velocity: for the filtered inverse (D30),
    // at levels whose every singular value clears the filter's floor.
    let certifiable = parameters
        .velocity_inverse
        .certifiable_policy(&parameters.rank_policy);
    let levels = order.iter().enumerate().zip(svds.iter_mut());
    for (((level, &index), svd), try_certified) in levels.zip(try_certified.iter_mut()) {
        let task = checked_task(tasks, level, index, limited.nrows())?;
        let rows = task.rows();
        // r = −λ_i e_i − J_i q̇_{i−1}
        // J̃_i = J_i P^A_{i−1} (J_i itself at the first level when no joint is locked, P^A_0 = I, q̇_0 = 0, read in
        // place by the certified paths and copied only for the SVD), decomposed in place into W = J̃_i V. Both
        // products with J_i come from one pass over its rows.
        let mut r = residual.rows_mut(0, rows);
        let mut w = limited.rows_mut(0, rows);
        let projected = level > 0 || free < N;
        if projected {
            mul_rows_and_vector_to(
                task.jacobian(),
                &solution.projector,
                &solution.velocity,
                &mut w,
                &mut r,
            );
            r.zip_apply(task.error(), |ri, ei| *ri = -task.gain() * ei - *ri);
        } else {
            r.zip_apply(task.error(), |ri, ei| *ri = -task.gain() * ei);
        }
        let limited_jacobian = if !projected {
            task.jacobian().rows(0, rows)
        } else {
            w.rows(0, rows)
        };
        let scale = task.jacobian().norm();
        // Two certified paths without the SVD (D15), each answering only when it can confirm what the SVD would decide:
        // a level that sees every joint direction free (P^A_{i−1} = I) with at least N rows, of full column rank N
        // (J̃_i⁺ r is then the least-squares solution); a level of one or two rows of full row rank (J̃_i⁺ = J̃_iᵀ G⁻¹ and
        // its row-space projector in closed form). Otherwise, and for damped least squares, the SVD.
        let policy = &parameters.rank_policy;
        let eligible = free == N && rows >= N && certifiable.is_some();
        let certified = match &certifiable {
            Some(certifiable) if eligible && *try_certified => {
                solve_full_column_rank(&limited_jacobian, &r, certifiable, scale, step)
                    .map(|bound| (N, bound))
            }
            Some(certifiable) if rows <= 2 => {
                // A level that takes the last free directions leaves P^A_i = 0 (set below): no update to compute.
                let projector = (free > rows).then_some(&mut solution.projector);
                solve_small_stack_level(&limited_jacobian, &r, certifiable, scale, step, projector)
                    .map(|sigma_min| (rows, sigma_min))
            }
            _ => None,
        };
        let (rank, smallest_kept_singular_value) = match certified {
            Some((rank, sigma_min)) => (rank, Some(sigma_min)),
            None => {
                if !projected {
                    w.copy_from(task.jacobian());
                }
                svd.decompose_warm(&mut w, policy, scale)
                    .map_err(|source| StackError::Linalg { level, source })?;
                svd.solve(&w, &r, parameters.velocity_inverse, step)
                    .map_err(|source| StackError::Linalg { level, source })?;
                let (rank, smallest) = (svd.rank(), svd.smallest_kept());
                // Worth trying next step if this one would have passed the certificate's condition bound
                // (‖J̃‖_F = ‖J_i‖_F here, since P^A_{i−1} = I); for a square level, whose rows are equilibrated first
                // (the bound then applies to a condition number the SVD of J_i does not give), if σ_min clears the
                // certificate's rank test, which no bound below σ_min can pass otherwise.
                *try_certified = rank == N
                    && smallest.is_some_and(|s| match &certifiable {
                        Some(certifiable) if eligible && rows == N => {
                            s > rank_test_threshold::<N>(certifiable, scale, scale)
                        }
                        Some(_) if eligible => s * FAST_PATH_CONDITION_BOUND >= scale,
                        _ => false,
                    });
                (rank, smallest)
            }
        };
        solution.velocity += &*step;
        // rank P^A_i = rank P^A_{i−1} − rank J̃_i: once the stack has used every joint direction, P^A_i = 0 exactly
        // (no subtraction left to do, and no rounding noise for the levels below or the avoidance term). A level of
        // full column rank always gets there; a small certified level has already updated the projector (or left it
        // to be zeroed here).
        free = free.saturating_sub(rank);
        if free == 0 {
            solution.projector.fill(0.0);
        } else if certified.is_none() {
            svd.subtract_row_space_projector(&mut solution.projector);
        }
        solution.levels.push(LevelDiagnostics {
            task: index,
            rows,
            rank,
            smallest_kept_singular_value,
            certified: certified.is_some(),
            fully_achievable: rank == rows,
        });
    }
    Ok(solution)
}

/// Checks a stack order against a task list of `available` tasks and a workspace of `capacity` levels: every index
/// names a task, none twice, and the levels fit.
pub(crate) fn check_order(
    order: &[usize],
    available: usize,
    capacity: usize,
) -> Result<(), StackError> {
    for (level, &task) in order.iter().enumerate() {
        if task >= available {
            return Err(StackError::UnknownTask {
                level,
                task,
                available,
            });
        }
        if let Some(first_level) = order[..level].iter().position(|&t| t == task) {
            return Err(StackError::DuplicateTask {
                task,
                first_level,
                level,
            });
        }
    }
    if order.len() > capacity {
        return Err(StackError::CapacityExceeded {
            what: "levels",
            found: order.len(),
            capacity,
        });
    }
    Ok(())
}

pub(crate) fn checked_task<const N: usize>(
    tasks: &[TaskValue<N>],
    level: usize,
    index: usize,
    capacity: usize,
) -> Result<&TaskValue<N>, StackError> {
    let task = tasks.get(index).ok_or(StackError::UnknownTask {
        level,
        task: index,
        available: tasks.len(),
    })?;
    if task.rows() > capacity {
        return Err(StackError::CapacityExceeded {
            what: "task rows",
            found: task.rows(),
            capacity,
        });
    }
    // One scalar scan of each contiguous (column-major) buffer; the index names the entry.
    let rows = task.rows();
    let buffers = [
        ("error", task.error().as_slice()),
        ("jacobian", task.jacobian().as_slice()),
    ];
    for (what, values) in buffers {
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Err(StackError::NonFiniteTask {
                level,
                task: index,
                what,
                row: k % rows,
                column: k / rows,
                value: values[k],
            });
        }
    }
    Ok(task)
}
