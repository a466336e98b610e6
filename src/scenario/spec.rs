//! The sections of a scenario file, as written: poses in metres and degrees, the robot, the camera intrinsics, the
//! target, the goal and the start (the world), and the tasks, the avoidance, the obstacles and the visibility cost.

use super::{invalid, ScenarioError};
use crate::avoidance::Geometry;
use crate::bounds::{ANGLE_RAD, LENGTH_M};
use crate::feature::InteractionSource;
use crate::visual_task::FourthTask;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// A rigid transform in a file: translation in metres, then roll–pitch–yaw in degrees (`R = Rz(yaw) Ry(pitch)
/// Rx(roll)`, nalgebra's `from_euler_angles`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseSpec {
    /// Translation (m).
    pub translation_m: [f64; 3],
    /// Roll, pitch, yaw (degrees).
    #[serde(default)]
    pub rpy_deg: [f64; 3],
}

impl PoseSpec {
    /// The pose written as a translation and roll–pitch–yaw angles.
    pub fn from_isometry(pose: &Isometry3<f64>) -> Self {
        let (roll, pitch, yaw) = pose.rotation.euler_angles();
        Self {
            translation_m: pose.translation.vector.into(),
            rpy_deg: [roll, pitch, yaw].map(f64::to_degrees),
        }
    }

    /// The rigid transform; `field` names the pose in errors.
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] for a translation beyond [`LENGTH_M`] or an angle beyond [`ANGLE_RAD`] (both
    /// naming the value).
    pub fn to_isometry(self, field: &str) -> Result<Isometry3<f64>, ScenarioError> {
        let [roll, pitch, yaw] = self.rpy_deg.map(f64::to_radians);
        // (field, range, values checked, values written): the angles are checked in radians.
        for (part, range, values, written) in [
            (
                "translation_m",
                LENGTH_M,
                self.translation_m,
                self.translation_m,
            ),
            ("rpy_deg", ANGLE_RAD, [roll, pitch, yaw], self.rpy_deg),
        ] {
            if let Some(i) = values.iter().position(|&v| !range.contains(v)) {
                return Err(invalid(
                    &format!("{field}.{part}"),
                    format!(
                        "value {i} = {:e} is out of range: {}",
                        written[i], range.text
                    ),
                ));
            }
        }
        let [x, y, z] = self.translation_m;
        Ok(Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        ))
    }
}

/// Joint limits that replace the chain's own (`[robot] joint_limits = { lower = [..], upper = [..] }`), e.g. the
/// narrower ranges of a real controller's safety configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointLimitsSpec {
    /// `q^min` (m or rad per joint, as the chain), `N` values: finite, or `-inf` for a continuous joint left
    /// unlimited.
    pub lower: Vec<f64>,
    /// `q^max` (m or rad per joint), `N` values, each above its `lower`: finite, or `inf` for a continuous joint left
    /// unlimited. Finite limits on a continuous joint are soft limits the joint-limit cost keeps it within.
    pub upper: Vec<f64>,
}

/// The robot: a built-in arm by name, or a URDF file; either with optional joint limits replacing the chain's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, untagged)]
pub enum RobotSpec {
    /// A built-in robot (`"afma6"`, `"ur5e"`, `"rail7"`) with its camera mount.
    Builtin {
        /// Its name.
        builtin: String,
        /// Joint limits replacing the built-in ones (default: the robot's own).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        joint_limits: Option<JointLimitsSpec>,
    },
    /// A chain of a URDF file (path relative to the scenario file) with a camera on the tip link.
    Urdf {
        /// The URDF file.
        urdf: PathBuf,
        /// The base link.
        base_link: String,
        /// The tip (end-effector) link.
        tip_link: String,
        /// The camera frame as a link of the URDF (z forward, x right, y down), rigidly attached to the tip link by
        /// fixed joints; `camera_mount`, if given, is then an extra offset of the camera in that link's frame.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        camera_link: Option<String>,
        /// The camera pose in the tip frame (`e_from_c`, ViSP `eMc`), or in the `camera_link` frame when that is
        /// given (default there: the identity). Required without `camera_link`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        camera_mount: Option<PoseSpec>,
        /// Where `package://NAME/…` mesh URIs of the URDF's collision geometry lead: package name → directory
        /// (relative to the scenario file). Searched before `ROS_PACKAGE_PATH`; relative mesh paths are resolved
        /// against the URDF file's directory.
        #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
        packages: BTreeMap<String, PathBuf>,
        /// Joint limits replacing the URDF's (default: the URDF's own).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        joint_limits: Option<JointLimitsSpec>,
    },
}

/// Pinhole intrinsics (px).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// Horizontal focal length (px).
    pub fx: f64,
    /// Vertical focal length (px).
    pub fy: f64,
    /// Principal point abscissa (px).
    pub cx: f64,
    /// Principal point ordinate (px).
    pub cy: f64,
    /// Image width (px).
    pub width: f64,
    /// Image height (px).
    pub height: f64,
}

/// The target rectangle (m), four points in its plane `z = 0`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetSpec {
    /// Width along the object x axis (m).
    pub width_m: f64,
    /// Height along the object y axis (m).
    pub height_m: f64,
}

