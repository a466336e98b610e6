//! The complete control law: task stack, projected-gradient avoidance and continuity ([\[M18\]](crate::theory#m18), [(F19)](crate::theory#f19), [D1](crate::theory#d1)).
//!
//! ```text
//! u(t)  = q̇_n(t) − κ P^A_n ∇h(q)                                   (stack [M14] + avoidance [M18])
//! q̇(t) = u(t) + e^{−μ (t−τ)} ( q̇(τ⁻) − u(τ) )                     (transition over the full law, D1)
//! ```
//!
//! [`control_step`] evaluates one step from evaluated tasks ([`crate::task::TaskValue`]), a stack order, an optional
//! cost ([`crate::avoidance::Cost`]) and the time. It is a free function on a model ([`ControlLaw`], immutable) and a
//! workspace ([`ControlWorkspace`], allocated once): it allocates nothing and returns a [`ControlOutput`] that borrows
//! the workspace. The workspace remembers the last velocity it returned; when the caller says the stack changed at this
//! step, that velocity becomes `q̇(τ⁻)` and the new law is blended from it, so `q̇(τ⁺) = q̇(τ⁻)` exactly. A fresh
//! workspace starts at rest: its first step is a switch from `q̇ = 0` (ViSP's smooth start).
//!
//! The avoidance gradient goes through `P^A_n` by default; for a one-level stack a law may use ViSP's large projection
//! operator instead ([`AvoidanceProjection::NormPreserving`], [D16](crate::theory#d16)), which acts even when the task
//! has full rank while leaving the decay of `‖e‖` to the task.
//!
//! ```
//! use servostack::law::{control_step, ControlLaw, ControlWorkspace, StackChange};
//! use servostack::task::{TaskValue, TaskJacobian};
//! use servostack::avoidance::{Cost, JointLimits};
//! use nalgebra::{DVector, Vector3};
//!
//! let task = TaskValue::<3>::from_parts("x", DVector::from_vec(vec![0.2]), TaskJacobian::from_row_slice(&[1.0, 0.0, 0.0]), 1.0)?;
//! let tasks = [task];
//! let limits = JointLimits::new(Vector3::repeat(-1.0), Vector3::repeat(1.0), 0.1)?;
//! let law = ControlLaw::new(10.0, 0.5)?; // μ = 10 s⁻¹, κ = 0.5 s⁻¹
//! let mut workspace = ControlWorkspace::new(&tasks);
//! let q = Vector3::new(0.0, 0.95, 0.0); // joint 1 deep in its activation band
//! let first = control_step(&law, &mut workspace, &tasks, &[0], Some(&limits as &dyn Cost<3>), &q, 0.0, StackChange::Changed)?;
//! assert_eq!(first.velocity().norm(), 0.0); // smooth start from rest
//! let later = control_step(&law, &mut workspace, &tasks, &[0], Some(&limits as &dyn Cost<3>), &q, 1.0, StackChange::Unchanged)?;
//! assert!(later.law()[0] < 0.0 && later.law()[1] < 0.0); // task drives joint 0, avoidance pulls joint 1 back
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::avoidance::{Cost, CostError, JointLimits};
use crate::bounds::{GAIN_PER_S, TRANSITION_GAIN_PER_S};
use crate::continuity::Transition;
use crate::math::{first_non_finite, JointVector};
use crate::stack::{solve_stack, StackError, StackParameters, StackSolution, StackWorkspace};
use crate::task::TaskValue;

pub mod hqp;
pub mod sns;
use hqp::{HqpError, HqpLaw, HqpParameters, HqpSolution, HqpWorkspace};
use sns::{SnsBounds, SnsError, SnsLaw, SnsSolution, SnsWorkspace};

