//! `servostack.VisualServo`: the Rust façade [`servostack::servo::VisualServo`] behind one call per control period,
//! `step(t, corners, q)`, which returns the joint velocity to send as a NumPy array.

use crate::convert::{array1, corners, from_py, raise, read_vector};
use crate::model::{Camera, Robot};
use crate::scenario::{event_dict, Scenario};
use crate::{ScenarioError, ServoError};
use numpy::PyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use servostack::camera::CalibratedCamera;
use servostack::controller::{ControllerParameters, StackEvent};
use servostack::depth::DepthSource;
use servostack::math::JointVector;
use servostack::scenario::{with_joint_count, Experiment, ForJointCount, MAX_JOINTS};
use servostack::servo::{
    Corners, DesiredImage, ServoConfig, ServoError as RustServoError, ServoMethod, TaskChoice,
    VisualServo as RustServo,
};
use servostack::target::RectangleTarget;
use servostack::task::Task;
use servostack::visual_task::{FourthTask, VisualContext};

/// What one period gave, read from a servo of any joint count.
struct Output<'a> {
    velocity: &'a [f64],
    unscaled_velocity: &'a [f64],
    scale: f64,
    error_norm: f64,
    task_errors: &'a [f64],
    task_gains: &'a [f64],
    stacked: &'a [usize],
    event: Option<&'static str>,
    held: bool,
    locked: &'a [bool],
    stack_velocity_norm: f64,
    converged: bool,
    depths: [f64; 4],
    camera_twist: &'a [f64],
    new_frame: bool,
    iteration: usize,
}

/// A [`RustServo`] of any joint count.
trait AnyServo: Send + Sync {
    /// One period ([`RustServo::step`], or [`RustServo::step_normalized`] when `normalized`); `q` has `N` values.
    fn step(
        &mut self,
        time: f64,
        corners: &Corners,
        q: &[f64],
        normalized: bool,
    ) -> Result<(), RustServoError>;
    fn output(&self) -> Output<'_>;
    fn events(&self) -> &[StackEvent];
    fn task_names(&self) -> Vec<String>;
}

impl<const N: usize> AnyServo for RustServo<N> {
    fn step(
        &mut self,
        time: f64,
        corners: &Corners,
        q: &[f64],
        normalized: bool,
    ) -> Result<(), RustServoError> {
        let q = JointVector::<N>::from_column_slice(q);
        if normalized {
            self.step_normalized(time, corners, &q).map(|_| ())
        } else {
            RustServo::step(self, time, corners, &q).map(|_| ())
        }
    }

    fn output(&self) -> Output<'_> {
        let o = self.last_output();
        Output {
            velocity: o.velocity.as_slice(),
            unscaled_velocity: o.unscaled_velocity.as_slice(),
            scale: o.scale,
            error_norm: o.error_norm,
            task_errors: &o.task_errors[..o.task_count],
            task_gains: &o.task_gains[..o.task_count],
            stacked: o.stacked(),
            event: o.event.map(|kind| kind.name()),
            held: o.held,
            locked: &o.locked,
            stack_velocity_norm: o.stack_velocity_norm,
            converged: o.converged,
            depths: o.depths,
            camera_twist: o.camera_twist.as_slice(),
            new_frame: o.new_frame,
            iteration: o.iteration,
        }
    }

    fn events(&self) -> &[StackEvent] {
        self.controller().events()
    }

    fn task_names(&self) -> Vec<String> {
        self.tasks()
            .iter()
            .map(|task| Task::<N, VisualContext<'_, N>>::name(task).to_owned())
            .collect()
    }
}

