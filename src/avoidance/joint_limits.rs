//! The joint-limit cost of Chaumette & Marchand ([theory §5](crate::theory#s5), [\[M19\]](crate::theory#m19)–[\[M21\]](crate::theory#m21), [(F37)](crate::theory#f37)–[(F38)](crate::theory#f38)).
//!
//! Per joint `i`, with range `Δq_i = q_i^max − q_i^min` and activation ratio `ρ ∈ (0, 1/2)` (default 0.1):
//!
//! ```text
//! [M19]  q̃_i^min = q_i^min + ρ Δq_i ,   q̃_i^max = q_i^max − ρ Δq_i          (activation thresholds)
//! [M20]  h(q) = ½ Σ_i δ_i² / Δq_i ,   δ_i = q_i − q̃_i^max  above,  q_i − q̃_i^min  below,  0 inside
//! [M21]  ∇h = ( δ_1/Δq_1, …, δ_N/Δq_N )ᵀ
//! ```
//!
//! `h` is zero, with zero gradient, inside the acceptable box `[q̃^min, q̃^max]`, and continuously differentiable
//! everywhere. Units: `δ_i` and `Δq_i` are in the joint's unit (m or rad), so `h` is in m or rad per joint term and `∇h`
//! is dimensionless; the avoidance gain `κ` carries the unit 1/s.
//!
//! An **unlimited** joint (limits `−∞` and `+∞`, a URDF continuous joint) has no activation band: its term of `h` and
//! its entry of `∇h` are zero, it never violates its limits, and its angle is used as it is, never wrapped
//! ([D18](crate::theory#d18)). Soft limits for such a joint are finite limits given in its place
//! ([`crate::robot::SerialChain::with_limits`], a scenario's `robot.joint_limits`).

use super::{checked_cost, dead_band, Cost, CostError};
use crate::bounds::JOINT_POSITION;
use crate::math::{first_non_finite, JointVector};

/// The largest speed (m/s or rad/s) towards a limit at distance `distance` (m or rad; clamped at 0) that the braking
/// of [D25](crate::theory#d25) at rate `rate` (`ξ`, s⁻¹) allows when the velocity may change by at most
/// `deceleration · period` per period (`aΔt`; [D31](crate::theory#d31)):
///
/// ```text
/// B(d) = ξ d                     for ξ² d ≤ a   (the exponential approach of D25, which slows by ξ² d ≤ a)
/// B(d) = min( ξ d, S(d − c) )    beyond,        S(x) = ( −aΔt + √(a²Δt² + 8 a x) ) / 2
/// ```
///
/// `S(x)` is the largest speed `v` with `v (v + aΔt) ≤ 2 a x`: slowing by `aΔt` each period from `v` to rest covers
/// `x`. The offset `c` (`a/(2ξ²)` as `Δt → 0`, where `B` is continuous) is the distance the exponential approach needs
/// at the end; it is the smallest that keeps the set `v ≤ B(d)` invariant: from any speed `v ≤ B(d)` held for `Δt`,
/// the speed `v − aΔt` (or any lower) is again within `B` at the new distance `d − vΔt`. So the joint can always brake
/// in time without changing its velocity by more than `aΔt` per period, and with `ξ Δt ≤ 1`, `v Δt ≤ ξ d Δt ≤ d`: the
/// limit is never crossed. `ξ d` alone for `deceleration = +∞` (`+∞` when `rate` is too); for `rate = +∞` (no
/// braking: SNS and the QP cascade) with a finite deceleration, `S(d)` alone, the stopping distance; 0 for a
/// deceleration or a rate that is not `> 0`.
pub fn braking_speed(distance: f64, rate: f64, deceleration: f64, period: f64) -> f64 {
    let d = distance.max(0.0);
    if deceleration == f64::INFINITY {
        return if rate == f64::INFINITY {
            f64::INFINITY
        } else {
            rate * d
        };
    }
    if !(deceleration > 0.0 && rate > 0.0) {
        return 0.0;
    }
    if rate == f64::INFINITY {
        // No braking: only the distance the limited deceleration needs to stop.
        return stopping_speed(d, deceleration, period);
    }
    let linear = rate * d;
    let (a, xi) = (deceleration, rate);
    let junction = a / (xi * xi);
    if d <= junction {
        return linear;
    }
    let h = a * period.max(0.0);
    let growth = 1.0 + xi * period.max(0.0);
    // The least speed one period of the exponential approach may need from d: L(d) = (ξ d + aΔt) / (1 + ξΔt). The
    // offset makes S(d − c) ≤ L(d) beyond the junction: c = max over d ≥ a/ξ² of d − L(L + aΔt)/(2a), a concave
    // parabola in d, whose maximum is at its vertex (where L = a(1 + ξΔt)/ξ − aΔt/2) or at the junction.
    let vertex = (growth * (a * growth / xi - 0.5 * h) - h) / xi;
    let at = vertex.max(junction);
    let speed_there = (xi * at + h) / growth;
    let offset = at - speed_there * (speed_there + h) / (2.0 * a);
    let x = d - offset;
    let stopping = if x > 0.0 {
        0.5 * (-h + (h * h + 8.0 * a * x).sqrt())
    } else {
        0.0
    };
    linear.min(stopping)
}

