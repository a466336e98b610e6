//! The method's settings: everything of a scenario that is not the world ([`Settings`]), and the run of an
//! [`Experiment`] with them ([theory §9](crate::theory#s9)).

use super::{invalid, Experiment, RunKind, ScenarioError};
use super::{AvoidanceSpec, InteractionKind, TasksSpec, VisibilitySpec};
use crate::avoidance::CostError;
use crate::camera::ImagePoint;
use crate::controller::{ControllerParameters, HardLimitRule, RemovalCriterion};
use crate::depth::DepthSource;
use crate::feature::Observation;
use crate::law::{BoundedLaw, ControlLaw};
use crate::linalg::VelocityInverse;
use crate::measurement::{MeasurementModel, MeasurementParameters};
use crate::servo::AdaptiveGain;
use crate::sim::{
    simulate_with, Drive, Run, RunLog, Scene, Sensing, SimError, SimulationParameters,
};
use crate::stack::StackParameters;
use crate::task::TaskError;
use crate::visual_task::{
    classical_task_with, image_points_task, paper_tasks_with, FourthTask, VisualTask,
};
use std::borrow::Cow;

/// How the method runs, apart from the world it runs in: the sections `[tasks]`, `[avoidance]`, `[controller]`,
/// `[simulation]`, `[visibility]`, `[measurement]` and `depth` of a scenario file ([`super::Scenario::settings`]),
/// each field documented on its type. The world (robot, camera, target, goal, start, obstacles) is the
/// [`Experiment`]'s, so that each value has one place: [`Experiment::run`] reads every field here and nothing of a
/// scenario.
///
/// [`Settings::default`] is the paper's method as `assets/scenarios/paper_afma6.toml` sets it ([`Settings::paper`]);
/// change a field with struct update syntax: `Settings { avoidance: AvoidanceSpec { gain: 1.0, ..paper.avoidance },
/// ..paper }`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// The visual tasks: gains, interaction source, depths, fourth task, damping, adaptive gain.
    pub tasks: TasksSpec,
    /// The joint-limit cost's activation ratio `ρ`, the avoidance gain `κ` and the transition gain `μ`.
    pub avoidance: AvoidanceSpec,
    /// The stack controller's thresholds. Only the full method removes tasks, brakes (`braking_rate`) and locks
    /// (`lock_band`), or saturates in the null space instead (`hard_limit_rule`); `allow_removal` must stay `true`
    /// (the [`RunKind`] decides removal).
    pub controller: ControllerParameters,
    /// Period, budget, convergence threshold, image margin, velocity limits.
    pub simulation: SimulationParameters,
    /// A visibility cost of the target points (none by default; the full method has one of
    /// [`SimulationParameters::visibility_margin_px`] anyway).
    pub visibility: Option<VisibilitySpec>,
    /// The camera the controller has against the true one ([`MeasurementParameters`]; default: exact). The true lens's
    /// distortion is the experiment's camera's when it has one ([`Experiment::builder`]).
    pub measurement: MeasurementParameters,
    /// Where the points' depths come from; `None`: the true depths.
    pub depth: Option<DepthSource>,
}

impl Default for Settings {
    /// [`Settings::paper`].
    fn default() -> Self {
        Self::paper()
    }
}

impl Settings {
    /// The paper's method as the reference scenario `assets/scenarios/paper_afma6.toml` sets it: `λ_i = 0.5 s⁻¹`
    /// (classical too), exact interaction matrices, `ρ = 0.1`, `κ = 10 s⁻¹`, `μ = 10 max λ_i`, `ε_add = 0.01`,
    /// `T_pred = 0.05 s`, `h_max = 2.5·10⁻³`, the combined removal criterion, `Δt = 0.01 s`, 10 000 iterations,
    /// `‖e_i‖ < 10⁻⁴`, velocity limits 0.2 m/s and 0.7 rad/s; the exact camera and the true depths.
    pub fn paper() -> Self {
        Self {
            tasks: TasksSpec {
                gains: [0.5; 4],
                classical_gain: 0.5,
                interaction: InteractionKind::Exact,
                a_priori_depth_m: None,
                area_depth_m: None,
                fourth_task: FourthTask::default(),
                damping: 0.0,
                adaptive_gain: None,
            },
            avoidance: AvoidanceSpec {
                activation_ratio: 0.1,
                gain: 10.0,
                transition_gain: None,
            },
            controller: ControllerParameters {
                settle_velocity: 0.01,
                prediction_horizon: 0.05,
                removal_threshold: Some(2.5e-3),
                criterion: RemovalCriterion::Combined,
                ..ControllerParameters::default()
            },
            simulation: SimulationParameters {
                period: 0.01,
                max_iterations: 10_000,
                convergence_error: 1e-4,
                image_margin: 0.0,
                max_prismatic_velocity_m_s: 0.2,
                max_revolute_velocity_rad_s: 0.7,
                ..SimulationParameters::default()
            },
            visibility: None,
            measurement: MeasurementParameters::default(),
            depth: None,
        }
    }

