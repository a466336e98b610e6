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
use crate::camera::{CameraIntrinsics, ImagePoint};
use crate::feature::point_interaction;
use crate::math::{acceleration_limit_scale, velocity_limit_scale, JointVector};
use nalgebra::Vector6;

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

/// The braking of [D25](crate::theory#d25) before the border of the image: the largest `s ∈ [0, 1]` such that, with
/// the camera twist `s v` (`v = cVe eJe q̇`, camera frame), no point of `points` moves towards the border of the image
/// less `margin_px` faster than `ξ` times its distance to it, in pixels: `|u̇_j| ≤ ξ d_j`. The point's image velocity
/// is `(ẋ_j, ẏ_j) = L_j v` ([`point_interaction`], with the point's depth) and `u̇_j = f_x ẋ_j`, `v̇_j = f_y ẏ_j`.
/// A point that leaves the image ends a run as surely as a joint past its limit, and faster: the visibility cost
/// only acts within its band, which a camera moving at the joints' velocity limits crosses within a few periods.
/// `ξ = +∞` gives 1 (no braking); a point already on or past the border stops every motion that takes it further.
pub fn image_braking_scale(
    intrinsics: &CameraIntrinsics,
    margin_px: f64,
    points: &[ImagePoint],
    twist: &Vector6<f64>,
    rate: f64,
) -> f64 {
    if !rate.is_finite() {
        return 1.0;
    }
    let mut scale: f64 = 1.0;
    for point in points {
        let (row_x, row_y) = point_interaction(point.x, point.y, 1.0 / point.depth);
        let (u, v) = intrinsics.normalized_to_pixel(point.x, point.y);
        // The pixel map is affine: the difference of two images is the pixel velocity.
        let (u_moved, v_moved) = intrinsics
            .normalized_to_pixel(point.x + (row_x * twist)[0], point.y + (row_y * twist)[0]);
        for (speed, position, extent) in [
            (u_moved - u, u, intrinsics.width()),
            (v_moved - v, v, intrinsics.height()),
        ] {
            let room = if speed > 0.0 {
                extent - margin_px - position
            } else {
                position - margin_px
            };
            let allowed = rate * room.max(0.0);
            if speed.abs() > allowed {
                scale = scale.min(allowed / speed.abs());
            }
        }
    }
    scale
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

    /// A 640 × 480 px image, focal length 600 px, principal point at its centre.
    fn intrinsics() -> CameraIntrinsics {
        CameraIntrinsics::new(600.0, 600.0, 320.0, 240.0, 640.0, 480.0).unwrap()
    }

    /// A point 80 px from the right border (`x = 0.4`, depth 1 m): the camera translating at 1 m/s along `−x_c`
    /// moves it right at `f_x / Z` = 600 px/s; at `ξ = 5 s⁻¹` it may approach at 400 px/s, so the twist is scaled by
    /// 2/3. Moving it left, or with `ξ = +∞`, nothing is scaled; past the border the motion out stops.
    #[test]
    fn a_point_approaches_the_image_border_at_most_at_the_braking_rate() {
        let near_right = [ImagePoint {
            x: 0.4,
            y: 0.0,
            depth: 1.0,
        }];
        let towards = Vector6::new(-1.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let scale = image_braking_scale(&intrinsics(), 0.0, &near_right, &towards, 5.0);
        assert!((scale - 2.0 / 3.0).abs() < 1e-12, "{scale}");
        // A margin of 20 px leaves 60 px: 300 px/s allowed.
        let scale = image_braking_scale(&intrinsics(), 20.0, &near_right, &towards, 5.0);
        assert!((scale - 0.5).abs() < 1e-12, "{scale}");
        assert_eq!(
            image_braking_scale(&intrinsics(), 0.0, &near_right, &(-towards), 5.0),
            1.0
        );
        assert_eq!(
            image_braking_scale(&intrinsics(), 0.0, &near_right, &towards, f64::INFINITY),
            1.0
        );
        let past_border = [ImagePoint {
            x: 0.54,
            y: 0.0,
            depth: 1.0,
        }];
        assert_eq!(
            image_braking_scale(&intrinsics(), 0.0, &past_border, &towards, 5.0),
            0.0
        );
        // Slow enough: 60 px/s against 400 px/s allowed.
        let slow = towards * 0.1;
        assert_eq!(
            image_braking_scale(&intrinsics(), 0.0, &near_right, &slow, 5.0),
            1.0
        );
    }

    /// The camera moving towards the target spreads the points out of the image: a point at `y = −0.3` (60 px from
    /// the top border), depth 0.5 m, under a translation of 0.5 m/s along the optical axis moves at
    /// `f_y y ζ v_z` = −180 px/s; `ξ = 2 s⁻¹` allows 120 px/s: scale 2/3, whichever point binds first.
    #[test]
    fn an_approach_that_spreads_the_target_out_of_the_image_is_braked() {
        let points = [
            ImagePoint {
                x: 0.0,
                y: -0.3,
                depth: 0.5,
            },
            ImagePoint {
                x: 0.0,
                y: 0.1,
                depth: 0.5,
            },
        ];
        let approach = Vector6::new(0.0, 0.0, 0.5, 0.0, 0.0, 0.0);
        let scale = image_braking_scale(&intrinsics(), 0.0, &points, &approach, 2.0);
        assert!((scale - 2.0 / 3.0).abs() < 1e-12, "{scale}");
    }
}
