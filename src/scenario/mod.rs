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
//! | run (in outputs) | tasks | avoidance | removal |
//! |---|---|---|---|
//! | `Classical` (`classical`) | one task of six features | no | no |
//! | `Stack` (`stack`) | the four tasks pushed one by one | no | no |
//! | `StackGradient` (`stack_gradient`) | the four tasks pushed one by one | projected gradient | no |
//! | `FullMethod` (`stack_controller`) | the four tasks pushed one by one | projected gradient | yes |
//!
//! A scenario is two parts, each field in one: the world — `robot`, `camera`, `target`, `desired`, `start`,
//! `obstacles` — becomes an [`Experiment`] ([`Scenario::experiment`]), and the method — `tasks`, `avoidance`,
//! `controller`, `simulation`, `visibility`, `measurement`, `depth` — is its [`Settings`] ([`Scenario::settings`]);
//! `scenario.run(kind)` is `scenario.experiment()?.run(&scenario.settings(), kind)`. Without a file,
//! [`Experiment::builder`] makes the world from the chain, mount, camera and target you hold, and
//! [`Settings::default`] is the paper's method.
//!
//! [`generate`] writes the paper's scenario for any arm (a URDF with base and tool links and a camera mount): the zoo
//! of real arms of `assets/zoo.toml` ([`Zoo`]) runs the study on every arm of `example-robot-data` that way.
//!
//! ```
//! let scenario = servostack::scenario::Scenario::from_toml_str(
//!     include_str!("../../assets/scenarios/paper_afma6.toml"), None)?;
//! assert_eq!(scenario.name, "paper_afma6");
//! # Ok::<(), servostack::scenario::ScenarioError>(())
//! ```

use crate::avoidance::{CostError, LinkColliders, MeshPaths, Obstacle, ObstacleCost, ObstaclePair};
use crate::camera::{BrownConrady, CameraError, CameraIntrinsics, EyeInHand};
use crate::controller::{ControllerParameters, RemovalCriterion};
use crate::depth::DepthSource;
use crate::law::LawError;
use crate::math::JointVector;
use crate::measurement::MeasurementParameters;
use crate::robot::{builtin, JointKind, RobotError, SerialChain};
use crate::sim::{Run, RunLog, Scene, SimError, SimulationParameters};
use crate::target::{RectangleTarget, TargetError};
use crate::task::TaskError;
use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

mod experiment;
mod generate;
mod overrides;
mod settings;
mod spec;
mod text_bounds;
mod zoo;

pub use experiment::{Experiment, ExperimentBuilder};
pub use generate::{generate, ArmSpec, GAIN_FACTOR, MIN_GOAL_SINGULAR_VALUE};
pub use settings::Settings;
pub use spec::{
    AdaptiveGainSpec, AvoidanceSpec, CameraSpec, DesiredSpec, InteractionKind, JointLimitsSpec,
    ObstacleSpec, PoseSpec, RobotSpec, StartSpec, TargetSpec, TasksSpec, VisibilitySpec,
};
pub use text_bounds::{MAX_SCENARIO_BYTES, MAX_SCENARIO_DEPTH};
pub use zoo::{ExcludedArm, Zoo};

/// The records [`Scenario::run`] keeps at most (65 536, a minute of a 1 kHz loop; a few tens of megabytes): every
/// record of a shorter run, evenly spaced ones of a longer one ([`crate::sim::Decimated`]).
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

/// The paper's four methods ([theory §9](crate::theory#s9)). In outputs (file names, JSON, the tables of `docs/`) a
/// method is written by [`RunKind::name`]; the full method's name there is `stack_controller`, kept from the
/// crate's first outputs so that stored results still read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RunKind {
    /// Classical IBVS: one task with the six features, no avoidance.
    Classical,
    /// Tasks pushed one by one, no avoidance.
    Stack,
    /// Tasks pushed one by one, with projected-gradient joint-limit avoidance.
    StackGradient,
    /// The full method: avoidance and the stack controller's removals and re-insertions. Written
    /// `stack_controller` in outputs.
    #[serde(rename = "stack_controller")]
    FullMethod,
    /// Saturation in the null space ([theory §13](crate::theory#s13)): tasks pushed one by one as by the full method,
    /// the joint-limit cost as the last level, every joint velocity kept inside the box of the position and velocity
    /// limits; no removal, no braking, no lock. Not one of the paper's methods.
    Sns,
    /// The hierarchical QP cascade ([theory §14](crate::theory#s14)): the same pushes, the tasks then the joint-limit
    /// cost as lexicographic least-squares levels in the same box as SNS's; no removal, no braking, no lock. Not one
    /// of the paper's methods.
    Hqp,
}

impl RunKind {
    /// The four runs, in the paper's order.
    pub const ALL: [RunKind; 4] = [
        Self::Classical,
        Self::Stack,
        Self::StackGradient,
        Self::FullMethod,
    ];

    /// Every method a scenario or a study can run: the paper's four, then SNS and the QP cascade.
    pub const SELECTABLE: [RunKind; 6] = [
        Self::Classical,
        Self::Stack,
        Self::StackGradient,
        Self::FullMethod,
        Self::Sns,
        Self::Hqp,
    ];

