//! Kinematic simulation: a robot with an eye-in-hand camera looking at a planar target, driven by the stack controller
//! ([theory §9](crate::theory#s9), [D11](crate::theory#d11)).
//!
//! Each iteration at time `t = k·Δt`:
//!
//! 1. forward kinematics and `eJe(q)`; the camera pose `base_from_camera = base_from_tip · e_from_c` and the object
//!    pose in the camera `c_from_o = base_from_camera⁻¹ · base_from_object`;
//! 2. projection of the four target points (normalised `x, y` and depth `Z`), the target plane `(A, B, C)`, the
//!    camera Jacobian `cVe · eJe`; a point behind the camera or outside the image (with a margin in pixels) ends the
//!    run as **feature lost**;
//! 3. every visual task is evaluated (`e_i`, `L_i`, `J_i`, [\[M42\]](crate::theory#m42)); when the stack is complete and the error of
//!    every task is below the convergence threshold, the run has **converged**;
//! 4. one controller iteration ([`StackController::step`], given the scene's limits: for the full method, a joint
//!    braked onto a limit that the law drives in is locked, D26) gives `q̇`, scaled uniformly into the robot's velocity limits
//!    and, for the full method, braked before the hard limits (D25,
//!    [`ControllerParameters::braking_rate`](crate::controller::ControllerParameters::braking_rate)); the controller is
//!    told what was sent; explicit Euler `q ← q + Δt q̇`;
//! 5. a joint outside `[q^min, q^max]` ends the run as **joint limit** (D11: a real robot stops at its limit), with the
//!    joint, the iteration and the tasks stacked; when the scene has obstacles, a link–obstacle signed distance `≤ 0`
//!    ends it as **collision**.
//!
//! The avoidance cost given to the law and the controller is the sum ([`CompositeCost`]) of the joint-limit cost and,
//! when the scene has them, the obstacle cost ([`Scene::with_obstacles`]) and the visibility cost
//! ([`Scene::with_visibility_margin`]).
//!
//! Each iteration makes a [`Record`]: `q`, `q̇`, each task's error norm, the stack, the cost and its prediction, the
//! criteria, and the image points. The records go to a [`RunLog`] the caller chooses, so that a run of any length uses
//! bounded memory: every record (`Vec<Record<N>>`, what [`simulate`] keeps for the figures), an evenly spaced subset
//! of bounded size ([`Decimated`]), none ([`SummaryOnly`]) or a stream of JSON lines to a file ([`JsonLines`]). The
//! [`Run`] that [`simulate_with`] returns holds the outcome, the controller's event log (bounded: each task is pushed
//! once and removed at most `max_removals` times before the fallback of D13) and the summary of the run, accumulated
//! iteration by iteration and exact whatever the log kept: iterations, the last record (final errors, stack),
//! largest velocity step, continuity at every stack change, smallest joint-limit margin and obstacle distance.

use crate::avoidance::{CompositeCost, Cost, CostError, JointLimits, ObstacleCost, VisibilityCost};
use crate::bounds::{MAX_ITERATIONS, PERIOD_S};
use crate::camera::{project_points, CameraError, CameraIntrinsics, EyeInHand, ImagePoint};
use crate::controller::{
    ControllerError, ControllerParameters, ControllerStatus, EventKind, StackController,
    StackEvent, TaskCriteria,
};
use crate::depth::{assign_depths, DepthError, DepthEstimator, DepthSource, Depths};
use crate::feature::{FeatureError, Observation};
use crate::law::sns::SnsBounds;
use crate::law::{BoundedLaw, ControlLaw, LawError};
use crate::math::{JointVector, KinematicJacobian};
use crate::measurement::{
    perturbed_eye_in_hand, MeasurementError, MeasurementModel, MeasurementParameters,
};
use crate::robot::{KinematicsWorkspace, RobotError, SerialChain};
use crate::servo::AdaptiveGain;
use crate::target::{RectangleTarget, TargetError, TargetPlane};
use crate::task::{Task, TaskError, TaskValue};
use crate::visual_task::{VisualContext, VisualTask};
use nalgebra::Isometry3;
use nalgebra::{Point2, Point3, Vector3, Vector6};

