//! Saturation in the null space (SNS): the task stack under hard joint-velocity bounds ([theory §13](crate::theory#s13);
//! Flacco, De Luca & Khatib, *Control of redundant robots under hard joint constraints: saturation in the null
//! space*, IEEE T-RO 31(3), 2015, the prioritized algorithm with task scaling).
//!
//! Each step, the joint positions, velocities and (optionally) accelerations give a box `[q̇^lo, q̇^hi]` of admissible
//! joint velocities ([`SnsBounds::velocity_box`]):
//!
//! ```text
//! q̇^hi_i = min( (q^max_i − q_i)/Δt,  V_i(q^max_i − q_i),  v_i )      then ∩ [q̇⁻_i − a_i Δt, q̇⁻_i + a_i Δt]
//! q̇^lo_i = max( (q^min_i − q_i)/Δt, −V_i(q_i − q^min_i), −v_i )
//! ```
//!
//! (the stopping speeds `V_i` of a velocity held for whole periods, [`stopping_speed`], about `√(2 a_i d)`, and the
//! band around the last velocity `q̇⁻` only with acceleration limits `a`). The levels are
//! solved in order, each keeping what the levels above achieved. At level `k`, with `q̇_{k−1}` and `P_{k−1}` from above
//! and the set `S` of joints this level has saturated (empty at first):
//!
//! ```text
//! q̃   = q̇_{k−1} + (E_S P_{k−1})⁺ (q̇^sat_S − E_S q̇_{k−1})      (saturated joints at their bound, levels above kept)
//! P̄   = P_{k−1} − (E_S P_{k−1})⁺ (E_S P_{k−1})                  (the directions left that move no saturated joint)
//! q̇_k(s) = q̃ + (J_k P̄)⁺ (s ẋ_k − J_k q̃)  =  b + s a,    ẋ_k = −λ_k e_k
//! ```
//!
//! `E_S` selects the rows of the saturated joints. If `q̇_k(1)` lies in the box, the level is met. Otherwise the
//! *task scaling factor* is the largest `s ∈ [0, 1]` with `b + s a` in the box on the unsaturated joints; the joint that
//! limits it (the most critical) is saturated at the bound it passes, and the level is solved again, until it is met
//! or no joint can be saturated (its row of `P̄` is zero: it moves only with the levels above). The level then keeps
//! the largest scale found, or, if none was feasible, does nothing (`q̇_k = q̇_{k−1}`). The projector passed down is
//! the stack's, `P_k = P_{k−1} − (J_k P_{k−1})⁺ J_k P_{k−1}` ([\[M8\]](crate::theory#m8)): a lower level never changes
//! what `J_k` sees, and may move a joint this level saturated, which the lower level then saturates again if needed.
//! An optional last level `J = I` with target `q̇*` (the law's avoidance term `−κ∇h`) is solved the same way; its
//! inverse is `P̄` itself. The result is clamped into the box last, which changes it only by rounding unless no
//! level could be kept inside (`q = 0` itself outside the box, for a configuration already past a limit).
//!
//! With the box inactive every level is met at the first solve and `q̇_n` is the stack's [\[M14\]](crate::theory#m14),
//! `q̇_n + P_n q̇*` with a target. Fixed-size storage sized once: the solve allocates nothing.

use crate::avoidance::{stopping_speed, JointLimits};
use crate::linalg::{mul_rows_and_vector_to, ColumnSvd};
use crate::math::{first_non_finite, JointMatrix, JointVector};
use crate::stack::{check_order, checked_task, StackError, StackParameters};
use crate::task::{TaskJacobian, TaskValue};
use nalgebra::DVector;