/// The largest speed (m/s or rad/s) towards a limit at distance `distance` from which a velocity held for whole
/// periods of `period` (`Δt`) and slowed by at most `deceleration · period` (`h = aΔt`) each period comes to rest
/// within the distance: the inverse of the distance covered, `D(v) = Δt Σ_{k ≥ 0} (v − k h)₊`,
///
/// ```text
/// V(d) = d / ((n + 1) Δt) + n h / 2,   n = ⌊(√(1 + 8 d / (h Δt)) − 1) / 2⌋   (D(n h) = h Δt n (n + 1) / 2 ≤ d)
/// ```
///
/// `d/Δt` below one period's worth (`n = 0`), `√(2 a d)` far away. The set `v ≤ V(d)` is invariant: `D(v − h) =
/// D(v) − vΔt`, so from `v ≤ V(d)` held for `Δt`, `v − h ≤ V(d − vΔt)`, and `vΔt ≤ D(v) ≤ d`: the limit is never
/// crossed. 0 for `d ≤ 0`; `d/Δt` for a deceleration of `+∞`. What SNS's and the QP cascade's box and the full
/// method's [`braking_speed`] without braking (`rate = +∞`) use.
pub fn stopping_speed(distance: f64, deceleration: f64, period: f64) -> f64 {
    let h = deceleration * period;
    if distance.is_nan() || distance <= 0.0 || h.is_nan() || h <= 0.0 {
        return 0.0;
    }
    if h == f64::INFINITY {
        return distance / period;
    }
    let whole = ((1.0 + 8.0 * distance / (h * period)).sqrt() - 1.0) / 2.0;
    let n = whole.floor().max(0.0);
    (distance / ((n + 1.0) * period) + n * h / 2.0).min((n + 1.0) * h)
}

/// Joint limits and the cost [\[M20\]](crate::theory#m20) that keeps a configuration away from them.
#[derive(Debug, Clone, PartialEq)]
pub struct JointLimits<const N: usize> {
    lower: JointVector<N>,
    upper: JointVector<N>,
    rho: f64,
}

impl<const N: usize> JointLimits<N> {
    /// The activation ratio of the paper and of ViSP's 2005 Afma6 model ([theory §5](crate::theory#s5)).
    pub const DEFAULT_ACTIVATION_RATIO: f64 = 0.1;

    /// Limits `lower < upper` (m or rad per joint, within [`JOINT_POSITION`]), or `lower = −∞`, `upper = +∞` for an
    /// unlimited joint, with activation ratio `rho ∈ (0, 1/2)`.
    ///
    /// # Errors
    /// [`CostError::InvalidLimits`] for a pair that is neither finite, within range and ordered nor `(−∞, +∞)` (a NaN,
    /// one infinite bound, a bound beyond the range), [`CostError::InvalidActivationRatio`].
    pub fn new(lower: JointVector<N>, upper: JointVector<N>, rho: f64) -> Result<Self, CostError> {
        if !(rho.is_finite() && rho > 0.0 && rho < 0.5) {
            return Err(CostError::InvalidActivationRatio { rho });
        }
        for joint in 0..N {
            let (lo, hi) = (lower[joint], upper[joint]);
            let unlimited = lo == f64::NEG_INFINITY && hi == f64::INFINITY;
            if !(unlimited
                || (JOINT_POSITION.contains(lo) && JOINT_POSITION.contains(hi) && lo < hi))
            {
                return Err(CostError::InvalidLimits {
                    joint,
                    lower: lo,
                    upper: hi,
                });
            }
        }
        Ok(Self { lower, upper, rho })
    }

    /// Lower limits `q^min`.
    pub fn lower(&self) -> &JointVector<N> {
        &self.lower
    }

    /// Upper limits `q^max`.
    pub fn upper(&self) -> &JointVector<N> {
        &self.upper
    }

    /// The activation ratio `ρ`.
    pub fn activation_ratio(&self) -> f64 {
        self.rho
    }