/// Errors of the control law.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LawError {
    /// The transition gain `μ` must lie in [`TRANSITION_GAIN_PER_S`] (s⁻¹): a slower transition than 1000 s, or a
    /// faster one than a microsecond, is a unit error, and `1/μ` sets the controller's prediction horizon.
    #[error("transition gain μ = {mu} must be finite, within [1e-3, 1e6] s⁻¹")]
    InvalidTransitionGain {
        /// The gain given.
        mu: f64,
    },
    /// The avoidance gain `κ` must lie in [`GAIN_PER_S`] (s⁻¹).
    #[error("avoidance gain κ = {kappa} must be finite, within [0, 1e6] s⁻¹")]
    InvalidAvoidanceGain {
        /// The gain given.
        kappa: f64,
    },
    /// The time is not finite, or earlier than the last stack modification.
    #[error(
        "time t = {time} s is not finite or precedes the last stack change τ = {switch_time} s"
    )]
    InvalidTime {
        /// The time given.
        time: f64,
        /// The time of the last stack change.
        switch_time: f64,
    },
    /// The time does not increase strictly from the last step: the law's clock (and the transition's decay) would run
    /// backwards or stand still.
    #[error("time t = {time} s is not after the last step's time {previous} s")]
    TimeNotIncreasing {
        /// The time given (s).
        time: f64,
        /// The time of the last step (s).
        previous: f64,
    },
    /// The joint configuration holds a NaN or an infinity.
    #[error("joint {joint} = {value} is not finite")]
    NonFiniteConfiguration {
        /// The first offending joint (0-based).
        joint: usize,
        /// Its value.
        value: f64,
    },
    /// The stack solve failed.
    #[error(transparent)]
    Stack(#[from] StackError),
    /// The avoidance cost failed.
    #[error(transparent)]
    Cost(#[from] CostError),
    /// The law produced a non-finite velocity (for example, a cost gradient overflowed).
    #[error("the control law produced a non-finite velocity")]
    NonFiniteVelocity,
    /// The lock band of D26 is outside `(0, 0.5)` (a fraction of each joint's range).
    #[error("lock band {band} must be within (0, 0.5) of a joint's range")]
    InvalidLockBand {
        /// The band given.
        band: f64,
    },
    /// The sigmoid bounds of [`AvoidanceProjection::NormPreserving`] must be finite with `0 ≤ lower < upper`.
    #[error("norm-preserving projection bounds {lower} .. {upper} must be finite with 0 ≤ lower < upper")]
    InvalidProjectionBounds {
        /// The lower bound given.
        lower: f64,
        /// The upper bound given.
        upper: f64,
    },
    /// The SNS solve or its bounds failed.
    #[error(transparent)]
    Sns(#[from] SnsError),
    /// SNS takes the avoidance term as its last level `J = I`, which is the kernel projection
    /// ([`AvoidanceProjection::Kernel`]) when no bound is active; another projection has no SNS counterpart.
    #[error("saturation in the null space needs the kernel avoidance projection")]
    SnsNeedsKernelProjection,
    /// The QP cascade failed (its parameters, the box, a level's QP).
    #[error(transparent)]
    Hqp(#[from] HqpError),
    /// The QP cascade takes the avoidance term as its last level `J = I`, which is the kernel projection when no bound
    /// is active, as SNS does ([`LawError::SnsNeedsKernelProjection`]).
    #[error("the hierarchical QP needs the kernel avoidance projection")]
    HqpNeedsKernelProjection,
    /// [`AvoidanceProjection::NormPreserving`] is defined for a stack of one level only.
    #[error("the norm-preserving projection needs a stack of one level, not {levels}")]
    NormPreservingNeedsOneLevel {
        /// The number of levels of the stack given.
        levels: usize,
    },
}

/// The projector the avoidance gradient goes through ([D16](crate::theory#d16)).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum AvoidanceProjection {
    /// `P^A_n`, the projector onto the kernel of the whole stack ([\[M18\]](crate::theory#m18)): the avoidance never
    /// disturbs a task. The paper's law, and the default.
    #[default]
    Kernel,
    /// ViSP's large projection operator (`vpServo::secondaryTaskJointLimitAvoidance`; Marey & Chaumette, ICRA 2010) for a
    /// stack of one level `(e, J)`, with `g = Jᵀ e`:
    ///
    /// ```text
    /// P = s(‖e‖) (I − g gᵀ / ‖g‖²) + (1 − s(‖e‖)) P^A_1
    /// s(x) = 0 for x < lower,  1 for x > upper,  1 / (1 + exp(−12 (x − lower)/(upper − lower) + 6)) between
    /// ```
    ///
    /// `eᵀ J P ∇h = s eᵀ J (I − g gᵀ/‖g‖²) ∇h = 0`: the avoidance leaves `d‖e‖²/dt` unchanged (the norm of the error still
    /// decays as the task alone makes it), but it may change the error's direction. Far from the goal it acts even
    /// when the task has full rank (`P^A_1 = 0`); near the goal (`‖e‖ < lower`) it is the kernel projector. ViSP's
    /// bounds are `lower = 0.1`, `upper = 0.7`, in the task's units.
    NormPreserving {
        /// `‖e‖` below which the kernel projector alone acts.
        lower: f64,
        /// `‖e‖` above which the norm-preserving projector alone acts.
        upper: f64,
    },
}

impl AvoidanceProjection {
    /// ViSP's bounds, `NormPreserving { lower: 0.1, upper: 0.7 }`.
    pub const VISP: Self = Self::NormPreserving {
        lower: 0.1,
        upper: 0.7,
    };

    /// Checks the bounds.
    ///
    /// # Errors
    /// [`LawError::InvalidProjectionBounds`].
    pub fn validate(&self) -> Result<(), LawError> {
        match *self {
            Self::Kernel => Ok(()),
            Self::NormPreserving { lower, upper }
                if lower.is_finite() && upper.is_finite() && 0.0 <= lower && lower < upper =>
            {
                Ok(())
            }
            Self::NormPreserving { lower, upper } => {
                Err(LawError::InvalidProjectionBounds { lower, upper })
            }
        }
    }

    /// `P ∇h` for the stack `order` of `tasks` whose solution is `solution` (`P = P^A_n` for [`Self::Kernel`]).
    fn project<const N: usize>(
        &self,
        solution: &StackSolution<N>,
        tasks: &[TaskValue<N>],
        order: &[usize],
        gradient: &JointVector<N>,
    ) -> Result<JointVector<N>, LawError> {
        let kernel = solution.projector() * gradient;
        let Self::NormPreserving { lower, upper } = *self else {
            return Ok(kernel);
        };
        let task = match order {
            [index] => tasks.get(*index).ok_or(StackError::UnknownTask {
                level: 0,
                task: *index,
                available: tasks.len(),
            })?,
            _ => {
                return Err(LawError::NormPreservingNeedsOneLevel {
                    levels: order.len(),
                })
            }
        };
        let norm = task.error().norm();
        let weight = if norm < lower {
            0.0
        } else if norm > upper {
            1.0
        } else {
            1.0 / (1.0 + (-12.0 * (norm - lower) / (upper - lower) + 6.0).exp())
        };
        let g: JointVector<N> = task.jacobian().tr_mul(task.error());
        let g_sq = g.norm_squared();
        if weight == 0.0 || g_sq == 0.0 {
            return Ok(kernel);
        }
        let mut projected = gradient - g * (g.dot(gradient) / g_sq);
        projected *= weight;
        projected.axpy(1.0 - weight, &kernel, 1.0);
        // Locked joints stay still (D26).
        for (value, _) in projected
            .iter_mut()
            .zip(solution.locked_joints())
            .filter(|(_, &l)| l)
        {
            *value = 0.0;
        }
        Ok(projected)
    }
}

/// The model of the control law: how the stack is inverted and the gains `μ` and `κ`. Immutable after construction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlLaw {
    stack: StackParameters,
    transition_gain: f64,
    avoidance_gain: f64,
    projection: AvoidanceProjection,
}

impl ControlLaw {
    /// The ratio `μ / max_i λ_i` of the paper ([theory §3](crate::theory#s3), [D1](crate::theory#d1)).
    pub const TRANSITION_TO_TASK_GAIN_RATIO: f64 = 10.0;

    /// A law with transition gain `μ` (s⁻¹, > 0) and avoidance gain `κ` (s⁻¹, ≥ 0; 0 disables avoidance), and the
    /// default stack parameters.
    ///
    /// # Errors
    /// [`LawError::InvalidTransitionGain`], [`LawError::InvalidAvoidanceGain`].
    pub fn new(transition_gain: f64, avoidance_gain: f64) -> Result<Self, LawError> {
        Self::with_stack_parameters(StackParameters::default(), transition_gain, avoidance_gain)
    }

    /// A law with `μ = 10 · max_i λ_i` over `tasks` ([D1](crate::theory#d1)) and avoidance gain `κ`.
    ///
    /// # Errors
    /// As [`ControlLaw::new`]; an empty task list gives [`LawError::InvalidTransitionGain`] with `μ = 0`.
    pub fn with_default_transition<const N: usize>(
        tasks: &[TaskValue<N>],
        avoidance_gain: f64,
    ) -> Result<Self, LawError> {
        let max_gain = tasks.iter().map(TaskValue::gain).fold(0.0, f64::max);
        Self::new(
            Self::TRANSITION_TO_TASK_GAIN_RATIO * max_gain,
            avoidance_gain,
        )
    }

    /// A law with explicit stack parameters.
    ///
    /// # Errors
    /// As [`ControlLaw::new`], plus invalid stack parameters.
    pub fn with_stack_parameters(
        stack: StackParameters,
        transition_gain: f64,
        avoidance_gain: f64,
    ) -> Result<Self, LawError> {
        stack.validate()?;
        if !TRANSITION_GAIN_PER_S.contains(transition_gain) {
            return Err(LawError::InvalidTransitionGain {
                mu: transition_gain,
            });
        }
        if !GAIN_PER_S.contains(avoidance_gain) {
            return Err(LawError::InvalidAvoidanceGain {
                kappa: avoidance_gain,
            });
        }
        Ok(Self {
            stack,
            transition_gain,
            avoidance_gain,
            projection: AvoidanceProjection::Kernel,
        })
    }

    /// The same law with the avoidance gradient projected by `projection` ([D16](crate::theory#d16)).
    ///
    /// # Errors
    /// [`LawError::InvalidProjectionBounds`].
    pub fn with_avoidance_projection(
        mut self,
        projection: AvoidanceProjection,
    ) -> Result<Self, LawError> {
        projection.validate()?;
        self.projection = projection;
        Ok(self)
    }

    /// The projector of the avoidance gradient.
    pub fn avoidance_projection(&self) -> AvoidanceProjection {
        self.projection
    }

    /// The avoidance term `−κ P ∇h` for the stack `order` of `tasks`, solved into `solution` (`P = P^A_n` by default,
    /// [D16](crate::theory#d16)).
    ///
    /// # Errors
    /// [`LawError::NormPreservingNeedsOneLevel`] for a norm-preserving projection on a stack of another size.
    pub fn avoidance_term<const N: usize>(
        &self,
        solution: &StackSolution<N>,
        tasks: &[TaskValue<N>],
        order: &[usize],
        gradient: &JointVector<N>,
    ) -> Result<JointVector<N>, LawError> {
        Ok(self.projection.project(solution, tasks, order, gradient)? * -self.avoidance_gain)
    }

    /// The stack parameters.
    pub fn stack_parameters(&self) -> &StackParameters {
        &self.stack
    }

    /// `μ` (s⁻¹).
    pub fn transition_gain(&self) -> f64 {
        self.transition_gain
    }

    /// `κ` (s⁻¹).
    pub fn avoidance_gain(&self) -> f64 {
        self.avoidance_gain
    }
}

/// Whether the stack order given to [`control_step`] differs from the previous step's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StackChange {
    /// Same stack as the previous step: the transition keeps decaying.
    Unchanged,
    /// A task was pushed or removed at this step: `τ ← t` and the transition restarts from the last velocity sent.
    Changed,
}