/// Errors of the simulation (distinct from the run's outcome: a joint limit or a lost feature is an outcome, not an
/// error).
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// A simulation parameter is out of range.
    #[error("simulation parameter `{name}` = {value} is invalid: {expected}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is expected.
        expected: &'static str,
    },
    /// The start configuration is outside the joint limits.
    #[error("start configuration: joint {joint} = {value} is outside [{lower}, {upper}]")]
    StartOutsideLimits {
        /// The joint (0-based).
        joint: usize,
        /// Its value.
        value: f64,
        /// Lower limit.
        lower: f64,
        /// Upper limit.
        upper: f64,
    },
    /// The robot model failed (non-finite configuration).
    #[error(transparent)]
    Robot(#[from] RobotError),
    /// The camera model failed.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// The target model failed.
    #[error(transparent)]
    Target(#[from] TargetError),
    /// A feature is undefined on the desired or current image.
    #[error(transparent)]
    Feature(#[from] FeatureError),
    /// A task failed.
    #[error(transparent)]
    Task(#[from] TaskError),
    /// The controller failed.
    #[error(transparent)]
    Controller(#[from] ControllerError),
    /// The joint-limit cost failed.
    #[error(transparent)]
    Cost(#[from] CostError),
    /// The measurement model or the depth source has invalid parameters.
    #[error(transparent)]
    Measurement(#[from] MeasurementError),
    /// The run log could not keep a record (an I/O error of a [`JsonLines`] log).
    #[error("run log, iteration {iteration}: {message}")]
    Log {
        /// The iteration whose record was refused.
        iteration: usize,
        /// The log's message.
        message: String,
    },
}

/// The world: a robot with its camera, the camera's intrinsics, the target and where it stands.
#[derive(Debug, Clone)]
pub struct Scene<const N: usize> {
    chain: SerialChain<N>,
    mount: EyeInHand,
    intrinsics: CameraIntrinsics,
    target: RectangleTarget,
    base_from_object: Isometry3<f64>,
    desired_camera_from_object: Isometry3<f64>,
    limits: JointLimits<N>,
    obstacles: Option<ObstacleCost<N>>,
    visibility: Option<VisibilityCost<N>>,
}

/// What the camera sees at one configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View<const N: usize> {
    /// The four target points: normalised coordinates and depth.
    pub points: [ImagePoint; 4],
    /// The target plane `1/Z = A x + B y + C`.
    pub plane: TargetPlane,
    /// The camera Jacobian `cVe · eJe(q)` (6 × N).
    pub camera_jacobian: KinematicJacobian<N>,
    /// The object pose in the camera frame (ViSP `cMo`).
    pub c_from_o: Isometry3<f64>,
}

impl<const N: usize> Default for View<N> {
    /// A placeholder for [`Scene::observe_into`] to fill: every point at the origin of the image plane with zero
    /// depth, the plane `1/Z = 0`, a zero Jacobian, the identity pose.
    fn default() -> Self {
        Self {
            points: [ImagePoint::default(); 4],
            plane: TargetPlane::default(),
            camera_jacobian: KinematicJacobian::zeros(),
            c_from_o: Isometry3::identity(),
        }
    }
}

impl<const N: usize> View<N> {
    /// The observation of the four points with the plane model, for the features.
    ///
    /// # Errors
    /// [`FeatureError`] when the points are unusable (e.g. the plane is behind the camera).
    pub fn observation(&self) -> Result<Observation<'_>, FeatureError> {
        Observation::new(&self.points, Some(&self.plane))
    }
}

impl<const N: usize> Scene<N> {
    /// A scene whose target is placed so that, at the configuration `desired_q`, the camera sees it at
    /// `desired_camera_from_object` (ViSP `cdMo`): `base_from_object = base_from_camera(desired_q) · cdMo`. The desired
    /// pose is then reachable by construction. `rho` is the activation ratio of the joint-limit cost ([\[M19\]](crate::theory#m19)).
    ///
    /// # Errors
    /// Non-finite `desired_q`, invalid `rho` or limits.
    pub fn with_target_seen_from(
        chain: SerialChain<N>,
        mount: EyeInHand,
        intrinsics: CameraIntrinsics,
        target: RectangleTarget,
        desired_q: &JointVector<N>,
        desired_camera_from_object: &Isometry3<f64>,
        rho: f64,
    ) -> Result<Self, SimError> {
        let mut workspace = KinematicsWorkspace::new();
        let state = chain.kinematics(&mut workspace, desired_q)?;
        let base_from_object =
            mount.base_from_camera(state.base_from_tip()) * desired_camera_from_object;
        let limits = JointLimits::new(*chain.lower_limits(), *chain.upper_limits(), rho)?;
        Ok(Self {
            chain,
            mount,
            intrinsics,
            target,
            base_from_object,
            desired_camera_from_object: *desired_camera_from_object,
            limits,
            obstacles: None,
            visibility: None,
        })
    }

    /// The scene with the joint-limit cost of activation ratio `rho` ([\[M19\]](crate::theory#m19)) in place of its own.
    ///
    /// # Errors
    /// [`SimError::Cost`] for a ratio outside `(0, 1/2)`.
    pub fn with_activation_ratio(mut self, rho: f64) -> Result<Self, SimError> {
        self.limits = JointLimits::new(*self.limits.lower(), *self.limits.upper(), rho)?;
        Ok(self)
    }

    /// The scene with world obstacles: their cost joins the avoidance cost, and a link–obstacle contact ends a run
    /// as [`Outcome::Collision`].
    pub fn with_obstacles(mut self, obstacles: ObstacleCost<N>) -> Self {
        self.obstacles = Some(obstacles);
        self
    }

    /// The scene with the visibility cost of its target points ([`VisibilityCost`]), active within `margin_px`
    /// pixels of the image border.
    ///
    /// # Errors
    /// [`SimError::Cost`] for an invalid margin.
    pub fn with_visibility_margin(self, margin_px: f64) -> Result<Self, SimError> {
        let cost = self.visibility_cost(margin_px, None)?;
        Ok(self.with_visibility(cost))
    }

    /// The scene with `cost` as its visibility cost (built by [`Self::visibility_cost`]).
    pub fn with_visibility(mut self, cost: VisibilityCost<N>) -> Self {
        self.visibility = Some(cost);
        self
    }

    /// The visibility cost of this scene's target ([`VisibilityCost`]), active within `margin_px` of the image border
    /// and, given `facing_activation_deg`, beyond that angle between the target's front normal and its line of sight
    /// ([`VisibilityCost::with_facing`], [D27](crate::theory#d27); the front is the side the goal camera sees).
    ///
    /// # Errors
    /// An invalid margin or activation angle ([`CostError`]).
    pub fn visibility_cost(
        &self,
        margin_px: f64,
        facing_activation_deg: Option<f64>,
    ) -> Result<VisibilityCost<N>, SimError> {
        let points = self.target.points().map(|p| self.base_from_object * p);
        let cost = VisibilityCost::new(
            self.chain.clone(),
            self.mount,
            &self.intrinsics,
            &points,
            margin_px,
        )?;
        Ok(match facing_activation_deg {
            None => cost,
            Some(activation) => {
                let normal = self.base_from_object.rotation * self.front_normal_in_target();
                let centre = Point3::from(self.base_from_object.translation.vector);
                cost.with_facing(centre, normal, activation)?
            }
        })
    }

    /// The target's front normal in its own frame: `±z`, towards the side its goal camera sees it from.
    fn front_normal_in_target(&self) -> Vector3<f64> {
        let goal = self
            .desired_camera_from_object
            .inverse_transform_point(&Point3::origin());
        Vector3::new(0.0, 0.0, if goal.z < 0.0 { -1.0 } else { 1.0 })
    }

    /// The obstacle cost, if the scene has obstacles.
    pub fn obstacles(&self) -> Option<&ObstacleCost<N>> {
        self.obstacles.as_ref()
    }

    /// The visibility cost, if enabled.
    pub fn visibility(&self) -> Option<&VisibilityCost<N>> {
        self.visibility.as_ref()
    }

    /// The avoidance cost of the scene: joint limits, plus obstacles and visibility when present (built once per
    /// run; evaluating it allocates nothing).
    pub fn avoidance_cost(&self) -> CompositeCost<'_, N> {
        let mut cost = CompositeCost::new().with(&self.limits);
        if let Some(obstacles) = &self.obstacles {
            cost.push(obstacles);
        }
        if let Some(visibility) = &self.visibility {
            cost.push(visibility);
        }
        cost
    }

    /// The robot.
    pub fn chain(&self) -> &SerialChain<N> {
        &self.chain
    }

    /// The camera mount on the end effector (`eMc`).
    pub fn mount(&self) -> &EyeInHand {
        &self.mount
    }

    /// The camera intrinsics.
    pub fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    /// The target.
    pub fn target(&self) -> &RectangleTarget {
        &self.target
    }

    /// The joint limits and their cost ([\[M19\]](crate::theory#m19)–\[M21\]).
    pub fn limits(&self) -> &JointLimits<N> {
        &self.limits
    }

    /// The target pose in the robot base frame.
    pub fn base_from_object(&self) -> &Isometry3<f64> {
        &self.base_from_object
    }

    /// The goal: the target pose in the camera frame at the desired configuration (ViSP `cdMo`).
    pub fn desired_camera_from_object(&self) -> &Isometry3<f64> {
        &self.desired_camera_from_object
    }

    /// How far the camera that sees the target at `c_from_o` is from its goal: the translation (m) and the rotation
    /// angle (degrees) of `c_from_o · cdMo⁻¹`, the camera's displacement expressed in its goal frame.
    pub fn distance_to_goal(&self, c_from_o: &Isometry3<f64>) -> (f64, f64) {
        let c_from_cd = c_from_o * self.desired_camera_from_object.inverse();
        (
            c_from_cd.translation.vector.norm(),
            c_from_cd.rotation.angle().to_degrees(),
        )
    }

    /// The angle (degrees, in `[0, 180]`) at which the camera that sees the target at `c_from_o` looks at it
    /// ([D27](crate::theory#d27)): between the normal of the target's plane on its front side — the side the camera
    /// sees it from at its goal pose — and the line from the target's centre (the origin of its frame) to the
    /// camera's optical centre. 0 head-on, 90 edge-on, above 90 from behind.
    pub fn target_incidence_deg(&self, c_from_o: &Isometry3<f64>) -> f64 {
        // The optical centre in the target frame o; the target's plane is z = 0 of o.
        let camera = c_from_o.inverse_transform_point(&Point3::origin()).coords;
        let distance = camera.norm();
        if distance == 0.0 {
            return 90.0; // the optical centre on the target's centre: in its plane
        }
        (self.front_normal_in_target().dot(&camera) / distance)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    }

    /// The view of the target from the camera pose `c_from_o` (no robot involved: for desired images).
    ///
    /// # Errors
    /// A point at or behind the camera, a plane through the optical centre.
    pub fn view_from(&self, c_from_o: &Isometry3<f64>) -> Result<View<N>, SimError> {
        let mut view = View::default();
        self.project_into(c_from_o, &mut view)?;
        Ok(view)
    }

    /// The points, plane and pose of the view from `c_from_o`, written into `view` (its Jacobian untouched).
    fn project_into(&self, c_from_o: &Isometry3<f64>, view: &mut View<N>) -> Result<(), SimError> {
        project_points(c_from_o, self.target.points(), &mut view.points)?;
        view.plane = self.target.plane_in_camera(c_from_o)?;
        view.c_from_o = *c_from_o;
        Ok(())
    }

    /// What the camera sees at configuration `q`: points, plane, camera Jacobian. Allocation-free. A control loop
    /// calls [`Self::observe_into`] instead, which writes into a view it keeps (a view is about half a kilobyte, and
    /// each move of the returned value copies it).
    ///
    /// # Errors
    /// Non-finite `q`, a point at or behind the camera, a plane through the optical centre.
    pub fn observe(
        &self,
        workspace: &mut KinematicsWorkspace<N>,
        q: &JointVector<N>,
    ) -> Result<View<N>, SimError> {
        let mut view = View::default();
        self.observe_into(workspace, q, &mut view)?;
        Ok(view)
    }

    /// [`Self::observe`], written into `view` in place. After an error the content of `view` is unspecified.
    ///
    /// # Errors
    /// As [`Self::observe`].
    pub fn observe_into(
        &self,
        workspace: &mut KinematicsWorkspace<N>,
        q: &JointVector<N>,
        view: &mut View<N>,
    ) -> Result<(), SimError> {
        let state = self.chain.kinematics(workspace, q)?;
        let base_from_camera = self.mount.base_from_camera(state.base_from_tip());
        let c_from_o = base_from_camera.inverse() * self.base_from_object;
        self.project_into(&c_from_o, view)?;
        // cVe · eJe   [M42]
        crate::linalg::mul_rows_to(
            self.mount.c_v_e(),
            state.tip_jacobian(),
            &mut view.camera_jacobian,
        );
        Ok(())
    }
}

/// Parameters of a simulation run.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimulationParameters {
    /// The control period `Δt` (s), within [`PERIOD_S`].
    pub period: f64,
    /// The iteration budget, at most [`MAX_ITERATIONS`] (10⁷).
    pub max_iterations: usize,
    /// The run has converged when the stack is complete and `‖e_i‖ < convergence_error` for every task (the noise-free
    /// errors when the camera is not exact), and has stayed so for `convergence_hold_s`.
    pub convergence_error: f64,
    /// How long (s, ≥ 0; default 0: the first period below) the task errors must stay below `convergence_error` for
    /// the run to count as converged: with pixel noise the errors first cross the threshold while the camera still
    /// moves, and "settled" means staying below ([D21](crate::theory#d21)).
    pub convergence_hold_s: f64,
    /// How far from its goal pose (m) the camera may end when the task errors have converged
    /// ([D22](crate::theory#d22)); beyond this or [`Self::goal_tolerance_deg`] the run ends as [`Outcome::OffGoal`]
    /// (default 0.01 m; `+∞`: no check).
    pub goal_tolerance_m: f64,
    /// The rotation (degrees) allowed between the camera and its goal pose at convergence (default 1°; `+∞`: no
    /// check).
    pub goal_tolerance_deg: f64,
    /// A point closer than this to the image border (px) is lost.
    pub image_margin: f64,
    /// The largest angle (degrees) between the target's normal and its line of sight at which the target is still
    /// tracked ([`Scene::target_incidence_deg`]; [D27](crate::theory#d27)). Seen more obliquely, or from behind, the
    /// run ends as [`Outcome::ImageDegenerate`], and a start so seen is not a valid situation. Default 80°: the target
    /// then spans `cos 80° ≈ 0.17` of its head-on width across its normal, a permissive bound for a detector (set it
    /// to the angle your tracker handles); within `(0, 180]`, 180 switching the check off.
    pub max_incidence_deg: f64,
    /// The full method keeps the target facing the camera: its visibility cost (the default one, and a scenario's
    /// `[visibility]`) rises from `max_incidence_deg − facing_margin_deg` on ([D27](crate::theory#d27),
    /// [`VisibilityCost::with_facing`]), as it rises within `visibility_margin_px` of the image border. Degrees, within
    /// `[0, max_incidence_deg]`; default 15. With `max_incidence_deg` at 180 and no margin there is no facing term.
    pub facing_margin_deg: f64,
    /// The robot's velocity limit of a prismatic joint (m/s, > 0; default `+∞`: none). The controller's velocity is
    /// scaled uniformly into the limits (its direction kept) and the scaled velocity fed back to the controller, as
    /// [`crate::servo::VisualServo`] does.
    pub max_prismatic_velocity_m_s: f64,
    /// The robot's velocity limit of a revolute joint (rad/s, > 0; default `+∞`: none).
    pub max_revolute_velocity_rad_s: f64,
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

/// How a run ended.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(tag = "outcome", rename_all = "snake_case")]
pub enum Outcome {
    /// Every task stacked and achieved, with the camera at its goal pose (within
    /// [`SimulationParameters::goal_tolerance_m`] and [`SimulationParameters::goal_tolerance_deg`]).
    Converged,
    /// Every task stacked and its error below the threshold, but the camera away from its goal pose: the features
    /// take their desired values at another pose too ([D22](crate::theory#d22)), or measurement errors bias where they
    /// settle. The loop would stay there: the run ends.
    OffGoal {
        /// The camera's distance to its goal pose (m).
        translation_m: f64,
        /// The rotation between the camera and its goal pose (degrees).
        rotation_deg: f64,
    },
    /// A joint left its limits (D11).
    JointLimit {
        /// The joint (0-based).
        joint: usize,
        /// The tasks stacked when it happened (indices into the task list).
        stacked: Vec<usize>,
    },
    /// A target point went behind the camera or out of the image.
    FeatureLost {
        /// The point (0-based).
        point: usize,
    },
    /// The iteration budget ran out with every task stacked: the errors were still above the threshold.
    MaxIterations {
        /// What the run was doing (the task errors at the end).
        reason: String,
    },
    /// The iteration budget ran out while a task was removed or waiting to be pushed, or the controller held before a
    /// hard limit and the robot came to rest (D13): the run names the task and why.
    Stalled {
        /// The task that waited (index into the task list).
        task: usize,
        /// Why it could not come in.
        reason: String,
    },
    /// The target is seen edge-on: its plane passes through the optical centre, it is seen more obliquely than
    /// [`SimulationParameters::max_incidence_deg`] (D27), or a feature is undefined on the image (collinear points,
    /// vanishing area).
    ImageDegenerate {
        /// What is undefined.
        reason: String,
    },
    /// A link touched or penetrated an obstacle (signed distance `≤ 0`).
    Collision {
        /// The link.
        link: String,
        /// The obstacle.
        obstacle: String,
        /// Their signed distance (m, `≤ 0`).
        distance: f64,
        /// The tasks stacked when it happened.
        stacked: Vec<usize>,
    },
}

impl Outcome {
    /// Every [`Outcome::name`], in the order of the variants.
    pub const NAMES: [&'static str; 8] = [
        "converged",
        "off_goal",
        "joint_limit",
        "feature_lost",
        "max_iterations",
        "stalled",
        "image_degenerate",
        "collision",
    ];

    /// The short name used in summaries: `converged`, `off_goal`, `joint_limit`, `feature_lost`, `max_iterations`,
    /// `stalled`, `image_degenerate`, `collision`.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Converged => "converged",
            Self::OffGoal { .. } => "off_goal",
            Self::JointLimit { .. } => "joint_limit",
            Self::FeatureLost { .. } => "feature_lost",
            Self::MaxIterations { .. } => "max_iterations",
            Self::Stalled { .. } => "stalled",
            Self::ImageDegenerate { .. } => "image_degenerate",
            Self::Collision { .. } => "collision",
        }
    }
}

/// One iteration of the run log.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Record<const N: usize> {
    /// The iteration.
    pub iteration: usize,
    /// Its time (s).
    pub time: f64,
    /// The configuration.
    pub q: JointVector<N>,
    /// The velocity sent (zero at the last record of a run that ended before stepping).
    pub velocity: JointVector<N>,
    /// Whether a velocity was sent at this iteration (`false` for the last record of a run that ended before stepping).
    pub sent: bool,
    /// `‖e_i‖` for every task of the list (stacked or not).
    pub task_errors: Vec<f64>,
    /// The tasks stacked at this iteration.
    pub stacked: Vec<usize>,
    /// `h(q)` of the joint-limit cost alone (whatever the run avoids; for the joint-limit figures and margins).
    pub cost: f64,
    /// The controller's predicted `h(q̂)` of the cost it drives with (joint limits, plus obstacles and visibility when
    /// the scene has them; 0 for runs without avoidance): not comparable with [`Record::cost`] when obstacles are on.
    pub predicted_cost: f64,
    /// The criteria of the stacked tasks (empty when `∇h = 0` or without avoidance).
    pub criteria: Vec<TaskCriteria>,
    /// The image points (normalised).
    pub image: [ImagePoint; 4],
    /// The smallest link–obstacle signed distance at `q` (m), when the scene has obstacles.
    pub obstacle_distance: Option<f64>,
}

