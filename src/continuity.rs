//! The transition term that keeps the joint velocity continuous when the stack changes ([theory §3](crate::theory#s3), [\[M11\]](crate::theory#m11)–[\[M15\]](crate::theory#m15), [D1](crate::theory#d1)).
//!
//! Let `u(t)` be the control law of the current stack (the stack velocity plus the avoidance term, [`crate::law`]).
//! When the stack is modified (a task pushed or removed) at time `τ`, `u` jumps. The non-homogeneous first-order law of
//! the paper adds a term that starts at the jump and dies out at rate `μ`:
//!
//! ```text
//! D1 / [M15] / (F16), (F19):   q̇(t) = u(t) + e^{−μ (t−τ)} ( q̇(τ⁻) − u(τ) )
//! ```
//!
//! so `q̇(τ⁺) = q̇(τ⁻)` exactly, whatever the ranks of the old and new stacks, while the convergence gains `λ_i` and the
//! transition length `1/μ` stay decoupled. `μ` (s⁻¹) defaults to `10 · max_i λ_i` ([D1](crate::theory#d1), the paper's `μ = 10 λ`).
//! This is also ViSP's `vpServo::computeControlLaw(t, e_dot_init)`, for a whole stack instead of one task.

use crate::math::JointVector;

/// The state of the transition since the last stack modification: `τ`, `q̇(τ⁻)` and `u(τ)`; and the law's clock, the
/// time of its last step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transition<const N: usize> {
    switch_time: f64,
    velocity_before: JointVector<N>,
    law_at_switch: JointVector<N>,
    /// The time of the last step of the law ([`crate::law::control_step`]), which the next must follow strictly.
    last_step_time: f64,
}

impl<const N: usize> Default for Transition<N> {
    /// No transition: `q̇(τ⁻) = u(τ) = 0` at `τ = 0`, so the blend is `u(t)` itself; no step taken yet.
    fn default() -> Self {
        Self {
            switch_time: 0.0,
            velocity_before: JointVector::zeros(),
            law_at_switch: JointVector::zeros(),
            last_step_time: f64::NEG_INFINITY,
        }
    }
}

impl<const N: usize> Transition<N> {
    /// Records a stack modification at time `switch_time` (s): the velocity sent just before, `q̇(τ⁻)`, and the new
    /// law evaluated at that instant, `u(τ)`.
    pub fn switch(
        &mut self,
        switch_time: f64,
        velocity_before: &JointVector<N>,
        law_at_switch: &JointVector<N>,
    ) {
        self.switch_time = switch_time;
        self.velocity_before.copy_from(velocity_before);
        self.law_at_switch.copy_from(law_at_switch);
    }

    /// The time `τ` (s) of the last stack modification.
    pub fn switch_time(&self) -> f64 {
        self.switch_time
    }

    /// The time (s) of the last step of the law, `−∞` before the first: the next step's time must be strictly later.
    pub fn last_step_time(&self) -> f64 {
        self.last_step_time
    }

    /// Records a step of the law at `time` (s).
    pub(crate) fn stepped_at(&mut self, time: f64) {
        self.last_step_time = time;
    }

    /// The velocity sent just before the last modification, `q̇(τ⁻)`.
    pub fn velocity_before(&self) -> &JointVector<N> {
        &self.velocity_before
    }

    /// The decay factor `e^{−μ (t−τ)}` at time `t` (s), for `μ` in s⁻¹ (1 at the switch, → 0 after a few `1/μ`).
    pub fn decay(&self, mu: f64, time: f64) -> f64 {
        (-mu * (time - self.switch_time)).exp()
    }

    /// The blended velocity `u(t) + e^{−μ(t−τ)} (q̇(τ⁻) − u(τ))` of [D1](crate::theory#d1), written into `out`; returns the decay factor
    /// it used ([`Self::decay`]).
    pub fn blend(&self, mu: f64, time: f64, law: &JointVector<N>, out: &mut JointVector<N>) -> f64 {
        let decay = self.decay(mu, time);
        out.copy_from(law);
        out.axpy(decay, &self.velocity_before, 1.0);
        out.axpy(-decay, &self.law_at_switch, 1.0);
        decay
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn blend_starts_at_the_old_velocity_and_decays_exponentially() {
        let mut transition = Transition::<3>::default();
        let before = JointVector::<3>::new(0.3, -0.1, 0.2);
        let law = JointVector::<3>::new(-0.5, 0.4, 0.0);
        transition.switch(2.0, &before, &law);
        let mut out = JointVector::zeros();
        transition.blend(4.0, 2.0, &law, &mut out);
        assert_relative_eq!(out, before, epsilon = 1e-15);
        // With a constant law, the gap to the law shrinks as e^{−μ(t−τ)}.
        let decay = transition.blend(4.0, 2.5, &law, &mut out);
        assert_relative_eq!(decay, (-2.0f64).exp(), epsilon = 1e-15);
        assert_relative_eq!(out - law, (before - law) * (-2.0f64).exp(), epsilon = 1e-15);
    }
}
