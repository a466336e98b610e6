//! The task abstraction: a task function `e_i` (`m_i` rows), its Jacobian `J_i = ∂e_i/∂q` (`m_i × N`) and its gain
//! `λ_i` ([theory §0](crate::theory#s0), [\[M14\]](crate::theory#m14), [(F15)](crate::theory#f15)).
//!
//! A [`Task`] evaluates itself, for the current state of the world given as a context `C`, into a [`TaskValue`] that
//! was sized once (its `m_i` rows) when the task list was built. The stack solve ([`crate::stack`]) reads only
//! `TaskValue`s, so any source of `(e, J, λ)` plugs in: visual tasks (`J_i = L_i cVe eJe`, [\[M42\]](crate::theory#m42)), or the synthetic
//! tasks of this module — a [`ConstantTask`] with given matrices, and a [`LinearTask`] `e = A (q − q*)` — that make the
//! stack testable without robots or cameras. A task may have more rows than the robot has joints (a four-point task has
//! 8).
//!
//! ```
//! use servostack::task::{ConstantTask, Task, TaskValue};
//! use nalgebra::{DVector, OMatrix, Dyn, Const};
//!
//! // A 2-row task on a 6-joint robot: e = (0.1, −0.2), J = first two rows of the identity, λ = 0.5 s⁻¹.
//! let jacobian = OMatrix::<f64, Dyn, Const<6>>::from_fn(2, |i, j| if i == j { 1.0 } else { 0.0 });
//! let task = ConstantTask::new("xy", DVector::from_vec(vec![0.1, -0.2]), jacobian, 0.5)?;
//! // A constant task accepts any context; the unit context `()` will do.
//! let mut value = TaskValue::<6>::for_task::<(), _>(&task)?;
//! task.evaluate(&(), &mut value)?;
//! assert_eq!(value.rows(), 2);
//! assert_eq!(value.error()[1], -0.2);
//! # Ok::<(), servostack::task::TaskError>(())
//! ```

use crate::math::{all_finite, JointVector};
use nalgebra::{Const, DVector, Dyn, OMatrix, U6};

/// A task Jacobian: `m` rows (run-time), `N` joint columns.
pub type TaskJacobian<const N: usize> = OMatrix<f64, Dyn, Const<N>>;

/// The interaction matrix of a sensor-based task: `m` rows, 6 columns, `ṡ = L v` for the sensor twist `v = (υ, ω)`.
pub type InteractionMatrix = OMatrix<f64, Dyn, U6>;

/// Errors of task construction and evaluation.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TaskError {
    /// A task must have at least one row.
    #[error("task `{name}` has zero rows")]
    ZeroRows {
        /// The task's name.
        name: String,
    },
    /// The gain must be finite, strictly positive and within [`crate::bounds::GAIN_PER_S`] (s⁻¹).
    #[error("task `{name}`: gain λ = {gain} must be > 0 and within [0, 1e6] s⁻¹")]
    InvalidGain {
        /// The task's name.
        name: String,
        /// The gain given.
        gain: f64,
    },
    /// The error and the Jacobian disagree on the number of rows, or a value does not fit the task's size.
    #[error("task `{name}`: {what} has {found} rows, expected {expected}")]
    DimensionMismatch {
        /// The task's name.
        name: String,
        /// Which quantity has the wrong size.
        what: &'static str,
        /// The expected number of rows.
        expected: usize,
        /// The number found.
        found: usize,
    },
    /// The task's error or Jacobian holds a NaN or an infinity.
    #[error("task `{name}`: {what} holds a non-finite value")]
    NonFinite {
        /// The task's name.
        name: String,
        /// `"error"`, `"jacobian"` or the input that was not finite.
        what: &'static str,
    },
    /// A task-specific evaluation failure, for task implementations outside this crate.
    #[error("task `{name}`: {reason}")]
    Evaluation {
        /// The task's name.
        name: String,
        /// What went wrong.
        reason: String,
    },
    /// A visual feature of the task is undefined in the current (or desired) image; the feature's error, with its
    /// values, is the source.
    #[error("task `{name}`: {source}")]
    Feature {
        /// The task's name.
        name: String,
        /// The feature's error.
        source: crate::feature::FeatureError,
    },
}

