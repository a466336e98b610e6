//! Scenario files: everything a simulated experiment needs, in TOML ([theory §9](crate::theory#s9),
//! [D12](crate::theory#d12)).
//!
//! A scenario names the robot (a built-in arm, or a URDF file with base and tip links and a camera link or mount), the
//! camera intrinsics, the target rectangle, the desired pose (a desired joint configuration and the pose of the target
//! seen from the camera there: the target is placed so that this pose is reachable), the start configuration, the
//! tasks (gains and interaction source), the avoidance, the controller thresholds and the simulation period and budget.
//! Field names carry their units (`translation_m`, `rpy_deg`); unknown fields are errors, so a value written in the
//! wrong unit under the wrong name is caught, and every semantic error names its field.
//!
//! Optional sections add avoidance beyond the joint limits (both join the avoidance cost of the runs with avoidance):
//!
//! ```toml
//! [[obstacles]]                       # a world obstacle, pose in the robot base frame
//! name = "post"
//! shape = { sphere = { radius_m = 0.05 } }   # or box = { size_m = [..] }, cylinder/capsule = { radius_m, length_m },
//!                                     # convex_hull = { points_m = [[x, y, z], ...] }
//! pose = { translation_m = [0.1, 0.2, 0.3], rpy_deg = [0.0, 0.0, 0.0] }
//! influence_distance_m = 0.1          # the cost is zero farther than this
//! links = ["afma6_camera", "afma6_end_effector"]   # links (with URDF <collision> shapes) kept away from it
//!
//! [visibility]
//! margin_px = 30.0                    # the cost grows when a target point comes closer than this to the border
//! ```
//!
//! From one scenario, [`Scenario::run`] runs any of the paper's four [`RunKind`]s ([theory §9](crate::theory#s9)):
//!
//! | run | tasks | avoidance | removal |
//! |---|---|---|---|
//! | `classical` | one task of six features | no | no |
//! | `stack` | the four tasks pushed one by one | no | no |
//! | `stack_gradient` | the four tasks pushed one by one | projected gradient | no |
//! | `stack_controller` | the four tasks pushed one by one | projected gradient | yes (the full method) |
//!
//! [`generate`] writes the paper's scenario for any arm (a URDF with base and tool links and a camera mount): the zoo
//! of real arms of `assets/zoo.toml` ([`Zoo`]) runs the study on every arm of `example-robot-data` that way.
//!
//! ```
//! let scenario = servostack::scenario::Scenario::from_toml_str(
//!     include_str!("../assets/scenarios/paper_afma6.toml"), None)?;
//! assert_eq!(scenario.name, "paper_afma6");
//! # Ok::<(), servostack::scenario::ScenarioError>(())
//! ```

