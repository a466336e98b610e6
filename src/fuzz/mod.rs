//! The fuzz harness of the crate ([D17](crate::theory#d17)): structured mutations of the shipped URDFs and scenario
//! files, of mesh and calibration files ([`readers`]), random inputs to the public control-step functions and random
//! sequences of good and corrupted frames through the façade ([`servo_sequence`]), each run through load → validate →
//! (when accepted) a few kinematics, cost and control steps, on a worker thread of known stack size, with a time
//! limit.
//!
//! A case passes when it returns (no hang), does not panic and returns no non-finite number, nor a value that
//! contradicts its definition, inside an `Ok`: a rejected input is a pass, as long as its error is an error. `tests/suite/fuzz.rs` runs a bounded, seeded number of cases
//! and replays every input that once failed (`tests/data/fuzz_regressions/`); `examples/fuzz.rs` runs for as long as
//! asked and saves new failures there. Not part of the crate's API (hidden from its docs): it is here so that the
//! test and the example share it.

pub mod mutate;
pub mod readers;
pub mod servo_sequence;

pub use readers::{calibration_case, mesh_case};

use crate::avoidance::{Cost, JointLimits};
use crate::controller::{ControllerParameters, StackController};
use crate::law::{control_step, ControlLaw, ControlWorkspace, StackChange};
use crate::math::{all_finite, JointVector};
use crate::robot::{builtin, KinematicsWorkspace, RobotError, SerialChain};
use crate::scenario::{RunKind, Scenario, ScenarioError};
use crate::sim::{Record, RunLog};
use crate::task::{TaskJacobian, TaskValue};
use mutate::Syntax;
use nalgebra::DVector;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use std::panic::AssertUnwindSafe;
use std::sync::mpsc;
use std::time::Duration;

/// The stack size of the worker thread (bytes): Rust's default for spawned threads. The URDF depth limit is checked
/// safe for it by the cases that deepen nesting far beyond the limit.
pub const WORKER_STACK_BYTES: usize = 2 << 20;

/// The simulation budget of an accepted scenario case (iterations): enough to push every task and step the
/// controller, short enough for thousands of cases a second.
pub const SCENARIO_ITERATIONS: usize = 20;

/// What a case is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Case {
    /// URDF text loaded as the chain of a built-in robot (its base and tip links and joint count).
    Urdf {
        /// The built-in robot whose chain is loaded (`afma6`, `ur5e`, `rail7`).
        robot: String,
        /// The text.
        text: String,
    },
    /// A scenario file.
    Scenario {
        /// The text.
        text: String,
    },
    /// Random inputs to [`control_step`] and [`StackController::step`], drawn from a seed.
    Control {
        /// The seed.
        seed: u64,
    },
    /// A mesh file's bytes, read as a file of this extension.
    Mesh {
        /// `stl`, `obj` or `dae`.
        extension: String,
        /// The bytes.
        bytes: Vec<u8>,
    },
    /// A calibration file.
    Calibration {
        /// The text.
        text: String,
    },
    /// A sequence of good and corrupted periods through the façade, drawn from a seed.
    Servo {
        /// The seed.
        seed: u64,
    },
}

/// How a case ended, when it returned.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Verdict {
    /// The input was accepted and every step returned finite values or an error.
    Accepted,
    /// The input was rejected with an error (its message).
    Rejected(String),
    /// A non-finite number was returned inside an `Ok` (where).
    NonFinite(String),
    /// A finite value returned inside an `Ok` contradicts its definition (what).
    Wrong(String),
    /// The case panicked (the message).
    Panicked(String),
}

impl Verdict {
    /// `true` for a failure: a panic or a non-finite value.
    pub fn is_failure(&self) -> bool {
        matches!(
            self,
            Self::NonFinite(_) | Self::Wrong(_) | Self::Panicked(_)
        )
    }
}