/// The evaluated task: error `e_i` (`m_i`), Jacobian `J_i` (`m_i × N`) and gain `λ_i` (s⁻¹), plus, for a sensor-based
/// task, its interaction matrix `L_i` (`m_i × 6`, with `J_i = L_i W J_q`, [\[M42\]](crate::theory#m42); zero for joint-space tasks). Its
/// storage is allocated once, by [`TaskValue::new`] or [`TaskValue::for_task`]; evaluating a task only overwrites it.
#[derive(Debug, Clone, PartialEq)]
pub struct TaskValue<const N: usize> {
    error: DVector<f64>,
    jacobian: TaskJacobian<N>,
    interaction: InteractionMatrix,
    gain: f64,
}

impl<const N: usize> TaskValue<N> {
    /// Storage for a task of `rows` rows and gain `gain` (s⁻¹), zero-filled.
    ///
    /// # Errors
    /// [`TaskError::ZeroRows`], [`TaskError::InvalidGain`].
    pub fn new(name: &str, rows: usize, gain: f64) -> Result<Self, TaskError> {
        if rows == 0 {
            return Err(TaskError::ZeroRows { name: name.into() });
        }
        validate_gain(name, gain)?;
        Ok(Self {
            error: DVector::zeros(rows),
            jacobian: TaskJacobian::zeros(rows),
            interaction: InteractionMatrix::zeros(rows),
            gain,
        })
    }

    /// Storage sized for `task`.
    ///
    /// # Errors
    /// As [`TaskValue::new`].
    pub fn for_task<C: ?Sized, T: Task<N, C> + ?Sized>(task: &T) -> Result<Self, TaskError> {
        Self::new(task.name(), task.rows(), task.gain())
    }

    /// A value from explicit matrices (a synthetic task), validated.
    ///
    /// # Errors
    /// Zero rows, mismatched sizes, non-finite entries, invalid gain.
    pub fn from_parts(
        name: &str,
        error: DVector<f64>,
        jacobian: TaskJacobian<N>,
        gain: f64,
    ) -> Result<Self, TaskError> {
        let mut value = Self::new(name, error.len(), gain)?;
        value.set(name, &error, &jacobian)?;
        Ok(value)
    }

    /// Overwrites error and Jacobian with copies of `error` and `jacobian`, after checking sizes and finiteness.
    ///
    /// # Errors
    /// [`TaskError::DimensionMismatch`], [`TaskError::NonFinite`].
    pub fn set(
        &mut self,
        name: &str,
        error: &DVector<f64>,
        jacobian: &TaskJacobian<N>,
    ) -> Result<(), TaskError> {
        check_rows(name, "error", self.rows(), error.len())?;
        check_rows(name, "jacobian", self.rows(), jacobian.nrows())?;
        self.error.copy_from(error);
        self.jacobian.copy_from(jacobian);
        self.check_finite(name)
    }

    /// Number of rows `m_i`.
    pub fn rows(&self) -> usize {
        self.error.len()
    }

    /// The task error `e_i`.
    pub fn error(&self) -> &DVector<f64> {
        &self.error
    }

    /// The task Jacobian `J_i = ∂e_i/∂q`.
    pub fn jacobian(&self) -> &TaskJacobian<N> {
        &self.jacobian
    }

    /// The gain `λ_i` (s⁻¹).
    pub fn gain(&self) -> f64 {
        self.gain
    }

    /// Replaces the gain `λ_i` (s⁻¹) for the next steps, e.g. an adaptive gain `λ(‖e_i‖)` recomputed each period
    /// ([`crate::servo::AdaptiveGain`]). `name` only labels the error.
    ///
    /// # Errors
    /// [`TaskError::InvalidGain`] when `gain` is not finite and strictly positive (the gain is then unchanged).
    pub fn set_gain(&mut self, name: &str, gain: f64) -> Result<(), TaskError> {
        validate_gain(name, gain)?;
        self.gain = gain;
        Ok(())
    }

    /// The interaction matrix `L_i` of a sensor-based task (zero for joint-space tasks).
    pub fn interaction(&self) -> &InteractionMatrix {
        &self.interaction
    }

