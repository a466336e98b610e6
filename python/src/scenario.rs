//! Scenarios, experiments and runs: `servostack.Scenario` (a scenario file, TOML text or a dict of the same
//! sections), `servostack.Experiment` (the world: from a scenario or from a robot, camera, target, goal and start)
//! and `servostack.Run` (one of the four methods run on it: outcome, events, and the records as NumPy arrays).

use crate::convert::{array1, array2, corners_to_py, from_py, pose_to_py, raise, run_kind, to_py};
use crate::model::{Camera, Robot};
use crate::ScenarioError;
use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use servostack::controller::StackEvent;
use servostack::math::JointVector;
use servostack::nalgebra::Isometry3;
use servostack::scenario::{
    with_joint_count, Experiment as RustExperiment, ForJointCount, RunKind,
    Scenario as RustScenario, ScenarioError as RustScenarioError, Settings,
};
use servostack::servo::Corners;
use servostack::sim::Run as RustRun;
use servostack::target::RectangleTarget;
use std::path::PathBuf;

/// A stack event as a dict: `iteration`, `time` (s), `kind` (`push`, `remove`, `reinsert`, ...), `task` (index),
/// `task_name`, `law_jump` (the jump the law alone would have made).
pub fn event_dict<'py>(
    py: Python<'py>,
    event: &StackEvent,
    task_names: &[String],
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("iteration", event.iteration)?;
    d.set_item("time", event.time)?;
    d.set_item("kind", event.kind.name())?;
    d.set_item("task", event.task)?;
    d.set_item("task_name", task_names.get(event.task))?;
    d.set_item("law_jump", event.law_jump)?;
    Ok(d)
}

/// A scenario file's content: the world (robot, camera, target, desired, start, obstacles) and the method's
/// settings (tasks, avoidance, controller, simulation, ...).
#[pyclass(frozen, module = "servostack")]
pub struct Scenario {
    scenario: RustScenario,
}

impl Scenario {
    pub fn inner(&self) -> &RustScenario {
        &self.scenario
    }

    pub fn joint_count(&self) -> PyResult<usize> {
        self.scenario.joint_count().map_err(raise::<ScenarioError>)
    }
}

/// An [`RustExperiment`] of any joint count.
trait AnyExperiment: Send + Sync {
    fn start(&self) -> &[f64];
    fn desired_joints(&self) -> &[f64];
    fn desired_pose(&self) -> &Isometry3<f64>;
    /// The corners at `q` (`N` values).
    fn corners(&self, q: &[f64]) -> PyResult<Corners>;
    fn run(&self, settings: &Settings, kind: RunKind) -> Result<Run, RustScenarioError>;
}

impl<const N: usize> AnyExperiment for RustExperiment<N> {
    fn start(&self) -> &[f64] {
        self.start.as_slice()
    }

    fn desired_joints(&self) -> &[f64] {
        self.desired_joints.as_slice()
    }

    fn desired_pose(&self) -> &Isometry3<f64> {
        &self.desired_camera_from_target
    }

    fn corners(&self, q: &[f64]) -> PyResult<Corners> {
        if q.len() != N {
            return Err(PyValueError::new_err(format!(
                "q: {} values, expected {N}",
                q.len()
            )));
        }
        RustExperiment::corners(self, &JointVector::<N>::from_column_slice(q))
            .map_err(raise::<ScenarioError>)
    }

    fn run(&self, settings: &Settings, kind: RunKind) -> Result<Run, RustScenarioError> {
        RustExperiment::run(self, settings, kind).map(Run::from)
    }
}

/// [`RustScenario::experiment`] for the scenario's joint count.
struct FromScenario<'a>(&'a RustScenario);

impl ForJointCount for FromScenario<'_> {
    type Output = Result<Box<dyn AnyExperiment>, RustScenarioError>;
    fn call<const N: usize>(self) -> Self::Output {
        Ok(Box::new(self.0.experiment::<N>()?))
    }
}

/// [`RustExperiment::builder`] for the robot's joint count.
struct FromModels<'a> {
    robot: &'a Robot,
    camera: &'a Camera,
    target: RectangleTarget,
    goal_joints: Vec<f64>,
    goal_pose: Isometry3<f64>,
    start: Vec<f64>,
}

