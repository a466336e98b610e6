//! The world of a simulation: the [`Scene`] (a robot with its eye-in-hand camera, the camera's intrinsics, the
//! target and where it stands, the joint limits and the optional obstacle and visibility costs) and the [`View`] the
//! camera has of the target at one configuration.

use super::SimError;
use crate::avoidance::{CompositeCost, JointLimits, ObstacleCost, VisibilityCost};
use crate::camera::{project_points, CameraIntrinsics, EyeInHand, ImagePoint};
use crate::feature::{FeatureError, Observation};
use crate::math::{JointVector, KinematicJacobian};
use crate::robot::{KinematicsWorkspace, SerialChain};
use crate::target::{RectangleTarget, TargetPlane};
use nalgebra::{Isometry3, Point3, Vector3};

/// The world: a robot with its camera, the camera's intrinsics, the target and where it stands.
#[derive(Debug, Clone)]
pub struct Scene<const N: usize> {
    pub(super) chain: SerialChain<N>,
    pub(super) mount: EyeInHand,
    pub(super) intrinsics: CameraIntrinsics,
    pub(super) target: RectangleTarget,
    pub(super) base_from_object: Isometry3<f64>,
    pub(super) desired_camera_from_object: Isometry3<f64>,
    pub(super) limits: JointLimits<N>,
    pub(super) obstacles: Option<ObstacleCost<N>>,
    pub(super) visibility: Option<VisibilityCost<N>>,
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

    /// The scene with world obstacles: their cost joins the avoidance cost, and a link–obstacle contact ends a run as
    /// [`Outcome::Collision`](super::Outcome::Collision).
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
    /// An invalid margin or activation angle ([`CostError`](crate::avoidance::CostError)).
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