    /// Mutable access to error and Jacobian for a [`Task::evaluate`] implementation. Sizes cannot change.
    pub fn parts_mut(&mut self) -> (&mut DVector<f64>, &mut TaskJacobian<N>) {
        (&mut self.error, &mut self.jacobian)
    }

    /// Mutable access to error, Jacobian and interaction matrix, for a sensor-based [`Task::evaluate`].
    pub fn sensor_parts_mut(
        &mut self,
    ) -> (
        &mut DVector<f64>,
        &mut TaskJacobian<N>,
        &mut InteractionMatrix,
    ) {
        (&mut self.error, &mut self.jacobian, &mut self.interaction)
    }

    /// Checks that error and Jacobian are finite (for task implementations; the stack solve checks every level
    /// itself and reports the level and task index).
    ///
    /// # Errors
    /// [`TaskError::NonFinite`].
    pub fn check_finite(&self, name: &str) -> Result<(), TaskError> {
        if !all_finite(&self.error) {
            return Err(TaskError::NonFinite {
                name: name.into(),
                what: "error",
            });
        }
        if !all_finite(&self.jacobian) {
            return Err(TaskError::NonFinite {
                name: name.into(),
                what: "jacobian",
            });
        }
        Ok(())
    }
}

fn validate_gain(name: &str, gain: f64) -> Result<(), TaskError> {
    if gain > 0.0 && crate::bounds::GAIN_PER_S.contains(gain) {
        Ok(())
    } else {
        Err(TaskError::InvalidGain {
            name: name.into(),
            gain,
        })
    }
}

fn check_rows(
    name: &str,
    what: &'static str,
    expected: usize,
    found: usize,
) -> Result<(), TaskError> {
    if expected == found {
        Ok(())
    } else {
        Err(TaskError::DimensionMismatch {
            name: name.into(),
            what,
            expected,
            found,
        })
    }
}

/// A task: something that, given the current state of the world `C`, writes its error `e_i` and Jacobian `J_i`.
///
/// `rows` and `gain` are fixed for the task's lifetime; [`TaskValue::for_task`] sizes the storage from them.
/// Implementations must not allocate in `evaluate` and must report undefined values as errors, not NaN.
pub trait Task<const N: usize, C: ?Sized> {
    /// A short name (used in logs and errors).
    fn name(&self) -> &str;
    /// The number of rows `m_i` of the task function.
    fn rows(&self) -> usize;
    /// The convergence gain `λ_i` (s⁻¹) of `ė_i = −λ_i e_i` ([(F15)](crate::theory#f15)).
    fn gain(&self) -> f64;
    /// Writes `e_i` and `J_i` for the state `context` into `out` (sized by [`TaskValue::for_task`]).
    ///
    /// # Errors
    /// Whatever makes the task undefined in this state.
    fn evaluate(&self, context: &C, out: &mut TaskValue<N>) -> Result<(), TaskError>;
}

/// A synthetic task with constant error and Jacobian, whatever the context. For tests, examples and benches of the
/// stack alone.
#[derive(Debug, Clone, PartialEq)]
pub struct ConstantTask<const N: usize> {
    name: String,
    value: TaskValue<N>,
}

impl<const N: usize> ConstantTask<N> {
    /// A task with error `error` (`m`), Jacobian `jacobian` (`m × N`) and gain `gain` (s⁻¹).
    ///
    /// # Errors
    /// Zero rows, mismatched sizes, non-finite entries, invalid gain.
    pub fn new(
        name: &str,
        error: DVector<f64>,
        jacobian: TaskJacobian<N>,
        gain: f64,
    ) -> Result<Self, TaskError> {
        Ok(Self {
            name: name.into(),
            value: TaskValue::from_parts(name, error, jacobian, gain)?,
        })
    }
}

impl<const N: usize, C: ?Sized> Task<N, C> for ConstantTask<N> {
    fn name(&self) -> &str {
        &self.name
    }
    fn rows(&self) -> usize {
        self.value.rows()
    }
    fn gain(&self) -> f64 {
        self.value.gain()
    }
    fn evaluate(&self, _context: &C, out: &mut TaskValue<N>) -> Result<(), TaskError> {
        out.set(&self.name, &self.value.error, &self.value.jacobian)
    }
}