/// Every parameter of a [`ServoConfig`] but the robot's chain.
struct Parts {
    mount: servostack::camera::EyeInHand,
    camera: CalibratedCamera,
    target: RectangleTarget,
    desired: DesiredImage,
    tasks: TaskChoice,
    transition_gain: Option<f64>,
    avoidance_gain: f64,
    activation_ratio: f64,
    controller: ControllerParameters,
    depth: DepthSource,
    /// Per joint; `None`: no limit.
    max_joint_velocity: Option<Vec<f64>>,
    /// Per joint; `None`: no limit.
    max_joint_acceleration: Option<Vec<f64>>,
    convergence_error: f64,
    protect_centroid: bool,
    method: ServoMethod,
    control_period_s: Option<f64>,
}

impl Parts {
    fn config<const N: usize>(
        self,
        chain: servostack::robot::SerialChain<N>,
    ) -> PyResult<ServoConfig<N>> {
        let mut config =
            ServoConfig::new(chain, self.mount, self.camera, self.target, self.desired);
        config.tasks = self.tasks;
        config.transition_gain = self.transition_gain;
        config.avoidance_gain = self.avoidance_gain;
        config.activation_ratio = self.activation_ratio;
        config.controller = self.controller;
        config.depth = self.depth;
        config.convergence_error = self.convergence_error;
        config.protect_centroid = self.protect_centroid;
        config.method = self.method;
        config.control_period_s = self.control_period_s;
        if let Some(limits) = self.max_joint_velocity {
            config.max_joint_velocity = per_joint(&limits, "max_joint_velocity")?;
        }
        if let Some(limits) = self.max_joint_acceleration {
            config.max_joint_acceleration = per_joint(&limits, "max_joint_acceleration")?;
        }
        Ok(config)
    }
}

/// One value per joint of a robot with `N` joints, or a `ValueError` naming the parameter `name`.
fn per_joint<const N: usize>(values: &[f64], name: &str) -> PyResult<JointVector<N>> {
    if values.len() != N {
        return Err(PyValueError::new_err(format!(
            "{name}: {} values for a robot with {N} joints",
            values.len()
        )));
    }
    Ok(JointVector::from_column_slice(values))
}

/// [`RustServo::new`] for a robot of a joint count known at run time.
struct Build<'a> {
    robot: &'a Robot,
    parts: Parts,
}

impl ForJointCount for Build<'_> {
    type Output = PyResult<Box<dyn AnyServo>>;
    fn call<const N: usize>(self) -> Self::Output {
        let config = self.parts.config(self.robot.chain::<N>()?.clone())?;
        Ok(Box::new(
            RustServo::new(config).map_err(raise::<ServoError>)?,
        ))
    }
}

/// The servo of a scenario's full method: its world and settings, as the simulation of `full_method` runs them.
struct FromScenario<'a>(&'a servostack::scenario::Scenario);

impl ForJointCount for FromScenario<'_> {
    type Output = PyResult<Box<dyn AnyServo>>;
    fn call<const N: usize>(self) -> Self::Output {
        let experiment = self.0.experiment::<N>().map_err(raise::<ScenarioError>)?;
        let config = scenario_config(self.0, &experiment)?;
        Ok(Box::new(
            RustServo::new(config).map_err(raise::<ServoError>)?,
        ))
    }
}