impl<const N: usize> Record<N> {
    /// A record with empty buffers, filled by the simulation.
    fn empty() -> Self {
        Self {
            iteration: 0,
            time: 0.0,
            q: JointVector::zeros(),
            velocity: JointVector::zeros(),
            sent: false,
            task_errors: Vec::new(),
            stacked: Vec::new(),
            cost: 0.0,
            predicted_cost: 0.0,
            criteria: Vec::new(),
            image: [ImagePoint::default(); 4],
            obstacle_distance: None,
        }
    }
}

/// Continuity of the velocity sent at one stack change (D14), from [`Run::event_continuity`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct EventContinuity {
    /// The iteration of the change.
    pub iteration: usize,
    /// What changed.
    pub kind: EventKind,
    /// The task.
    pub task: usize,
    /// `‖u(τ) − q̇(τ⁻)‖`: the jump the law alone would have made.
    pub law_jump: f64,
    /// `‖q̇_k − q̇_{k−1}‖` at the change (zero up to rounding with the transition term).
    pub jump: f64,
    /// The largest `‖q̇_j − q̇_{j−1}‖` after the change, up to the next one: the transition spreads the law's jump over
    /// a ramp whose first step is about `(1 − e^{−μΔt})` times it.
    pub max_step_after: f64,
}