/// The shipped URDFs, by built-in robot name.
pub const URDF_SEEDS: [(&str, &str); 3] = [
    ("afma6", builtin::AFMA6_URDF),
    ("ur5e", builtin::UR5E_URDF),
    ("rail7", builtin::RAIL7_URDF),
];

/// The shipped scenario files, by name.
pub const SCENARIO_SEEDS: [(&str, &str); 9] = [
    (
        "obstacle_afma6",
        include_str!("../../assets/scenarios/obstacle_afma6.toml"),
    ),
    (
        "paper_afma6",
        include_str!("../../assets/scenarios/paper_afma6.toml"),
    ),
    (
        "paper_afma6_noisy_camera",
        include_str!("../../assets/scenarios/paper_afma6_noisy_camera.toml"),
    ),
    (
        "paper_afma6_pixel_noise",
        include_str!("../../assets/scenarios/paper_afma6_pixel_noise.toml"),
    ),
    (
        "paper_afma6_real_camera",
        include_str!("../../assets/scenarios/paper_afma6_real_camera.toml"),
    ),
    (
        "rail7_limits",
        include_str!("../../assets/scenarios/rail7_limits.toml"),
    ),
    (
        "square_marker_afma6",
        include_str!("../../assets/scenarios/square_marker_afma6.toml"),
    ),
    ("ur5e", include_str!("../../assets/scenarios/ur5e.toml")),
    (
        "ur5e_limits",
        include_str!("../../assets/scenarios/ur5e_limits.toml"),
    ),
];

/// A mutated URDF case from the seeds.
pub fn urdf_case(rng: &mut StdRng) -> Case {
    let (robot, text) = URDF_SEEDS[rng.random_range(0..URDF_SEEDS.len())];
    Case::Urdf {
        robot: robot.to_owned(),
        text: mutate::mutate(text, Syntax::Xml, rng),
    }
}

/// A mutated scenario case from the seeds.
pub fn scenario_case(rng: &mut StdRng) -> Case {
    let (_, text) = SCENARIO_SEEDS[rng.random_range(0..SCENARIO_SEEDS.len())];
    Case::Scenario {
        text: mutate::mutate(text, Syntax::Toml, rng),
    }
}

/// Runs one case on the calling thread (see [`Worker`] for the guarded run).
pub fn run_case(case: &Case) -> Verdict {
    match case {
        Case::Urdf { robot, text } => match robot.as_str() {
            "rail7" => check_urdf::<7>(robot, text),
            _ => check_urdf::<6>(robot, text),
        },
        Case::Scenario { text } => check_scenario(text),
        Case::Control { seed } => check_control(*seed),
        Case::Mesh { extension, bytes } => readers::check_mesh(extension, bytes),
        Case::Calibration { text } => readers::check_calibration(text),
        Case::Servo { seed } => servo_sequence::check_servo(*seed),
    }
}

/// `Err(where)` unless every value is finite.
fn finite(what: &str, values: &[f64]) -> Result<(), String> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(format!("{what}[{i}] = {}", values[i])),
    }
}

/// `Err(where)` unless a predicted cost is finite or `+∞`, the controller's documented value for a prediction that
/// takes a target point behind the camera (the worst there is).
fn predicted(what: &str, value: f64) -> Result<(), String> {
    finite(what, &[value]).or(if value == f64::INFINITY {
        Ok(())
    } else {
        Err(format!("{what} = {value}"))
    })
}

fn verdict(result: Result<Option<String>, String>) -> Verdict {
    match result {
        Ok(None) => Verdict::Accepted,
        Ok(Some(error)) => Verdict::Rejected(error),
        Err(non_finite) => Verdict::NonFinite(non_finite),
    }
}