/// The façade's configuration of the full method of `scenario` on its `experiment`: the scenario's camera, target,
/// desired pose, gains, `κ`, `ρ`, `μ`, controller, velocity and acceleration limits and convergence threshold, with the depths from
/// the target's pose seen in the image (the simulation's true depths, up to rounding). What the façade does not model
/// (obstacles, a visibility cost, camera errors, damping, a priori depths, an adaptive gain) is an error.
fn scenario_config<const N: usize>(
    scenario: &servostack::scenario::Scenario,
    experiment: &Experiment<N>,
) -> PyResult<ServoConfig<N>> {
    let settings = scenario.settings();
    let t = &settings.tasks;
    let unsupported = [
        ("obstacles", !scenario.obstacles.is_empty()),
        ("visibility", settings.visibility.is_some()),
        ("measurement", !settings.measurement.is_exact()),
        ("tasks.damping", t.damping != 0.0),
        ("tasks.a_priori_depth_m", t.a_priori_depth_m.is_some()),
        ("tasks.area_depth_m", t.area_depth_m.is_some()),
        ("tasks.adaptive_gain", t.adaptive_gain.is_some()),
    ];
    if let Some((field, _)) = unsupported.iter().find(|(_, set)| *set) {
        return Err(ServoError::new_err(format!(
            "the servo does not model the scenario's `{field}`: run the scenario instead"
        )));
    }
    let scene = &experiment.scene;
    // The robot's velocity and acceleration limits per joint, as the simulation takes them.
    let motion = settings.simulation.motion_limits(scene.chain());
    let camera = CalibratedCamera {
        intrinsics: *scene.intrinsics(),
        distortion: experiment.lens,
    };
    let parts = Parts {
        mount: *scene.mount(),
        camera,
        target: *scene.target(),
        desired: DesiredImage::Pose(experiment.desired_camera_from_target),
        tasks: TaskChoice::Sequence {
            gains: t.gains,
            fourth: t.fourth_task,
        },
        transition_gain: settings.avoidance.transition_gain,
        avoidance_gain: settings.avoidance.gain,
        activation_ratio: settings.avoidance.activation_ratio,
        controller: settings.controller,
        depth: settings.depth.unwrap_or(DepthSource::TargetPose),
        max_joint_velocity: Some(motion.max_velocity.iter().copied().collect()),
        max_joint_acceleration: Some(motion.max_acceleration.iter().copied().collect()),
        convergence_error: settings.simulation.convergence_error,
        protect_centroid: true,
        method: ServoMethod::FullMethod,
        // The scenario's period sizes the box of its `hard_limit_rule = "saturate_in_null_space"`, as in its runs.
        control_period_s: Some(settings.simulation.period),
    };
    let mut config = parts.config(scene.chain().clone())?;
    config.interaction = t.interaction.into();
    Ok(config)
}

/// A depth source: `"desired"`, `"target_pose"`, a constant depth (m), or the serde form as a dict
/// (`{"kind": "estimated", "initial_depth_m": 0.5, "memory_s": 1.0, "window_frames": 10}`).
fn depth_source(value: &Bound<'_, PyAny>) -> PyResult<DepthSource> {
    if let Ok(depth_m) = value.extract::<f64>() {
        return Ok(DepthSource::Constant { depth_m });
    }
    if let Ok(kind) = value.cast::<PyString>() {
        let dict = PyDict::new(value.py());
        dict.set_item("kind", kind)?;
        return from_py(dict.as_any(), "depth");
    }
    from_py(value, "depth")
}

/// The servo: robot, camera, target and parameters, built once; one [`VisualServo::step`] per control period.
#[pyclass(module = "servostack")]
pub struct VisualServo {
    servo: Box<dyn AnyServo>,
    joints: usize,
    /// `q` of the period being stepped, read without allocating.
    q: [f64; MAX_JOINTS],
}

impl VisualServo {
    fn of(servo: Box<dyn AnyServo>, joints: usize) -> Self {
        Self {
            servo,
            joints,
            q: [0.0; MAX_JOINTS],
        }
    }

    fn period(
        &mut self,
        time: f64,
        corners_value: &Bound<'_, PyAny>,
        q: &Bound<'_, PyAny>,
        normalized: bool,
    ) -> PyResult<()> {
        let corners = corners(corners_value)?;
        let n = self.joints;
        read_vector(q, &mut self.q[..n], "q")?;
        let q = &self.q[..n];
        self.servo
            .step(time, &corners, q, normalized)
            .map_err(raise::<ServoError>)
    }
}