/// Errors of the SNS bounds and solve.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SnsError {
    /// The control period must be finite and positive.
    #[error("control period Δt = {period} s must be finite and > 0")]
    InvalidPeriod {
        /// The period given (s).
        period: f64,
    },
    /// A joint's velocity limit must be positive (`+∞` for none).
    #[error("joint {joint}: velocity limit {value} must be > 0 (or +∞)")]
    InvalidVelocityLimit {
        /// The joint (0-based).
        joint: usize,
        /// The limit given.
        value: f64,
    },
    /// A joint's acceleration limit must be positive (`+∞`: none).
    #[error("joint {joint}: acceleration limit {value} must be > 0 (or +∞)")]
    InvalidAccelerationLimit {
        /// The joint (0-based).
        joint: usize,
        /// The limit given.
        value: f64,
    },
    /// A joint position, velocity or target holds a NaN or an infinity.
    #[error("joint {joint}: {what} = {value} is not finite")]
    NonFiniteJointValue {
        /// `"configuration"`, `"previous velocity"` or `"joint-space target"`.
        what: &'static str,
        /// The joint (0-based).
        joint: usize,
        /// The value.
        value: f64,
    },
    /// A velocity box whose lower bound is above its upper bound, or holds a NaN (`−∞ ≤ lower ≤ upper ≤ +∞`, with a
    /// finite point in between).
    #[error("joint {joint}: velocity bounds {lower} .. {upper} are not an interval")]
    InvalidBox {
        /// The joint (0-based).
        joint: usize,
        /// The lower bound given.
        lower: f64,
        /// The upper bound given.
        upper: f64,
    },
    /// The task stack is invalid (unknown or repeated task, non-finite task data, capacity) or its algebra failed.
    #[error(transparent)]
    Stack(#[from] StackError),
}

/// The hard joint bounds of SNS: position limits, velocity limits, optional acceleration limits, and the control period
/// that turns them into a velocity box at each step. Immutable after construction.
#[derive(Debug, Clone, PartialEq)]
pub struct SnsBounds<const N: usize> {
    limits: JointLimits<N>,
    max_velocity: JointVector<N>,
    max_acceleration: Option<JointVector<N>>,
    period: f64,
}

/// A relative margin kept from the position limits, so that `q + q̇ Δt` computed in floating point stays inside.
const POSITION_MARGIN: f64 = 1e-9;

impl<const N: usize> SnsBounds<N> {
    /// Bounds from position `limits` (unlimited joints allowed), velocity limits `max_velocity` (m/s or rad/s, `> 0`,
    /// `+∞` for none) and the control period `period` (s, `> 0`).
    ///
    /// # Errors
    /// [`SnsError::InvalidVelocityLimit`], [`SnsError::InvalidPeriod`].
    pub fn new(
        limits: JointLimits<N>,
        max_velocity: JointVector<N>,
        period: f64,
    ) -> Result<Self, SnsError> {
        if !(period.is_finite() && period > 0.0) {
            return Err(SnsError::InvalidPeriod { period });
        }
        if let Some((joint, &value)) = max_velocity
            .iter()
            .enumerate()
            .find(|(_, v)| v.is_nan() || **v <= 0.0)
        {
            return Err(SnsError::InvalidVelocityLimit { joint, value });
        }
        Ok(Self {
            limits,
            max_velocity,
            max_acceleration: None,
            period,
        })
    }

    /// The same bounds with acceleration limits (m/s² or rad/s², `> 0`; `+∞` for none on that joint).
    ///
    /// # Errors
    /// [`SnsError::InvalidAccelerationLimit`].
    pub fn with_max_acceleration(
        mut self,
        max_acceleration: JointVector<N>,
    ) -> Result<Self, SnsError> {
        let invalid = max_acceleration
            .iter()
            .enumerate()
            .find(|(_, a)| a.is_nan() || **a <= 0.0);
        if let Some((joint, &value)) = invalid {
            return Err(SnsError::InvalidAccelerationLimit { joint, value });
        }
        self.max_acceleration = Some(max_acceleration);
        Ok(self)
    }

    /// The position limits.
    pub fn limits(&self) -> &JointLimits<N> {
        &self.limits
    }