/// Configurations to evaluate a chain at: zero, the limits, inside, and far beyond any range.
fn configurations<const N: usize>(
    lower: &JointVector<N>,
    upper: &JointVector<N>,
    rng: &mut StdRng,
) -> Vec<JointVector<N>> {
    let clamp = |v: f64| v.clamp(-1e3, 1e3);
    let inside = JointVector::<N>::from_fn(|i, _| {
        let (lo, hi) = (clamp(lower[i]), clamp(upper[i]));
        lo + rng.random::<f64>() * (hi - lo)
    });
    let huge = JointVector::<N>::from_fn(|_, _| match rng.random_range(0..4) {
        0 => 1e308,
        1 => -1e308,
        2 => 1e150,
        _ => 0.0,
    });
    vec![
        JointVector::zeros(),
        lower.map(clamp),
        upper.map(clamp),
        inside,
        huge,
    ]
}

fn check_urdf<const N: usize>(robot: &str, text: &str) -> Verdict {
    let mut rng = StdRng::seed_from_u64(text.len() as u64);
    verdict(urdf_steps::<N>(robot, text, &mut rng))
}

/// Loads the chain; when accepted, checks its model and evaluates the kinematics and the joint-limit cost.
fn urdf_steps<const N: usize>(
    robot: &str,
    text: &str,
    rng: &mut StdRng,
) -> Result<Option<String>, String> {
    let (base, tip) = match robot {
        "afma6" => ("afma6_base", "afma6_end_effector"),
        "ur5e" => ("base_link", "tool0"),
        _ => ("rail7_base", "rail7_tool"),
    };
    let chain = match SerialChain::<N>::from_urdf_str(text, base, tip) {
        Ok(chain) => chain,
        Err(error) => return Ok(Some(error.to_string())),
    };
    for joint in chain.joints() {
        let axis = joint.axis().into_inner();
        finite("axis", axis.as_slice())?;
        if (axis.norm() - 1.0).abs() > 1e-9 {
            return Err(format!(
                "axis {axis:?} of joint {} is not unit",
                joint.name()
            ));
        }
        finite("origin", joint.origin().translation.vector.as_slice())?;
    }
    let mut workspace = KinematicsWorkspace::new();
    let (lower, upper) = (*chain.lower_limits(), *chain.upper_limits());
    for q in configurations(&lower, &upper, rng) {
        if let Ok(state) = chain.kinematics(&mut workspace, &q) {
            finite(
                "tip pose",
                state.base_from_tip().translation.vector.as_slice(),
            )?;
            finite("base Jacobian", state.base_jacobian().as_slice())?;
            finite("tip Jacobian", state.tip_jacobian().as_slice())?;
        }
    }
    // The cost over the chain's limits (continuous joints given ±π).
    let bound = |v: f64, pi: f64| if v.is_finite() { v } else { pi };
    let lower = lower.map(|v| bound(v, -std::f64::consts::PI));
    let upper = upper.map(|v| bound(v, std::f64::consts::PI));
    if let Ok(limits) = JointLimits::new(lower, upper, 0.1) {
        let mut gradient = JointVector::<N>::zeros();
        for q in configurations(&lower, &upper, rng) {
            if let Ok(value) = limits.value_and_gradient(&q, &mut gradient) {
                finite("joint-limit cost", &[value])?;
                finite("joint-limit gradient", gradient.as_slice())?;
            }
        }
    }
    Ok(None)
}

/// A run log that finds the first non-finite number of the records.
#[derive(Default)]
struct FiniteRecords {
    first: Option<String>,
}

impl<const N: usize> RunLog<N> for FiniteRecords {
    fn record(&mut self, r: &Record<N>) -> Result<(), String> {
        if self.first.is_none() {
            let image: Vec<f64> = r.image.iter().flat_map(|p| [p.x, p.y, p.depth]).collect();
            let check = finite("q", r.q.as_slice())
                .and(finite("velocity", r.velocity.as_slice()))
                .and(finite("task errors", &r.task_errors))
                .and(finite("time and cost", &[r.time, r.cost]))
                .and(predicted("predicted cost", r.predicted_cost))
                .and(finite("image", &image));
            self.first = check.err().map(|e| format!("record {}: {e}", r.iteration));
        }
        Ok(())
    }
}

