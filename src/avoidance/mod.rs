//! Avoidance by the projected gradient of a cost (MATH §4, \[M16\]–\[M18\], (F17)–(F19)).
//!
//! An "obstacle" is any scalar cost `h(q) ≥ 0` (a potential: zero where the robot is safe, growing towards danger)
//! with its gradient `∇h = (∂h/∂q)ᵀ`. The avoidance term of the control law ([`crate::law`]) is `−κ P^A_n ∇h`: the
//! steepest descent of `h`, projected onto the joint directions that the whole task stack leaves free, so that it never
//! disturbs a stacked task. The stack controller also predicts `h` ahead in time to decide when to remove a task
//! (MATH §6.2).
//!
//! Costs implement [`Cost`]. This module provides the joint-limit cost of Chaumette & Marchand ([`JointLimits`],
//! MATH \[M19\]–\[M21\]).

mod joint_limits;

pub use joint_limits::JointLimits;

use crate::math::JointVector;

/// Errors of costs.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CostError {
    /// The activation ratio `ρ` of the joint-limit cost must lie in `(0, 1/2)` (MATH \[M19\]).
    #[error("activation ratio ρ = {rho} must lie in (0, 1/2)")]
    InvalidActivationRatio {
        /// The ratio given.
        rho: f64,
    },
    /// A joint's limits are not finite or not ordered (`lower < upper`).
    #[error("joint {joint}: limits [{lower}, {upper}] must be finite with lower < upper")]
    InvalidLimits {
        /// The joint index (0-based).
        joint: usize,
        /// Its lower limit.
        lower: f64,
        /// Its upper limit.
        upper: f64,
    },
    /// The configuration holds a NaN or an infinity.
    #[error("joint configuration holds a non-finite value")]
    NonFiniteConfiguration,
}

/// A differentiable scalar cost `h(q)` on the joint space, minimised by the projected-gradient term (MATH \[M16\]).
///
/// Implementations must be allocation-free and must return an error, never NaN, on bad input.
pub trait Cost<const N: usize> {
    /// The cost `h(q)` (dimensionless or in the cost's own unit; `0` where there is nothing to avoid).
    ///
    /// # Errors
    /// [`CostError::NonFiniteConfiguration`] and cost-specific failures.
    fn value(&self, q: &JointVector<N>) -> Result<f64, CostError>;

    /// The cost `h(q)`, with its gradient `∇h(q) = (∂h/∂q)ᵀ` written into `gradient`.
    ///
    /// # Errors
    /// As [`Cost::value`].
    fn value_and_gradient(
        &self,
        q: &JointVector<N>,
        gradient: &mut JointVector<N>,
    ) -> Result<f64, CostError>;
}

#[cfg(test)]
pub(crate) mod test_support {
    use super::Cost;
    use crate::math::JointVector;

    /// Central finite differences of a cost's value, compared to its analytic gradient; returns the max abs error.
    pub fn gradient_error<const N: usize>(
        cost: &impl Cost<N>,
        q: &JointVector<N>,
        step: f64,
    ) -> f64 {
        let mut analytic = JointVector::<N>::zeros();
        cost.value_and_gradient(q, &mut analytic).unwrap();
        (0..N)
            .map(|i| {
                let mut plus = *q;
                let mut minus = *q;
                plus[i] += step;
                minus[i] -= step;
                let numeric =
                    (cost.value(&plus).unwrap() - cost.value(&minus).unwrap()) / (2.0 * step);
                (numeric - analytic[i]).abs()
            })
            .fold(0.0, f64::max)
    }
}
