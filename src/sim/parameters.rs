//! The parameters of a simulation run ([`SimulationParameters`]: period, budget, convergence and goal tolerances,
//! image margin and incidence bound, velocity and acceleration limits, visibility margin) and their validation.

use super::SimError;
use crate::avoidance::MotionLimits;
use crate::bounds::{ACCELERATION_PER_S2, MAX_ITERATIONS, PERIOD_S};
use crate::math::JointVector;
use crate::robot::SerialChain;

/// Parameters of a simulation run.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimulationParameters {
    /// The control period `Δt` (s), within [`PERIOD_S`].
    pub period: f64,
    /// The iteration budget, at most [`MAX_ITERATIONS`] (10⁷).
    pub max_iterations: usize,
    /// The run has converged when the stack is complete and `‖e_i‖ < convergence_error` for every task (the noise-free
    /// errors when the camera is not exact), and has stayed so for `convergence_hold_s`. The full method's restart
    /// ([D29](crate::theory#d29)) takes a run whose error has stopped falling against a limit for short of its goal
    /// while a stacked task's measured error is above it.
    pub convergence_error: f64,
    /// How long (s, ≥ 0; default 0: the first period below) the task errors must stay below `convergence_error` for
    /// the run to count as converged: with pixel noise the errors first cross the threshold while the camera still
    /// moves, and "settled" means staying below ([D21](crate::theory#d21)).
    pub convergence_hold_s: f64,
    /// How far from its goal pose (m) the camera may end when the task errors have converged
    /// ([D22](crate::theory#d22)); beyond this or [`Self::goal_tolerance_deg`] the run ends as
    /// [`Outcome::OffGoal`](super::Outcome::OffGoal) (default 0.01 m; `+∞`: no check).
    pub goal_tolerance_m: f64,
    /// The rotation (degrees) allowed between the camera and its goal pose at convergence (default 1°; `+∞`: no
    /// check).
    pub goal_tolerance_deg: f64,
    /// A point closer than this to the image border (px) is lost.
    pub image_margin: f64,
    /// The largest angle (degrees) between the target's normal and its line of sight at which the target is still
    /// tracked ([`Scene::target_incidence_deg`](super::Scene::target_incidence_deg); [D27](crate::theory#d27)). Seen
    /// more obliquely, or from behind, the run ends as [`Outcome::ImageDegenerate`](super::Outcome::ImageDegenerate),
    /// and a start so seen is not a valid situation. Default 80°: the target then spans `cos 80° ≈ 0.17` of its head-on
    /// width across its normal, a permissive bound for a detector (set it to the angle your tracker handles); within
    /// `(0, 180]`, 180 switching the check off.
    pub max_incidence_deg: f64,
    /// The full method keeps the target facing the camera: its visibility cost (the default one, and a scenario's
    /// `[visibility]`) rises from `max_incidence_deg − facing_margin_deg` on ([D27](crate::theory#d27),
    /// [`VisibilityCost::with_facing`](crate::avoidance::VisibilityCost::with_facing)), as it rises within
    /// `visibility_margin_px` of the image border. Degrees, within `[0, max_incidence_deg]`; default 15. With
    /// `max_incidence_deg` at 180 and no margin there is no facing term.
    pub facing_margin_deg: f64,
    /// The robot's velocity limit of a prismatic joint (m/s, > 0; default `+∞`: none). The controller's velocity is
    /// scaled uniformly into the limits (its direction kept) and the scaled velocity fed back to the controller, as
    /// [`crate::servo::VisualServo`] does.
    pub max_prismatic_velocity_m_s: f64,
    /// The robot's velocity limit of a revolute joint (rad/s, > 0; default `+∞`: none).
    pub max_revolute_velocity_rad_s: f64,
    /// The robot's acceleration limit of a prismatic joint (m/s², within [`ACCELERATION_PER_S2`] or `+∞`: none, the
    /// default; about 1 m/s² on an
    /// industrial arm's or a gantry's axes). The change of the velocity sent from one period to the next is scaled
    /// uniformly into `a_i Δt`, and the braking before a hard limit keeps the stopping distance, as
    /// [`crate::servo::VisualServo`] does ([`crate::avoidance::MotionLimits`], [D31](crate::theory#d31)); SNS and the
    /// QP cascade get the limits in their box too.
    pub max_prismatic_acceleration_m_s2: f64,
    /// The robot's acceleration limit of a revolute joint (rad/s², within [`ACCELERATION_PER_S2`] or `+∞`: none, the
    /// default; an industrial arm's
    /// controller allows a few rad/s², 2 to 5).
    pub max_revolute_acceleration_rad_s2: f64,
    /// The full method keeps the target points this far from the image border (px; default 20): when the scene has no
    /// visibility cost of its own, one with this margin joins the full method's avoidance cost, and guards its
    /// removals (D6 (d)): a removal must not bring the predicted points deeper into that band than keeping the task.
    pub visibility_margin_px: f64,
}