fn check_scenario(text: &str) -> Verdict {
    let scenario = match Scenario::from_toml_str(text, None) {
        Ok(scenario) => scenario,
        Err(error) => return Verdict::Rejected(error.to_string()),
    };
    let result = match scenario_steps::<6>(scenario.clone()) {
        Err(ScenarioError::Robot(RobotError::JointCount { found: 7, .. })) => {
            scenario_steps::<7>(scenario)
        }
        other => other,
    };
    match result {
        Ok(None) => Verdict::Accepted,
        Ok(Some(non_finite)) => Verdict::NonFinite(non_finite),
        Err(error) => Verdict::Rejected(error.to_string()),
    }
}

/// Validates the scenario and, when accepted, runs each of its runs for [`SCENARIO_ITERATIONS`] at most; `Ok(Some)`
/// names a non-finite value of a run.
fn scenario_steps<const N: usize>(mut scenario: Scenario) -> Result<Option<String>, ScenarioError> {
    scenario.simulation.max_iterations =
        scenario.simulation.max_iterations.min(SCENARIO_ITERATIONS);
    let experiment = scenario.experiment::<N>()?;
    for kind in RunKind::ALL {
        let mut log = FiniteRecords::default();
        let run = match experiment.run_with(&scenario.settings(), kind, &mut log) {
            Ok(run) => run,
            Err(_) => continue,
        };
        let summary = [
            run.max_velocity_step(),
            run.max_velocity_jump(),
            run.min_normalized_margin(),
            run.final_error_norm().unwrap_or(0.0),
        ];
        let events: Vec<f64> = run.events.iter().map(|e| e.law_jump).collect();
        let check = finite("run summary", &summary).and(finite("event law jumps", &events));
        if let Some(problem) = log.first.or(check.err()) {
            return Ok(Some(format!("{}: {problem}", kind.name())));
        }
    }
    Ok(None)
}

/// A number for a random input: extreme with probability `extreme` (NaN, ±∞, ±1e308, subnormal, zero), otherwise
/// ordinary over seven decades.
fn draw(rng: &mut StdRng, extreme: f64) -> f64 {
    const EXTREMES: [f64; 7] = [
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        -1e308,
        1e308,
        1e-310,
        0.0,
    ];
    if rng.random_bool(extreme) {
        EXTREMES[rng.random_range(0..EXTREMES.len())]
    } else {
        rng.random_range(-1.0..1.0) * 10f64.powi(rng.random_range(-3..4))
    }
}

fn check_control(seed: u64) -> Verdict {
    verdict(control_steps(seed))
}