#[pymethods]
impl VisualServo {
    /// The servo of `robot` (a `Robot`) seen through `camera` (a `Camera`) looking at a `target` rectangle
    /// `(width_m, height_m)`, driven to `desired_pose` (`cdMo`, 4 × 4) or to taught `desired_pixels` (four `(u, v)`)
    /// at `desired_depth` (m). `tasks` is `"sequence"` (the paper's four tasks, gains `gains`, stacked by the
    /// controller) or `"classical"` (one task of six features, gain `classical_gain`). `depth`: `"desired"`,
    /// `"target_pose"`, a constant (m) or a dict. `controller`: the `[controller]` keys of a scenario file, as a
    /// dict. `method`: `"full_method"` (the paper's), `"sns"` (saturation in the null space) or `"hqp"` (the
    /// hierarchical QP cascade), the last two with `control_period` (s), the loop's period that sizes their box.
    /// `max_joint_velocity` (rad/s, m/s) and `max_joint_acceleration` (rad/s², m/s²): one value per joint, `> 0`,
    /// `inf` for none (default: no limit). Every other parameter as `ServoConfig`'s field of the same name.
    #[new]
    #[pyo3(signature = (
        robot, camera, target, desired_pose = None, *, desired_pixels = None, desired_depth = None,
        tasks = "sequence", gains = [0.5; 4], classical_gain = 0.5, depth = None, avoidance_gain = 10.0,
        activation_ratio = 0.1, transition_gain = None, max_joint_velocity = None,
        max_joint_acceleration = None, convergence_error = 1e-4,
        controller = None, protect_centroid = true, method = "full_method", control_period = None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        robot: &Robot,
        camera: &Camera,
        target: (f64, f64),
        desired_pose: Option<&Bound<'_, PyAny>>,
        desired_pixels: Option<[(f64, f64); 4]>,
        desired_depth: Option<f64>,
        tasks: &str,
        gains: [f64; 4],
        classical_gain: f64,
        depth: Option<&Bound<'_, PyAny>>,
        avoidance_gain: f64,
        activation_ratio: f64,
        transition_gain: Option<f64>,
        max_joint_velocity: Option<&Bound<'_, PyAny>>,
        max_joint_acceleration: Option<&Bound<'_, PyAny>>,
        convergence_error: f64,
        controller: Option<&Bound<'_, PyAny>>,
        protect_centroid: bool,
        method: &str,
        control_period: Option<f64>,
    ) -> PyResult<Self> {
        let desired = match (desired_pose, desired_pixels, desired_depth) {
            (Some(pose), None, None) => {
                DesiredImage::Pose(crate::convert::pose(pose, "desired_pose")?)
            }
            (None, Some(pixels), Some(depth_m)) => DesiredImage::Pixels { pixels, depth_m },
            _ => {
                return Err(PyValueError::new_err(
                    "give desired_pose, or desired_pixels with desired_depth",
                ))
            }
        };
        let fourth = FourthTask::Auto;
        let tasks = match tasks {
            "sequence" => TaskChoice::Sequence { gains, fourth },
            "classical" => TaskChoice::Classical {
                gain: classical_gain,
                fourth,
            },
            other => {
                return Err(PyValueError::new_err(format!(
                    "tasks = {other:?}: expected \"sequence\" or \"classical\""
                )))
            }
        };
        let method = match method {
            "full_method" => ServoMethod::FullMethod,
            "sns" => ServoMethod::SaturationInNullSpace,
            "hqp" => ServoMethod::HierarchicalQp,
            other => {
                return Err(PyValueError::new_err(format!(
                    "method = {other:?}: expected \"full_method\", \"sns\" or \"hqp\""
                )))
            }
        };
        let target = RectangleTarget::new(target.0, target.1).map_err(raise::<ServoError>)?;
        let parts = Parts {
            mount: robot.mount,
            camera: camera.camera,
            target,
            desired,
            tasks,
            transition_gain,
            avoidance_gain,
            activation_ratio,
            controller: match controller {
                Some(c) => from_py(c, "controller")?,
                None => ControllerParameters::default(),
            },
            depth: match depth {
                Some(d) => depth_source(d)?,
                None => DepthSource::Desired,
            },
            max_joint_velocity: max_joint_velocity
                .map(|v| crate::convert::vector(v, "max_joint_velocity"))
                .transpose()?,
            max_joint_acceleration: max_joint_acceleration
                .map(|v| crate::convert::vector(v, "max_joint_acceleration"))
                .transpose()?,
            convergence_error,
            protect_centroid,
            method,
            control_period_s: control_period,
        };
        let servo = with_joint_count(robot.joints(), Build { robot, parts })
            .map_err(raise::<ServoError>)??;
        Ok(Self::of(servo, robot.joints()))
    }

    /// The servo of a scenario's full method (its world and settings), with the depths from the target's pose in
    /// the image: driven by the scenario's `experiment().corners(q)`, it runs as `scenario.run("full_method")`.
    #[staticmethod]
    fn from_scenario(scenario: &Scenario) -> PyResult<Self> {
        let joints = scenario.joint_count()?;
        let servo = with_joint_count(joints, FromScenario(scenario.inner()))
            .map_err(raise::<ScenarioError>)??;
        Ok(Self::of(servo, joints))
    }

    /// One period at time `t` (s, strictly increasing) with the measured `corners` (px: a (4, 2) array, or four
    /// `(u, v)` or `None`) and joint positions `q` (rad, m): returns the joint velocity to send (rad/s, m/s). A bad
    /// period raises `ServoError` and leaves the servo as it was (hold the last velocity).
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        t: f64,
        corners: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.period(t, corners, q, false)?;
        Ok(array1(py, self.servo.output().velocity))
    }

    /// As `step`, with corners already undistorted and normalised (`x = X/Z`, `y = Y/Z`).
    fn step_normalized<'py>(
        &mut self,
        py: Python<'py>,
        t: f64,
        corners: &Bound<'py, PyAny>,
        q: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.period(t, corners, q, true)?;
        Ok(array1(py, self.servo.output().velocity))
    }

    /// Whether the last accepted period converged (every task stacked and achieved, corners at their goal).
    #[getter]
    fn converged(&self) -> bool {
        self.servo.output().converged
    }

    /// The number of joints.
    #[getter]
    fn joint_count(&self) -> usize {
        self.joints
    }

    /// The tasks' names, in priority order.
    #[getter]
    fn task_names(&self) -> Vec<String> {
        self.servo.task_names()
    }

    /// The last accepted period's output, as a dict (arrays for vectors; `event` is `None` or the change's name).
    #[getter]
    fn output<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let o = self.servo.output();
        let d = PyDict::new(py);
        d.set_item("velocity", array1(py, o.velocity))?;
        d.set_item("unscaled_velocity", array1(py, o.unscaled_velocity))?;
        d.set_item("scale", o.scale)?;
        d.set_item("error_norm", o.error_norm)?;
        d.set_item("task_errors", array1(py, o.task_errors))?;
        d.set_item("task_gains", array1(py, o.task_gains))?;
        d.set_item("stacked", o.stacked.to_vec())?;
        d.set_item("event", o.event)?;
        d.set_item("held", o.held)?;
        d.set_item("locked", o.locked.to_vec())?;
        d.set_item("stack_velocity_norm", o.stack_velocity_norm)?;
        d.set_item("converged", o.converged)?;
        d.set_item("depths", array1(py, &o.depths))?;
        d.set_item("camera_twist", array1(py, o.camera_twist))?;
        d.set_item("new_frame", o.new_frame)?;
        d.set_item("iteration", o.iteration)?;
        Ok(d)
    }

    /// The controller's stack events so far (as `Run.events`).
    #[getter]
    fn events<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let names = self.servo.task_names();
        self.servo
            .events()
            .iter()
            .map(|event| event_dict(py, event, &names))
            .collect()
    }

    fn __repr__(&self) -> String {
        format!(
            "VisualServo({} joints, tasks {:?})",
            self.joints,
            self.servo.task_names()
        )
    }
}