    /// The control period `Δt` (s).
    pub fn period(&self) -> f64 {
        self.period
    }

    /// The box of admissible velocities at configuration `q` after the velocity `previous` (module docs). Precedence
    /// when the bounds disagree: position over velocity over acceleration. A joint past a position limit gets the
    /// velocity bounded towards its range; an acceleration band that misses the hard box gives the point of the hard
    /// box nearest the band. `lower ≤ upper` always.
    ///
    /// # Errors
    /// [`SnsError::NonFiniteJointValue`] for a non-finite `q` or `previous`.
    pub fn velocity_box(
        &self,
        q: &JointVector<N>,
        previous: &JointVector<N>,
        lower: &mut JointVector<N>,
        upper: &mut JointVector<N>,
    ) -> Result<(), SnsError> {
        for (what, values) in [("configuration", q), ("previous velocity", previous)] {
            if let Some((joint, value)) = first_non_finite(values) {
                return Err(SnsError::NonFiniteJointValue { what, joint, value });
            }
        }
        let dt = self.period;
        for i in 0..N {
            let (q_min, q_max) = (self.limits.lower()[i], self.limits.upper()[i]);
            let (below, above) = (
                (q_min - q[i]) * (1.0 - POSITION_MARGIN),
                (q_max - q[i]) * (1.0 - POSITION_MARGIN),
            );
            let (mut lo, mut hi) = (below / dt, above / dt);
            if let Some(a) = self.max_acceleration.as_ref().filter(|a| a[i].is_finite()) {
                // The stopping speed of a velocity held for whole periods (√(2ad) is overshot by one).
                lo = lo.max(-stopping_speed(-below, a[i], dt));
                hi = hi.min(stopping_speed(above, a[i], dt));
            }
            // Past a limit the two position bounds can cross: the one that returns into the range wins.
            lo = lo.min(hi);
            let v = self.max_velocity[i];
            (lo, hi) = (lo.clamp(-v, v), hi.clamp(-v, v));
            if let Some(a) = self.max_acceleration.as_ref().filter(|a| a[i].is_finite()) {
                let (band_lo, band_hi) = (previous[i] - a[i] * dt, previous[i] + a[i] * dt);
                (lo, hi) = if band_lo > hi {
                    (hi, hi)
                } else if band_hi < lo {
                    (lo, lo)
                } else {
                    (lo.max(band_lo), hi.min(band_hi))
                };
            }
            lower[i] = lo;
            upper[i] = hi;
        }
        Ok(())
    }
}

/// What SNS did with a level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LevelOutcome {
    /// The level's full velocity `ẋ_k` is realised (possibly with joints saturated).
    Met,
    /// Only `s ẋ_k` with `0 ≤ s < 1` fits in the box.
    Scaled {
        /// The task scaling factor `s`.
        scale: f64,
    },
    /// No scale of the level fits in the box with the joints that could be saturated: the level adds nothing.
    Dropped,
}

/// One level of an SNS solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SnsLevel<const N: usize> {
    /// The task index at this level; `None` for the joint-space target.
    pub task: Option<usize>,
    /// What the level achieved.
    pub outcome: LevelOutcome,
    /// The joints this level saturated.
    pub saturated: [bool; N],
}

/// The result of [`solve_sns`].
#[derive(Debug, Clone, PartialEq)]
pub struct SnsSolution<const N: usize> {
    velocity: JointVector<N>,
    levels: Vec<SnsLevel<N>>,
    clamped: f64,
}

impl<const N: usize> SnsSolution<N> {
    /// The joint velocity, inside the box.
    pub fn velocity(&self) -> &JointVector<N> {
        &self.velocity
    }

    /// Per level, highest priority first (the joint-space target last, if given).
    pub fn levels(&self) -> &[SnsLevel<N>] {
        &self.levels
    }

