//! The world of a run ([`Experiment`]): a robot with its camera mount, the camera, the target placed where the camera
//! sees it at the goal, the goal and the start; built from a scenario ([`super::Scenario::experiment`]) or from the
//! models you hold ([`Experiment::builder`]), and run with [`Settings`].

use super::{invalid, RunKind, ScenarioError, Settings, DEFAULT_RECORD_CAPACITY};
use crate::avoidance::{CostError, ObstacleCost};
use crate::camera::{BrownConrady, CalibratedCamera, EyeInHand};
use crate::math::JointVector;
use crate::robot::{KinematicsWorkspace, SerialChain};
use crate::servo::Corners;
use crate::sim::{Decimated, Run, RunLog, Scene, SimError};
use crate::target::RectangleTarget;
use nalgebra::Isometry3;

/// The world of a run: the scene (robot, mount, camera intrinsics, target, obstacles), the start, and the goal (the
/// desired joints and the target seen from the camera there). How the method runs is the [`Settings`]'
/// ([`Experiment::run`]): a field is in one of the two, never both.
#[derive(Debug, Clone)]
pub struct Experiment<const N: usize> {
    /// The scene: robot, camera mount and intrinsics, the target placed so that the camera sees it at
    /// `desired_camera_from_target` from `desired_joints`, obstacles. A run sets its joint-limit cost's activation
    /// ratio and adds its visibility cost from the [`Settings`].
    pub scene: Scene<N>,
    /// The start configuration `q(0)`.
    pub start: JointVector<N>,
    /// The desired joint configuration.
    pub desired_joints: JointVector<N>,
    /// The target pose in the desired camera frame (ViSP `cdMo`).
    pub desired_camera_from_target: Isometry3<f64>,
    /// The true lens's distortion (none for a pinhole camera): the run's measurement sees the image through it
    /// ([`Settings::measurement`]).
    pub lens: BrownConrady,
}

impl<const N: usize> Experiment<N> {
    /// A builder of the experiment of these models; then [`ExperimentBuilder::goal`] and [`ExperimentBuilder::start`]
    /// (both required), [`ExperimentBuilder::obstacles`] (optional), [`ExperimentBuilder::build`]. `camera` is a
    /// [`CalibratedCamera`] (its lens distortion is the true lens of the runs) or [`crate::camera::CameraIntrinsics`].
    pub fn builder(
        chain: SerialChain<N>,
        mount: EyeInHand,
        camera: impl Into<CalibratedCamera>,
        target: RectangleTarget,
    ) -> ExperimentBuilder<N> {
        ExperimentBuilder {
            chain,
            mount,
            camera: camera.into(),
            target,
            goal: None,
            start: None,
            obstacles: None,
        }
    }

    /// Runs the method `kind` ([theory §9](crate::theory#s9)) on this experiment with `settings`.
    ///
    /// Its records are kept in bounded memory ([`DEFAULT_RECORD_CAPACITY`]): every record of a run up to that many
    /// iterations, evenly spaced ones beyond ([`Decimated`]). For every record of a longer run, pass a
    /// `Vec<Record<N>>` to [`Experiment::run_with`].
    ///
    /// # Errors
    /// Invalid settings (each naming its field), a start from which the camera does not see the whole target, a lens
    /// distortion given both here and in `settings.measurement` with different values, tasks undefined at the goal,
    /// simulation failures. The run's outcome (converged, joint limit, ...) is data in the [`Run`], not an error.
    pub fn run(&self, settings: &Settings, kind: RunKind) -> Result<Run<N>, ScenarioError> {
        let mut records = Decimated::new(DEFAULT_RECORD_CAPACITY);
        let mut run = self.run_with(settings, kind, &mut records)?;
        run.records = records.into_records();
        Ok(run)
    }

    /// As [`Experiment::run`], with the records given to `log` ([`crate::sim::simulate_with`]): a run of any length
    /// in bounded memory with [`crate::sim::SummaryOnly`], [`Decimated`] or [`crate::sim::JsonLines`].
    ///
    /// # Errors
    /// As [`Experiment::run`].
    pub fn run_with(
        &self,
        settings: &Settings,
        kind: RunKind,
        log: &mut dyn RunLog<N>,
    ) -> Result<Run<N>, ScenarioError> {
        settings.run(self, kind, log)
    }