/// Random tasks, order, law, cost, configurations and times given to [`control_step`] and
/// [`StackController::step`]; every `Ok` must hold finite numbers.
fn control_steps(seed: u64) -> Result<Option<String>, String> {
    const N: usize = 6;
    let mut rng = StdRng::seed_from_u64(seed);
    // Per case: ordinary inputs, a few extremes, or many (so that most cases get past the validation).
    let extreme = [0.0, 0.005, 0.05, 0.3][rng.random_range(0..4)];
    let count = rng.random_range(1..=4);
    let mut tasks = Vec::with_capacity(count);
    for k in 0..count {
        let rows = rng.random_range(1..=8);
        let error = DVector::from_fn(rows, |_, _| draw(&mut rng, extreme));
        let jacobian = TaskJacobian::<N>::from_fn(rows, |_, _| draw(&mut rng, extreme));
        let gain = draw(&mut rng, extreme).abs();
        match TaskValue::from_parts(&format!("t{k}"), error, jacobian, gain) {
            Ok(task) => tasks.push(task),
            Err(error) => return Ok(Some(error.to_string())),
        }
    }
    let law = match ControlLaw::new(draw(&mut rng, extreme).abs(), draw(&mut rng, extreme).abs()) {
        Ok(law) => law,
        Err(error) => return Ok(Some(error.to_string())),
    };
    let order: Vec<usize> = (0..rng.random_range(0..=count + 1))
        .map(|_| rng.random_range(0..=count))
        .collect();
    let limits = JointLimits::new(
        JointVector::<N>::from_fn(|_, _| draw(&mut rng, extreme)),
        JointVector::<N>::from_fn(|_, _| draw(&mut rng, extreme)),
        0.1,
    )
    .ok();
    let cost = limits.as_ref().map(|l| l as &dyn Cost<N>);
    let mut workspace = ControlWorkspace::new(&tasks);
    let mut controller = StackController::new(ControllerParameters::default(), &tasks).ok();
    let mut time = 0.0;
    for iteration in 0..8 {
        time = match rng.random_range(0..10) {
            0 => time - 0.01,
            1 => time,
            2 => f64::NAN,
            _ => time + 0.01,
        };
        let q = JointVector::<N>::from_fn(|_, _| draw(&mut rng, extreme));
        let change = if rng.random_bool(0.3) {
            StackChange::Changed
        } else {
            StackChange::Unchanged
        };
        if let Ok(out) = control_step(&law, &mut workspace, &tasks, &order, cost, &q, time, change)
        {
            finite("velocity", out.velocity().as_slice())?;
            finite("law", out.law().as_slice())?;
            finite("gradient", out.gradient().as_slice())?;
            finite("cost", &[out.cost(), out.decay()])?;
        }
        if let Some(Ok(step)) = controller
            .as_mut()
            .map(|c| c.step(&law, &tasks, cost, &q, iteration, time))
        {
            finite("controller velocity", step.velocity.as_slice())?;
            finite("controller costs", &[step.stack_velocity_norm, step.cost])?;
            predicted("controller predicted cost", step.predicted_cost)?;
        }
    }
    if all_finite(workspace.last_output().velocity()) {
        Ok(None)
    } else {
        Err("the workspace's last velocity".to_owned())
    }
}

/// A thread of [`WORKER_STACK_BYTES`] that runs cases one at a time, each under `catch_unwind`, so that a case that
/// does not return within its time limit is detected (and the worker abandoned).
pub struct Worker {
    jobs: mpsc::Sender<Case>,
    verdicts: mpsc::Receiver<Verdict>,
}

impl Worker {
    /// A new worker thread.
    ///
    /// # Errors
    /// The operating system's error when the thread cannot be spawned.
    pub fn new() -> std::io::Result<Self> {
        let (jobs, cases) = mpsc::channel::<Case>();
        let (results, verdicts) = mpsc::channel();
        std::thread::Builder::new()
            .name("fuzz-worker".into())
            .stack_size(WORKER_STACK_BYTES)
            .spawn(move || {
                for case in cases {
                    let verdict = std::panic::catch_unwind(AssertUnwindSafe(|| run_case(&case)))
                        .unwrap_or_else(|payload| {
                            let message = payload
                                .downcast_ref::<&str>()
                                .map(|s| (*s).to_owned())
                                .or_else(|| payload.downcast_ref::<String>().cloned())
                                .unwrap_or_default();
                            Verdict::Panicked(message)
                        });
                    if results.send(verdict).is_err() {
                        break;
                    }
                }
            })?;
        Ok(Self { jobs, verdicts })
    }

    /// Runs `case`; `None` when it has not returned within `limit` (a hang: make a new worker for the next case).
    pub fn run(&self, case: Case, limit: Duration) -> Option<Verdict> {
        self.jobs.send(case).ok()?;
        self.verdicts.recv_timeout(limit).ok()
    }
}

/// The counts of a fuzz run, per kind of input.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counts {
    /// Cases run.
    pub cases: usize,
    /// Inputs accepted (and stepped).
    pub accepted: usize,
    /// Inputs rejected with an error.
    pub rejected: usize,
    /// Cases that panicked.
    pub panics: usize,
    /// Cases that returned a non-finite value inside an `Ok`.
    pub non_finite: usize,
    /// Cases that returned a value contradicting its definition inside an `Ok`.
    pub wrong: usize,
    /// Cases that did not return within the time limit.
    pub hangs: usize,
}