/// The result of one control step.
#[derive(Debug, Clone, PartialEq)]
pub struct ControlOutput<const N: usize> {
    velocity: JointVector<N>,
    law: JointVector<N>,
    gradient: JointVector<N>,
    cost: f64,
    decay: f64,
}

impl<const N: usize> ControlOutput<N> {
    /// The joint velocity to send, `q̇(t)` ([D1](crate::theory#d1)): finite by construction.
    pub fn velocity(&self) -> &JointVector<N> {
        &self.velocity
    }

    /// The law without the transition term, `u(t) = q̇_n − κ P^A_n ∇h`.
    pub fn law(&self) -> &JointVector<N> {
        &self.law
    }

    /// The cost gradient `∇h(q)` (zero without a cost).
    pub fn gradient(&self) -> &JointVector<N> {
        &self.gradient
    }

    /// The cost `h(q)` (zero without a cost).
    pub fn cost(&self) -> f64 {
        self.cost
    }

    /// The transition factor `e^{−μ(t−τ)}` at this step.
    pub fn decay(&self) -> f64 {
        self.decay
    }
}

/// Preallocated storage and memory (`q̇(τ⁻)`, `τ`, `u(τ)`) of the control law.
#[derive(Debug, Clone)]
pub struct ControlWorkspace<const N: usize> {
    stack: StackWorkspace<N>,
    /// How the law meets the hard joint limits.
    hard_limits: HardLimits<N>,
    transition: Transition<N>,
    output: ControlOutput<N>,
}