    /// The four corners of the target in pixels, in the order of [`RectangleTarget::points`], as the experiment's
    /// camera images them at configuration `q` (through its lens): a simulated detector for a
    /// [`crate::servo::VisualServo`] loop. A corner behind the camera or outside the image is `None`.
    ///
    /// # Errors
    /// A non-finite `q` ([`SimError::Robot`]).
    pub fn corners(&self, q: &JointVector<N>) -> Result<Corners, SimError> {
        let mut workspace = KinematicsWorkspace::new();
        let state = self.scene.chain().kinematics(&mut workspace, q)?;
        let base_from_camera = self.scene.mount().base_from_camera(state.base_from_tip());
        let camera_from_target = base_from_camera.inverse() * self.scene.base_from_object();
        let camera = CalibratedCamera {
            intrinsics: *self.scene.intrinsics(),
            distortion: self.lens,
        };
        let intrinsics = self.scene.intrinsics();
        Ok(self.scene.target().points().map(|corner| {
            let p = camera_from_target * corner;
            let (u, v) = camera.pixel_of(p.x / p.z, p.y / p.z);
            let inside =
                (0.0..=intrinsics.width()).contains(&u) && (0.0..=intrinsics.height()).contains(&v);
            (p.z > 0.0 && inside).then_some((u, v))
        }))
    }
}

/// The builder of an [`Experiment`] from the models you hold ([`Experiment::builder`]).
#[derive(Debug, Clone)]
#[must_use = "a builder does nothing until `build`"]
pub struct ExperimentBuilder<const N: usize> {
    chain: SerialChain<N>,
    mount: EyeInHand,
    camera: CalibratedCamera,
    target: RectangleTarget,
    goal: Option<(JointVector<N>, Isometry3<f64>)>,
    start: Option<JointVector<N>>,
    obstacles: Option<ObstacleCost<N>>,
}

impl<const N: usize> ExperimentBuilder<N> {
    /// The goal: at the joint configuration `desired_joints`, the camera sees the target at `camera_from_target`
    /// (ViSP `cdMo`); the target is placed in the world so (the goal is reachable by construction).
    pub fn goal(
        mut self,
        desired_joints: JointVector<N>,
        camera_from_target: Isometry3<f64>,
    ) -> Self {
        self.goal = Some((desired_joints, camera_from_target));
        self
    }

    /// The start configuration `q(0)` (m or rad per joint, within the joint limits).
    pub fn start(mut self, start: JointVector<N>) -> Self {
        self.start = Some(start);
        self
    }

    /// World obstacles: their cost joins the avoidance cost of the runs with avoidance, and a contact ends a run as
    /// a collision ([`Scene::with_obstacles`]).
    pub fn obstacles(mut self, obstacles: ObstacleCost<N>) -> Self {
        self.obstacles = Some(obstacles);
        self
    }

    /// The experiment, every value checked.
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming `desired` or `start` when not given, `desired.joints` or `start.joints` when
    /// not finite or outside the chain's limits; a desired configuration the chain cannot evaluate.
    pub fn build(self) -> Result<Experiment<N>, ScenarioError> {
        let (desired_joints, desired_camera_from_target) = self
            .goal
            .ok_or_else(|| invalid("desired", "no goal: call `.goal(desired_joints, cdMo)`"))?;
        let start = self
            .start
            .ok_or_else(|| invalid("start", "no start: call `.start(q0)`"))?;
        for (field, q) in [
            ("start.joints", &start),
            ("desired.joints", &desired_joints),
        ] {
            super::check_joints(&self.chain, field, q)?;
        }
        let ratio = crate::avoidance::JointLimits::<N>::DEFAULT_ACTIVATION_RATIO;
        let mut scene = Scene::with_target_seen_from(
            self.chain,
            self.mount,
            self.camera.intrinsics,
            self.target,
            &desired_joints,
            &desired_camera_from_target,
            ratio,
        )
        .map_err(|e| match e {
            SimError::Cost(cost @ CostError::InvalidLimits { .. }) => {
                invalid("robot.joint_limits", cost.to_string())
            }
            other => other.into(),
        })?;
        if let Some(obstacles) = self.obstacles {
            scene = scene.with_obstacles(obstacles);
        }
        Ok(Experiment {
            scene,
            start,
            desired_joints,
            desired_camera_from_target,
            lens: self.camera.distortion,
        })
    }
}