    /// The largest change the final clamp into the box made to a joint velocity: rounding when the levels fit, more
    /// only when no level could keep a joint inside (for instance `q` already past a limit with `0` outside the box).
    pub fn clamped(&self) -> f64 {
        self.clamped
    }
}

/// Preallocated storage for [`solve_sns`], sized once for the largest task and the number of levels.
#[derive(Debug, Clone)]
pub struct SnsWorkspace<const N: usize> {
    limited: TaskJacobian<N>,
    desired: DVector<f64>,
    coupling: DVector<f64>,
    /// One decomposition per level, warm-started from the previous step's, for the level before any saturation.
    svds: Vec<ColumnSvd<N>>,
    /// The decomposition of the level with joints saturated.
    saturated_svd: ColumnSvd<N>,
    projector: JointMatrix<N>,
    saturated_projector: JointMatrix<N>,
    solution: SnsSolution<N>,
}

impl<const N: usize> SnsWorkspace<N> {
    /// A workspace for tasks of at most `max_rows` rows and stacks of at most `max_levels` levels.
    pub fn with_capacity(max_rows: usize, max_levels: usize) -> Self {
        let rows = max_rows.max(1);
        Self {
            limited: TaskJacobian::zeros(rows),
            desired: DVector::zeros(rows),
            coupling: DVector::zeros(rows),
            svds: vec![ColumnSvd::default(); max_levels],
            saturated_svd: ColumnSvd::default(),
            projector: JointMatrix::identity(),
            saturated_projector: JointMatrix::identity(),
            solution: SnsSolution {
                velocity: JointVector::zeros(),
                levels: Vec::with_capacity(max_levels + 1),
                clamped: 0.0,
            },
        }
    }

    /// The result of the last solve (unspecified after a failed one).
    pub fn solution(&self) -> &SnsSolution<N> {
        &self.solution
    }
}