/// Where the camera must end: at joint configuration `joints`, it sees the target at `camera_from_target` (ViSP `cdMo`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DesiredSpec {
    /// The desired joint configuration `q_d` (m or rad per joint).
    pub joints: Vec<f64>,
    /// The target pose in the desired camera frame.
    pub camera_from_target: PoseSpec,
}

/// The start configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StartSpec {
    /// `q(0)` (m or rad per joint), inside the joint limits.
    pub joints: Vec<f64>,
}

/// The visual tasks.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TasksSpec {
    /// `λ_i` (s⁻¹) of centroid, angle, area (`a_n`) and third-order tasks.
    pub gains: [f64; 4],
    /// `λ` (s⁻¹) of the classical six-feature task.
    pub classical_gain: f64,
    /// Where interaction matrices are evaluated ([D10](crate::theory#d10)): `"exact"`, `"paper_approx"` or `"desired"`.
    #[serde(default)]
    pub interaction: InteractionKind,
    /// The a-priori depth `Z_g` (m) of the paper's centroid approximation (F31); default: the desired depth.
    #[serde(default)]
    pub a_priori_depth_m: Option<f64>,
    /// `Z*` (m), the depth that normalises the size feature `a_n = Z* √(a*/a)` (\[M37\]); default: the desired depth
    /// (the target centre's depth at the goal). Another value scales the feature and its interaction matrix.
    #[serde(default)]
    pub area_depth_m: Option<f64>,
    /// The fourth task: `"auto"` (default: the paper's `P_x, P_y`, or the side ratios on a centrally symmetric target
    /// such as a square marker seen head-on, [D9](crate::theory#d9)), `"paper_invariants"` or `"side_ratios"`.
    #[serde(default)]
    pub fourth_task: FourthTask,
    /// `δ` of damped least squares for the velocity term of every stack level (same unit as the singular values of
    /// the projected Jacobians; 0, the default: the truncated pseudo-inverse, [D2](crate::theory#d2)). Bounds the
    /// velocity near singular configurations, at the price of a small bias there.
    #[serde(default)]
    pub damping: f64,
    /// An adaptive gain `λ(‖e_i‖∞)` replacing every task's gain, the classical task's included (the servo façade's
    /// [`AdaptiveGain`](crate::servo::AdaptiveGain)); absent: the constant gains above. A gain that is lower at the goal than far from it
    /// (`at_zero < at_infinity`, a negative `slope_at_zero`) averages pixel noise over a longer time near the goal
    /// ([D21](crate::theory#d21)).
    #[serde(default)]
    pub adaptive_gain: Option<AdaptiveGainSpec>,
}

/// [`AdaptiveGain::new`](crate::servo::AdaptiveGain::new)'s three parameters as written in files: `λ(x) = a e^{−b x} + c`, `a = λ(0) − λ(∞)`,
/// `b = λ'(0)/a`, `c = λ(∞)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdaptiveGainSpec {
    /// `λ(0)` (s⁻¹, > 0): the gain at the goal.
    pub at_zero: f64,
    /// `λ(∞)` (s⁻¹, > 0): the gain far from it.
    pub at_infinity: f64,
    /// `λ'(0)` (s⁻¹ per unit of `‖e‖∞`), of the sign of `λ(0) − λ(∞)`.
    pub slope_at_zero: f64,
}

/// The interaction source as written in files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InteractionKind {
    /// [`InteractionSource::Exact`].
    #[default]
    Exact,
    /// [`InteractionSource::PaperApprox`].
    PaperApprox,
    /// [`InteractionSource::Desired`].
    Desired,
}

impl From<InteractionKind> for InteractionSource {
    fn from(kind: InteractionKind) -> Self {
        match kind {
            InteractionKind::Exact => Self::Exact,
            InteractionKind::PaperApprox => Self::PaperApprox,
            InteractionKind::Desired => Self::Desired,
        }
    }
}

/// Joint-limit avoidance and the transition term.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AvoidanceSpec {
    /// `ρ` of [\[M19\]](crate::theory#m19), in (0, 1/2).
    pub activation_ratio: f64,
    /// `κ` (s⁻¹), the projected-gradient gain.
    pub gain: f64,
    /// `μ` (s⁻¹) of the transition term; default `10 · max λ_i` (D1).
    #[serde(default)]
    pub transition_gain: Option<f64>,
}

/// A world obstacle and the links it must be kept away from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleSpec {
    /// Its name (reported on collision).
    pub name: String,
    /// Its shape (sizes in m).
    pub shape: Geometry,
    /// Its pose in the robot base frame.
    pub pose: PoseSpec,
    /// `d_i` (m, > 0): the obstacle cost is zero for links farther than this.
    pub influence_distance_m: f64,
    /// The links (with URDF `<collision>` shapes) paired with it.
    pub links: Vec<String>,
}

/// The visibility cost ([`crate::avoidance::VisibilityCost`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VisibilitySpec {
    /// The band along the image border (px) where the cost is active.
    pub margin_px: f64,
}