    /// Checks the adaptive gain, the controller's thresholds and the simulation parameters (the measurement and the
    /// depth source are checked when a run starts).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] naming `tasks.adaptive_gain` or `controller`, or `controller.allow_removal` when
    /// `false` (the [`RunKind`] decides removal); [`ScenarioError::Simulation`] naming the simulation parameter.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        self.adaptive_gain()?;
        if !self.controller.allow_removal {
            // The run kind decides removal; a `false` here would be read by no run.
            return Err(invalid(
                "controller.allow_removal",
                "the method decides it: the full method removes tasks, the three others do not (the full method \
                 without removal is `stack_gradient`)",
            ));
        }
        self.controller
            .validate()
            .map_err(|e| invalid("controller", e.to_string()))?;
        self.simulation.validate()?;
        Ok(())
    }

    /// `tasks.adaptive_gain`, checked: both gains in [`crate::bounds::GAIN_PER_S`] and [`AdaptiveGain::new`]'s rules.
    pub(super) fn adaptive_gain(&self) -> Result<Option<AdaptiveGain>, ScenarioError> {
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

    /// The scene a run of `experiment` uses: its joint-limit cost with `avoidance.activation_ratio`, the visibility
    /// cost of `visibility`; and the start checked against `simulation` (the target entirely in the image, within
    /// `image_margin`, seen at most at `max_incidence_deg`, D27). Borrowed when the scene is already so.
    ///
    /// # Errors
    /// An invalid ratio or margin, a visibility cost in both the scene and the settings, a start the camera does not
    /// see the target from (each naming its field).
    pub(super) fn scene_for<'e, const N: usize>(
        &self,
        experiment: &'e Experiment<N>,
    ) -> Result<Cow<'e, Scene<N>>, ScenarioError> {
        let mut scene = Cow::Borrowed(&experiment.scene);
        let ratio = self.avoidance.activation_ratio;
        if scene.limits().activation_ratio() != ratio {
            scene = Cow::Owned(scene.into_owned().with_activation_ratio(ratio).map_err(
                |e| match e {
                    SimError::Cost(cost @ CostError::InvalidActivationRatio { .. }) => {
                        invalid("avoidance.activation_ratio", cost.to_string())
                    }
                    other => other.into(),
                },
            )?);
        }
        if let Some(visibility) = self.visibility {
            if scene.visibility().is_some() {
                return Err(invalid(
                    "visibility",
                    "the experiment's scene has a visibility cost already: give it once",
                ));
            }
            let cost = scene
                .visibility_cost(
                    visibility.margin_px,
                    self.simulation.facing_activation_deg(),
                )
                .map_err(|e| invalid("visibility.margin_px", e.to_string()))?;
            scene = Cow::Owned(scene.into_owned().with_visibility(cost));
        }
        let mut workspace = crate::robot::KinematicsWorkspace::new();
        let view = match scene.observe(&mut workspace, &experiment.start) {
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
        Ok(scene)
    }

    /// `measurement` with the true lens of the experiment's camera: its distortion, unless the settings give the
    /// same or none.
    fn measurement_for<const N: usize>(
        &self,
        experiment: &Experiment<N>,
    ) -> Result<MeasurementParameters, ScenarioError> {
        let mut measurement = self.measurement;
        if experiment.lens.is_identity() {
            return Ok(measurement);
        }
        let Ok(lens) = <[f64; 5]>::try_from(experiment.lens.coefficients()) else {
            return Err(invalid(
                "camera",
                format!(
                    "the simulated measurement takes a plumb-bob lens (k1, k2, p1, p2, k3); the experiment's camera has the {} coefficients {:?}",
                    experiment.lens.coefficients().len(),
                    experiment.lens.coefficients()
                ),
            ));
        };
        if measurement.distortion_coefficients == [0.0; 5] {
            measurement.distortion_coefficients = lens;
        } else if measurement.distortion_coefficients != lens {
            return Err(invalid(
                "measurement.distortion_coefficients",
                format!(
                    "{:?} differ from the distortion {lens:?} of the experiment's camera: give the lens once",
                    measurement.distortion_coefficients
                ),
            ));
        }
        Ok(measurement)
    }

    /// The controller's view of the camera when the camera is not exact or a depth source is named: the desired image
    /// points read through the nominal camera (pixels of the true camera, normalised by the believed intrinsics and
    /// undistortion), with their desired depths.
    fn sensing<const N: usize>(
        &self,
        measurement: MeasurementParameters,
        scene: &Scene<N>,
        desired: &[ImagePoint; 4],
    ) -> Result<Option<Sensing<'static>>, ScenarioError> {
        if measurement.is_exact() && self.depth.is_none() {
            return Ok(None);
        }
        let field = |e: &dyn std::fmt::Display| invalid("measurement", e.to_string());
        if let Some(depth) = &self.depth {
            depth
                .validate()
                .map_err(|e| invalid("depth", e.to_string()))?;
        }
        let model = MeasurementModel::new(
            &measurement,
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
            measurement,
            depth: self.depth,
            desired_points,
            true_tasks: &[],
        }))
    }

    /// The run of `kind` on `experiment` with these settings, its records given to `log` ([`Experiment::run_with`]).
    pub(super) fn run<const N: usize>(
        &self,
        experiment: &Experiment<N>,
        kind: RunKind,
        log: &mut dyn RunLog<N>,
    ) -> Result<Run<N>, ScenarioError> {
        self.validate()?;
        let scene = self.scene_for(experiment)?;
        let desired_view = scene.view_from(&experiment.desired_camera_from_target)?;
        let measurement = self.measurement_for(experiment)?;
        let sensing = self.sensing(measurement, &scene, &desired_view.points)?;
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
        let full_method = kind == RunKind::FullMethod;
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
                    if full_method {
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
        let avoid = matches!(
            kind,
            RunKind::StackGradient | RunKind::FullMethod | RunKind::Sns | RunKind::Hqp
        );
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
        // Damping, when asked for, applies to every method; otherwise the full method filters its near-singular levels
        // (D30) and the baselines keep the paper's truncated pseudo-inverse.
        let stack = StackParameters {
            velocity_inverse: match self.tasks.damping {
                0.0 if full_method => self.controller.velocity_inverse(),
                0.0 => VelocityInverse::Truncated,
                damping => VelocityInverse::Damped { damping },
            },
            ..StackParameters::default()
        };
        let law = ControlLaw::with_stack_parameters(stack, mu, kappa)?;
        // The baselines are the paper's laws as they are: no removal, no braking before the limits (D25) and no
        // lock along them (D26).
        let saturate_in_null_space = kind == RunKind::Sns
            || (full_method
                && self.controller.hard_limit_rule == HardLimitRule::SaturateInNullSpace);
        let bounded_law = if saturate_in_null_space {
            Some(BoundedLaw::SaturationInNullSpace)
        } else {
            (kind == RunKind::Hqp).then_some(BoundedLaw::HierarchicalQp)
        };
        let brake_and_lock = full_method && bounded_law.is_none();
        let controller = ControllerParameters {
            allow_removal: full_method,
            braking_rate: if brake_and_lock {
                self.controller.braking_rate
            } else {
                f64::INFINITY
            },
            lock_band: if brake_and_lock {
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
            guard_visibility: full_method,
            // The centroid (first of the paper's tasks) keeps the target in the image.
            protected_tasks: if full_method { &[0] } else { &[] },
            sensing: sensing.as_ref(),
            adaptive_gain,
            reserve_task: full_method,
            bounded_law,
        };
        Ok(simulate_with(
            &scene,
            &tasks,
            drive,
            &experiment.start,
            &self.simulation,
            log,
        )?)
    }
}