/// Where the records of a run go, one per iteration, as they are made (observers, not an unbounded
/// log): the caller chooses how much of a run it keeps.
///
/// `Vec<Record<N>>` keeps every record (memory grows with the run: for figures of runs of bounded length),
/// [`Decimated`] an evenly spaced subset of bounded size, [`SummaryOnly`] nothing, [`JsonLines`] streams every record
/// to a writer. The [`Run`] returned by [`simulate_with`] has the summary of the run whatever the log keeps.
pub trait RunLog<const N: usize> {
    /// Receives the record of one iteration, in order.
    ///
    /// # Errors
    /// A log that cannot keep the record (an I/O error) returns its message; the run stops with [`SimError::Log`].
    fn record(&mut self, record: &Record<N>) -> Result<(), String>;
}

/// Every record: memory grows with the run (about 1 KB per iteration with four tasks).
impl<const N: usize> RunLog<N> for Vec<Record<N>> {
    fn record(&mut self, record: &Record<N>) -> Result<(), String> {
        self.push(record.clone());
        Ok(())
    }
}

/// No record: the [`Run`]'s summary only, constant memory.
#[derive(Debug, Clone, Copy, Default)]
pub struct SummaryOnly;

impl<const N: usize> RunLog<N> for SummaryOnly {
    fn record(&mut self, _: &Record<N>) -> Result<(), String> {
        Ok(())
    }
}

/// At most `capacity` records, evenly spaced: the records of the iterations that are multiples of a stride, the
/// stride starting at 1 and doubling (every other record kept dropped) whenever the log is full. Memory is bounded by
/// `capacity` records for any run length; a run of `n` iterations keeps between `capacity/2` and `capacity` of them
/// (all of them when `n ≤ capacity`).
#[derive(Debug, Clone, PartialEq)]
pub struct Decimated<const N: usize> {
    capacity: usize,
    stride: usize,
    records: Vec<Record<N>>,
}

impl<const N: usize> Decimated<N> {
    /// A log keeping at most `capacity` records (at least 2: the stride doubles by halving a full log).
    pub fn new(capacity: usize) -> Self {
        let capacity = capacity.max(2);
        Self {
            capacity,
            stride: 1,
            records: Vec::with_capacity(capacity),
        }
    }

    /// The records kept, in iteration order.
    pub fn records(&self) -> &[Record<N>] {
        &self.records
    }

    /// The current stride: the records kept are those of the iterations that are multiples of it.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// The records kept.
    pub fn into_records(self) -> Vec<Record<N>> {
        self.records
    }
}

impl<const N: usize> RunLog<N> for Decimated<N> {
    fn record(&mut self, record: &Record<N>) -> Result<(), String> {
        if !record.iteration.is_multiple_of(self.stride) {
            return Ok(());
        }
        if self.records.len() == self.capacity {
            self.stride *= 2;
            let stride = self.stride;
            self.records.retain(|r| r.iteration.is_multiple_of(stride));
            if !record.iteration.is_multiple_of(stride) {
                return Ok(());
            }
        }
        self.records.push(record.clone());
        Ok(())
    }
}

/// Every record streamed to a writer as one JSON object per line (the fields of [`Record`]; `q`, `velocity` as
/// arrays). Memory is that of the writer's buffer: give it a `BufWriter` around a file.
#[derive(Debug)]
pub struct JsonLines<W: std::io::Write> {
    writer: W,
}

impl<W: std::io::Write> JsonLines<W> {
    /// A log writing to `writer`.
    pub fn new(writer: W) -> Self {
        Self { writer }
    }

    /// The writer, flushed.
    ///
    /// # Errors
    /// The writer's flush error.
    pub fn into_inner(mut self) -> std::io::Result<W> {
        self.writer.flush()?;
        Ok(self.writer)
    }
}

impl<const N: usize, W: std::io::Write> RunLog<N> for JsonLines<W> {
    fn record(&mut self, record: &Record<N>) -> Result<(), String> {
        serde_json::to_writer(&mut self.writer, record).map_err(|e| e.to_string())?;
        self.writer.write_all(b"\n").map_err(|e| e.to_string())
    }
}

/// The summary of a run, accumulated record by record (exact without the records).
#[derive(Debug, Clone, PartialEq)]
struct Totals<const N: usize> {
    iterations: usize,
    last: Option<Record<N>>,
    /// The last velocity sent (zero before the first: the run starts at rest).
    last_sent: JointVector<N>,
    max_velocity_step: f64,
    min_normalized_margin: f64,
    min_obstacle_distance: Option<f64>,
    continuity: Vec<EventContinuity>,
}

impl<const N: usize> Totals<N> {
    /// Before the first iteration, at `start`.
    fn new(limits: &JointLimits<N>, start: &JointVector<N>) -> Self {
        Self {
            iterations: 0,
            last: None,
            last_sent: JointVector::zeros(),
            max_velocity_step: 0.0,
            min_normalized_margin: limits.normalized_margin(start),
            min_obstacle_distance: None,
            continuity: Vec::new(),
        }
    }

    /// Adds the record of the next iteration, with the controller's event log after it.
    fn add(&mut self, record: Record<N>, limits: &JointLimits<N>, events: &[StackEvent]) {
        self.iterations = record.iteration + 1;
        self.min_normalized_margin = self
            .min_normalized_margin
            .min(limits.normalized_margin(&record.q));
        self.min_obstacle_distance = match (self.min_obstacle_distance, record.obstacle_distance) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        if record.sent {
            // D14: the step at this iteration is the jump of the changes made at it, and otherwise belongs to the window
            // after the last change.
            let step = (record.velocity - self.last_sent).norm();
            self.last_sent = record.velocity;
            self.max_velocity_step = self.max_velocity_step.max(step);
            let known = self.continuity.len();
            let changes = events
                .get(known..)
                .unwrap_or_default()
                .iter()
                .take_while(|e| e.iteration == record.iteration);
            self.continuity.extend(changes.map(|e| EventContinuity {
                iteration: e.iteration,
                kind: e.kind,
                task: e.task,
                law_jump: e.law_jump,
                jump: step,
                max_step_after: 0.0,
            }));
            if self.continuity.len() == known {
                if let Some(last) = self.continuity.last_mut() {
                    last.max_step_after = last.max_step_after.max(step);
                }
            }
        }
        self.last = Some(record);
    }
}