    /// `true` when joint `i` is unlimited (limits `−∞`, `+∞`): it has no term in `h` ([D18](crate::theory#d18)).
    pub fn is_unlimited(&self, joint: usize) -> bool {
        self.lower[joint] == f64::NEG_INFINITY
    }

    /// The range `Δq_i = q_i^max − q_i^min` of joint `i` (`+∞` for an unlimited joint).
    fn range(&self, joint: usize) -> f64 {
        self.upper[joint] - self.lower[joint]
    }

    /// The activation thresholds `(q̃^min, q̃^max)` of [\[M19\]](crate::theory#m19); `(−∞, +∞)` for an unlimited
    /// joint.
    pub fn activation_thresholds(&self) -> (JointVector<N>, JointVector<N>) {
        let threshold = |i: usize, side: f64| {
            let (lower, upper) = (self.lower[i], self.upper[i]);
            if self.is_unlimited(i) {
                side * f64::INFINITY
            } else if side < 0.0 {
                lower + self.rho * (upper - lower)
            } else {
                upper - self.rho * (upper - lower)
            }
        };
        (
            JointVector::from_fn(|i, _| threshold(i, -1.0)),
            JointVector::from_fn(|i, _| threshold(i, 1.0)),
        )
    }

    /// The braking of [D25](crate::theory#d25): the uniform scale `s ∈ [0, 1]` such that every joint moving towards a
    /// finite limit keeps `|s q̇_i| ≤ ξ d_i`, `d_i ≥ 0` its distance to that limit (m or rad), `ξ` the braking rate
    /// `rate` (s⁻¹), `q̇` a joint velocity (m/s or rad/s). `s = min(1, min_i ξ d_i / |q̇_i|)`: 1 far from the limits;
    /// near one the whole velocity is scaled, so its direction, and with it every task's priority, is kept. Sent for a
    /// period `Δt ≤ 1/ξ`, the velocity moves each such joint by at most `ξ Δt d_i ≤ d_i`: the distance shrinks by at
    /// most the factor `1 − ξ Δt` per period and the limit is approached, never crossed. A joint already past a limit
    /// and moving further out gives `s = 0`. Unlimited joints and a rate of `+∞` never brake.
    pub fn braking_scale(&self, q: &JointVector<N>, velocity: &JointVector<N>, rate: f64) -> f64 {
        // With no acceleration limit, `braking_speed` is `ξ d_i` (an unlimited joint's `+∞`): the same loop.
        self.braking_scale_under_acceleration(
            q,
            velocity,
            rate,
            &JointVector::repeat(f64::INFINITY),
            0.0,
        )
    }

    /// The braking of [D25](crate::theory#d25) under acceleration limits ([D31](crate::theory#d31)): the uniform scale
    /// `s ∈ [0, 1]` such that every joint moving towards a finite limit keeps `|s q̇_i| ≤ B_i`, with `B_i =`
    /// [`braking_speed`]`(d_i, ξ, a_i, Δt)`: the speed from which the joint can still stop before its limit when its
    /// velocity changes by at most `a_i Δt` per period. `max_acceleration` holds `a_i` (`> 0`, `+∞`: none; all `+∞`
    /// gives [`Self::braking_scale`] exactly); `period` is the period `Δt` (s, `≥ 0`) the velocity is held. A rate of
    /// `+∞` never brakes.
    pub fn braking_scale_under_acceleration(
        &self,
        q: &JointVector<N>,
        velocity: &JointVector<N>,
        rate: f64,
        max_acceleration: &JointVector<N>,
        period: f64,
    ) -> f64 {
        if rate == f64::INFINITY {
            return 1.0;
        }
        let mut scale: f64 = 1.0;
        for joint in 0..N {
            let speed = velocity[joint];
            let distance = if speed > 0.0 {
                self.upper[joint] - q[joint]
            } else if speed < 0.0 {
                q[joint] - self.lower[joint]
            } else {
                continue;
            };
            let allowed = braking_speed(distance, rate, max_acceleration[joint], period);
            if allowed < speed.abs() {
                scale = scale.min(allowed / speed.abs());
            }
        }
        scale
    }