use crate::avoidance::{
    CostError, Geometry, LinkColliders, MeshPaths, Obstacle, ObstacleCost, ObstaclePair,
};
use crate::bounds::{ANGLE_RAD, LENGTH_M};
use crate::camera::ImagePoint;
use crate::camera::{CameraError, CameraIntrinsics, EyeInHand};
use crate::controller::{ControllerParameters, RemovalCriterion};
use crate::depth::DepthSource;
use crate::feature::InteractionSource;
use crate::feature::Observation;
use crate::law::{ControlLaw, LawError};
use crate::linalg::VelocityInverse;
use crate::math::JointVector;
use crate::measurement::{MeasurementModel, MeasurementParameters};
use crate::robot::{builtin, JointKind, RobotError, SerialChain};
use crate::servo::AdaptiveGain;
use crate::sim::{
    simulate_with, Decimated, Drive, Run, RunLog, Scene, Sensing, SimError, SimulationParameters,
};
use crate::stack::StackParameters;
use crate::target::{RectangleTarget, TargetError};
use crate::task::TaskError;
use crate::visual_task::{
    classical_task_with, image_points_task, paper_tasks_with, FourthTask, VisualTask,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

mod generate;
mod overrides;
mod text_bounds;
mod zoo;

pub use generate::{generate, ArmSpec, MIN_GOAL_SINGULAR_VALUE};
pub use text_bounds::{MAX_SCENARIO_BYTES, MAX_SCENARIO_DEPTH};
pub use zoo::{ExcludedArm, Zoo};

/// The records [`Scenario::run`] keeps at most (65 536, a minute of a 1 kHz loop; a few tens of megabytes): every
/// record of a shorter run, evenly spaced ones of a longer one ([`Decimated`]).
pub const DEFAULT_RECORD_CAPACITY: usize = 1 << 16;

/// Errors of scenario files. Each names the field at fault.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("cannot read scenario {path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The scenario text is larger than [`MAX_SCENARIO_BYTES`] (checked before parsing, [D17](crate::theory#d17)).
    #[error("scenario of {bytes} bytes is larger than the limit of {limit} bytes")]
    TooLarge {
        /// The size of the text or file (bytes).
        bytes: u64,
        /// [`MAX_SCENARIO_BYTES`].
        limit: usize,
    },
    /// The scenario nests arrays or inline tables deeper than [`MAX_SCENARIO_DEPTH`] (checked before parsing: the
    /// parser would overflow the stack, [D17](crate::theory#d17)).
    #[error("scenario nests arrays or tables {depth} deep at line {line}: the limit is {limit}")]
    TooDeep {
        /// The depth reached when the limit was passed.
        depth: usize,
        /// [`MAX_SCENARIO_DEPTH`].
        limit: usize,
        /// The line (1-based) where it was passed.
        line: usize,
    },
    /// The file is not valid TOML for a scenario (missing or unknown field, wrong type); the message names the field
    /// and its line.
    #[error("scenario syntax: {0}")]
    Syntax(#[from] toml::de::Error),
    /// A field has an invalid value.
    #[error("scenario field `{field}`: {reason}")]
    Invalid {
        /// The field, as a dotted path (`start.joints`).
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// The robot could not be built.
    #[error("scenario field `robot`: {0}")]
    Robot(#[from] RobotError),
    /// The camera could not be built.
    #[error("scenario field `camera`: {0}")]
    Camera(#[from] CameraError),
    /// The target could not be built.
    #[error("scenario field `target`: {0}")]
    Target(#[from] TargetError),
    /// The tasks could not be built (a feature undefined at the desired pose, a bad gain).
    #[error("scenario field `tasks`: {0}")]
    Task(#[from] TaskError),
    /// The control law's gains are invalid.
    #[error("scenario field `avoidance`: {0}")]
    Law(#[from] LawError),
    /// The simulation could not run.
    #[error(transparent)]
    Simulation(#[from] SimError),
}

fn invalid(field: &str, reason: impl Into<String>) -> ScenarioError {
    ScenarioError::Invalid {
        field: field.into(),
        reason: reason.into(),
    }
}

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
    /// [`AdaptiveGain`]); absent: the constant gains above. A gain that is lower at the goal than far from it
    /// (`at_zero < at_infinity`, a negative `slope_at_zero`) averages pixel noise over a longer time near the goal
    /// ([D21](crate::theory#d21)).
    #[serde(default)]
    pub adaptive_gain: Option<AdaptiveGainSpec>,
}

/// [`AdaptiveGain::new`]'s three parameters as written in files: `λ(x) = a e^{−b x} + c`, `a = λ(0) − λ(∞)`,
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

/// A complete scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// A short name, reported in summaries.
    pub name: String,
    /// What the scenario shows, and why its values were chosen.
    #[serde(default)]
    pub description: String,
    /// The robot.
    pub robot: RobotSpec,
    /// The camera intrinsics.
    pub camera: CameraSpec,
    /// The target.
    pub target: TargetSpec,
    /// The desired pose.
    pub desired: DesiredSpec,
    /// The start configuration.
    pub start: StartSpec,
    /// The tasks.
    pub tasks: TasksSpec,
    /// Avoidance and transition.
    pub avoidance: AvoidanceSpec,
    /// The stack controller's thresholds (defaults of [`ControllerParameters`] when absent; `allow_removal` is set by
    /// the run kind).
    #[serde(default)]
    pub controller: ControllerParameters,
    /// Period, budget, convergence threshold, image margin.
    #[serde(default)]
    pub simulation: SimulationParameters,
    /// World obstacles (none by default).
    #[serde(default)]
    pub obstacles: Vec<ObstacleSpec>,
    /// The visibility cost (off by default).
    #[serde(default)]
    pub visibility: Option<VisibilitySpec>,
    /// The camera the controller has against the true one: pixel noise, intrinsics and hand-eye errors,
    /// distortion, a slower camera, latency ([`MeasurementParameters`]; default: the exact camera).
    #[serde(default)]
    pub measurement: MeasurementParameters,
    /// Where the points' depths come from ([`DepthSource`]); absent: the true depths (the simulation's oracle).
    #[serde(default)]
    pub depth: Option<DepthSource>,
    /// The directory relative paths are resolved against (set by [`Scenario::from_file`]).
    #[serde(skip)]
    pub base_dir: Option<PathBuf>,
}

/// The paper's four runs ([theory §9](crate::theory#s9)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RunKind {
    /// Classical IBVS: one task with the six features, no avoidance.
    Classical,
    /// Tasks pushed one by one, no avoidance.
    Stack,
    /// Tasks pushed one by one, with projected-gradient joint-limit avoidance.
    StackGradient,
    /// The full method: avoidance and the stack controller's removals and re-insertions.
    StackController,
}

impl RunKind {
    /// The four runs, in the paper's order.
    pub const ALL: [RunKind; 4] = [
        Self::Classical,
        Self::Stack,
        Self::StackGradient,
        Self::StackController,
    ];

    /// The run's name: `classical`, `stack`, `stack_gradient`, `stack_controller`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Classical => "classical",
            Self::Stack => "stack",
            Self::StackGradient => "stack_gradient",
            Self::StackController => "stack_controller",
        }
    }
}

/// The joint counts [`with_joint_count`] dispatches to: `1..=MAX_JOINTS`.
pub const MAX_JOINTS: usize = 12;

/// Work generic in the joint count `N`, for [`with_joint_count`]: a runner's body, written once for every `N`.
pub trait ForJointCount {
    /// What the work returns.
    type Output;
    /// Does the work for a robot of `N` joints.
    fn call<const N: usize>(self) -> Self::Output;
}

/// Calls `work.call::<N>()` with `N = joints`, a count known only at run time (read from a scenario's robot with
/// [`Scenario::joint_count`]), for any `N` in `1..=`[`MAX_JOINTS`].
///
/// # Errors
/// [`ScenarioError::Invalid`] naming `robot` for a joint count outside that range.
pub fn with_joint_count<W: ForJointCount>(
    joints: usize,
    work: W,
) -> Result<W::Output, ScenarioError> {
    Ok(match joints {
        1 => work.call::<1>(),
        2 => work.call::<2>(),
        3 => work.call::<3>(),
        4 => work.call::<4>(),
        5 => work.call::<5>(),
        6 => work.call::<6>(),
        7 => work.call::<7>(),
        8 => work.call::<8>(),
        9 => work.call::<9>(),
        10 => work.call::<10>(),
        11 => work.call::<11>(),
        12 => work.call::<12>(),
        _ => {
            return Err(invalid(
                "robot",
                format!("the chain has {joints} joints: the runners handle 1 to {MAX_JOINTS}"),
            ))
        }
    })
}

/// A scenario turned into models: the scene and what the runs need.
#[derive(Debug, Clone)]
pub struct Experiment<const N: usize> {
    /// The scene (robot, camera, target, limits).
    pub scene: Scene<N>,
    /// The start configuration.
    pub start: JointVector<N>,
    /// The desired joint configuration.
    pub desired_joints: JointVector<N>,
    /// The target pose in the desired camera frame.
    pub desired_camera_from_target: Isometry3<f64>,
}

impl Scenario {
    /// Parses a scenario; relative paths are resolved against `base_dir` (or the working directory).
    ///
    /// # Errors
    /// [`ScenarioError::TooLarge`], [`ScenarioError::TooDeep`] for text beyond the bounds checked before parsing
    /// ([D17](crate::theory#d17)); [`ScenarioError::Syntax`] naming the field and line.
    pub fn from_toml_str(text: &str, base_dir: Option<&Path>) -> Result<Self, ScenarioError> {
        text_bounds::check_scenario_text(text)?;
        let mut scenario: Self = toml::from_str(text)?;
        scenario.base_dir = base_dir.map(Path::to_path_buf);
        Ok(scenario)
    }

    /// Reads and parses a scenario file.
    ///
    /// # Errors
    /// [`ScenarioError::Io`], [`ScenarioError::TooLarge`] (the file is not read), then those of
    /// [`Scenario::from_toml_str`].
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self, ScenarioError> {
        let path = path.as_ref();
        let text = text_bounds::read_scenario_file(path)?;
        Self::from_toml_str(&text, path.parent())
    }

    /// The scene and configurations, with every field checked.
    ///
    /// # Errors
    /// The first invalid field: an unknown robot, a joint vector of the wrong size or outside the limits, invalid
    /// intrinsics, target, poses, gains or thresholds.
    pub fn experiment<const N: usize>(&self) -> Result<Experiment<N>, ScenarioError> {
        self.adaptive_gain()?;
        let (chain, camera) = self.robot_model::<N>()?;
        let desired_joints = joints::<N>("desired.joints", &self.desired.joints)?;
        let start = joints::<N>("start.joints", &self.start.joints)?;
        for (field, q) in [
            ("start.joints", &start),
            ("desired.joints", &desired_joints),
        ] {
            if let Some(joint) = (0..N)
                .find(|&i| !(chain.lower_limits()[i]..=chain.upper_limits()[i]).contains(&q[i]))
            {
                return Err(invalid(
                    field,
                    format!(
                        "joint {joint} = {} is outside its limits [{}, {}]",
                        q[joint],
                        chain.lower_limits()[joint],
                        chain.upper_limits()[joint]
                    ),
                ));
            }
        }
        let c = self.camera;
        let intrinsics = CameraIntrinsics::new(c.fx, c.fy, c.cx, c.cy, c.width, c.height)?;
        let target = RectangleTarget::new(self.target.width_m, self.target.height_m)?;
        let desired_camera_from_target = self
            .desired
            .camera_from_target
            .to_isometry("desired.camera_from_target")?;
        let scene = Scene::with_target_seen_from(
            chain,
            camera,
            intrinsics,
            target,
            &desired_joints,
            &desired_camera_from_target,
            self.avoidance.activation_ratio,
        )
        .map_err(|e| match e {
            SimError::Cost(cost @ CostError::InvalidActivationRatio { .. }) => {
                invalid("avoidance.activation_ratio", cost.to_string())
            }
            SimError::Cost(cost) => invalid("robot.joint_limits", cost.to_string()),
            other => other.into(),
        })?;
        let mut scene = scene;
        if !self.obstacles.is_empty() {
            let obstacles = self.obstacle_cost(scene.chain().clone())?;
            scene = scene.with_obstacles(obstacles);
        }
        self.controller
            .validate()
            .map_err(|e| invalid("controller", e.to_string()))?;
        self.simulation.validate()?;
        if let Some(visibility) = self.visibility {
            let cost = scene
                .visibility_cost(
                    visibility.margin_px,
                    self.simulation.facing_activation_deg(),
                )
                .map_err(|e| invalid("visibility.margin_px", e.to_string()))?;
            scene = scene.with_visibility(cost);
        }
        let mut workspace = crate::robot::KinematicsWorkspace::new();
        let view = match scene.observe(&mut workspace, &start) {
            Ok(view)
                if scene
                    .intrinsics()
                    .all_in_field_of_view(&view.points, self.simulation.image_margin) =>
            {
                view
            }
            _ => {
                return Err(invalid(
                    "start.joints",
                    "the target is not entirely in the image at the start",
                ))
            }
        };
        // A target the camera sees too obliquely at the start is not tracked there (D27).
        let incidence = scene.target_incidence_deg(&view.c_from_o);
        if incidence > self.simulation.max_incidence_deg {
            return Err(invalid(
                "start.joints",
                crate::sim::incidence_reason(incidence, self.simulation.max_incidence_deg),
            ));
        }
        Ok(Experiment {
            scene,
            start,
            desired_joints,
            desired_camera_from_target,
        })
    }

    /// The obstacle cost of the `[[obstacles]]` list, with the link shapes of the robot's URDF.
    fn obstacle_cost<const N: usize>(
        &self,
        chain: SerialChain<N>,
    ) -> Result<ObstacleCost<N>, ScenarioError> {
        let (urdf, meshes) = match &self.robot {
            RobotSpec::Builtin { builtin, .. } => (
                builtin::urdf_by_name(builtin)?.to_owned(),
                MeshPaths::new(""),
            ),
            RobotSpec::Urdf { urdf, packages, .. } => {
                let path = self.resolve(urdf);
                let xml = crate::robot::read_urdf_file(&path)?;
                let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
                let meshes =
                    packages
                        .iter()
                        .fold(MeshPaths::new(dir), |meshes, (name, package_dir)| {
                            meshes.with_package(name, self.resolve(package_dir))
                        });
                (xml, meshes)
            }
        };
        let links = LinkColliders::from_urdf_robot_with_meshes(
            &crate::robot::parse_urdf(&urdf)?,
            &chain,
            &meshes,
        )
        .map_err(|e| invalid("robot (collision geometry)", e.to_string()))?;
        let mut obstacles = Vec::with_capacity(self.obstacles.len());
        let mut pairs = Vec::new();
        for (i, spec) in self.obstacles.iter().enumerate() {
            let field = |name: &str| format!("obstacles[{i}].{name}");
            let pose = spec.pose.to_isometry(&field("pose"))?;
            obstacles.push(
                Obstacle::new(&spec.name, spec.shape.clone(), pose)
                    .map_err(|e| invalid(&field("shape"), e.to_string()))?,
            );
            for link in &spec.links {
                let pair = ObstaclePair {
                    link: link.clone(),
                    obstacle: spec.name.clone(),
                    influence_distance: spec.influence_distance_m,
                };
                // Check each pair alone, so the error names its field.
                ObstacleCost::new(
                    chain.clone(),
                    &links,
                    obstacles.clone(),
                    std::slice::from_ref(&pair),
                )
                .map_err(|e| match e {
                    CostError::InvalidInfluenceDistance { .. } => {
                        invalid(&field("influence_distance_m"), e.to_string())
                    }
                    _ => invalid(&field("links"), e.to_string()),
                })?;
                pairs.push(pair);
            }
        }
        ObstacleCost::new(chain, &links, obstacles, &pairs)
            .map_err(|e| invalid("obstacles", e.to_string()))
    }

    fn resolve(&self, path: &Path) -> PathBuf {
        match &self.base_dir {
            Some(dir) if path.is_relative() => dir.join(path),
            _ => path.to_path_buf(),
        }
    }

    /// The number of independent joints of the scenario's robot (its chain from base to tip), for
    /// [`with_joint_count`].
    ///
    /// # Errors
    /// As [`Scenario::robot_model`], except a joint count.
    pub fn joint_count(&self) -> Result<usize, ScenarioError> {
        match self.robot_model::<0>() {
            Ok(_) => Ok(0),
            Err(ScenarioError::Robot(RobotError::JointCount { found, .. })) => Ok(found),
            Err(error) => Err(error),
        }
    }

    /// The kind of each independent joint of the scenario's robot, base to tip, for callers that are not generic in
    /// the joint count.
    ///
    /// # Errors
    /// As [`Scenario::robot_model`], and a joint count outside `1..=`[`MAX_JOINTS`].
    pub fn joint_kinds(&self) -> Result<Vec<JointKind>, ScenarioError> {
        struct Kinds<'s>(&'s Scenario);
        impl ForJointCount for Kinds<'_> {
            type Output = Result<Vec<JointKind>, ScenarioError>;
            fn call<const N: usize>(self) -> Self::Output {
                let (chain, _) = self.0.robot_model::<N>()?;
                Ok(chain.joints().iter().map(|joint| joint.kind()).collect())
            }
        }
        with_joint_count(self.joint_count()?, Kinds(self))?
    }

    /// The robot's chain (with the `joint_limits` override, if any) and camera mount.
    ///
    /// # Errors
    /// An unknown built-in, an unreadable or invalid URDF, a chain without `N` joints, an invalid mount; joint limits
    /// of the wrong size, non-finite or with `lower ≥ upper` (naming `robot.joint_limits.lower` or `.upper`).
    pub fn robot_model<const N: usize>(
        &self,
    ) -> Result<(SerialChain<N>, EyeInHand), ScenarioError> {
        let (chain, camera, limits) = match &self.robot {
            RobotSpec::Builtin {
                builtin,
                joint_limits,
            } => {
                let robot = builtin::by_name::<N>(builtin)?;
                (robot.chain, robot.camera, joint_limits)
            }
            RobotSpec::Urdf {
                urdf,
                base_link,
                tip_link,
                camera_link,
                camera_mount,
                joint_limits,
                ..
            } => {
                let xml = crate::robot::read_urdf_file(&self.resolve(urdf))?;
                let robot = crate::robot::parse_urdf(&xml)?;
                let chain = SerialChain::from_urdf_robot(&robot, base_link, tip_link)?;
                let offset = match camera_mount {
                    Some(pose) => Some(pose.to_isometry("robot.camera_mount")?),
                    None => None,
                };
                let mount = match (camera_link, offset) {
                    (Some(link), offset) => {
                        let tip_from_link =
                            SerialChain::<0>::from_urdf_robot(&robot, tip_link, link)
                                .map_err(|e| {
                                    invalid(
                                        "robot.camera_link",
                                        format!(
                                            "{link:?} must hang from the tip link {tip_link:?} by fixed joints: {e}"
                                        ),
                                    )
                                })?;
                        tip_from_link.segment_from_tip() * offset.unwrap_or_else(Isometry3::identity)
                    }
                    (None, Some(mount)) => mount,
                    (None, None) => {
                        return Err(invalid(
                            "robot.camera_mount",
                            "give the camera as robot.camera_link (a URDF link) or robot.camera_mount (its pose \
                             in the tip frame)",
                        ))
                    }
                };
                (chain, EyeInHand::new(mount)?, joint_limits)
            }
        };
        let Some(limits) = limits else {
            return Ok((chain, camera));
        };
        let lower = limit_values::<N>("robot.joint_limits.lower", &limits.lower)?;
        let upper = limit_values::<N>("robot.joint_limits.upper", &limits.upper)?;
        if let Some(i) = (0..N).find(|&i| lower[i] >= upper[i]) {
            return Err(invalid(
                "robot.joint_limits.upper",
                format!(
                    "joint {i}: upper = {} is not above robot.joint_limits.lower = {}",
                    upper[i], lower[i]
                ),
            ));
        }
        let chain = chain
            .with_limits(lower, upper)
            .map_err(|e| invalid("robot.joint_limits", e.to_string()))?;
        Ok((chain, camera))
    }

    /// Runs one of the four runs of [theory §9](crate::theory#s9) on this scenario.
    ///
    /// Its records are kept in bounded memory ([`DEFAULT_RECORD_CAPACITY`]): every record of a run up to that many
    /// iterations, evenly spaced ones beyond ([`Decimated`]), so that a budget of any size cannot exhaust memory. For
    /// every record of a longer run, pass a `Vec<Record<N>>` to [`Scenario::run_experiment_with`].
    ///
    /// # Errors
    /// Invalid fields (see [`Scenario::experiment`]), tasks undefined at the desired pose, simulation failures. The
    /// run's outcome (converged, joint limit, ...) is data in the [`Run`], not an error.
    pub fn run<const N: usize>(&self, kind: RunKind) -> Result<Run<N>, ScenarioError> {
        let experiment = self.experiment::<N>()?;
        self.run_experiment(&experiment, kind)
    }

    /// As [`Scenario::run`], on an experiment already built.
    ///
    /// # Errors
    /// As [`Scenario::run`].
    pub fn run_experiment<const N: usize>(
        &self,
        experiment: &Experiment<N>,
        kind: RunKind,
    ) -> Result<Run<N>, ScenarioError> {
        let mut records = Decimated::new(DEFAULT_RECORD_CAPACITY);
        let mut run = self.run_experiment_with(experiment, kind, &mut records)?;
        run.records = records.into_records();
        Ok(run)
    }

    /// As [`Scenario::run_experiment`], with the records given to `log` ([`simulate_with`]): a run of any length in
    /// bounded memory with [`crate::sim::SummaryOnly`], [`crate::sim::Decimated`] or [`crate::sim::JsonLines`].
    ///
    /// # Errors
    /// As [`Scenario::run`].
    pub fn run_experiment_with<const N: usize>(
        &self,
        experiment: &Experiment<N>,
        kind: RunKind,
        log: &mut dyn RunLog<N>,
    ) -> Result<Run<N>, ScenarioError> {
        let desired_view = experiment
            .scene
            .view_from(&experiment.desired_camera_from_target)?;
        let sensing = self.sensing(&experiment.scene, &desired_view.points)?;
        let desired = match &sensing {
            // The desired image as the controller's camera reads it (taught at the goal, as on a real robot).
            Some(sensing) => Observation::new(&sensing.desired_points, None),
            None => desired_view.observation(),
        }
        .map_err(SimError::from)?;
        let goal_depth = experiment.desired_camera_from_target.translation.z;
        let a_priori_depth = self.tasks.a_priori_depth_m.unwrap_or(goal_depth);
        let desired_depth = self.tasks.area_depth_m.unwrap_or(goal_depth);
        let source = self.tasks.interaction.into();
        let tasks_for = |desired: &Observation<'_>| -> Result<Vec<VisualTask>, TaskError> {
            match kind {
                RunKind::Classical => Ok(vec![classical_task_with(
                    desired,
                    desired_depth,
                    a_priori_depth,
                    self.tasks.classical_gain,
                    source,
                    self.tasks.fourth_task,
                )?]),
                _ => {
                    let mut tasks = paper_tasks_with(
                        desired,
                        desired_depth,
                        a_priori_depth,
                        self.tasks.gains,
                        source,
                        self.tasks.fourth_task,
                    )?;
                    // The full method holds the image points in reserve (D23), at the last task's gain.
                    if kind == RunKind::StackController {
                        tasks.push(image_points_task(desired, self.tasks.gains[3], source)?);
                    }
                    Ok(tasks)
                }
            }
        };
        let tasks = tasks_for(&desired)?;
        // With a real camera, the same tasks on the true desired image measure the run's noise-free errors.
        let true_tasks = match &sensing {
            Some(_) => tasks_for(&desired_view.observation().map_err(SimError::from)?)?,
            None => Vec::new(),
        };
        let sensing = sensing.map(|s| s.with_true_tasks(&true_tasks));
        let avoid = matches!(kind, RunKind::StackGradient | RunKind::StackController);
        let kappa = if avoid { self.avoidance.gain } else { 0.0 };
        let adaptive_gain = self.adaptive_gain()?;
        let max_gain = match (kind, adaptive_gain) {
            (_, Some(adaptive)) => adaptive.max_gain(),
            (RunKind::Classical, None) => self.tasks.classical_gain,
            _ => self.tasks.gains.iter().copied().fold(0.0, f64::max),
        };
        let mu = self
            .avoidance
            .transition_gain
            .unwrap_or(ControlLaw::TRANSITION_TO_TASK_GAIN_RATIO * max_gain);
        let stack = StackParameters {
            velocity_inverse: if self.tasks.damping == 0.0 {
                VelocityInverse::Truncated
            } else {
                VelocityInverse::Damped {
                    damping: self.tasks.damping,
                }
            },
            ..StackParameters::default()
        };
        let law = ControlLaw::with_stack_parameters(stack, mu, kappa)?;
        // The baselines are the paper's laws as they are: no removal, no braking before the limits (D25) and no
        // lock along them (D26).
        let full_method = kind == RunKind::StackController;
        let controller = ControllerParameters {
            allow_removal: full_method,
            braking_rate: if full_method {
                self.controller.braking_rate
            } else {
                f64::INFINITY
            },
            lock_band: if full_method {
                self.controller.lock_band
            } else {
                0.0
            },
            ..self.controller
        };
        let drive = Drive {
            law: &law,
            controller,
            avoid_joint_limits: avoid,
            guard_visibility: kind == RunKind::StackController,
            // The centroid (first of the paper's tasks) keeps the target in the image.
            protected_tasks: if kind == RunKind::StackController {
                &[0]
            } else {
                &[]
            },
            sensing: sensing.as_ref(),
            adaptive_gain,
            reserve_task: kind == RunKind::StackController,
        };
        Ok(simulate_with(
            &experiment.scene,
            &tasks,
            drive,
            &experiment.start,
            &self.simulation,
            log,
        )?)
    }
}