/// A finished run: its outcome, the records its log kept, the event log and the run's summary.
#[derive(Debug, Clone, PartialEq)]
pub struct Run<const N: usize> {
    /// How it ended.
    pub outcome: Outcome,
    /// The control period `Δt` (s).
    pub period: f64,
    /// The names of the tasks, by index.
    pub task_names: Vec<String>,
    /// One record per iteration from [`simulate`]; empty from [`simulate_with`] (its [`RunLog`] has the records).
    pub records: Vec<Record<N>>,
    /// The controller's event log.
    pub events: Vec<StackEvent>,
    /// The joint limits, for normalised plots and margins.
    pub limits: JointLimits<N>,
    totals: Totals<N>,
}

impl<const N: usize> Run<N> {
    /// The number of iterations recorded: the index of the last recorded iteration, plus one. A run whose target is
    /// lost when iteration `k` observes it (out of the image, behind the camera, seen too obliquely) records `k`; 0
    /// when it ended before its first record, e.g. a target lost at the start.
    pub fn iterations(&self) -> usize {
        self.totals.iterations
    }

    /// The record of the last iteration, `None` when the run ended before its first record.
    pub fn last_record(&self) -> Option<&Record<N>> {
        self.totals.last.as_ref()
    }

    /// `‖q̇_k − q̇_{k−1}‖` for every iteration `k` of [`Run::records`] that sent a velocity (D14; `q̇_{−1} = 0`: the
    /// run starts at rest). Needs every record ([`simulate`]); the summaries below do not.
    pub fn velocity_steps(&self) -> Vec<f64> {
        let sent = || {
            std::iter::once(JointVector::zeros())
                .chain(self.records.iter().filter(|r| r.sent).map(|r| r.velocity))
        };
        sent()
            .zip(sent().skip(1))
            .map(|(before, after): (JointVector<N>, _)| (after - before).norm())
            .collect()
    }

    /// The largest step-to-step change of the velocity sent over the run, `max_k ‖q̇_k − q̇_{k−1}‖` (D14; 0 when
    /// nothing was sent); divide by [`Run::period`] for the largest acceleration.
    pub fn max_velocity_step(&self) -> f64 {
        self.totals.max_velocity_step
    }

    /// The largest `‖q̇(τ⁺) − q̇(τ⁻)‖` over the stack changes: the velocity sent at the iteration of a change against
    /// the one sent at the iteration before (zero before the first iteration: the run starts at rest). D1 makes it
    /// zero up to rounding; [`Run::event_continuity`] says what happens after.
    pub fn max_velocity_jump(&self) -> f64 {
        self.totals
            .continuity
            .iter()
            .map(|c| c.jump)
            .fold(0.0, f64::max)
    }

    /// Continuity at and after every stack change that sent a velocity (D14): the jump at the change, the largest
    /// velocity step in the window from the change to the next one, and the jump the law alone would have made.
    pub fn event_continuity(&self) -> Vec<EventContinuity> {
        self.totals.continuity.clone()
    }

    /// `‖[e_1; …; e_n]‖` at the last iteration; `None` when the run ended before its first record.
    pub fn final_error_norm(&self) -> Option<f64> {
        self.last_record()
            .map(|r| r.task_errors.iter().map(|e| e * e).sum::<f64>().sqrt())
    }

    /// The smallest distance to a limit over time (the start and every iteration) and joints, as a fraction of the
    /// joint's range.
    pub fn min_normalized_margin(&self) -> f64 {
        self.totals.min_normalized_margin
    }

    /// The smallest link–obstacle signed distance over the run (m; negative when penetrating), including the
    /// configuration where a collision ended it; `None` without obstacles.
    pub fn min_obstacle_distance(&self) -> Option<f64> {
        let at_collision = match &self.outcome {
            Outcome::Collision { distance, .. } => Some(*distance),
            _ => None,
        };
        self.totals
            .min_obstacle_distance
            .into_iter()
            .chain(at_collision)
            .reduce(f64::min)
    }

    /// The names of the tasks stacked at the end.
    pub fn stacked_at_end(&self) -> Vec<&str> {
        self.last_record()
            .map(|r| {
                r.stacked
                    .iter()
                    .map(|&i| self.task_names[i].as_str())
                    .collect()
            })
            .unwrap_or_default()
    }

    /// The events of one kind.
    pub fn events_of(&self, kind: EventKind) -> impl Iterator<Item = &StackEvent> {
        self.events.iter().filter(move |e| e.kind == kind)
    }
}

/// Evaluates every task in `context`; the error of the first that fails, as text.
fn evaluate_all<const N: usize>(
    tasks: &[VisualTask],
    context: &VisualContext<'_, N>,
    values: &mut [TaskValue<N>],
) -> Result<(), String> {
    tasks
        .iter()
        .zip(values.iter_mut())
        .try_for_each(|(task, value)| task.evaluate(context, value))
        .map_err(|e| e.to_string())
}

/// The camera Jacobian `cVe · eJe(q)` of the mount the controller believes in.
fn believed_camera_jacobian<const N: usize>(
    scene: &Scene<N>,
    believed: &EyeInHand,
    workspace: &mut KinematicsWorkspace<N>,
    q: &JointVector<N>,
) -> Result<KinematicJacobian<N>, SimError> {
    let state = scene.chain.kinematics(workspace, q)?;
    Ok(believed.camera_jacobian(state.tip_jacobian()))
}

/// How a run that used its whole budget ended — stalled on a task that could not come in (D13), or still converging —
/// or one whose controller held (D13) once the robot is at rest.
fn budget_outcome<const N: usize>(
    controller: &StackController<N>,
    task_names: &[String],
    last: Option<&Record<N>>,
) -> Outcome {
    let errors = last.map(|r| r.task_errors.as_slice()).unwrap_or_default();
    let error_list = task_names
        .iter()
        .zip(errors)
        .map(|(name, e)| format!("{name} {e:.1e}"))
        .collect::<Vec<_>>()
        .join(", ");
    match controller.status() {
        ControllerStatus::Reinserting {
            task,
            last_test: Some(test),
            ..
        } => Outcome::Stalled {
            task,
            reason: format!(
                "{} was removed and its re-insertion was refused to the end: the cost predicted with it back is \
                 {:.2e} > {:.2e} (task errors: {error_list})",
                task_names[task], test.predicted_cost, test.threshold
            ),
        },
        ControllerStatus::Reinserting {
            task,
            last_test: None,
            stack_velocity_norm,
        } => Outcome::Stalled {
            task,
            reason: format!(
                "{} was removed and its re-insertion was never tested (a test waits for the stack to settle and for \
                 the task's dwell): ‖q̇_n‖ = {stack_velocity_norm:.2e} at the end (task errors: {error_list})",
                task_names[task]
            ),
        },
        ControllerStatus::Pushing {
            next,
            stack_velocity_norm,
        } => Outcome::Stalled {
            task: next,
            reason: format!(
                "{} was never pushed: the stack did not settle (‖q̇_n‖ = {stack_velocity_norm:.2e} at the end; task \
                 errors: {error_list})",
                task_names[next]
            ),
        },
        ControllerStatus::Held { task, time } => Outcome::Stalled {
            task,
            reason: format!(
                "held at t = {time:.2} s: after the fallback the law was predicted past a hard limit (or to lose the \
                 target) one transition ahead and no task could be removed, so every task was dropped from {} on and \
                 the robot kept inside its limits (task errors: {error_list})",
                task_names[task]
            ),
        },
        ControllerStatus::Complete => {
            // The joints held at a limit at the end (D26): the tasks were pressing them into it.
            let locked = controller.law_workspace().locked_joints();
            let locked_list = (0..N)
                .filter(|&joint| locked[joint])
                .map(|joint| joint.to_string())
                .collect::<Vec<_>>();
            let locked_note = if locked_list.is_empty() {
                String::new()
            } else {
                format!(
                    "; locked at a hard limit, the tasks pressing them in: joint {}",
                    locked_list.join(", ")
                )
            };
            Outcome::MaxIterations {
                reason: format!(
                    "every task stacked; task errors at the end: {error_list}{locked_note}"
                ),
            }
        }
    }
}