    /// Clamps each joint of `velocity` into `[−B(q_i − q_i^min), B(q_i^max − q_i)]`, `B` the [`braking_speed`] at rate
    /// `rate` with the joint's acceleration limit over `period` ([D31](crate::theory#d31)); returns whether a joint was
    /// clamped. The clamp is per joint, so it changes the velocity's direction; it only ever slows a joint down. A
    /// velocity that changed by at most `a_i Δt` from one within these bounds at the last period stays within `a_i Δt`
    /// of it once clamped (the bounds are invariant, [`braking_speed`]). A rate of `+∞` clamps nothing.
    pub fn clamp_to_stopping_distance(
        &self,
        q: &JointVector<N>,
        velocity: &mut JointVector<N>,
        rate: f64,
        max_acceleration: &JointVector<N>,
        period: f64,
    ) -> bool {
        if rate == f64::INFINITY {
            return false;
        }
        let mut clamped = false;
        for joint in 0..N {
            let a = max_acceleration[joint];
            let high = braking_speed(self.upper[joint] - q[joint], rate, a, period);
            let low = -braking_speed(q[joint] - self.lower[joint], rate, a, period);
            let v = velocity[joint];
            if v > high || v < low {
                velocity[joint] = v.clamp(low, high);
                clamped = true;
            }
        }
        clamped
    }

    /// The lock of [D26](crate::theory#d26): marks in `locked` every joint within `band · Δq_i` of a finite limit
    /// (`band`, a fraction of the range) that `velocity` drives towards that limit, or past it; returns `true` when it
    /// marked a joint not marked before. Joints already marked, unlimited joints and joints moving away stay as they
    /// are.
    pub fn lock_pressed_joints(
        &self,
        q: &JointVector<N>,
        velocity: &JointVector<N>,
        band: f64,
        locked: &mut [bool; N],
    ) -> bool {
        let mut marked = false;
        for (joint, lock) in locked.iter_mut().enumerate() {
            if *lock || self.is_unlimited(joint) {
                continue;
            }
            let width = band * self.range(joint);
            let speed = velocity[joint];
            let pressed = (speed < 0.0 && q[joint] - self.lower[joint] < width)
                || (speed > 0.0 && self.upper[joint] - q[joint] < width);
            if pressed {
                *lock = true;
                marked = true;
            }
        }
        marked
    }

    /// `δ_i` of [\[M20\]](crate::theory#m20): how far joint `i` has gone into its activation band (signed, 0 inside the
    /// acceptable box, always 0 for an unlimited joint).
    fn penetration(&self, q: &JointVector<N>, joint: usize) -> f64 {
        if self.is_unlimited(joint) {
            return 0.0;
        }
        let band = self.rho * self.range(joint);
        dead_band(q[joint], self.lower[joint] + band, self.upper[joint] - band)
    }

    /// The value of `h` when one joint, `joint`, has gone half-way through its activation band and every other joint is
    /// in the acceptable box: `½ (ρΔq/2)² / Δq = ρ² Δq / 8`. The stack controller's default `h_max` is the smallest of
    /// these over the joints ([D6](crate::theory#d6)). `None` for a joint index `≥ N` and for an unlimited joint (no
    /// band).
    pub fn half_band_cost(&self, joint: usize) -> Option<f64> {
        (joint < N && !self.is_unlimited(joint))
            .then(|| self.rho * self.rho * self.range(joint) / 8.0)
    }

    /// The value of `h` when one joint, `joint`, is at its hard limit and every other joint is in the acceptable box:
    /// `½ (ρΔq)² / Δq = ρ² Δq / 2`. A removal threshold `h_max` above it cannot see that joint reach its limit: the
    /// stack controller watches the hard limits themselves too ([`Cost::forbids`], [D6](crate::theory#d6)). `None`
    /// for a joint index `≥ N` and for an unlimited joint.
    pub fn limit_cost(&self, joint: usize) -> Option<f64> {
        (joint < N && !self.is_unlimited(joint))
            .then(|| 0.5 * self.rho * self.rho * self.range(joint))
    }

    /// The default removal threshold `h_max` of [D6](crate::theory#d6): the smallest [`Self::half_band_cost`] over the
    /// limited joints (`+∞` when every joint is unlimited: `h` is then always 0).
    pub fn default_removal_threshold(&self) -> f64 {
        (0..N)
            .filter_map(|joint| self.half_band_cost(joint))
            .fold(f64::INFINITY, f64::min)
    }

    /// The first joint outside its hard limits `[q^min, q^max]` ([D11](crate::theory#d11)), or `None`.
    pub fn violated_joint(&self, q: &JointVector<N>) -> Option<usize> {
        (0..N).find(|&i| self.is_outside(q, i))
    }

    /// Whether joint `joint` of `q` lies outside `[q^min, q^max]` (a NaN coordinate counts as outside).
    fn is_outside(&self, q: &JointVector<N>, joint: usize) -> bool {
        !(self.lower[joint] <= q[joint] && q[joint] <= self.upper[joint])
    }