    /// The method's name in outputs: `classical`, `stack`, `stack_gradient`, `stack_controller` (the full method),
    /// `sns`, `hqp`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Classical => "classical",
            Self::Stack => "stack",
            Self::StackGradient => "stack_gradient",
            Self::FullMethod => "stack_controller",
            Self::Sns => "sns",
            Self::Hqp => "hqp",
        }
    }

    /// The method named `name` ([`Self::name`]) among [`Self::SELECTABLE`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::SELECTABLE.into_iter().find(|k| k.name() == name)
    }

    /// One of the paper's three baselines (classical, stack, stack + gradient): the methods the full method's
    /// "covered" and "worse than stack + gradient" columns are measured against.
    pub fn is_paper_baseline(self) -> bool {
        matches!(self, Self::Classical | Self::Stack | Self::StackGradient)
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

    /// The world of this scenario (robot, camera, target, goal, start, obstacles), with every field checked: those
    /// of the world, and the [`Settings`] the runs will read (the visibility margin and the start's view of the
    /// target included), so that a valid experiment is one the scenario's runs accept.
    ///
    /// # Errors
    /// The first invalid field: an unknown robot, a joint vector of the wrong size or outside the limits, invalid
    /// intrinsics, target, poses, gains or thresholds, a start from which the target is not entirely in the image.
    pub fn experiment<const N: usize>(&self) -> Result<Experiment<N>, ScenarioError> {
        self.experiment_on(self.robot_model::<N>()?)
    }

    /// [`Self::experiment`] on a robot model already read by [`Self::robot_model`] from this scenario's `[robot]`
    /// (or from a scenario with the same `[robot]`): what a study does for the many situations it draws of one robot,
    /// which would otherwise read and parse the URDF file for each.
    pub(crate) fn experiment_on<const N: usize>(
        &self,
        (chain, mount): (SerialChain<N>, EyeInHand),
    ) -> Result<Experiment<N>, ScenarioError> {
        let settings = self.settings();
        settings.adaptive_gain()?;
        let desired_joints = joints::<N>("desired.joints", &self.desired.joints)?;
        let start = joints::<N>("start.joints", &self.start.joints)?;
        for (field, q) in [
            ("start.joints", &start),
            ("desired.joints", &desired_joints),
        ] {
            check_joints(&chain, field, q)?;
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
            mount,
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
        settings.validate()?;
        let experiment = Experiment {
            scene,
            start,
            desired_joints,
            desired_camera_from_target,
            lens: BrownConrady::default(),
        };
        settings.scene_for(&experiment)?;
        Ok(experiment)
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
        let (chain, mount, limits) = match &self.robot {
            RobotSpec::Builtin {
                builtin,
                joint_limits,
            } => {
                let robot = builtin::by_name::<N>(builtin)?;
                (robot.chain, robot.mount, joint_limits)
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
            return Ok((chain, mount));
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
        Ok((chain, mount))
    }

    /// The method's settings of this scenario: its `tasks`, `avoidance`, `controller`, `simulation`, `visibility`,
    /// `measurement` and `depth` ([`Settings`]).
    pub fn settings(&self) -> Settings {
        Settings {
            tasks: self.tasks,
            avoidance: self.avoidance,
            controller: self.controller,
            simulation: self.simulation,
            visibility: self.visibility,
            measurement: self.measurement,
            depth: self.depth,
        }
    }

    /// Writes `settings` into this scenario's fields ([`Scenario::settings`]).
    pub fn set_settings(&mut self, settings: Settings) {
        let Settings {
            tasks,
            avoidance,
            controller,
            simulation,
            visibility,
            measurement,
            depth,
        } = settings;
        self.tasks = tasks;
        self.avoidance = avoidance;
        self.controller = controller;
        self.simulation = simulation;
        self.visibility = visibility;
        self.measurement = measurement;
        self.depth = depth;
    }

    /// Runs one of the four methods of [theory §9](crate::theory#s9) on this scenario: its [`Experiment`] (the world)
    /// run with its [`Settings`] (`self.experiment()?.run(&self.settings(), kind)`), so that every field counts.
    ///
    /// Its records are kept in bounded memory ([`DEFAULT_RECORD_CAPACITY`], [`Experiment::run`]); for another log,
    /// [`Scenario::run_with`].
    ///
    /// # Errors
    /// Invalid fields (see [`Scenario::experiment`]), tasks undefined at the desired pose, simulation failures. The
    /// run's outcome (converged, joint limit, ...) is data in the [`Run`], not an error.
    pub fn run<const N: usize>(&self, kind: RunKind) -> Result<Run<N>, ScenarioError> {
        self.experiment::<N>()?.run(&self.settings(), kind)
    }

    /// As [`Scenario::run`], with the records given to `log` ([`Experiment::run_with`]).
    ///
    /// # Errors
    /// As [`Scenario::run`].
    pub fn run_with<const N: usize>(
        &self,
        kind: RunKind,
        log: &mut dyn RunLog<N>,
    ) -> Result<Run<N>, ScenarioError> {
        self.experiment::<N>()?
            .run_with(&self.settings(), kind, log)
    }
}

/// `q` within the limits of `chain`, or an error naming `field`.
fn check_joints<const N: usize>(
    chain: &SerialChain<N>,
    field: &str,
    q: &JointVector<N>,
) -> Result<(), ScenarioError> {
    if let Some(joint) = (0..N).find(|&i| {
        !(q[i].is_finite() && (chain.lower_limits()[i]..=chain.upper_limits()[i]).contains(&q[i]))
    }) {
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
    Ok(())
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
