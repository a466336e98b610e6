//! The velocity sent to the joints ([D25](crate::theory#d25), [D31](crate::theory#d31)): the controller's velocity
//! shaped by the robot's velocity and acceleration limits and by the braking before the hard limits. One path for the
//! servo façade ([`crate::servo::VisualServo`]) and the simulation ([`crate::sim::simulate`]).
//!
//! ```text
//! s   = s_v · s_b                 s_v: uniform scaling into |q̇_i| ≤ q̇_i^max; s_b: braking with the stopping distance
//! q̇*  = s q̇                       the target, in the controller's direction
//! σ   = max σ ≤ 1 with |σ (q̇*_i − q̇_i⁻)| ≤ a_i Δt      (q̇⁻ the velocity sent last)
//! q̇   = q̇*                         when σ = 1
//! q̇   = clamp_B(q̇⁻ + σ (q̇* − q̇⁻))  otherwise: each joint within the speed from which it can still stop
//! ```
//!
//! With every `a_i = +∞` the sent velocity is `s q̇`, with `s` the scalings of D25 alone, bit for bit.

use super::JointLimits;
use crate::math::{acceleration_limit_scale, velocity_limit_scale, JointVector};

/// The robot's limits on the motion of its joints: velocity and acceleration, per joint, and the longest period a
/// velocity may be held.
///
/// The fields are checked by the façade's and the simulation's validation (`> 0`, not NaN; `+∞`: no limit; the period
/// finite and `≥ 0`); [`Self::shape`] does not check them again, and never panics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionLimits<const N: usize> {
    /// `q̇_i^max` per joint (rad/s for revolute, m/s for prismatic joints; `+∞`: no limit).
    pub max_velocity: JointVector<N>,
    /// `a_i` per joint, the largest change of the joint's velocity per second (rad/s², m/s²; `+∞`: no limit).
    pub max_acceleration: JointVector<N>,
    /// The longest time (s) a velocity may be held before the next one is sent: the stopping distance assumes the
    /// velocity is held for `max(Δt, longest_period)` ([D31](crate::theory#d31)). 0 when only `Δt` is known.
    pub longest_period: f64,
}

/// The velocity to send, from [`MotionLimits::shape`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShapedVelocity<const N: usize> {
    /// The joint velocity to send (rad/s, m/s).
    pub velocity: JointVector<N>,
    /// `s ∈ [0, 1]`: the uniform scaling of the controller's velocity into the velocity limits and the braking before
    /// the hard limits.
    pub scale: f64,
    /// `σ ∈ [0, 1]`: the fraction of the change from the velocity sent last towards `s q̇` that the acceleration
    /// limits allow; 1 when the change is within them.
    pub acceleration_scale: f64,
    /// Whether a joint was clamped to the speed from which it can still stop before its limit (the direction of the
    /// change bends only then).
    pub stopping_clamp: bool,
}

impl<const N: usize> MotionLimits<N> {
    /// No limit on any joint.
    pub fn unlimited() -> Self {
        Self {
            max_velocity: JointVector::repeat(f64::INFINITY),
            max_acceleration: JointVector::repeat(f64::INFINITY),
            longest_period: 0.0,
        }
    }