    /// The configuration normalised per joint to `(q − q^min)/Δq`: 0 at the lower limit, 1 at the upper (the paper's
    /// Fig. 5–7 axes). An unlimited joint reads 0.5, as far from a limit as a joint can be.
    pub fn normalized(&self, q: &JointVector<N>) -> JointVector<N> {
        JointVector::from_fn(|i, _| {
            if self.is_unlimited(i) {
                0.5
            } else {
                (q[i] - self.lower[i]) / self.range(i)
            }
        })
    }

    /// The smallest distance to a hard limit over the joints, divided by the joint's range (negative outside); an
    /// unlimited joint counts as 0.5 (see [`Self::normalized`]).
    pub fn normalized_margin(&self, q: &JointVector<N>) -> f64 {
        self.normalized(q)
            .iter()
            .map(|&s| s.min(1.0 - s))
            .fold(f64::INFINITY, f64::min)
    }
}

impl<const N: usize> Cost<N> for JointLimits<N> {
    fn name(&self) -> &str {
        "joint_limits"
    }

    /// [D6](crate::theory#d6): the cost of one joint half-way through its activation band ([`Self::default_removal_threshold`]).
    fn default_removal_threshold(&self) -> Option<f64> {
        Some(JointLimits::default_removal_threshold(self))
    }

    /// A joint outside its hard limits ([`JointLimits::violated_joint`]).
    fn forbids(&self, q: &JointVector<N>) -> bool {
        self.violated_joint(q).is_some()
    }

    /// [\[M20\]](crate::theory#m20).
    fn value(&self, q: &JointVector<N>) -> Result<f64, CostError> {
        if let Some((joint, value)) = first_non_finite(q) {
            return Err(CostError::NonFiniteConfiguration { joint, value });
        }
        let value = (0..N)
            .map(|i| 0.5 * self.penetration(q, i).powi(2) / self.range(i))
            .sum();
        checked_cost::<N>(self.name(), value, None)
    }