impl ForJointCount for FromModels<'_> {
    type Output = PyResult<Box<dyn AnyExperiment>>;
    fn call<const N: usize>(self) -> Self::Output {
        let joints = |name: &str, values: &[f64]| {
            if values.len() == N {
                Ok(JointVector::<N>::from_column_slice(values))
            } else {
                Err(PyValueError::new_err(format!(
                    "{name}: {} values for a robot with {N} joints",
                    values.len()
                )))
            }
        };
        let chain = self.robot.chain::<N>()?.clone();
        let experiment =
            RustExperiment::builder(chain, self.robot.mount, self.camera.camera, self.target)
                .goal(joints("goal_joints", &self.goal_joints)?, self.goal_pose)
                .start(joints("start", &self.start)?)
                .build()
                .map_err(raise::<ScenarioError>)?;
        Ok(Box::new(experiment))
    }
}

#[pymethods]
impl Scenario {
    /// Reads a scenario file (TOML); relative paths in it are resolved against its directory.
    #[staticmethod]
    fn from_file(path: PathBuf) -> PyResult<Self> {
        let scenario = RustScenario::from_file(path).map_err(raise::<ScenarioError>)?;
        Ok(Self { scenario })
    }

    /// Parses scenario text (TOML); relative paths are resolved against `base_dir` (or the working directory).
    #[staticmethod]
    #[pyo3(signature = (text, base_dir = None))]
    fn from_toml(text: &str, base_dir: Option<PathBuf>) -> PyResult<Self> {
        let scenario = RustScenario::from_toml_str(text, base_dir.as_deref())
            .map_err(raise::<ScenarioError>)?;
        Ok(Self { scenario })
    }

    /// A scenario from a dict of the file's sections (`to_dict()`'s shape); unknown keys are errors.
    #[staticmethod]
    #[pyo3(signature = (sections, base_dir = None))]
    fn from_dict(sections: &Bound<'_, PyAny>, base_dir: Option<PathBuf>) -> PyResult<Self> {
        let mut scenario: RustScenario = from_py(sections, "scenario")?;
        scenario.base_dir = base_dir;
        Ok(Self { scenario })
    }

    /// The scenario's sections as a dict (edit it and pass it to `from_dict` to change a field).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.scenario)
    }

    #[getter]
    fn name(&self) -> &str {
        &self.scenario.name
    }

    #[getter]
    fn description(&self) -> &str {
        &self.scenario.description
    }

    /// The control period `Δt` of the simulation (s).
    #[getter]
    fn period(&self) -> f64 {
        self.scenario.simulation.period
    }

    /// The number of joints of the scenario's robot.
    #[getter(joint_count)]
    fn py_joint_count(&self) -> PyResult<usize> {
        self.joint_count()
    }

    /// The world of this scenario, every field checked, with the scenario's settings for its runs.
    fn experiment(&self) -> PyResult<Experiment> {
        let experiment = with_joint_count(self.joint_count()?, FromScenario(&self.scenario))
            .map_err(raise::<ScenarioError>)?
            .map_err(raise::<ScenarioError>)?;
        Ok(Experiment {
            experiment,
            settings: self.scenario.settings(),
            joints: self.joint_count()?,
        })
    }

    /// Runs a method (`classical`, `stack`, `stack_gradient`, `full_method`) on this scenario (`Scenario::run`).
    fn run(&self, py: Python<'_>, method: &str) -> PyResult<Run> {
        self.experiment()?.run(py, method)
    }

    fn __repr__(&self) -> String {
        format!("Scenario({:?})", self.scenario.name)
    }
}

/// The world of a run: robot, camera, target placed where the camera sees it at the goal, goal and start; run with
/// the settings of its scenario (the paper's when built from models).
#[pyclass(frozen, module = "servostack")]
pub struct Experiment {
    experiment: Box<dyn AnyExperiment>,
    settings: Settings,
    joints: usize,
}

