//! The closed visual-servoing loop on the Afma6 peer scene (docs/peer_scene.md), shared by `benches/peer.rs`,
//! `benches/control_loop.rs` and the zero-allocation test (`tests/suite/allocation.rs`), so that what is timed is exactly
//! what is proven allocation-free.
//!
//! Include with `#[path = "…/benches/common/servo_loop.rs"] mod servo_loop;`.
//!
//! One iteration ([`ServoLoop::step`]) = forward kinematics and `eJe`, camera pose, projection of the four points and
//! the target plane, the camera Jacobian `cVe eJe` ([`Scene::observe_into`]); the observation and every task's features,
//! interaction matrix and `J = L cVe eJe` ([`Task::evaluate`]); the control law (a bare [`control_step`], or a whole
//! [`StackController::step`]); the Euler step `q ← q + Δt q̇`.
#![allow(dead_code)] // each including crate uses part of it

use nalgebra::Isometry3;
use servostack::avoidance::{CompositeCost, Cost, VisibilityCost};
use servostack::camera::CameraIntrinsics;
use servostack::controller::{ControllerParameters, StackController};
use servostack::feature::{AllPoints, AreaNormalization, FeatureSet, InteractionSource};
use servostack::law::{
    control_step, AvoidanceProjection, ControlLaw, ControlWorkspace, StackChange,
};
use servostack::math::JointVector;
use servostack::robot::{builtin, KinematicsWorkspace};
use servostack::sim::{Scene, SimulationParameters, View};
use servostack::target::RectangleTarget;
use servostack::task::{Task, TaskValue};
use servostack::visual_task::{classical_task, paper_tasks, VisualContext, VisualTask};

/// Control period `Δt` (s).
pub const PERIOD: f64 = 0.01;
/// Task gain `λ` (s⁻¹).
pub const GAIN: f64 = 0.5;
/// Transition gain `μ` (s⁻¹), ViSP's default.
pub const MU: f64 = 4.0;
/// Avoidance gain `κ` (s⁻¹) of variant C and of the controller loops: ViSP's `secondaryTask` uses the task gain.
pub const KAPPA: f64 = GAIN;
/// Desired depth `Z*` (m).
pub const DESIRED_DEPTH: f64 = 0.5;
/// `q_d` (m, m, m, rad, rad, rad).
pub const DESIRED_Q: [f64; 6] = [0.0, 0.0, 0.0, 0.0, 0.3, 0.0];
/// `q0 − q_d`.
pub const START_OFFSET: [f64; 6] = [0.05, -0.04, -0.10, 0.25, -0.18, 0.12];

/// The variants of the peer scene (docs/peer_scene.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variant {
    /// Four points (8 rows), `q̇ = −λ J⁺ e`.
    A,
    /// ViSP's moment vector `(x_n, y_n, a_n, P_x, P_y, α)`, same law.
    B,
    /// A with the continuity term (`q̇(0) = 0`) and the joint-limit projected gradient. The 8-row task has full rank,
    /// so `P^A = 0` and the avoidance term is zero: servostack does less work here than ViSP, whose large projection
    /// operator acts while `‖e‖ > 0.1`.
    C,
    /// C with ViSP's large projection operator ([`AvoidanceProjection::VISP`]): the avoidance term is computed and
    /// applied while joint 4 is in its activation band and `‖e‖ > 0.1`, as ViSP's `secondaryTaskJointLimitAvoidance`
    /// is non-zero then. The comparable-work variant of C.
    CL,
}

impl Variant {
    /// All variants, in order.
    pub const ALL: [Variant; 4] = [Variant::A, Variant::B, Variant::C, Variant::CL];

    /// `"A"`, `"B"`, `"C"`, `"CL"`.
    pub fn name(self) -> &'static str {
        match self {
            Variant::A => "A",
            Variant::B => "B",
            Variant::C => "C",
            Variant::CL => "CL",
        }
    }

    /// With the joint-limit avoidance and the continuity term (C and CL).
    fn avoids(self) -> bool {
        matches!(self, Variant::C | Variant::CL)
    }
}