    /// [\[M20\]](crate::theory#m20) and [\[M21\]](crate::theory#m21).
    fn value_and_gradient(
        &self,
        q: &JointVector<N>,
        gradient: &mut JointVector<N>,
    ) -> Result<f64, CostError> {
        if let Some((joint, value)) = first_non_finite(q) {
            return Err(CostError::NonFiniteConfiguration { joint, value });
        }
        let mut value = 0.0;
        for i in 0..N {
            let delta = self.penetration(q, i);
            gradient[i] = delta / self.range(i);
            value += 0.5 * delta * gradient[i];
        }
        checked_cost(self.name(), value, Some(gradient))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::avoidance::test_support::gradient_error;
    use proptest::prelude::*;

    fn limits() -> JointLimits<6> {
        JointLimits::new(
            JointVector::<6>::from_row_slice(&[
                -0.6501, -0.6001, -0.5001, -2.7301, -0.1001, -1.5901,
            ]),
            JointVector::<6>::from_row_slice(&[0.7001, 0.5201, 0.4601, 2.7301, 2.4801, 1.5901]),
            0.1,
        )
        .unwrap()
    }

    #[test]
    fn zero_inside_the_acceptable_box() {
        let limits = limits();
        let (low, high) = limits.activation_thresholds();
        for q in [low, high, (low + high) * 0.5] {
            let mut gradient = JointVector::repeat(1.0);
            assert_eq!(limits.value_and_gradient(&q, &mut gradient).unwrap(), 0.0);
            assert_eq!(gradient, JointVector::<6>::zeros());
        }
    }

    #[test]
    fn hand_computed_value() {
        // One prismatic joint with range 1.35 m, 0.05 m beyond its upper threshold:
        // h = ½ · 0.05² / 1.35.
        let limits = limits();
        let (_, high) = limits.activation_thresholds();
        let mut q = (limits.lower() + limits.upper()) * 0.5;
        q[0] = high[0] + 0.05;
        assert!((limits.value(&q).unwrap() - 0.5 * 0.05 * 0.05 / 1.3502).abs() < 1e-15);
        assert!((limits.half_band_cost(0).unwrap() - 0.01 * 1.3502 / 8.0).abs() < 1e-15);
        assert_eq!(limits.half_band_cost(6), None);
        assert_eq!(limits.violated_joint(&q), None);
        q[3] = 2.75;
        assert_eq!(limits.violated_joint(&q), Some(3));
    }

    #[test]
    fn gradient_matches_finite_differences_one_step_from_a_threshold() {
        // The draw that showed central differences miss by more than 1e-8 within one step of a threshold.
        let limits = limits();
        let (low, _) = limits.activation_thresholds();
        let mut q = (limits.lower() + limits.upper()) * 0.5;
        q[2] = low[2] + 2.9e-7;
        assert!(gradient_error(&limits, &q, 1e-6) < 1e-8 + 1e-6 / (4.0 * limits.range(2)));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Driven as hard as `V` and `a` allow towards a limit (each period the largest speed within `aΔt` of the last
        /// and within `V` of the distance left), a joint never crosses it, always finds such a speed, and comes to rest;
        /// `V` is `√(2ad)` within a period's worth far away and `d/Δt` within one period's travel.
        #[test]
        fn stopping_speed_never_overshoots(
            a in 0.01f64..20.0,
            period in 1e-4f64..0.05,
            d0 in 1e-6f64..2.0,
            v0 in 0.0f64..1.0,
        ) {
            let h = a * period;
            let mut d = d0;
            let mut v = v0.min(stopping_speed(d, a, period));
            for _ in 0..100_000 {
                d -= v * period;
                prop_assert!(d >= -1e-12 * d0, "crossed: d = {d}");
                let bound = stopping_speed(d, a, period);
                prop_assert!(v - h <= bound * (1.0 + 1e-9) + 1e-15, "no speed within reach: v {v}, bound {bound}");
                v = (v + h).min(bound);
                if v <= 1e-12 { break; }
            }
            let far = 1e3 * a * period * period;
            let v_far = stopping_speed(far, a, period);
            prop_assert!((v_far - (2.0 * a * far).sqrt()).abs() <= h);
            let near = 0.5 * a * period * period;
            prop_assert!((stopping_speed(near, a, period) - near / period).abs() <= 1e-12 * near / period);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]
        /// The gradient matches central differences everywhere (the cost is C¹), including across the limits.
        ///
        /// The gradient is piecewise linear: its slope jumps by `1/range` at each activation threshold. Within one step
        /// `h` of a threshold, central differences are off by up to `h / (4 · range)` (for `g(x) = c·max(0, x − k)`
        /// the difference quotient is `c (x − k + h)² / 4h`), so there the tolerance is that bound; elsewhere the cost
        /// is quadratic and central differences are exact up to rounding.
        #[test]
        fn gradient_matches_finite_differences(s in proptest::collection::vec(-0.2..1.2f64, 6)) {
            const STEP: f64 = 1e-6;
            let limits = limits();
            let q = JointVector::<6>::from_fn(|i, _| limits.lower()[i] + s[i] * (limits.upper()[i] - limits.lower()[i]));
            let (low, high) = limits.activation_thresholds();
            let kink_bound = (0..6)
                .filter(|&i| (q[i] - low[i]).abs() < STEP || (q[i] - high[i]).abs() < STEP)
                .map(|i| STEP / (4.0 * limits.range(i)))
                .fold(0.0, f64::max);
            prop_assert!(gradient_error(&limits, &q, STEP) < 1e-8 + kink_bound);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// D25: braked, the velocity sent for any period `Δt ≤ 1/ξ` keeps every joint inside its limits, from anywhere
        /// inside them, and is scaled no more than the closest joint needs: some joint moving towards its limit is at
        /// exactly `|s q̇_i| = ξ d_i` when `s < 1`.
        #[test]
        fn braking_never_crosses_a_limit(
            s in proptest::collection::vec(0.0..=1.0f64, 6),
            v in proptest::collection::vec(-5.0..5.0f64, 6),
            rate in 0.5..50.0f64,
            fraction in 0.01..=1.0f64,
        ) {
            let limits = limits();
            let q = JointVector::<6>::from_fn(|i, _| limits.lower()[i] + s[i] * (limits.upper()[i] - limits.lower()[i]));
            let velocity = JointVector::<6>::from_row_slice(&v);
            let scale = limits.braking_scale(&q, &velocity, rate);
            prop_assert!((0.0..=1.0).contains(&scale));
            let period = fraction / rate;
            let next = q + velocity * (scale * period);
            for i in 0..6 {
                prop_assert!(limits.lower()[i] <= next[i] && next[i] <= limits.upper()[i], "joint {i}: {}", next[i]);
            }
            if scale < 1.0 {
                let tight = (0..6).any(|i| {
                    let d = if velocity[i] > 0.0 { limits.upper()[i] - q[i] } else { q[i] - limits.lower()[i] };
                    ((scale * velocity[i]).abs() - rate * d).abs() <= 1e-12 * (1.0 + velocity[i].abs())
                });
                prop_assert!(tight, "scaled by {scale} with no joint at its bound");
            }
        }
    }

    /// D25 at the edges: far from the limits the velocity is sent as it is; a joint past a limit and moving further
    /// out stops everything; moving back in, it brakes nothing; an unlimited joint and a rate of `+∞` never brake.
    #[test]
    fn braking_at_the_edges() {
        let limits = limits();
        let middle = (limits.lower() + limits.upper()) * 0.5;
        let slow = JointVector::<6>::repeat(0.01);
        assert_eq!(limits.braking_scale(&middle, &slow, 5.0), 1.0);
        let mut past = middle;
        past[4] = limits.upper()[4] + 0.01;
        let mut outwards = JointVector::<6>::zeros();
        outwards[4] = 0.1;
        assert_eq!(limits.braking_scale(&past, &outwards, 5.0), 0.0);
        assert_eq!(limits.braking_scale(&past, &-outwards, 5.0), 1.0);
        assert_eq!(limits.braking_scale(&past, &outwards, f64::INFINITY), 1.0);
        let inf = f64::INFINITY;
        let free = JointLimits::<2>::new(
            JointVector::<2>::new(-inf, -1.0),
            JointVector::<2>::new(inf, 1.0),
            0.1,
        )
        .unwrap();
        let q = JointVector::<2>::new(1e6, 0.0);
        assert_eq!(
            free.braking_scale(&q, &JointVector::<2>::new(100.0, 0.0), 5.0),
            1.0
        );
        // The limited joint, 1 rad from its limit at 10 rad/s: ξ d / |q̇| = 5 · 1 / 10.
        assert_eq!(
            free.braking_scale(&q, &JointVector::<2>::new(100.0, 10.0), 5.0),
            0.5
        );
    }

    /// D26: a joint is locked when it is within the band of a limit and driven towards it (or past it); not when it
    /// moves away, sits outside the band, is unlimited or already locked; the band is a fraction of each joint's range.
    #[test]
    fn lock_marks_the_joints_pressed_into_a_limit() {
        let inf = f64::INFINITY;
        let limits = JointLimits::<4>::new(
            JointVector::<4>::new(-1.0, 0.0, -inf, -2.0),
            JointVector::<4>::new(1.0, 0.1, inf, 2.0),
            0.1,
        )
        .unwrap();
        // Band 1e−3 of the range: 2e−3 rad on joint 0, 1e−4 m on joint 1, 4e−3 rad on joint 3.
        let band = 1e-3;
        let q = JointVector::<4>::new(-1.0 + 1.9e-3, 0.1 - 0.9e-4, 1e9, 2.0 - 4.1e-3);
        let mut locked = [false; 4];
        let inwards = JointVector::<4>::new(-1.0, 1.0, 1.0, 1.0);
        assert!(limits.lock_pressed_joints(&q, &inwards, band, &mut locked));
        // Joint 3 is 4.1e−3 from its limit, outside its 4e−3 band; joint 2 has no limit.
        assert_eq!(locked, [true, true, false, false]);
        // Nothing new to mark: false, and the marks stay.
        assert!(!limits.lock_pressed_joints(&q, &inwards, band, &mut locked));
        assert_eq!(locked, [true, true, false, false]);
        let mut locked = [false; 4];
        assert!(!limits.lock_pressed_joints(&q, &-inwards, band, &mut locked));
        assert_eq!(locked, [false; 4]);
        // A joint past its limit and driven further out is locked too.
        let past = JointVector::<4>::new(-1.1, 0.05, 0.0, 0.0);
        assert!(limits.lock_pressed_joints(&past, &inwards, band, &mut locked));
        assert_eq!(locked, [true, false, false, false]);
        // Far from every limit, or with a zero band, nothing is locked.
        let mut locked = [false; 4];
        let middle = JointVector::<4>::new(0.0, 0.05, 0.0, 0.0);
        assert!(!limits.lock_pressed_joints(&middle, &inwards, band, &mut locked));
        assert!(!limits.lock_pressed_joints(&q, &inwards, 0.0, &mut locked));
        assert_eq!(locked, [false; 4]);
    }

    /// An unlimited joint (a continuous joint) adds nothing to `h` or `∇h` however far it turns, is never violated,
    /// and leaves the limited joints' terms as they were.
    #[test]
    fn unlimited_joints_have_no_term() {
        let inf = f64::INFINITY;
        let mixed = JointLimits::new(
            JointVector::<2>::new(-1.0, -inf),
            JointVector::<2>::new(1.0, inf),
            0.1,
        )
        .unwrap();
        let alone =
            JointLimits::new(JointVector::<1>::new(-1.0), JointVector::<1>::new(1.0), 0.1).unwrap();
        assert!(mixed.is_unlimited(1) && !mixed.is_unlimited(0));
        for turned in [0.0, 3.5, -40.0, 1e6] {
            let q = JointVector::<2>::new(0.95, turned);
            let mut gradient = JointVector::<2>::repeat(f64::NAN);
            let h = mixed.value_and_gradient(&q, &mut gradient).unwrap();
            // Joint 0 is 0.15 rad past its threshold 0.8: the same cost as the limited joint alone.
            assert_eq!(h, alone.value(&JointVector::<1>::new(0.95)).unwrap());
            assert!(h > 0.0);
            assert_eq!(gradient[1], 0.0);
            assert_eq!(mixed.violated_joint(&q), None);
            assert_eq!(mixed.normalized(&q)[1], 0.5);
        }
        let (low, high) = mixed.activation_thresholds();
        assert_eq!((low[1], high[1]), (-inf, inf));
        assert!((low[0] + 0.8).abs() < 1e-15 && (high[0] - 0.8).abs() < 1e-15);
        assert_eq!(mixed.half_band_cost(1), None);
        assert_eq!(
            mixed.default_removal_threshold(),
            alone.default_removal_threshold()
        );
        let all_unlimited =
            JointLimits::new(JointVector::<1>::new(-inf), JointVector::<1>::new(inf), 0.1).unwrap();
        assert_eq!(all_unlimited.default_removal_threshold(), inf);
        // Half-unlimited or reversed infinite pairs are not an unlimited joint.
        for (lo, hi) in [(-inf, 1.0), (-1.0, inf), (inf, -inf), (-inf, -inf)] {
            assert!(matches!(
                JointLimits::new(JointVector::<1>::new(lo), JointVector::<1>::new(hi), 0.1),
                Err(CostError::InvalidLimits { joint: 0, .. })
            ));
        }
    }

    /// A short joint's cost at its limit, `½ (ρΔq)² / Δq`, computed by hand; forbidden only beyond its hard limit.
    #[test]
    fn a_short_joint_costs_little_at_its_limit_and_is_forbidden_beyond_it() {
        let inf = f64::INFINITY;
        // A 0.3 m slide, a 2 rad joint and an unlimited one; ρ = 0.1: at the limit, 0.5 · 0.03² / 0.3 = 1.5e-3 and
        // 0.5 · 0.2² / 2 = 1e-2.
        let limits = JointLimits::new(
            JointVector::<3>::new(0.0, -1.0, -inf),
            JointVector::<3>::new(0.3, 1.0, inf),
            0.1,
        )
        .unwrap();
        let slide_at_limit = limits.limit_cost(0).unwrap();
        assert!((slide_at_limit - 1.5e-3).abs() < 1e-15);
        assert!((limits.limit_cost(1).unwrap() - 1e-2).abs() < 1e-15);
        assert_eq!(limits.limit_cost(2), None);
        let at_limit = JointVector::<3>::new(0.3, 0.0, 0.0);
        assert!((limits.value(&at_limit).unwrap() - slide_at_limit).abs() < 1e-15);

        let (slide_past, joint_past) = (
            JointVector::<3>::new(0.31, 0.0, 1e6),
            JointVector::<3>::new(0.1, 1.01, 0.0),
        );
        assert!(limits.forbids(&slide_past) && limits.forbids(&joint_past));
        assert!(!limits.forbids(&at_limit));
    }

    #[test]
    fn bad_parameters_are_errors() {
        let (lo, hi) = (
            JointVector::<2>::new(0.0, 0.0),
            JointVector::<2>::new(1.0, 1.0),
        );
        for rho in [0.0, 0.5, -0.1, f64::NAN] {
            assert!(matches!(
                JointLimits::new(lo, hi, rho),
                Err(CostError::InvalidActivationRatio { .. })
            ));
        }
        assert_eq!(
            JointLimits::new(lo, JointVector::<2>::new(1.0, -1.0), 0.1),
            Err(CostError::InvalidLimits {
                joint: 1,
                lower: 0.0,
                upper: -1.0
            })
        );
        assert!(JointLimits::new(lo, JointVector::<2>::new(f64::INFINITY, 1.0), 0.1).is_err());
        let limits = JointLimits::new(lo, hi, 0.1).unwrap();
        assert!(matches!(
            limits.value(&JointVector::<2>::new(0.0, f64::NAN)),
            Err(CostError::NonFiniteConfiguration { joint: 1, value }) if value.is_nan()
        ));
    }
}