/// A synthetic joint-space task `e = A (q − q*)`, `J = A`, evaluated on the joint configuration `q`. It converges under
/// the stack law, so it drives simulations of the stack alone.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearTask<const N: usize> {
    name: String,
    matrix: TaskJacobian<N>,
    target: JointVector<N>,
    gain: f64,
}

impl<const N: usize> LinearTask<N> {
    /// The task `e = matrix (q − target)` with gain `gain` (s⁻¹).
    ///
    /// # Errors
    /// Zero rows, non-finite entries, invalid gain.
    pub fn new(
        name: &str,
        matrix: TaskJacobian<N>,
        target: JointVector<N>,
        gain: f64,
    ) -> Result<Self, TaskError> {
        TaskValue::from_parts(name, DVector::zeros(matrix.nrows()), matrix.clone(), gain)?;
        if !all_finite(&target) {
            return Err(TaskError::NonFinite {
                name: name.into(),
                what: "target",
            });
        }
        Ok(Self {
            name: name.into(),
            matrix,
            target,
            gain,
        })
    }
}

impl<const N: usize> Task<N, JointVector<N>> for LinearTask<N> {
    fn name(&self) -> &str {
        &self.name
    }
    fn rows(&self) -> usize {
        self.matrix.nrows()
    }
    fn gain(&self) -> f64 {
        self.gain
    }
    fn evaluate(&self, q: &JointVector<N>, out: &mut TaskValue<N>) -> Result<(), TaskError> {
        if !all_finite(q) {
            return Err(TaskError::NonFinite {
                name: self.name.clone(),
                what: "q",
            });
        }
        check_rows(&self.name, "storage", self.rows(), out.rows())?;
        let (error, jacobian) = out.parts_mut();
        jacobian.copy_from(&self.matrix);
        error.gemv(1.0, &self.matrix, q, 0.0);
        error.gemv(-1.0, &self.matrix, &self.target, 1.0);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_task_evaluates_affine_error() {
        let a = TaskJacobian::<3>::from_row_slice(&[1.0, 2.0, 0.0, 0.0, -1.0, 3.0]);
        let task = LinearTask::new("lin", a, JointVector::<3>::new(1.0, 0.0, -1.0), 2.0).unwrap();
        let mut value = TaskValue::for_task(&task).unwrap();
        task.evaluate(&JointVector::<3>::new(2.0, 1.0, 1.0), &mut value)
            .unwrap();
        // q − q* = (1, 1, 2): e = (1 + 2, −1 + 6).
        assert_eq!(value.error().as_slice(), &[3.0, 5.0]);
        assert_eq!(value.gain(), 2.0);
    }

    #[test]
    fn bad_tasks_are_errors() {
        assert!(matches!(
            TaskValue::<6>::new("t", 0, 1.0),
            Err(TaskError::ZeroRows { .. })
        ));
        for gain in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                TaskValue::<6>::new("t", 1, gain),
                Err(TaskError::InvalidGain { .. })
            ));
        }
        let mismatch = ConstantTask::<6>::new("t", DVector::zeros(2), TaskJacobian::zeros(3), 1.0);
        assert!(matches!(
            mismatch,
            Err(TaskError::DimensionMismatch {
                expected: 2,
                found: 3,
                ..
            })
        ));
        let mut jacobian = TaskJacobian::<6>::zeros(2);
        jacobian[(1, 4)] = f64::INFINITY;
        assert!(matches!(
            ConstantTask::new("t", DVector::zeros(2), jacobian, 1.0),
            Err(TaskError::NonFinite {
                what: "jacobian",
                ..
            })
        ));
        assert!(matches!(
            ConstantTask::<6>::new(
                "t",
                DVector::from_element(2, f64::NAN),
                TaskJacobian::zeros(2),
                1.0
            ),
            Err(TaskError::NonFinite { what: "error", .. })
        ));
        let task = LinearTask::new(
            "lin",
            TaskJacobian::<2>::identity_generic(Dyn(2), Const::<2>),
            JointVector::zeros(),
            1.0,
        )
        .unwrap();
        let mut value = TaskValue::for_task(&task).unwrap();
        assert!(matches!(
            task.evaluate(&JointVector::<2>::new(0.0, f64::NAN), &mut value),
            Err(TaskError::NonFinite { what: "q", .. })
        ));
    }
}