/// How the law meets the hard joint limits.
#[derive(Debug, Clone)]
enum HardLimits<const N: usize> {
    /// Not at all in the law: the stack law of the paper (the avoidance cost keeps away from them).
    Ignored,
    /// The lock of D26: the limits and the band.
    Lock(JointLimits<N>, f64),
    /// Saturation in the null space ([`sns`], theory §13).
    Saturate(Box<SnsLaw<N>>),
    /// The hierarchical QP cascade ([`hqp`], theory §14).
    Cascade(Box<HqpLaw<N>>),
}

/// A law that keeps every joint velocity inside the box of hard bounds ([`SnsBounds`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoundedLaw {
    /// Saturation in the null space ([`ControlWorkspace::saturate_in_null_space`], theory §13).
    SaturationInNullSpace,
    /// The hierarchical QP cascade with the default [`HqpParameters`] ([`ControlWorkspace::solve_as_hierarchical_qp`],
    /// theory §14).
    HierarchicalQp,
}

/// The memory of the law ([`ControlWorkspace::memory`]): the transition state, the last velocity returned and the
/// joints locked at the last step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LawMemory<const N: usize> {
    transition: Transition<N>,
    velocity: JointVector<N>,
    locked: [bool; N],
}

impl<const N: usize> LawMemory<N> {
    /// The last velocity returned (or reported sent): `q̇(τ⁻)` of a change made at the next step.
    pub fn velocity(&self) -> &JointVector<N> {
        &self.velocity
    }
}

