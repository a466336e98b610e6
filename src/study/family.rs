//! The families of situations a study draws: how a situation is perturbed from the scenario ([`Perturbation`]: the
//! start, the goal, the desired view, uniform or straight-feasible starts), the named [`Family`], the standard and
//! optional lists, and the drawing of one situation from a seeded stream.

use super::StudyError;
use crate::robot::{JointKind, SerialChain};
use crate::scenario::{PoseSpec, Scenario};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::RngExt;
use serde::{Deserialize, Serialize};

/// How the situations of a family are drawn from the scenario.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Perturbation {
    /// Every joint of the start moved uniformly within `±translation_m` (prismatic) or `±rotation_deg` (revolute).
    Start {
        /// Half-width for prismatic joints (m).
        translation_m: f64,
        /// Half-width for revolute joints (degrees).
        rotation_deg: f64,
    },
    /// Every joint of the goal configuration moved the same way (the target moves with the goal: it is placed so that
    /// the goal sees it as the desired view).
    Goal {
        /// Half-width for prismatic joints (m).
        translation_m: f64,
        /// Half-width for revolute joints (degrees).
        rotation_deg: f64,
    },
    /// The desired view turned about the target's centre by a rotation of uniform random axis and angle in
    /// `[0, max_angle_deg]` (the camera orbits the target at the goal).
    View {
        /// The largest angle (degrees).
        max_angle_deg: f64,
    },
    /// The start drawn uniformly inside the joint limits; an unlimited (continuous) joint is drawn uniformly in
    /// `[−π, π]`, one full turn. Only starts from which the camera sees the whole target, within the incidence bound
    /// of D27, are kept.
    Uniform,
    /// Uniform starts ([`Self::Uniform`]) kept only when they are straight-feasible
    /// ([`straight_feasible`](super::straight_feasible)): the straight joint-space path to the goal keeps the target in
    /// the image, within the incidence bound, and the joints inside their limits. A denominator no method defines
    /// (issue 43).
    Feasible,
}

/// A named family of situations.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Family {
    /// Its name in tables and files.
    pub name: String,
    /// How its situations are drawn.
    pub perturbation: Perturbation,
}

impl Family {
    /// A family.
    pub fn new(name: &str, perturbation: Perturbation) -> Self {
        Self {
            name: name.into(),
            perturbation,
        }
    }
}

/// The families of the study (issue's table): starts mild (±2 cm / ±3°), strong (±4 cm / ±6°), wide (±8 cm / ±12°);
/// goal moved ±2 cm / ±2° and ±4 cm / ±4°; desired view turned ≤ 5° and ≤ 10°; starts uniform inside the limits.
pub fn standard_families() -> Vec<Family> {
    use Perturbation::*;
    vec![
        Family::new(
            "mild",
            Start {
                translation_m: 0.02,
                rotation_deg: 3.0,
            },
        ),
        Family::new(
            "strong",
            Start {
                translation_m: 0.04,
                rotation_deg: 6.0,
            },
        ),
        Family::new(
            "wide",
            Start {
                translation_m: 0.08,
                rotation_deg: 12.0,
            },
        ),
        Family::new(
            "goal_2cm",
            Goal {
                translation_m: 0.02,
                rotation_deg: 2.0,
            },
        ),
        Family::new(
            "goal_4cm",
            Goal {
                translation_m: 0.04,
                rotation_deg: 4.0,
            },
        ),
        Family::new("view_5deg", View { max_angle_deg: 5.0 }),
        Family::new(
            "view_10deg",
            View {
                max_angle_deg: 10.0,
            },
        ),
        Family::new("uniform", Uniform),
    ]
}

/// The families run only when asked for by name: `feasible` ([`Perturbation::Feasible`]), whose draws some arms can
/// hardly produce (the straight path of a uniform start rarely keeps the target in view: on a UR5e 2 in 200).
pub fn optional_families() -> Vec<Family> {
    vec![Family::new("feasible", Perturbation::Feasible)]
}

impl Perturbation {
    pub(super) fn validate(&self) -> Result<(), StudyError> {
        let check = |name, value: f64| {
            if value.is_finite() && value >= 0.0 {
                Ok(())
            } else {
                Err(StudyError::InvalidParameter {
                    name,
                    value,
                    expected: "finite and ≥ 0",
                })
            }
        };
        match *self {
            Self::Start {
                translation_m,
                rotation_deg,
            }
            | Self::Goal {
                translation_m,
                rotation_deg,
            } => {
                check("translation_m", translation_m)?;
                check("rotation_deg", rotation_deg)
            }
            Self::View { max_angle_deg } => check("max_angle_deg", max_angle_deg),
            Self::Uniform | Self::Feasible => Ok(()),
        }
    }

    /// The scenario with one situation of this family drawn from `rng`, on `chain`, the scenario's robot.
    pub(super) fn apply<const N: usize>(
        &self,
        scenario: &Scenario,
        chain: &SerialChain<N>,
        rng: &mut StdRng,
    ) -> Result<Scenario, StudyError> {
        let mut drawn = scenario.clone();
        let kinds: Vec<JointKind> = chain.joints().iter().map(|j| j.kind()).collect();
        let jitter =
            |values: &mut Vec<f64>, rng: &mut StdRng, translation: f64, rotation_deg: f64| {
                for (value, kind) in values.iter_mut().zip(&kinds) {
                    let half = if kind.is_rotational() {
                        rotation_deg.to_radians()
                    } else {
                        translation
                    };
                    *value += rng.random_range(-1.0..=1.0) * half;
                }
            };
        match *self {
            Self::Start {
                translation_m,
                rotation_deg,
            } => jitter(&mut drawn.start.joints, rng, translation_m, rotation_deg),
            Self::Goal {
                translation_m,
                rotation_deg,
            } => jitter(&mut drawn.desired.joints, rng, translation_m, rotation_deg),
            Self::View { max_angle_deg } => {
                let axis = loop {
                    let v = Vector3::new(
                        rng.random_range(-1.0..=1.0),
                        rng.random_range(-1.0..=1.0),
                        rng.random_range(-1.0..=1.0),
                    );
                    let norm = v.norm();
                    if norm > 1e-3 && norm <= 1.0 {
                        break nalgebra::Unit::new_normalize(v);
                    }
                };
                let angle = rng.random_range(0.0..=max_angle_deg.to_radians());
                let cd_from_o = scenario
                    .desired
                    .camera_from_target
                    .to_isometry("desired.camera_from_target")?;
                // Turn the target about its own centre: the camera orbits it at the same distance.
                let turned = cd_from_o
                    * Isometry3::from_parts(
                        Translation3::identity(),
                        UnitQuaternion::from_axis_angle(&axis, angle),
                    );
                drawn.desired.camera_from_target = PoseSpec::from_isometry(&turned);
            }
            Self::Uniform | Self::Feasible => {
                for (i, value) in drawn.start.joints.iter_mut().enumerate() {
                    let (low, high) = match (chain.lower_limits()[i], chain.upper_limits()[i]) {
                        (low, high) if low.is_finite() && high.is_finite() => (low, high),
                        _ => (-std::f64::consts::PI, std::f64::consts::PI),
                    };
                    *value = rng.random_range(low..=high);
                }
            }
        }
        Ok(drawn)
    }
}