/// What drives the joints (one per loop, never moved in the loop: the size difference does not matter).
#[allow(clippy::large_enum_variant)]
enum Drive {
    /// The bare control law on one stack: `avoid` adds the joint-limit cost (with `κ`), `smooth_start` makes the first
    /// step a switch from rest (the continuity term).
    Law {
        workspace: ControlWorkspace<6>,
        avoid: bool,
        smooth_start: bool,
    },
    /// The stack controller with the joint-limit cost.
    Controller {
        controller: StackController<6>,
        parameters: ControllerParameters,
    },
}

/// The avoidance cost and the removal guard of the simulation's full method (`sim::simulate_with`).
struct FullMethodCosts {
    cost: CompositeCost<'static, 6>,
    guard: VisibilityCost<6>,
}

/// A servo loop on the peer scene: model (scene, tasks, law) and workspaces, allocated once.
pub struct ServoLoop {
    scene: Scene<6>,
    tasks: Vec<VisualTask>,
    values: Vec<TaskValue<6>>,
    law: ControlLaw,
    drive: Drive,
    kinematics: KinematicsWorkspace<6>,
    /// What the camera sees, rewritten at every step.
    view: View<6>,
    /// The full method's costs in the simulation (joint limits and visibility, the visibility guarding removals), in
    /// place of the joint limits alone.
    full_method: Option<FullMethodCosts>,
    start: JointVector<6>,
    q: JointVector<6>,
    iteration: usize,
}

/// The peer scene: Afma6, the 0.2 m × 0.1 m rectangle seen at `(0, 0, Z*)` without rotation from `q_d`; the joint
/// limits' activation ratio is `rho`.
fn scene(rho: f64) -> Scene<6> {
    let robot = builtin::afma6().expect("afma6");
    let intrinsics =
        CameraIntrinsics::new(600.0, 600.0, 320.0, 240.0, 640.0, 480.0).expect("intrinsics");
    Scene::with_target_seen_from(
        robot.chain,
        robot.mount,
        intrinsics,
        RectangleTarget::new(0.2, 0.1).expect("target"),
        &JointVector::from(DESIRED_Q),
        &Isometry3::translation(0.0, 0.0, DESIRED_DEPTH),
        rho,
    )
    .expect("scene")
}

fn start() -> JointVector<6> {
    JointVector::from(DESIRED_Q) + JointVector::from(START_OFFSET)
}