impl Counts {
    /// Counts one case (`None`: a hang).
    pub fn add(&mut self, verdict: Option<&Verdict>) {
        self.cases += 1;
        match verdict {
            Some(Verdict::Accepted) => self.accepted += 1,
            Some(Verdict::Rejected(_)) => self.rejected += 1,
            Some(Verdict::Panicked(_)) => self.panics += 1,
            Some(Verdict::NonFinite(_)) => self.non_finite += 1,
            Some(Verdict::Wrong(_)) => self.wrong += 1,
            None => self.hangs += 1,
        }
    }

    /// Panics, non-finite or wrong values and hangs.
    pub fn failures(&self) -> usize {
        self.panics + self.non_finite + self.wrong + self.hangs
    }
}

impl std::fmt::Display for Counts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} cases: {} accepted, {} rejected; {} panics, {} non-finite in Ok, {} wrong in Ok, {} hangs",
            self.cases,
            self.accepted,
            self.rejected,
            self.panics,
            self.non_finite,
            self.wrong,
            self.hangs
        )
    }
}

/// The file name of a regression case (kind, robot or extension, and a hash of the input), and its content.
pub fn regression_file(case: &Case) -> (String, Vec<u8>) {
    use std::hash::{Hash, Hasher};
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    case.hash(&mut hasher);
    let hash = hasher.finish();
    match case {
        Case::Urdf { robot, text } => (
            format!("urdf-{robot}-{hash:016x}.urdf"),
            text.clone().into_bytes(),
        ),
        Case::Scenario { text } => (
            format!("scenario-{hash:016x}.toml"),
            text.clone().into_bytes(),
        ),
        Case::Control { seed } => (
            format!("control-{seed}.seed"),
            seed.to_string().into_bytes(),
        ),
        Case::Mesh { extension, bytes } => (format!("mesh-{hash:016x}.{extension}"), bytes.clone()),
        Case::Calibration { text } => (
            format!("calibration-{hash:016x}.yaml"),
            text.clone().into_bytes(),
        ),
        Case::Servo { seed } => (format!("servo-{seed}.seed"), seed.to_string().into_bytes()),
    }
}

/// The case a regression file holds, from its name and content (`None` for a name of no kind, or text kinds whose
/// content is not UTF-8).
pub fn case_from_file(name: &str, content: &[u8]) -> Option<Case> {
    if let Some(rest) = name.strip_prefix("mesh-") {
        return Some(Case::Mesh {
            extension: rest.rsplit_once('.')?.1.to_owned(),
            bytes: content.to_vec(),
        });
    }
    let text = std::str::from_utf8(content).ok()?;
    if let Some(rest) = name.strip_prefix("urdf-") {
        let robot = rest.split('-').next()?;
        return Some(Case::Urdf {
            robot: robot.to_owned(),
            text: text.to_owned(),
        });
    }
    if name.starts_with("scenario-") {
        return Some(Case::Scenario {
            text: text.to_owned(),
        });
    }
    if name.starts_with("calibration-") {
        return Some(Case::Calibration {
            text: text.to_owned(),
        });
    }
    let seed = || text.trim().parse().ok();
    if name.starts_with("control-") {
        return seed().map(|seed| Case::Control { seed });
    }
    if name.starts_with("servo-") {
        return seed().map(|seed| Case::Servo { seed });
    }
    None
}

impl std::hash::Hash for Case {
    fn hash<H: std::hash::Hasher>(&self, state: &mut H) {
        match self {
            Case::Urdf { robot, text } => (0u8, robot, text).hash(state),
            Case::Scenario { text } => (1u8, text).hash(state),
            Case::Control { seed } => (2u8, seed).hash(state),
            Case::Mesh { extension, bytes } => (3u8, extension, bytes).hash(state),
            Case::Calibration { text } => (4u8, text).hash(state),
            Case::Servo { seed } => (5u8, seed).hash(state),
        }
    }
}
