//! ViSP's adaptive gain ([`AdaptiveGain`]), the gain `λ(‖e_i‖∞)` that can replace every task's constant gain.

use super::ServoError;
use crate::task::{TaskError, TaskValue};

/// ViSP's adaptive gain (`vpAdaptiveGain::initStandard`): `λ(x) = a e^{−b x} + c` with `a = λ(0) − λ(∞)`,
/// `b = λ'(0)/a`, `c = λ(∞)`, evaluated at `x = ‖e_i‖∞` (ViSP's `vpAdaptiveGain::operator()(vpColVector)`), so the gain
/// is `λ(0)` at the goal and tends to `λ(∞)` far from it. `λ'(0)` is the parameter as ViSP takes it; the derivative of
/// `λ` at 0 is `−a b = −λ'(0)`: a gain that decreases with the error (ViSP's use: faster near the goal) has
/// `λ(0) > λ(∞)` and `λ'(0) > 0`; one that increases with the error (slower near the goal, which filters pixel noise)
/// has `λ(0) < λ(∞)` and `λ'(0) < 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdaptiveGain {
    a: f64,
    b: f64,
    c: f64,
}

impl AdaptiveGain {
    /// `λ(0)` (s⁻¹, > 0), `λ(∞)` (s⁻¹, > 0), `λ'(0)` (s⁻¹ per unit of `‖e‖∞`, of the sign of `λ(0) − λ(∞)`; 0, or
    /// `λ(0) = λ(∞)`, gives the constant `λ(0)`).
    ///
    /// # Errors
    /// [`ServoError::InvalidParameter`] for a non-finite or non-positive gain, a non-finite slope, or a slope of the
    /// other sign than `λ(0) − λ(∞)` (`b < 0`: the gain would leave `[min, max]` of `λ(0), λ(∞)` without bound).
    pub fn new(at_zero: f64, at_infinity: f64, slope_at_zero: f64) -> Result<Self, ServoError> {
        let invalid = |name, value, expected| ServoError::InvalidParameter {
            name,
            value,
            expected,
        };
        for (name, value) in [("λ(0)", at_zero), ("λ(∞)", at_infinity)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(invalid(name, value, "finite and > 0 (s⁻¹)"));
            }
        }
        if !slope_at_zero.is_finite() {
            return Err(invalid("λ'(0)", slope_at_zero, "finite"));
        }
        let a = at_zero - at_infinity;
        if a == 0.0 || slope_at_zero == 0.0 {
            return Ok(Self {
                a: 0.0,
                b: 0.0,
                c: at_zero,
            });
        }
        let b = slope_at_zero / a;
        if !(b.is_finite() && b > 0.0) {
            return Err(invalid(
                "λ'(0)",
                slope_at_zero,
                "of the sign of λ(0) − λ(∞) (b = λ'(0)/(λ(0) − λ(∞)) must be > 0)",
            ));
        }
        Ok(Self {
            a,
            b,
            c: at_infinity,
        })
    }

    /// `λ(x) = a e^{−b x} + c` (s⁻¹) at `x ≥ 0` (a non-finite `x` gives `λ(∞)`).
    pub fn value(&self, x: f64) -> f64 {
        if x.is_finite() {
            self.a * (-self.b * x.abs()).exp() + self.c
        } else {
            self.c
        }
    }

    /// The largest gain it takes, `max(λ(0), λ(∞))` (s⁻¹), for the transition gain `μ = 10 max λ`.
    pub fn max_gain(&self) -> f64 {
        (self.a + self.c).max(self.c)
    }

    /// Sets the gain of the evaluated task `value` (named `name` in errors) to `λ(‖e‖∞)` of its current error.
    ///
    /// # Errors
    /// [`TaskError`] for a gain outside [`crate::bounds::GAIN_PER_S`] (only when `λ(0)` or `λ(∞)` is).
    pub fn apply<const N: usize>(
        &self,
        name: &str,
        value: &mut TaskValue<N>,
    ) -> Result<(), TaskError> {
        value.set_gain(name, self.value(value.error().amax()))
    }
}
