//! The simulation loop: how the tasks are driven ([`Drive`]) and [`simulate`] / [`simulate_with`], which observe,
//! evaluate the tasks, step the controller, limit and integrate the velocity, and end the run with its outcome.

use super::outcome::budget_outcome;
use super::run::Totals;
use super::sensing::SensingState;
use super::{
    incidence_reason, Outcome, Record, Run, RunLog, Scene, Sensing, SimError, SimulationParameters,
    View,
};
use crate::avoidance::{image_braking_scale, Cost, CostError};
use crate::camera::{CameraError, EyeInHand};
use crate::controller::{ControllerError, ControllerParameters, StackController, StackEvent};
use crate::feature::Observation;
use crate::law::sns::SnsBounds;
use crate::law::{BoundedLaw, ControlLaw, LawError};
use crate::math::{JointVector, KinematicJacobian};
use crate::robot::KinematicsWorkspace;
use crate::servo::AdaptiveGain;
use crate::task::{Task, TaskValue};
use crate::visual_task::{VisualContext, VisualTask};

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
/// [`SummaryOnly`](super::SummaryOnly), [`Decimated`](super::Decimated) or [`JsonLines`](super::JsonLines), a run of
/// any length uses bounded memory, and the [`Run`]'s summary (outcome, iterations, last record, velocity steps,
/// continuity, margins) is the same as with every record kept.
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
        .with_joint_limits(scene.limits.clone())?
        .with_goal_error(parameters.convergence_error)?;
    if drive.reserve_task {
        controller = controller.with_reserve_task()?;
    }
    let motion = parameters.motion_limits(&scene.chain);
    if let Some(law) = drive.bounded_law {
        let bounds = SnsBounds::new(scene.limits.clone(), motion.max_velocity, parameters.period)
            .and_then(|bounds| bounds.with_max_acceleration(motion.max_acceleration))
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
    let mut totals = Totals::new(&scene.limits, start, &motion, parameters.period);
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
        // The camera Jacobian the controller believes in, with a real camera.
        let believed_jacobian = match &sensing {
            Some(sensing) => Some(believed_camera_jacobian(
                scene,
                &sensing.believed,
                &mut workspace,
                &q,
            )?),
            None => None,
        };
        // The braking before the border of the image (D25), on the corners and the camera Jacobian the controller
        // sees; then the robot's velocity limits, the braking before a hard limit (D25) and the acceleration limits
        // (D31), as the servo façade shapes the velocity it sends; the controller told what was sent.
        let braking_rate = controller.parameters().braking_rate;
        let image_scale = if controller.parameters().brake_at_image_border {
            let (points, jacobian) = match (&sensing, &believed_jacobian) {
                (Some(sensing), Some(jacobian)) => (&sensing.points, jacobian),
                _ => (&view.points, &view.camera_jacobian),
            };
            image_braking_scale(
                &scene.intrinsics,
                parameters.image_margin,
                points,
                &(jacobian * step.velocity),
                braking_rate,
            )
        } else {
            1.0
        };
        let velocity = motion
            .shape(
                &scene.limits,
                &q,
                &(step.velocity * image_scale),
                &totals.last_sent,
                braking_rate,
                parameters.period,
            )
            .velocity;
        controller.set_sent_velocity(&velocity)?;
        record.velocity = velocity;
        record.sent = true;
        // The stack that produced the velocity sent (a change made at this iteration included).
        record.stacked.clear();
        record.stacked.extend_from_slice(controller.stacked());
        record.predicted_cost = step.predicted_cost;
        record.criteria.extend_from_slice(controller.criteria());
        if let (Some(sensing), Some(jacobian)) = (&mut sensing, &believed_jacobian) {
            sensing.sent(jacobian, &velocity, parameters.period);
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