/// A level of the solve: a task of the stack, or the joint-space target `J = I` below them.
#[derive(Clone, Copy)]
pub(super) enum Level<'a, const N: usize> {
    Task(usize, &'a TaskValue<N>),
    JointTarget(&'a JointVector<N>),
}

/// The terms of a level's velocity `b + s a` for the directions `projector` (`P_{k−1}` or `P̄`) and the base `q̃`.
pub(super) struct LevelTerms<const N: usize> {
    /// `a`, the part scaled by `s`.
    pub(super) scaled: JointVector<N>,
    /// `b`.
    pub(super) base: JointVector<N>,
}

/// Below this, a diagonal entry of `P̄` means the joint cannot move without disturbing the levels above.
const SATURATION_PIVOT_FLOOR: f64 = 1e-9;

/// Relative tolerance of the box tests inside the iterations (the final clamp removes what it lets through).
const BOX_TOLERANCE: f64 = 1e-12;

/// Solves the stack `order` of `tasks` (highest priority first), then the joint-space target `joint_target` if given,
/// by SNS in the velocity box `[lower, upper]` (module docs). Allocation-free when the workspace was sized for these
/// tasks.
///
/// # Errors
/// An invalid order, non-finite task data or target, a box that is not an interval ([`SnsError::InvalidBox`]), invalid
/// stack parameters, a failed decomposition. After an error the workspace's solution is unspecified.
#[allow(clippy::too_many_arguments)]
pub fn solve_sns<'w, const N: usize>(
    parameters: &StackParameters,
    workspace: &'w mut SnsWorkspace<N>,
    tasks: &[TaskValue<N>],
    order: &[usize],
    joint_target: Option<&JointVector<N>>,
    lower: &JointVector<N>,
    upper: &JointVector<N>,
) -> Result<&'w SnsSolution<N>, SnsError> {
    parameters.validate()?;
    check_order(order, tasks.len(), workspace.svds.len())?;
    check_box_and_target(lower, upper, joint_target)?;
    workspace.projector.fill_with_identity();
    workspace.solution.velocity.fill(0.0);
    workspace.solution.levels.clear();
    let mut free = N; // rank of P_{k−1}
    let capacity = workspace.limited.nrows();
    let task_levels = order.iter().enumerate().map(|(level, &index)| {
        let task = checked_task(tasks, level, index, capacity)?;
        Ok::<_, SnsError>((level, Level::Task(index, task)))
    });
    let target_level = joint_target.map(|target| Ok((order.len(), Level::JointTarget(target))));
    for item in task_levels.chain(target_level) {
        let (level, kind) = item?;
        let solved = solve_level(parameters, workspace, level, kind, lower, upper, &mut free)?;
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

/// Checks that `[lower, upper]` is a box with a finite point in every interval and that the joint-space target, if
/// given, is finite.
pub(super) fn check_box_and_target<const N: usize>(
    lower: &JointVector<N>,
    upper: &JointVector<N>,
    joint_target: Option<&JointVector<N>>,
) -> Result<(), SnsError> {
    for joint in 0..N {
        let (lo, hi) = (lower[joint], upper[joint]);
        if !(lo <= hi && lo < f64::INFINITY && hi > f64::NEG_INFINITY) {
            return Err(SnsError::InvalidBox {
                joint,
                lower: lo,
                upper: hi,
            });
        }
    }
    if let Some((joint, value)) = joint_target.and_then(first_non_finite) {
        return Err(SnsError::NonFiniteJointValue {
            what: "joint-space target",
            joint,
            value,
        });
    }
    Ok(())
}

pub(super) fn task_of<const N: usize>(level: Level<'_, N>) -> Option<usize> {
    match level {
        Level::Task(index, _) => Some(index),
        Level::JointTarget(_) => None,
    }
}

/// One level of [`solve_sns`]: saturates joints one by one until the level fits, updates the velocity in the
/// solution and the projector to `P_k`.
#[allow(clippy::too_many_arguments)]
fn solve_level<const N: usize>(
    parameters: &StackParameters,
    workspace: &mut SnsWorkspace<N>,
    level: usize,
    kind: Level<'_, N>,
    lower: &JointVector<N>,
    upper: &JointVector<N>,
    free: &mut usize,
) -> Result<SnsLevel<N>, StackError> {
    let above = workspace.solution.velocity;
    workspace
        .saturated_projector
        .copy_from(&workspace.projector);
    // The level before any saturation, with its own (warm) decomposition, which also gives P_k.
    // The rank of J_k P_{k−1}: a saturation that lowers the rank of the level leaves it unsolvable in the joints left
    // (the paper's singular case). None for the joint-space target, whose every saturation takes one direction.
    let mut level_rank = None;
    let mut terms = match kind {
        Level::Task(_, task) => {
            let svd = &mut workspace.svds[level];
            let terms = task_terms(
                parameters,
                workspace_buffers(
                    &mut workspace.limited,
                    &mut workspace.desired,
                    &mut workspace.coupling,
                ),
                svd,
                task,
                &workspace.projector,
                &above,
                level,
            )?;
            level_rank = Some(svd.rank());
            *free = free.saturating_sub(svd.rank());
            if *free == 0 {
                workspace.projector.fill(0.0);
            } else {
                svd.subtract_row_space_projector(&mut workspace.projector);
            }
            terms
        }
        Level::JointTarget(target) => {
            let terms = joint_target_terms(&workspace.projector, target, &above);
            *free = 0;
            workspace.projector.fill(0.0);
            terms
        }
    };
    let mut saturated = [false; N];
    let mut best: Option<(f64, JointVector<N>)> = None;
    let mut base = above;
    let outcome = loop {
        let scaling = task_scaling(&terms, lower, upper, &saturated);
        if let Some(scale) = scaling.feasible {
            if scale >= 1.0 {
                workspace.solution.velocity = terms.base + terms.scaled;
                break LevelOutcome::Met;
            }
            if best.as_ref().is_none_or(|(s, _)| scale > *s) {
                best = Some((scale, terms.base + terms.scaled * scale));
            }
        }
        // Saturate the most critical joint at the bound its full velocity passes, if it can still move on its own.
        let Some(joint) = scaling.critical else {
            break LevelOutcome::Dropped;
        };
        let pivot = workspace.saturated_projector[(joint, joint)];
        if pivot <= SATURATION_PIVOT_FLOOR {
            break LevelOutcome::Dropped;
        }
        let full = terms.base[joint] + terms.scaled[joint];
        let bound = if full > upper[joint] {
            upper[joint]
        } else {
            lower[joint]
        };
        let direction = workspace.saturated_projector.column(joint).clone_owned();
        base.axpy((bound - base[joint]) / pivot, &direction, 1.0);
        base[joint] = bound;
        workspace
            .saturated_projector
            .ger(-1.0 / pivot, &direction, &direction, 1.0);
        crate::linalg::symmetrize(&mut workspace.saturated_projector);
        saturated[joint] = true;
        terms = match kind {
            Level::Task(_, task) => {
                let terms = task_terms(
                    parameters,
                    workspace_buffers(
                        &mut workspace.limited,
                        &mut workspace.desired,
                        &mut workspace.coupling,
                    ),
                    &mut workspace.saturated_svd,
                    task,
                    &workspace.saturated_projector,
                    &base,
                    level,
                )?;
                if level_rank.is_some_and(|rank| workspace.saturated_svd.rank() < rank) {
                    break LevelOutcome::Dropped;
                }
                terms
            }
            Level::JointTarget(target) => {
                joint_target_terms(&workspace.saturated_projector, target, &base)
            }
        };
    };
    let outcome = match (outcome, best) {
        (LevelOutcome::Met, _) => LevelOutcome::Met,
        (_, Some((scale, velocity))) => {
            workspace.solution.velocity = velocity;
            LevelOutcome::Scaled { scale }
        }
        (_, None) => {
            workspace.solution.velocity = above;
            LevelOutcome::Dropped
        }
    };
    Ok(SnsLevel {
        task: task_of(kind),
        outcome,
        saturated,
    })
}

/// The storage a task level is solved in.
pub(super) struct Buffers<'a, const N: usize> {
    limited: &'a mut TaskJacobian<N>,
    desired: &'a mut DVector<f64>,
    coupling: &'a mut DVector<f64>,
}