#[pymethods]
impl Experiment {
    /// The experiment of these models: at `goal_joints` the camera sees the `target` rectangle `(width_m,
    /// height_m)` at `goal_pose` (`cdMo`, 4 × 4); the robot starts at `start`. Runs with the paper's settings.
    #[new]
    fn new(
        robot: &Robot,
        camera: &Camera,
        target: (f64, f64),
        goal_joints: &Bound<'_, PyAny>,
        goal_pose: &Bound<'_, PyAny>,
        start: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let models = FromModels {
            robot,
            camera,
            target: RectangleTarget::new(target.0, target.1).map_err(raise::<ScenarioError>)?,
            goal_joints: crate::convert::vector(goal_joints, "goal_joints")?,
            goal_pose: crate::convert::pose(goal_pose, "goal_pose")?,
            start: crate::convert::vector(start, "start")?,
        };
        let experiment =
            with_joint_count(robot.joints(), models).map_err(raise::<ScenarioError>)??;
        Ok(Self {
            experiment,
            settings: Settings::paper(),
            joints: robot.joints(),
        })
    }

    /// The start configuration (rad, m).
    #[getter]
    fn start<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.experiment.start())
    }

    /// The desired joint configuration (rad, m).
    #[getter]
    fn desired_joints<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.experiment.desired_joints())
    }

    /// The target's pose in the desired camera frame (`cdMo`, 4 × 4).
    #[getter]
    fn desired_pose<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        pose_to_py(py, self.experiment.desired_pose())
    }

    #[getter]
    fn joint_count(&self) -> usize {
        self.joints
    }

    /// The four corners (px) the experiment's camera images at `q`: four `(u, v)` tuples, `None` for a corner
    /// behind the camera or outside the image (a simulated detector for a `VisualServo` loop).
    fn corners<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let mut buffer = [0.0; servostack::scenario::MAX_JOINTS];
        let q_values = &mut buffer[..self.joints];
        crate::convert::read_vector(q, q_values, "q")?;
        corners_to_py(py, &self.experiment.corners(q_values)?)
    }

    /// Runs a method (`classical`, `stack`, `stack_gradient`, `full_method`) on this experiment (the GIL is
    /// released meanwhile).
    fn run(&self, py: Python<'_>, method: &str) -> PyResult<Run> {
        let kind = run_kind(method)?;
        let (experiment, settings) = (&self.experiment, &self.settings);
        py.detach(|| experiment.run(settings, kind))
            .map_err(raise::<ScenarioError>)
    }

    fn __repr__(&self) -> String {
        format!("Experiment({} joints)", self.joints)
    }
}

/// One run: its outcome, the controller's events, and one record per iteration (every iteration up to 65 536,
/// evenly spaced ones beyond).
#[pyclass(frozen, module = "servostack")]
pub struct Run {
    outcome: String,
    outcome_detail: String,
    period: f64,
    task_names: Vec<String>,
    iterations: usize,
    events: Vec<StackEvent>,
    joints: usize,
    /// Per record: time, then `q`, `q̇`, task errors and the image points (normalised x, y of each corner).
    times: Vec<f64>,
    q: Vec<f64>,
    velocity: Vec<f64>,
    task_errors: Vec<f64>,
    image: Vec<f64>,
    cost: Vec<f64>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    stacked_at_end: Vec<String>,
    max_velocity_jump: f64,
    min_normalized_margin: f64,
}

impl<const N: usize> From<RustRun<N>> for Run {
    fn from(run: RustRun<N>) -> Self {
        let records = &run.records;
        let flat = |f: &dyn Fn(&servostack::sim::Record<N>) -> Vec<f64>| -> Vec<f64> {
            records.iter().flat_map(f).collect()
        };
        Self {
            outcome: run.outcome.name().to_owned(),
            outcome_detail: format!("{:?}", run.outcome),
            period: run.period,
            iterations: run.iterations(),
            joints: N,
            times: records.iter().map(|r| r.time).collect(),
            q: flat(&|r| r.q.as_slice().to_vec()),
            velocity: flat(&|r| r.velocity.as_slice().to_vec()),
            task_errors: flat(&|r| r.task_errors.clone()),
            image: flat(&|r| r.image.iter().flat_map(|p| [p.x, p.y]).collect()),
            cost: records.iter().map(|r| r.cost).collect(),
            lower: run.limits.lower().as_slice().to_vec(),
            upper: run.limits.upper().as_slice().to_vec(),
            stacked_at_end: run.stacked_at_end().iter().map(|s| s.to_string()).collect(),
            max_velocity_jump: run.max_velocity_jump(),
            min_normalized_margin: run.min_normalized_margin(),
            task_names: run.task_names,
            events: run.events,
        }
    }
}