/// The point of a [`CostError::PointBehindCamera`] inside a controller error.
fn point_behind_camera(error: &ControllerError) -> Option<usize> {
    match error {
        ControllerError::Cost(CostError::PointBehindCamera { point, .. })
        | ControllerError::Law(LawError::Cost(CostError::PointBehindCamera { point, .. })) => {
            Some(*point)
        }
        _ => None,
    }
}

/// The closest (link, obstacle, signed distance) at `q`, when the scene has obstacles.
fn closest_obstacle<const N: usize>(
    scene: &Scene<N>,
    q: &JointVector<N>,
) -> Result<Option<(String, String, f64)>, SimError> {
    let Some(obstacles) = &scene.obstacles else {
        return Ok(None);
    };
    Ok(obstacles
        .closest_pair(q)?
        .map(|c| (c.link.to_owned(), c.obstacle.to_owned(), c.distance)))
}

/// What the controller sees of the target when the camera is not exact (a real camera): the measurement model
/// (pixel noise, intrinsics and hand-eye errors, distortion, a slower camera, latency), where the depths come from,
/// and the desired image as taught through that camera. Without it the controller sees the true image with the true
/// depths.
#[derive(Debug, Clone, Copy)]
pub struct Sensing<'a> {
    /// The camera the controller has, against the true one.
    pub measurement: MeasurementParameters,
    /// Where the points' depths come from; `None`: the true depths (a simulation-only oracle).
    pub depth: Option<DepthSource>,
    /// The desired image points as the nominal camera reads them, with their desired depths (for
    /// [`DepthSource::Desired`]).
    pub desired_points: [ImagePoint; 4],
    /// The run's tasks with their desired values from the true desired image: the noise-free errors of the run (its
    /// records and its convergence) are theirs on the true image. Empty: the controller's own tasks.
    pub true_tasks: &'a [VisualTask],
}

impl Sensing<'_> {
    /// The same sensing with `true_tasks`.
    pub fn with_true_tasks(self, true_tasks: &[VisualTask]) -> Sensing<'_> {
        Sensing {
            measurement: self.measurement,
            depth: self.depth,
            desired_points: self.desired_points,
            true_tasks,
        }
    }
}

/// The per-run state of [`Sensing`]: the measurement model, the believed camera mount, the depth estimator and the
/// believed camera twist (which the estimator and the prediction between frames use).
struct SensingState<'a> {
    sensing: &'a Sensing<'a>,
    model: MeasurementModel,
    believed: EyeInHand,
    estimator: Option<DepthEstimator>,
    believed_twist: Vector6<f64>,
    twist_sum: Vector6<f64>,
    twist_time: f64,
    /// The plane of the pose estimate the depth source uses: the perfect one of the previous period
    /// ([`DepthSource::PreviousPlane`]) or the one estimated from the last measured corners and the target model
    /// ([`DepthSource::TargetPose`]).
    plane: Option<TargetPlane>,
    target: RectangleTarget,
    measured: [Point2<f64>; 4],
    points: [ImagePoint; 4],
}

impl<'a> SensingState<'a> {
    fn new<const N: usize>(
        sensing: &'a Sensing<'a>,
        scene: &Scene<N>,
        period: f64,
    ) -> Result<Self, SimError> {
        let depth_error = |e: DepthError| SimError::Measurement(MeasurementError::Depth(e));
        Ok(Self {
            sensing,
            model: MeasurementModel::new(&sensing.measurement, scene.intrinsics, 4, period)?,
            believed: perturbed_eye_in_hand(&scene.mount, &sensing.measurement)?,
            estimator: match sensing.depth {
                Some(source) => source.estimator(4).map_err(depth_error)?,
                None => None,
            },
            believed_twist: Vector6::zeros(),
            twist_sum: Vector6::zeros(),
            twist_time: 0.0,
            plane: None,
            target: scene.target,
            measured: [Point2::origin(); 4],
            points: [ImagePoint::default(); 4],
        })
    }

    /// The points the controller sees at `time` for the true `view` (normalised through the nominal camera, with the
    /// depths of the source), or why the image is unusable.
    fn measure<const N: usize>(&mut self, time: f64, view: &View<N>) -> Result<(), String> {
        let depths = depths_of(
            self.sensing,
            self.estimator.as_ref(),
            self.plane.as_ref(),
            view,
        );
        let measurement = self
            .model
            .measure(time, &view.points, &self.believed_twist, depths)
            .map_err(|e| e.to_string())?;
        self.measured.copy_from_slice(measurement.normalized);
        if let (true, Some(estimator)) = (measurement.fresh, self.estimator.as_mut()) {
            let mean_twist = if self.twist_time > 0.0 {
                self.twist_sum / self.twist_time
            } else {
                Vector6::zeros()
            };
            match estimator.update(measurement.frame_time, &self.measured, &mean_twist) {
                // Noise larger than the motion: the estimator keeps its previous depths.
                Ok(_) | Err(DepthError::NonPositiveDepth { .. }) => {}
                Err(other) => return Err(other.to_string()),
            }
            (self.twist_sum, self.twist_time) = (Vector6::zeros(), 0.0);
        }
        let from_corners = self.sensing.depth == Some(DepthSource::TargetPose);
        if from_corners {
            let plane = self
                .target
                .plane_from_image(&self.measured)
                .map_err(|e| e.to_string())?;
            self.plane = Some(plane);
        }
        let depths = depths_of(
            self.sensing,
            self.estimator.as_ref(),
            self.plane.as_ref(),
            view,
        );
        assign_depths(depths, &self.measured, &mut self.points).map_err(|e| e.to_string())?;
        if !from_corners {
            // A perfect pose estimate, one period late.
            self.plane = Some(view.plane);
        }
        Ok(())
    }

    /// Records the velocity sent over the next `period`: the camera twist the controller believes it makes, for the
    /// depth estimator (averaged between frames) and the prediction between frames.
    fn sent<const N: usize>(
        &mut self,
        believed_jacobian: &KinematicJacobian<N>,
        velocity: &JointVector<N>,
        period: f64,
    ) {
        self.believed_twist = believed_jacobian * velocity;
        self.twist_sum += self.believed_twist * period;
        self.twist_time += period;
    }
}

/// The depths of `sensing`'s source: the estimator's, a constant, the desired image's, the plane of a pose estimate
/// (`plane`: a perfect one, one period late, or the one from the measured corners; the true plane before the first),
/// or the true depths of `view` (no source).
fn depths_of<'b, const N: usize>(
    sensing: &'b Sensing<'_>,
    estimator: Option<&'b DepthEstimator>,
    plane: Option<&'b TargetPlane>,
    view: &'b View<N>,
) -> Depths<'b> {
    match (&sensing.depth, estimator) {
        (_, Some(estimator)) => Depths::Estimated(estimator.depths()),
        (Some(DepthSource::Constant { depth_m }), None) => Depths::Constant(*depth_m),
        (Some(DepthSource::Desired), None) => Depths::Desired(&sensing.desired_points),
        (Some(DepthSource::PreviousPlane | DepthSource::TargetPose), None) => {
            Depths::Plane(plane.unwrap_or(&view.plane))
        }
        (Some(DepthSource::Estimated { .. }) | None, None) => Depths::Desired(&view.points),
    }
}