impl ServoLoop {
    fn with(
        scene: Scene<6>,
        tasks: Vec<VisualTask>,
        law: ControlLaw,
        drive: impl FnOnce(&[TaskValue<6>]) -> Drive,
    ) -> Self {
        let values: Vec<TaskValue<6>> = tasks
            .iter()
            .map(TaskValue::for_task::<VisualContext<'_, 6>, _>)
            .collect::<Result<_, _>>()
            .expect("task storage");
        let drive = drive(&values);
        Self {
            scene,
            tasks,
            values,
            law,
            drive,
            kinematics: KinematicsWorkspace::new(),
            view: View::default(),
            full_method: None,
            start: start(),
            q: start(),
            iteration: 0,
        }
    }

    /// One of the peer variants, at `q0`.
    pub fn peer(variant: Variant) -> Self {
        let scene = scene(0.1);
        let desired = scene
            .view_from(&Isometry3::translation(0.0, 0.0, DESIRED_DEPTH))
            .expect("desired view");
        let desired = desired.observation().expect("desired observation");
        let task = match variant {
            Variant::A | Variant::C | Variant::CL => VisualTask::new(
                "points",
                Box::new(AllPoints::new(4).expect("4 points")),
                &desired,
                GAIN,
                InteractionSource::Exact,
            ),
            Variant::B => {
                let normalization =
                    AreaNormalization::from_desired(&desired, DESIRED_DEPTH).expect("a*");
                VisualTask::new(
                    "moments",
                    Box::new(FeatureSet::visp_moments(normalization)),
                    &desired,
                    GAIN,
                    InteractionSource::Exact,
                )
            }
        }
        .expect("task");
        let kappa = if variant.avoids() { KAPPA } else { 0.0 };
        let mut law = ControlLaw::new(MU, kappa).expect("law");
        if variant == Variant::CL {
            law = law
                .with_avoidance_projection(AvoidanceProjection::VISP)
                .expect("projection");
        }
        Self::with(scene, vec![task], law, |values| Drive::Law {
            workspace: ControlWorkspace::new(values),
            avoid: variant.avoids(),
            smooth_start: variant.avoids(),
        })
    }

    /// Controller parameters for a steady benchmark: tasks are pushed one transition apart (`ε_add` large), and the
    /// removal threshold is out of reach, so that prediction and criteria run at every step but the stack stays full.
    fn steady_controller() -> ControllerParameters {
        ControllerParameters {
            settle_velocity: 1e3,
            settle_velocity_with_removal: 1e3,
            removal_threshold: Some(1e9),
            ..ControllerParameters::default()
        }
    }

    fn controlled(tasks: Vec<VisualTask>) -> Self {
        // ρ = 0.3: q_d lies in the activation band of joint 4, so ∇h ≠ 0 and the criteria are computed at every step.
        let scene = scene(0.3);
        let parameters = Self::steady_controller();
        let law = ControlLaw::new(10.0 * GAIN, KAPPA).expect("law");
        Self::with(scene, tasks, law, |values| Drive::Controller {
            controller: StackController::new(parameters, values).expect("controller"),
            parameters,
        })
    }

    /// The paper's four tasks (centroid, angle, `a_n`, `P_x/P_y`), stacked by the controller with joint-limit
    /// avoidance, prediction and criteria. Call [`Self::settle`] to stack them all.
    pub fn paper() -> Self {
        let scene = scene(0.3);
        let desired = scene
            .view_from(&Isometry3::translation(0.0, 0.0, DESIRED_DEPTH))
            .expect("desired view");
        let desired = desired.observation().expect("desired observation");
        let tasks = paper_tasks(
            &desired,
            DESIRED_DEPTH,
            DESIRED_DEPTH,
            [GAIN; 4],
            InteractionSource::Exact,
        )
        .expect("paper tasks");
        Self::controlled(tasks)
    }

    /// [`Self::paper`] with the costs of the simulation's full method: the visibility of the target (the simulation's
    /// default 20 px margin and facing term, D27) joins the avoidance cost and guards removals, evaluated at `q` and at
    /// the predicted `q̂`. Unlike the simulation, no reserve task (D23) and no joint locks (D26).
    pub fn paper_full_method() -> Self {
        let mut servo = Self::paper();
        let defaults = SimulationParameters::default();
        let guard = servo
            .scene
            .visibility_cost(
                defaults.visibility_margin_px,
                defaults.facing_activation_deg(),
            )
            .expect("visibility cost");
        let cost = CompositeCost::new()
            .with(servo.scene.limits().clone())
            .with(guard.clone());
        servo.full_method = Some(FullMethodCosts { cost, guard });
        servo
    }

    /// The classical six-row task (§7.7) in one level, under the controller with joint-limit avoidance.
    pub fn classical() -> Self {
        let scene = scene(0.3);
        let desired = scene
            .view_from(&Isometry3::translation(0.0, 0.0, DESIRED_DEPTH))
            .expect("desired view");
        let desired = desired.observation().expect("desired observation");
        let task = classical_task(
            &desired,
            DESIRED_DEPTH,
            DESIRED_DEPTH,
            GAIN,
            InteractionSource::Exact,
        )
        .expect("classical task");
        Self::controlled(vec![task])
    }

    /// Back to `q0`, `t = 0`, at rest (a fresh controller for the controller loops: this allocates).
    pub fn reset(&mut self) {
        self.q = self.start;
        self.iteration = 0;
        match &mut self.drive {
            Drive::Law { workspace, .. } => workspace.reset(&JointVector::zeros()),
            Drive::Controller {
                controller,
                parameters,
            } => *controller = StackController::new(*parameters, &self.values).expect("controller"),
        }
    }

    /// Runs until every task is stacked (controller loops; at once for the bare law).
    pub fn settle(&mut self) {
        while let Drive::Controller { controller, .. } = &self.drive {
            if controller.is_complete() {
                break;
            }
            self.step();
        }
    }

    /// One iteration of the loop (see the module docs). Panics on any failure: the scene is built to stay valid.
    pub fn step(&mut self) {
        let time = self.iteration as f64 * PERIOD;
        self.scene
            .observe_into(&mut self.kinematics, &self.q, &mut self.view)
            .expect("view");
        let observation = self.view.observation().expect("observation");
        let context = VisualContext {
            observation: &observation,
            camera_jacobian: &self.view.camera_jacobian,
        };
        for (task, value) in self.tasks.iter().zip(self.values.iter_mut()) {
            task.evaluate(&context, value).expect("task");
        }
        let (cost, guard): (&dyn Cost<6>, Option<&dyn Cost<6>>) = match &self.full_method {
            Some(full) => (&full.cost, Some(&full.guard)),
            None => (self.scene.limits(), None),
        };
        let velocity = match &mut self.drive {
            Drive::Law {
                workspace,
                avoid,
                smooth_start,
            } => {
                let change = if *smooth_start && self.iteration == 0 {
                    StackChange::Changed
                } else {
                    StackChange::Unchanged
                };
                let cost = avoid.then_some(cost);
                *control_step(
                    &self.law,
                    workspace,
                    &self.values,
                    &[0],
                    cost,
                    &self.q,
                    time,
                    change,
                )
                .expect("control step")
                .velocity()
            }
            Drive::Controller { controller, .. } => {
                controller
                    .step_guarded(
                        &self.law,
                        &self.values,
                        Some(cost),
                        guard,
                        &self.q,
                        self.iteration,
                        time,
                    )
                    .expect("controller step")
                    .velocity
            }
        };
        self.q += velocity * PERIOD;
        self.iteration += 1;
    }

    /// `‖[e_1; …; e_n]‖` as evaluated at the last step.
    pub fn error_norm(&self) -> f64 {
        self.values
            .iter()
            .map(|v| v.error().norm_squared())
            .sum::<f64>()
            .sqrt()
    }

    /// The current configuration.
    pub fn q(&self) -> &JointVector<6> {
        &self.q
    }

    /// The scene.
    pub fn scene(&self) -> &Scene<6> {
        &self.scene
    }

    /// The tasks.
    pub fn tasks(&self) -> &[VisualTask] {
        &self.tasks
    }

    /// The control law.
    pub fn law(&self) -> &ControlLaw {
        &self.law
    }

    /// The evaluated tasks of the last step.
    pub fn values(&self) -> &[TaskValue<6>] {
        &self.values
    }

    /// The avoidance term of the last step, `u − q̇_n` (`None` for the controller loops).
    pub fn avoidance(&self) -> Option<JointVector<6>> {
        match &self.drive {
            Drive::Law { workspace, .. } => {
                Some(workspace.last_output().law() - workspace.stack_solution().velocity())
            }
            Drive::Controller { .. } => None,
        }
    }

    /// The controller, for the controller loops.
    pub fn controller(&self) -> Option<&StackController<6>> {
        match &self.drive {
            Drive::Controller { controller, .. } => Some(controller),
            Drive::Law { .. } => None,
        }
    }

    /// The desired configuration, for checks.
    pub fn desired_q() -> JointVector<6> {
        JointVector::from(DESIRED_Q)
    }
}