impl Run {
    fn rows(&self) -> usize {
        self.times.len()
    }
}

#[pymethods]
impl Run {
    /// `converged`, `off_goal`, `joint_limit`, `feature_lost`, `max_iterations`, `stalled`, `image_degenerate` or
    /// `collision`.
    #[getter]
    fn outcome(&self) -> &str {
        &self.outcome
    }

    /// The outcome with its fields (the joint, the tasks stacked, the reason, ...), as Rust prints it.
    #[getter]
    fn outcome_detail(&self) -> &str {
        &self.outcome_detail
    }

    /// The control period `Δt` (s).
    #[getter]
    fn period(&self) -> f64 {
        self.period
    }

    #[getter]
    fn task_names(&self) -> Vec<String> {
        self.task_names.clone()
    }

    /// The number of iterations run (the index of the last one, plus one).
    #[getter]
    fn iterations(&self) -> usize {
        self.iterations
    }

    /// The stack events: dicts of `iteration`, `time`, `kind`, `task`, `task_name`, `law_jump`.
    #[getter]
    fn events<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.events
            .iter()
            .map(|event| event_dict(py, event, &self.task_names))
            .collect()
    }

    /// The time of each record (s), shape `(T,)`.
    #[getter]
    fn times<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.times)
    }

    /// The joint positions, shape `(T, N)`.
    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        array2(py, self.rows(), self.joints, self.q.clone())
    }

    /// The joint velocities sent, shape `(T, N)`.
    #[getter]
    fn velocity<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        array2(py, self.rows(), self.joints, self.velocity.clone())
    }

    /// `‖e_i‖` of every task (stacked or not), shape `(T, tasks)`.
    #[getter]
    fn task_errors<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let tasks = self.task_errors.len() / self.rows().max(1);
        array2(py, self.rows(), tasks, self.task_errors.clone())
    }

    /// The four image points (normalised `x, y`), shape `(T, 4, 2)`.
    #[getter]
    fn image<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let flat = array2(py, self.rows(), 8, self.image.clone())?;
        flat.call_method1("reshape", (self.rows(), 4, 2))
    }

    /// `h(q)` of the joint-limit cost, shape `(T,)`.
    #[getter]
    fn cost<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.cost)
    }

    /// The joint limits `(lower, upper)`, each of shape `(N,)`.
    #[getter]
    fn limits<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>) {
        (array1(py, &self.lower), array1(py, &self.upper))
    }

    /// The joint positions normalised into their limits (0 at the lower, 1 at the upper), shape `(T, N)`: the
    /// paper's figures.
    #[getter]
    fn normalized_q<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let n = self.joints;
        let values = self
            .q
            .iter()
            .enumerate()
            .map(|(i, q)| (q - self.lower[i % n]) / (self.upper[i % n] - self.lower[i % n]))
            .collect();
        array2(py, self.rows(), n, values)
    }

    /// The names of the tasks stacked at the end.
    #[getter]
    fn stacked_at_end(&self) -> Vec<String> {
        self.stacked_at_end.clone()
    }

    /// The largest jump of the velocity sent at a stack change (D1 makes it zero up to rounding).
    #[getter]
    fn max_velocity_jump(&self) -> f64 {
        self.max_velocity_jump
    }

    /// The smallest distance to a joint limit over the run, as a fraction of the joint's range.
    #[getter]
    fn min_normalized_margin(&self) -> f64 {
        self.min_normalized_margin
    }

    fn __repr__(&self) -> String {
        format!(
            "Run({}, {} iterations, {} events)",
            self.outcome,
            self.iterations,
            self.events.len()
        )
    }
}