/// How the tasks are driven in a run.
#[derive(Debug, Clone, Copy)]
pub struct Drive<'a> {
    /// The control law (gains, `μ`, `κ`).
    pub law: &'a ControlLaw,
    /// The controller's parameters (push, removal).
    pub controller: ControllerParameters,
    /// Whether the scene's avoidance cost ([`Scene::avoidance_cost`]: joint limits, plus obstacles and visibility when
    /// the scene has them) is given to the law and the controller (projected-gradient avoidance and prediction);
    /// without it, `κ` has no effect and no task is ever removed.
    pub avoid_joint_limits: bool,
    /// Whether removals are guarded by the visibility of the target ([`SimulationParameters::visibility_margin_px`],
    /// D6 (d)): the full method's default.
    pub guard_visibility: bool,
    /// Tasks never removed (D6 (e)): the full method protects the centroid, which keeps the target in the image.
    pub protected_tasks: &'a [usize],
    /// What the controller sees; `None`: the true image and depths.
    pub sensing: Option<&'a Sensing<'a>>,
    /// An adaptive gain `λ(‖e_i‖∞)` replacing every task's gain at every period (as the servo façade's); `None`: the
    /// tasks' constant gains.
    pub adaptive_gain: Option<AdaptiveGain>,
    /// Whether the last task of the list is held in reserve ([`StackController::with_reserve_task`],
    /// [D23](crate::theory#d23)): the full method's image points, which take the place of the last task when the
    /// features settle away from the desired image. Until then its error does not count for convergence.
    pub reserve_task: bool,
    /// The law that keeps every velocity inside the box of the joint limits, the robot's velocity limits and the period:
    /// SNS ([theory §13](crate::theory#s13)) or the QP cascade ([theory §14](crate::theory#s14)); `None`: no box.
    pub bounded_law: Option<BoundedLaw>,
}

/// Runs the tasks from `start` until convergence, a joint limit, a lost feature or the budget, and keeps every record
/// in [`Run::records`] (memory grows with the run: for runs of any length, see [`simulate_with`]).
///
/// # Errors
/// Invalid parameters, a start outside the limits, failures of the models (not outcomes).
pub fn simulate<const N: usize>(
    scene: &Scene<N>,
    tasks: &[VisualTask],
    drive: Drive<'_>,
    start: &JointVector<N>,
    parameters: &SimulationParameters,
) -> Result<Run<N>, SimError> {
    let mut records = Vec::new();
    let mut run = simulate_with(scene, tasks, drive, start, parameters, &mut records)?;
    run.records = records;
    Ok(run)
}