impl<const N: usize> ControlWorkspace<N> {
    /// A workspace for stacks of `tasks`, at rest (`q̇ = 0`).
    pub fn new(tasks: &[TaskValue<N>]) -> Self {
        Self {
            stack: StackWorkspace::new(tasks),
            hard_limits: HardLimits::Ignored,
            transition: Transition::default(),
            output: ControlOutput {
                velocity: JointVector::zeros(),
                law: JointVector::zeros(),
                gradient: JointVector::zeros(),
                cost: 0.0,
                decay: 0.0,
            },
        }
    }

    /// The stack solution of the last step (`q̇_n`, `P^A_n`, per-level diagnostics).
    pub fn stack_solution(&self) -> &StackSolution<N> {
        self.stack.solution()
    }

    /// The law slides along the hard limits `limits` ([D26](crate::theory#d26)): at each step, a joint within
    /// `band · Δq_i` of a limit (`band` a fraction of the range, in `(0, 0.5)`) that the law drives towards it is held
    /// still, and the stack and its avoidance term are solved again on the other joints
    /// ([`StackWorkspace::lock_joints`]), until no joint in the band is driven in. A change of the locked joints
    /// restarts the transition from the last velocity, as a stack change does, so the velocity stays continuous.
    /// Replaces the saturation in the null space if it was set ([`Self::saturate_in_null_space`]).
    ///
    /// # Errors
    /// [`LawError::InvalidLockBand`] for a band outside `(0, 0.5)`.
    pub fn lock_at_limits(&mut self, limits: JointLimits<N>, band: f64) -> Result<(), LawError> {
        if !(band > 0.0 && band < 0.5) {
            return Err(LawError::InvalidLockBand { band });
        }
        self.hard_limits = HardLimits::Lock(limits, band);
        Ok(())
    }