pub(super) fn workspace_buffers<'a, const N: usize>(
    limited: &'a mut TaskJacobian<N>,
    desired: &'a mut DVector<f64>,
    coupling: &'a mut DVector<f64>,
) -> Buffers<'a, N> {
    Buffers {
        limited,
        desired,
        coupling,
    }
}

/// `a = (J P)⁺ ẋ` with `ẋ = −λ e`, and `b = q̃ − (J P)⁺ J q̃`, for a task level.
pub(super) fn task_terms<const N: usize>(
    parameters: &StackParameters,
    buffers: Buffers<'_, N>,
    svd: &mut ColumnSvd<N>,
    task: &TaskValue<N>,
    projector: &JointMatrix<N>,
    base: &JointVector<N>,
    level: usize,
) -> Result<LevelTerms<N>, StackError> {
    let rows = task.rows();
    let mut w = buffers.limited.rows_mut(0, rows);
    let mut coupling = buffers.coupling.rows_mut(0, rows);
    let mut desired = buffers.desired.rows_mut(0, rows);
    mul_rows_and_vector_to(task.jacobian(), projector, base, &mut w, &mut coupling);
    coupling.neg_mut();
    desired.zip_apply(task.error(), |d, e| *d = -task.gain() * e);
    let linalg = |source| StackError::Linalg { level, source };
    svd.decompose_warm(&mut w, &parameters.rank_policy, task.jacobian().norm())
        .map_err(linalg)?;
    let mut scaled = JointVector::zeros();
    let mut correction = JointVector::zeros();
    svd.solve(&w, &desired, parameters.velocity_inverse, &mut scaled)
        .map_err(linalg)?;
    svd.solve(&w, &coupling, parameters.velocity_inverse, &mut correction)
        .map_err(linalg)?;
    Ok(LevelTerms {
        scaled,
        base: base + correction,
    })
}