impl Default for SimulationParameters {
    fn default() -> Self {
        Self {
            period: 0.01,
            max_iterations: 10_000,
            convergence_error: 1e-4,
            convergence_hold_s: 0.0,
            goal_tolerance_m: 0.01,
            goal_tolerance_deg: 1.0,
            image_margin: 0.0,
            max_incidence_deg: 80.0,
            facing_margin_deg: 15.0,
            max_prismatic_velocity_m_s: f64::INFINITY,
            max_revolute_velocity_rad_s: f64::INFINITY,
            max_prismatic_acceleration_m_s2: f64::INFINITY,
            max_revolute_acceleration_rad_s2: f64::INFINITY,
            visibility_margin_px: 20.0,
        }
    }
}

impl SimulationParameters {
    /// The angle (degrees) from which the full method's visibility cost turns against obliquity (D27):
    /// `max_incidence_deg − facing_margin_deg`, or `None` when that is 180° (the check is off).
    pub fn facing_activation_deg(&self) -> Option<f64> {
        let activation = self.max_incidence_deg - self.facing_margin_deg;
        (activation < 180.0).then_some(activation)
    }

    /// The robot's velocity and acceleration limits per joint of `chain`, by the joint's kind (revolute and continuous
    /// joints take the revolute limits), each velocity held for [`Self::period`]: what the simulation shapes the
    /// velocity it sends with.
    pub fn motion_limits<const N: usize>(&self, chain: &SerialChain<N>) -> MotionLimits<N> {
        let per_joint = |prismatic: f64, revolute: f64| {
            JointVector::<N>::from_fn(|i, _| {
                if chain.joints()[i].kind().is_rotational() {
                    revolute
                } else {
                    prismatic
                }
            })
        };
        MotionLimits {
            max_velocity: per_joint(
                self.max_prismatic_velocity_m_s,
                self.max_revolute_velocity_rad_s,
            ),
            max_acceleration: per_joint(
                self.max_prismatic_acceleration_m_s2,
                self.max_revolute_acceleration_rad_s2,
            ),
            longest_period: self.period,
        }
    }

    /// Checks every parameter.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`], naming the parameter.
    pub fn validate(&self) -> Result<(), SimError> {
        let invalid = |name, value, expected| {
            Err(SimError::InvalidParameter {
                name,
                value,
                expected,
            })
        };
        if !PERIOD_S.contains(self.period) {
            return invalid("period", self.period, PERIOD_S.text);
        }
        if self.max_iterations > MAX_ITERATIONS {
            return invalid(
                "max_iterations",
                self.max_iterations as f64,
                "at most 1e7 (2.8 hours of a 1 kHz loop)",
            );
        }
        if !(self.convergence_error.is_finite() && self.convergence_error > 0.0) {
            return invalid(
                "convergence_error",
                self.convergence_error,
                "finite and > 0",
            );
        }
        if !crate::bounds::DURATION_S.contains(self.convergence_hold_s) {
            return invalid(
                "convergence_hold_s",
                self.convergence_hold_s,
                crate::bounds::DURATION_S.text,
            );
        }
        if !(self.image_margin.is_finite() && self.image_margin >= 0.0) {
            return invalid("image_margin", self.image_margin, "finite and ≥ 0");
        }
        let incidence = self.max_incidence_deg;
        if !(incidence > 0.0 && incidence <= 180.0) {
            return invalid("max_incidence_deg", incidence, "within (0, 180] degrees");
        }
        let facing = self.facing_margin_deg;
        if !(facing >= 0.0 && facing <= incidence) {
            return invalid(
                "facing_margin_deg",
                facing,
                "within [0, max_incidence_deg] degrees",
            );
        }
        for (name, value) in [
            ("goal_tolerance_m", self.goal_tolerance_m),
            ("goal_tolerance_deg", self.goal_tolerance_deg),
            (
                "max_prismatic_velocity_m_s",
                self.max_prismatic_velocity_m_s,
            ),
            (
                "max_revolute_velocity_rad_s",
                self.max_revolute_velocity_rad_s,
            ),
        ] {
            if value.is_nan() || value <= 0.0 {
                return invalid(name, value, "> 0 (or +∞ for no limit)");
            }
        }
        for (name, value) in [
            (
                "max_prismatic_acceleration_m_s2",
                self.max_prismatic_acceleration_m_s2,
            ),
            (
                "max_revolute_acceleration_rad_s2",
                self.max_revolute_acceleration_rad_s2,
            ),
        ] {
            if !(value == f64::INFINITY || ACCELERATION_PER_S2.contains(value)) {
                return invalid(name, value, ACCELERATION_PER_S2.text);
            }
        }
        let guard = self.visibility_margin_px;
        if !(guard.is_finite() && guard >= 0.0) {
            return invalid("visibility_margin_px", guard, "finite and ≥ 0");
        }
        Ok(())
    }
}

/// Why a target seen at `incidence` degrees from its normal is not tracked (D27).
pub(crate) fn incidence_reason(incidence: f64, max_incidence_deg: f64) -> String {
    format!(
        "the target is seen {incidence:.1}° from its normal, beyond max_incidence_deg = {max_incidence_deg}°"
    )
}