    /// The velocity to send at `q` for the controller's velocity `velocity`, when `previous` was sent last (zero at
    /// rest) and the new one is held for `period` (`Δt`, s): scaled uniformly into the velocity limits, braked before
    /// the hard limits of `limits` at the rate `braking_rate` (`ξ`, s⁻¹; `+∞`: no braking) with the stopping distance
    /// the acceleration limits need, then the change from `previous` scaled uniformly into `a_i Δt` and each joint
    /// clamped to the speed from which it can still stop (module docs, [D31](crate::theory#d31)).
    ///
    /// Each joint of the result is within `a_i Δt` of `previous` (when `previous` was itself within the stopping
    /// bounds: the velocity this function sent last), within `q̇_i^max`, and does not take the joint past a limit
    /// within the period.
    pub fn shape(
        &self,
        limits: &JointLimits<N>,
        q: &JointVector<N>,
        velocity: &JointVector<N>,
        previous: &JointVector<N>,
        braking_rate: f64,
        period: f64,
    ) -> ShapedVelocity<N> {
        let hold = period.max(self.longest_period);
        let limit = velocity_limit_scale(velocity, &self.max_velocity);
        let braking = limits.braking_scale_under_acceleration(
            q,
            &(velocity * limit),
            braking_rate,
            &self.max_acceleration,
            hold,
        );
        let scale = limit * braking;
        let target = velocity * scale;
        let fraction = acceleration_limit_scale(previous, &target, &self.max_acceleration, period);
        let (velocity, stopping_clamp) = if fraction >= 1.0 {
            (target, false)
        } else {
            let mut velocity = previous + (target - previous) * fraction;
            let clamped = limits.clamp_to_stopping_distance(
                q,
                &mut velocity,
                braking_rate,
                &self.max_acceleration,
                hold,
            );
            (velocity, clamped)
        };
        ShapedVelocity {
            velocity,
            scale,
            acceleration_scale: fraction,
            stopping_clamp,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> JointLimits<3> {
        JointLimits::new(
            JointVector::from([-1.0, -1.0, f64::NEG_INFINITY]),
            JointVector::from([1.0, 1.0, f64::INFINITY]),
            0.1,
        )
        .unwrap()
    }

    /// Without acceleration limits the velocity is scaled into the velocity limits (here by 0.5 / 2) and nothing
    /// else: far from the limits the braking does not act.
    #[test]
    fn without_acceleration_limits_the_velocity_is_only_scaled_into_the_velocity_limits() {
        let motion = MotionLimits {
            max_velocity: JointVector::from([0.5, 0.5, 0.5]),
            ..MotionLimits::unlimited()
        };
        let q = JointVector::zeros();
        let v = JointVector::from([2.0, -1.0, 0.5]);
        let shaped = motion.shape(&limits(), &q, &v, &JointVector::zeros(), 5.0, 0.01);
        assert_eq!(shaped.scale, 0.25);
        assert_eq!(shaped.velocity, JointVector::from([0.5, -0.25, 0.125]));
        assert_eq!(shaped.acceleration_scale, 1.0);
        assert!(!shaped.stopping_clamp);
    }

    /// A change of 2 on the unlimited third joint under 1 per s² over 0.01 s: half a hundredth of the change, on
    /// every joint (far from the limits, where the braking does not act).
    #[test]
    fn the_change_is_scaled_uniformly_into_the_acceleration_limits() {
        let motion = MotionLimits {
            max_acceleration: JointVector::from([1.0, 1.0, 1.0]),
            ..MotionLimits::unlimited()
        };
        let q = JointVector::zeros();
        let previous = JointVector::from([0.0, 0.1, 0.0]);
        let v = JointVector::from([0.2, 0.1, -2.0]);
        let shaped = motion.shape(&limits(), &q, &v, &previous, 5.0, 0.01);
        assert!((shaped.acceleration_scale - 0.005).abs() < 1e-15);
        let expected = [0.001, 0.1, -0.01];
        for (got, want) in shaped.velocity.iter().zip(expected) {
            assert!((got - want).abs() < 1e-15, "{got} vs {want}");
        }
    }

    /// A joint driven at its limit while another one swings back and forth: over many periods every change stays
    /// within `a Δt`, the swinging joint's velocity limit holds and the limit is approached, never crossed.
    #[test]
    fn driven_at_a_limit_the_joint_stops_before_it_within_the_acceleration_limits() {
        let a = JointVector::from([2.0, 4.0, 1.0]);
        let motion = MotionLimits {
            max_velocity: JointVector::from([f64::INFINITY, 0.8, f64::INFINITY]),
            max_acceleration: a,
            longest_period: 0.0,
        };
        let (rate, dt) = (5.0, 0.01);
        let limits = limits();
        let mut q = JointVector::from([0.5, 0.0, 0.0]);
        let mut sent = JointVector::zeros();
        for k in 0..3000 {
            let v = JointVector::from([3.0, 3.0 * (k as f64 / 7.0).sin(), -2.0]);
            let shaped = motion.shape(&limits, &q, &v, &sent, rate, dt);
            for i in 0..3 {
                let step = (shaped.velocity[i] - sent[i]).abs();
                assert!(
                    step <= a[i] * dt * (1.0 + 1e-12),
                    "joint {i} at {k}: {step}"
                );
            }
            assert!(shaped.velocity[1].abs() <= 0.8 * (1.0 + 1e-12));
            sent = shaped.velocity;
            q += sent * dt;
            assert!(q[0] < 1.0 && q[1] < 1.0 && q[1] > -1.0, "{q} at {k}");
        }
        // It got there: within a millimetre of the limit.
        assert!(q[0] > 0.999, "{q}");
    }
}