/// `a = P q̇*` and `b = q̃ − P q̃` for the joint-space target (`J = I`, whose limited Jacobian `P` is its own
/// pseudo-inverse).
pub(super) fn joint_target_terms<const N: usize>(
    projector: &JointMatrix<N>,
    target: &JointVector<N>,
    base: &JointVector<N>,
) -> LevelTerms<N> {
    LevelTerms {
        scaled: projector * target,
        base: base - projector * base,
    }
}

/// The task scaling factor of a level and its most critical joint.
struct Scaling {
    /// The largest `s ∈ [0, 1]` with `b + s a` in the box on the unsaturated joints; `None` when none is.
    feasible: Option<f64>,
    /// The joint to saturate next: the one that limits `s` below 1, or, when no `s ≤ 1` fits, one that needs `s > 1`
    /// or that `a` does not move and is outside; `None` when `s = 1` fits.
    critical: Option<usize>,
}

fn task_scaling<const N: usize>(
    terms: &LevelTerms<N>,
    lower: &JointVector<N>,
    upper: &JointVector<N>,
    saturated: &[bool; N],
) -> Scaling {
    // Per unsaturated joint, the interval [from, to] of s that keeps b + s a in its box (empty: from > to).
    let (mut smallest_to, mut to_joint) = (f64::INFINITY, None);
    let (mut largest_from, mut from_joint) = (f64::NEG_INFINITY, None);
    for i in (0..N).filter(|&i| !saturated[i]) {
        let (lo, hi) = (widened(lower[i], -1.0), widened(upper[i], 1.0));
        let (a, b) = (terms.scaled[i], terms.base[i]);
        let (from, to) = if a.abs() <= f64::EPSILON * b.abs().max(1.0) {
            if lo <= b && b <= hi {
                (f64::NEG_INFINITY, f64::INFINITY)
            } else {
                (f64::INFINITY, f64::NEG_INFINITY)
            }
        } else if a > 0.0 {
            ((lo - b) / a, (hi - b) / a)
        } else {
            ((hi - b) / a, (lo - b) / a)
        };
        if to < smallest_to || to_joint.is_none() && to == smallest_to {
            (smallest_to, to_joint) = (to, Some(i));
        }
        if from > largest_from || from_joint.is_none() && from == largest_from {
            (largest_from, from_joint) = (from, Some(i));
        }
    }
    let top = smallest_to.min(1.0);
    let feasible = (top >= 0.0 && largest_from <= top).then_some(top);
    let critical = if smallest_to < 1.0 {
        to_joint
    } else if largest_from > 1.0 {
        from_joint
    } else {
        None
    };
    Scaling { feasible, critical }
}

/// `bound` moved outwards (`side` −1 for a lower bound, +1 for an upper one) by the box tolerance; infinite bounds stay.
pub(super) fn widened(bound: f64, side: f64) -> f64 {
    if bound.is_finite() {
        bound + side * BOX_TOLERANCE * (1.0 + bound.abs())
    } else {
        bound
    }
}

/// The largest `σ ∈ [0, 1]` with `law + σ (candidate − law)` in the box, applied to `candidate`: how the transition
/// term of D1 is kept inside the hard bounds ([theory §13](crate::theory#s13)). `law` must lie in the box; `candidate`
/// is unchanged when it already does.
pub fn pull_into_box<const N: usize>(
    law: &JointVector<N>,
    candidate: &mut JointVector<N>,
    lower: &JointVector<N>,
    upper: &JointVector<N>,
) {
    let mut sigma: f64 = 1.0;
    for i in 0..N {
        let offset = candidate[i] - law[i];
        if candidate[i] > upper[i] && offset > 0.0 {
            sigma = sigma.min(((upper[i] - law[i]) / offset).max(0.0));
        } else if candidate[i] < lower[i] && offset < 0.0 {
            sigma = sigma.min(((lower[i] - law[i]) / offset).max(0.0));
        }
    }
    if sigma < 1.0 {
        for i in 0..N {
            candidate[i] = (law[i] + sigma * (candidate[i] - law[i])).clamp(lower[i], upper[i]);
        }
    }
}