impl Scenario {
    /// `tasks.adaptive_gain`, checked: both gains in [`crate::bounds::GAIN_PER_S`] and [`AdaptiveGain::new`]'s rules.
    fn adaptive_gain(&self) -> Result<Option<AdaptiveGain>, ScenarioError> {
        let Some(spec) = self.tasks.adaptive_gain else {
            return Ok(None);
        };
        let field = "tasks.adaptive_gain";
        for (name, gain) in [("at_zero", spec.at_zero), ("at_infinity", spec.at_infinity)] {
            if !crate::bounds::GAIN_PER_S.contains(gain) {
                let expected = crate::bounds::GAIN_PER_S.text;
                return Err(invalid(
                    field,
                    format!("{name} = {gain}: expected {expected}"),
                ));
            }
        }
        AdaptiveGain::new(spec.at_zero, spec.at_infinity, spec.slope_at_zero)
            .map(Some)
            .map_err(|e| invalid(field, e.to_string()))
    }

    /// The controller's view of the camera when the scenario's camera is not exact or names a depth source: the
    /// desired image points read through the nominal camera (pixels of the true camera, normalised by the believed
    /// intrinsics and undistortion), with their desired depths.
    fn sensing<const N: usize>(
        &self,
        scene: &Scene<N>,
        desired: &[ImagePoint; 4],
    ) -> Result<Option<Sensing<'static>>, ScenarioError> {
        if self.measurement.is_exact() && self.depth.is_none() {
            return Ok(None);
        }
        let field = |e: &dyn std::fmt::Display| invalid("measurement", e.to_string());
        if let Some(depth) = &self.depth {
            depth
                .validate()
                .map_err(|e| invalid("depth", e.to_string()))?;
        }
        let model = MeasurementModel::new(
            &self.measurement,
            *scene.intrinsics(),
            desired.len(),
            self.simulation.period,
        )
        .map_err(|e| field(&e))?;
        let mut desired_points = *desired;
        for point in &mut desired_points {
            let (u, v) = model.true_camera().pixel_of(point.x, point.y);
            let (x, y) = model
                .nominal_camera()
                .normalized_of(u, v)
                .map_err(|e| field(&e))?;
            *point = ImagePoint::new(x, y, point.depth);
        }
        Ok(Some(Sensing {
            measurement: self.measurement,
            depth: self.depth,
            desired_points,
            true_tasks: &[],
        }))
    }
}

fn joints<const N: usize>(field: &str, values: &[f64]) -> Result<JointVector<N>, ScenarioError> {
    if values.len() != N {
        return Err(invalid(
            field,
            format!("{} values for a robot with {N} joints", values.len()),
        ));
    }
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(invalid(field, format!("value {i} is not finite")));
    }
    Ok(JointVector::from_column_slice(values))
}

/// `N` joint limits: any value but NaN (`±inf` leaves a continuous joint unlimited; the chain checks which joints
/// may be).
fn limit_values<const N: usize>(
    field: &str,
    values: &[f64],
) -> Result<JointVector<N>, ScenarioError> {
    if values.len() != N {
        return Err(invalid(
            field,
            format!("{} values for a robot with {N} joints", values.len()),
        ));
    }
    if let Some(i) = values.iter().position(|v| v.is_nan()) {
        return Err(invalid(
            field,
            format!(
                "value {i} is NaN, not finite (only ±inf, for a continuous joint left unlimited)"
            ),
        ));
    }
    Ok(JointVector::from_column_slice(values))
}

/// The criterion enum is part of the file format through [`ControllerParameters`].
const _: Option<RemovalCriterion> = None;