/// As [`simulate`], with the records given to `log` as they are made ([`Run::records`] stays empty): with
/// [`SummaryOnly`], [`Decimated`] or [`JsonLines`], a run of any length uses bounded memory, and the [`Run`]'s summary
/// (outcome, iterations, last record, velocity steps, continuity, margins) is the same as with every record kept.
///
/// # Errors
/// As [`simulate`]; [`SimError::Log`] when the log refuses a record.
pub fn simulate_with<const N: usize>(
    scene: &Scene<N>,
    tasks: &[VisualTask],
    drive: Drive<'_>,
    start: &JointVector<N>,
    parameters: &SimulationParameters,
    log: &mut dyn RunLog<N>,
) -> Result<Run<N>, SimError> {
    parameters.validate()?;
    // D25: braked for one period `Δt`, a joint covers at most `ξ Δt` of its distance to the limit (`ξ = +∞`: off).
    let braking_rate = drive.controller.braking_rate;
    if braking_rate.is_finite() && braking_rate * parameters.period > 1.0 {
        return Err(SimError::InvalidParameter {
            name: "controller.braking_rate",
            value: braking_rate,
            expected: "at most 1/period (s⁻¹): braked faster, a joint could cross its limit within one period",
        });
    }
    if let Some(joint) = scene.limits.violated_joint(start) {
        return Err(SimError::StartOutsideLimits {
            joint,
            value: start[joint],
            lower: scene.limits.lower()[joint],
            upper: scene.limits.upper()[joint],
        });
    }
    let mut values: Vec<TaskValue<N>> = tasks
        .iter()
        .map(TaskValue::for_task::<VisualContext<'_, N>, _>)
        .collect::<Result<_, _>>()?;
    // With a real camera, the noise-free task values (the run's errors and its convergence) apart from the measured
    // ones the controller gets.
    let mut true_values = match drive.sensing {
        Some(_) => values.clone(),
        None => Vec::new(),
    };
    let mut sensing = drive
        .sensing
        .map(|s| SensingState::new(s, scene, parameters.period))
        .transpose()?;
    let mut controller = StackController::new(drive.controller, &values)?
        .with_protected_tasks(drive.protected_tasks)?
        .with_joint_limits(scene.limits.clone())?;
    if drive.reserve_task {
        controller = controller.with_reserve_task()?;
    }
    let max_velocity = JointVector::<N>::from_fn(|i, _| {
        if scene.chain.joints()[i].kind().is_rotational() {
            parameters.max_revolute_velocity_rad_s
        } else {
            parameters.max_prismatic_velocity_m_s
        }
    });
    if let Some(law) = drive.bounded_law {
        let bounds = SnsBounds::new(scene.limits.clone(), max_velocity, parameters.period)
            .map_err(|e| ControllerError::Law(e.into()))?;
        controller = controller.with_bounded_law(law, bounds)?;
    }
    // The full method keeps the target in view: the scene's visibility cost, or one with the default margin, joins its
    // avoidance cost and guards its removals (D6 (d)).
    let default_visibility = match &scene.visibility {
        None if drive.guard_visibility && drive.controller.allow_removal => {
            Some(scene.visibility_cost(
                parameters.visibility_margin_px,
                parameters.facing_activation_deg(),
            )?)
        }
        _ => None,
    };
    let mut avoidance = scene.avoidance_cost();
    if let Some(visibility) = &default_visibility {
        avoidance.push(visibility);
    }
    let cost: Option<&dyn Cost<N>> = drive
        .avoid_joint_limits
        .then_some(&avoidance as &dyn Cost<N>);
    let guard = match (&default_visibility, &scene.visibility) {
        _ if !drive.guard_visibility => None,
        (Some(visibility), _) | (None, Some(visibility)) => Some(visibility as &dyn Cost<N>),
        (None, None) => None,
    };
    let mut workspace = KinematicsWorkspace::new();
    let mut q = *start;
    // The closest link–obstacle pair at the current `q`, computed once per configuration.
    let mut closest = closest_obstacle(scene, &q)?;
    let mut totals = Totals::new(&scene.limits, start);
    let keep = |totals: &mut Totals<N>,
                log: &mut dyn RunLog<N>,
                record: Record<N>,
                events: &[StackEvent]| {
        log.record(&record).map_err(|message| SimError::Log {
            iteration: record.iteration,
            message,
        })?;
        totals.add(record, &scene.limits, events);
        Ok::<_, SimError>(())
    };
    let task_names: Vec<String> = tasks
        .iter()
        .map(|t| Task::<N, VisualContext<'_, N>>::name(t).to_owned())
        .collect();
    let mut outcome = None;
    // The time the task errors went below the convergence threshold and have stayed there since.
    let mut below_since: Option<f64> = None;
    let mut view = View::default();
    for iteration in 0..parameters.max_iterations {
        let time = iteration as f64 * parameters.period;
        match scene.observe_into(&mut workspace, &q, &mut view) {
            Ok(()) => {}
            Err(SimError::Camera(CameraError::PointBehindCamera { index, .. })) => {
                outcome = Some(Outcome::FeatureLost { point: index });
                break;
            }
            Err(SimError::Target(error)) => {
                outcome = Some(Outcome::ImageDegenerate {
                    reason: error.to_string(),
                });
                break;
            }
            Err(error) => return Err(error),
        };
        if let Some(point) = view.points.iter().position(|p| {
            !scene
                .intrinsics
                .in_field_of_view(p, parameters.image_margin)
        }) {
            outcome = Some(Outcome::FeatureLost { point });
            break;
        }
        let incidence = scene.target_incidence_deg(&view.c_from_o);
        if incidence > parameters.max_incidence_deg {
            outcome = Some(Outcome::ImageDegenerate {
                reason: incidence_reason(incidence, parameters.max_incidence_deg),
            });
            break;
        }
        let observation = view.observation()?;
        let context = VisualContext {
            observation: &observation,
            camera_jacobian: &view.camera_jacobian,
        };
        // A target seen so obliquely that a feature is undefined (collinear points, vanishing area) is lost as well.
        let evaluated = match &mut sensing {
            None => evaluate_all(tasks, &context, &mut values),
            Some(sensing) => {
                let true_tasks = match sensing.sensing.true_tasks {
                    [] => tasks,
                    true_tasks => true_tasks,
                };
                evaluate_all(true_tasks, &context, &mut true_values)
            }
            .and_then(|()| {
                sensing.measure(time, &view)?;
                let measured =
                    Observation::new(&sensing.points, None).map_err(|e| e.to_string())?;
                let believed_jacobian =
                    believed_camera_jacobian(scene, &sensing.believed, &mut workspace, &q)
                        .map_err(|e| e.to_string())?;
                let context = VisualContext {
                    observation: &measured,
                    camera_jacobian: &believed_jacobian,
                };
                evaluate_all(tasks, &context, &mut values)
            }),
        };
        if let Err(reason) = evaluated {
            outcome = Some(Outcome::ImageDegenerate { reason });
            break;
        }
        let truth = if sensing.is_some() {
            &true_values
        } else {
            &values
        };
        // The previous record's buffers are reused (the log has its own copy): no allocation per iteration here.
        let mut record = totals.last.take().unwrap_or_else(Record::empty);
        record.iteration = iteration;
        record.time = time;
        record.q = q;
        record.velocity = JointVector::zeros();
        record.sent = false;
        record.task_errors.clear();
        record
            .task_errors
            .extend(truth.iter().map(|v| v.error().norm()));
        record.stacked.clear();
        record.stacked.extend_from_slice(controller.stacked());
        record.cost = scene.limits.value(&q)?;
        record.predicted_cost = 0.0;
        record.criteria.clear();
        record.image = view.points;
        record.obstacle_distance = closest.as_ref().map(|(_, _, d)| *d);
        // A reserve task counts for convergence once it is stacked.
        let waiting_reserve = controller.waiting_reserve();
        let below = controller.is_complete()
            && record
                .task_errors
                .iter()
                .enumerate()
                .all(|(i, &e)| e < parameters.convergence_error || Some(i) == waiting_reserve);
        below_since = if below {
            below_since.or(Some(time))
        } else {
            None
        };
        if below_since.is_some_and(|since| time - since >= parameters.convergence_hold_s) {
            keep(&mut totals, log, record, controller.events())?;
            // The features settled; where is the camera? (D22)
            let (translation_m, rotation_deg) = scene.distance_to_goal(&view.c_from_o);
            outcome = Some(
                if translation_m <= parameters.goal_tolerance_m
                    && rotation_deg <= parameters.goal_tolerance_deg
                {
                    Outcome::Converged
                } else {
                    Outcome::OffGoal {
                        translation_m,
                        rotation_deg,
                    }
                },
            );
            break;
        }
        if let Some(adaptive) = &drive.adaptive_gain {
            for (task, value) in tasks.iter().zip(values.iter_mut()) {
                adaptive.apply(Task::<N, VisualContext<'_, N>>::name(task), value)?;
            }
        }
        let step =
            match controller.step_guarded(drive.law, &values, cost, guard, &q, iteration, time) {
                Ok(step) => step,
                // The visibility cost is undefined once the (predicted) motion takes a point behind the camera: the
                // feature is lost, as when the camera itself gets there.
                Err(error) => match point_behind_camera(&error) {
                    Some(point) => {
                        keep(&mut totals, log, record, controller.events())?;
                        outcome = Some(Outcome::FeatureLost { point });
                        break;
                    }
                    None => return Err(error.into()),
                },
            };
        // The robot's velocity limits, then the braking before a hard limit (D25): uniform scalings, and the
        // controller told what was sent.
        let braking_rate = controller.parameters().braking_rate;
        let velocity = step.velocity
            * scene
                .limits
                .sent_velocity_scale(&q, &step.velocity, &max_velocity, braking_rate);
        controller.set_sent_velocity(&velocity)?;
        record.velocity = velocity;
        record.sent = true;
        // The stack that produced the velocity sent (a change made at this iteration included).
        record.stacked.clear();
        record.stacked.extend_from_slice(controller.stacked());
        record.predicted_cost = step.predicted_cost;
        record.criteria.extend_from_slice(controller.criteria());
        if let Some(sensing) = &mut sensing {
            let believed_jacobian =
                believed_camera_jacobian(scene, &sensing.believed, &mut workspace, &q)?;
            sensing.sent(&believed_jacobian, &velocity, parameters.period);
        }
        q += velocity * parameters.period;
        let hit = scene.limits.violated_joint(&q);
        closest = closest_obstacle(scene, &q)?;
        let contact = closest.clone().filter(|(_, _, d)| *d <= 0.0);
        let ended = match (hit, contact) {
            (Some(joint), _) => Some(Outcome::JointLimit {
                joint,
                stacked: record.stacked.clone(),
            }),
            (None, Some((link, obstacle, distance))) => Some(Outcome::Collision {
                link,
                obstacle,
                distance,
                stacked: record.stacked.clone(),
            }),
            // A held controller (D13) has given up: the run ends once the avoidance has brought the robot to rest.
            (None, None)
                if controller.is_held()
                    && velocity.norm() < controller.parameters().settle_velocity =>
            {
                Some(budget_outcome(&controller, &task_names, Some(&record)))
            }
            (None, None) => None,
        };
        keep(&mut totals, log, record, controller.events())?;
        if ended.is_some() {
            outcome = ended;
            break;
        }
    }
    let outcome = match outcome {
        Some(outcome) => outcome,
        None => budget_outcome(&controller, &task_names, totals.last.as_ref()),
    };
    Ok(Run {
        outcome,
        period: parameters.period,
        task_names,
        records: Vec::new(),
        events: controller.events().to_vec(),
        limits: scene.limits.clone(),
        totals,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::law::ControlLaw;
    use crate::task::TaskJacobian;
    use nalgebra::DVector;

    /// D26: a run whose budget ends with every task stacked names the joints its tasks hold locked at a limit, and
    /// only those.
    #[test]
    fn a_budget_that_ends_with_a_locked_joint_names_it() {
        // One task driving joint 1 down (e = 1, J = [0, 1]: q̇ = −λ J⁺ e = (0, −1)).
        let jacobian = TaskJacobian::<2>::from_row_slice(&[0.0, 1.0]);
        let tasks = [
            TaskValue::from_parts("reach", DVector::from_element(1, 1.0), jacobian, 1.0).unwrap(),
        ];
        let limits = JointLimits::new(
            JointVector::<2>::new(-1.0, -1.0),
            JointVector::<2>::new(1.0, 1.0),
            0.1,
        )
        .unwrap();
        let law = ControlLaw::new(10.0, 0.0).unwrap();
        let reason_at = |q: JointVector<2>| {
            let mut controller = StackController::new(ControllerParameters::default(), &tasks)
                .unwrap()
                .with_joint_limits(limits.clone())
                .unwrap();
            controller.step(&law, &tasks, None, &q, 0, 0.01).unwrap();
            assert!(controller.is_complete());
            match budget_outcome(&controller, &["reach".to_string()], None) {
                Outcome::MaxIterations { reason } => reason,
                other => panic!("{other:?}"),
            }
        };
        let at_limit = reason_at(JointVector::<2>::new(0.0, -1.0));
        assert!(
            at_limit.ends_with("locked at a hard limit, the tasks pressing them in: joint 1"),
            "{at_limit}"
        );
        let inside = reason_at(JointVector::<2>::new(0.0, -0.5));
        assert!(!inside.contains("locked"), "{inside}");
    }
}