    /// The law keeps every joint velocity inside the box of `bounds` by saturation in the null space (SNS,
    /// [theory §13](crate::theory#s13), [`sns`]): the stack's levels, then the avoidance term `−κ∇h` as a last
    /// joint-space level, each re-solved in the joints left after saturating those that would leave the box, scaled
    /// down only when they cannot be met. The transition of D1 is kept inside the box ([`sns::pull_into_box`]).
    /// Replaces the lock of D26 if it was set.
    pub fn saturate_in_null_space(&mut self, bounds: SnsBounds<N>) {
        let (max_rows, max_levels) = self.stack.capacity();
        self.hard_limits = HardLimits::Saturate(Box::new(SnsLaw::new(
            bounds,
            SnsWorkspace::with_capacity(max_rows, max_levels),
        )));
    }

    /// The law keeps every joint velocity inside the box of `bounds` as the hierarchical QP cascade
    /// ([theory §14](crate::theory#s14), [`hqp`]): the stack's levels, then the avoidance term `−κ∇h` (or `0`) as a
    /// last joint-space level, each a least-squares problem in the box that keeps the levels above at their optimum.
    /// The transition of D1 is kept inside the box as for SNS ([`sns::pull_into_box`]). Replaces the lock of D26 and
    /// the saturation in the null space if either was set.
    ///
    /// # Errors
    /// Invalid `parameters` ([`HqpParameters::validate`]).
    pub fn solve_as_hierarchical_qp(
        &mut self,
        bounds: SnsBounds<N>,
        parameters: &HqpParameters,
    ) -> Result<(), LawError> {
        let (max_rows, max_levels) = self.stack.capacity();
        let law = HqpLaw::new(
            bounds,
            HqpWorkspace::with_capacity(max_rows, max_levels, parameters)?,
        );
        self.hard_limits = HardLimits::Cascade(Box::new(law));
        Ok(())
    }

    /// Keeps the law inside the box of `bounds` by `law`, with its default settings.
    ///
    /// # Errors
    /// As [`Self::solve_as_hierarchical_qp`] (not with the default settings).
    pub fn bound(&mut self, law: BoundedLaw, bounds: SnsBounds<N>) -> Result<(), LawError> {
        match law {
            BoundedLaw::SaturationInNullSpace => {
                self.saturate_in_null_space(bounds);
                Ok(())
            }
            BoundedLaw::HierarchicalQp => {
                self.solve_as_hierarchical_qp(bounds, &HqpParameters::default())
            }
        }
    }

    /// The cascade's solve of the last step, when the law is the hierarchical QP.
    pub fn hqp_solution(&self) -> Option<&HqpSolution<N>> {
        match &self.hard_limits {
            HardLimits::Cascade(hqp) => Some(hqp.workspace().solution()),
            _ => None,
        }
    }

    /// The SNS solve of the last step, when the law saturates in the null space.
    pub fn sns_solution(&self) -> Option<&SnsSolution<N>> {
        match &self.hard_limits {
            HardLimits::Saturate(sns) => Some(sns.workspace().solution()),
            _ => None,
        }
    }

    /// The joints the last step held still (D26).
    pub fn locked_joints(&self) -> &[bool; N] {
        self.stack.locked_joints()
    }

    /// The transition state (`τ`, `q̇(τ⁻)`).
    pub fn transition(&self) -> &Transition<N> {
        &self.transition
    }

    /// The output of the last step; its velocity is the `q̇(τ⁻)` of the next stack change.
    pub fn last_output(&self) -> &ControlOutput<N> {
        &self.output
    }