/// A control law solved inside the box of [`SnsBounds`] ([`crate::law::ControlWorkspace::bound`]): each step, the box
/// at `q` after the velocity sent, then the solver of the workspace `W` within it. SNS ([`SnsLaw`]) and the QP cascade
/// ([`crate::law::hqp`]) are the two.
#[derive(Debug, Clone)]
pub(crate) struct BoxedLaw<const N: usize, W> {
    bounds: SnsBounds<N>,
    workspace: W,
    lower: JointVector<N>,
    upper: JointVector<N>,
}

/// SNS as the control law's solver ([`crate::law::ControlWorkspace::saturate_in_null_space`]).
pub(crate) type SnsLaw<const N: usize> = BoxedLaw<N, SnsWorkspace<N>>;

/// A workspace that solves the stack within a velocity box: [`solve_sns`]'s, and the QP cascade's.
pub(crate) trait BoxSolver<const N: usize> {
    /// Its error, which a box that is not an interval becomes.
    type Error: From<SnsError>;

    /// The velocity of the stack `order` of `tasks` in `[lower, upper]`, with the joint-space target last.
    fn solve_in_box(
        &mut self,
        parameters: &StackParameters,
        tasks: &[TaskValue<N>],
        order: &[usize],
        joint_target: Option<&JointVector<N>>,
        lower: &JointVector<N>,
        upper: &JointVector<N>,
    ) -> Result<JointVector<N>, Self::Error>;
}

impl<const N: usize> BoxSolver<N> for SnsWorkspace<N> {
    type Error = SnsError;

    fn solve_in_box(
        &mut self,
        parameters: &StackParameters,
        tasks: &[TaskValue<N>],
        order: &[usize],
        joint_target: Option<&JointVector<N>>,
        lower: &JointVector<N>,
        upper: &JointVector<N>,
    ) -> Result<JointVector<N>, SnsError> {
        solve_sns(parameters, self, tasks, order, joint_target, lower, upper)
            .map(|solution| *solution.velocity())
    }
}

impl<const N: usize, W> BoxedLaw<N, W> {
    pub(crate) fn new(bounds: SnsBounds<N>, workspace: W) -> Self {
        Self {
            bounds,
            workspace,
            lower: JointVector::zeros(),
            upper: JointVector::zeros(),
        }
    }

    /// The law's velocity: the box at `q` after the velocity `previous`, then the workspace's solver within it, with
    /// the joint-space target of the last level.
    pub(crate) fn solve(
        &mut self,
        parameters: &StackParameters,
        tasks: &[TaskValue<N>],
        order: &[usize],
        joint_target: Option<&JointVector<N>>,
        q: &JointVector<N>,
        previous: &JointVector<N>,
    ) -> Result<JointVector<N>, W::Error>
    where
        W: BoxSolver<N>,
    {
        self.bounds
            .velocity_box(q, previous, &mut self.lower, &mut self.upper)?;
        self.workspace.solve_in_box(
            parameters,
            tasks,
            order,
            joint_target,
            &self.lower,
            &self.upper,
        )
    }

    /// The workspace of the last solve.
    pub(crate) fn workspace(&self) -> &W {
        &self.workspace
    }

    /// [`pull_into_box`] with the last step's box.
    pub(crate) fn keep_in_box(&self, law: &JointVector<N>, candidate: &mut JointVector<N>) {
        pull_into_box(law, candidate, &self.lower, &self.upper);
    }
}