    /// Forgets the past: the next change starts from `velocity` (use `zeros` to start at rest).
    pub fn reset(&mut self, velocity: &JointVector<N>) {
        self.transition = Transition::default();
        self.output.velocity.copy_from(velocity);
    }

    /// Replaces the last velocity returned by the one the robot actually received (after a saturation, say): the next
    /// stack change blends from it (`q̇(τ⁻)`), so continuity holds for what was sent. The transition under way is kept.
    pub fn set_sent_velocity(&mut self, velocity: &JointVector<N>) {
        self.output.velocity.copy_from(velocity);
    }

    /// The memory of the law: the transition state, the last velocity returned and the joints locked.
    pub fn memory(&self) -> LawMemory<N> {
        LawMemory {
            transition: self.transition,
            velocity: self.output.velocity,
            locked: *self.stack.locked_joints(),
        }
    }

    /// Restores a memory taken by [`Self::memory`] (a step whose velocity was not sent leaves no trace).
    pub fn restore(&mut self, memory: LawMemory<N>) {
        self.transition = memory.transition;
        self.output.velocity = memory.velocity;
        self.stack.lock_joints(&memory.locked);
    }
}

/// One step of the control law [D1](crate::theory#d1)/[\[M18\]](crate::theory#m18) at time `time` (s) for the configuration `q`, the evaluated `tasks` stacked in
/// `order` (highest priority first) and an optional avoidance `cost`.
///
/// # Errors
/// Non-finite `q` or time, a time before the last change `τ` (a fresh workspace has `τ = 0`) or not strictly after the
/// last step's ([`LawError::TimeNotIncreasing`]; a step that failed does not count), stack or cost failures,
/// a non-finite result. On error the workspace keeps its transition, previous output and locked joints (the next
/// change still starts from the last velocity actually returned).
#[allow(clippy::too_many_arguments)]
pub fn control_step<'w, const N: usize>(
    law: &ControlLaw,
    workspace: &'w mut ControlWorkspace<N>,
    tasks: &[TaskValue<N>],
    order: &[usize],
    cost: Option<&dyn Cost<N>>,
    q: &JointVector<N>,
    time: f64,
    change: StackChange,
) -> Result<&'w ControlOutput<N>, LawError> {
    if let Some((joint, value)) = first_non_finite(q) {
        return Err(LawError::NonFiniteConfiguration { joint, value });
    }
    let switch_time = workspace.transition.switch_time();
    if !time.is_finite() || time < switch_time {
        return Err(LawError::InvalidTime { time, switch_time });
    }
    let previous = workspace.transition.last_step_time();
    if time <= previous {
        return Err(LawError::TimeNotIncreasing { time, previous });
    }
    let locked_before = *workspace.stack.locked_joints();
    let (law_velocity, gradient, cost_value) =
        match solve_law(law, workspace, tasks, order, cost, q) {
            Ok(solved) => solved,
            Err(error) => {
                workspace.stack.lock_joints(&locked_before);
                return Err(error);
            }
        };
    // A change of the locked joints is a change of the law (D26): it starts a transition.
    let change = if *workspace.stack.locked_joints() != locked_before {
        StackChange::Changed
    } else {
        change
    };
    let mut transition = workspace.transition;
    if change == StackChange::Changed {
        transition.switch(time, &workspace.output.velocity, &law_velocity);
    }
    let mut velocity = JointVector::zeros();
    let decay = transition.blend(law.transition_gain, time, &law_velocity, &mut velocity);
    match &workspace.hard_limits {
        HardLimits::Saturate(sns) => sns.keep_in_box(&law_velocity, &mut velocity),
        HardLimits::Cascade(hqp) => hqp.keep_in_box(&law_velocity, &mut velocity),
        HardLimits::Ignored | HardLimits::Lock(..) => {}
    }
    // Finite norms (hence finite entries): entries whose squares overflow are no velocity to send, and the
    // controller reads ‖q̇_n‖.
    let stack_norm = workspace.stack.solution().velocity().norm();
    if !(velocity.norm().is_finite() && stack_norm.is_finite() && cost_value.is_finite()) {
        workspace.stack.lock_joints(&locked_before);
        return Err(LawError::NonFiniteVelocity);
    }
    transition.stepped_at(time);
    workspace.transition = transition;
    let output = &mut workspace.output;
    output.velocity = velocity;
    output.law = law_velocity;
    output.gradient = gradient;
    output.cost = cost_value;
    output.decay = decay;
    Ok(output)
}

/// The law `u = q̇_n − κ P ∇h` ([\[M18\]](crate::theory#m18); `∇h = 0` without a cost; `P = P^A_n` by default, D16),
/// with its gradient and cost: solved with no joint locked, then, with the lock of D26, again with every joint the law
/// presses into a limit locked, until none is (at most `N` rounds). The locked set is left in the workspace.
fn solve_law<const N: usize>(
    law: &ControlLaw,
    workspace: &mut ControlWorkspace<N>,
    tasks: &[TaskValue<N>],
    order: &[usize],
    cost: Option<&dyn Cost<N>>,
    q: &JointVector<N>,
) -> Result<(JointVector<N>, JointVector<N>, f64), LawError> {
    let mut gradient = JointVector::zeros();
    let cost_value = match cost {
        Some(cost) => cost.value_and_gradient(q, &mut gradient)?,
        None => 0.0,
    };
    let ControlWorkspace {
        stack,
        hard_limits,
        output,
        ..
    } = workspace;
    let mut locked = [false; N];
    let previous = output.velocity;
    let bounded = match hard_limits {
        HardLimits::Saturate(sns) => {
            let projection = LawError::SnsNeedsKernelProjection;
            let target = bounded_target(law, stack, tasks, order, cost, &gradient, projection)?;
            Some(sns.solve(&law.stack, tasks, order, target.as_ref(), q, &previous)?)
        }
        HardLimits::Cascade(hqp) => {
            let projection = LawError::HqpNeedsKernelProjection;
            let target = bounded_target(law, stack, tasks, order, cost, &gradient, projection)?;
            Some(hqp.solve(&law.stack, tasks, order, target.as_ref(), q, &previous)?)
        }
        HardLimits::Ignored | HardLimits::Lock(..) => None,
    };
    if let Some(velocity) = bounded {
        return Ok((velocity, gradient, cost_value));
    }
    // Each round that goes on locks one more joint: at most N + 1 solves.
    loop {
        stack.lock_joints(&locked);
        let solution = solve_stack(&law.stack, stack, tasks, order)?;
        let mut law_velocity = *solution.velocity();
        if cost.is_some() {
            law_velocity += law.avoidance_term(solution, tasks, order, &gradient)?;
        }
        let pressed = match hard_limits {
            HardLimits::Lock(limits, band) => {
                limits.lock_pressed_joints(q, &law_velocity, *band, &mut locked)
            }
            HardLimits::Ignored | HardLimits::Saturate(_) | HardLimits::Cascade(_) => false,
        };
        if !pressed {
            return Ok((law_velocity, gradient, cost_value));
        }
    }
}

/// For a law in the box of hard bounds (SNS or the QP cascade): checks that the avoidance goes through `P^A_n` (else
/// `projection_error`), solves the stack without bounds, which stays the controller's reading of the stack (`‖q̇_n‖`,
/// `P^A_n`), and returns the joint-space target `−κ∇h` of the last level (`None` without a cost).
#[allow(clippy::too_many_arguments)]
fn bounded_target<const N: usize>(
    law: &ControlLaw,
    stack: &mut StackWorkspace<N>,
    tasks: &[TaskValue<N>],
    order: &[usize],
    cost: Option<&dyn Cost<N>>,
    gradient: &JointVector<N>,
    projection_error: LawError,
) -> Result<Option<JointVector<N>>, LawError> {
    if law.projection != AvoidanceProjection::Kernel {
        return Err(projection_error);
    }
    stack.lock_joints(&[false; N]);
    solve_stack(&law.stack, stack, tasks, order)?;
    Ok(cost.is_some().then(|| gradient * -law.avoidance_gain))
}

#[cfg(test)]
mod tests;
