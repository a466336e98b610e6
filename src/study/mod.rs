//! The convergence-domain study: from how many situations does each method reach its goal? (the paper's claim,
//! [theory §9](crate::theory#s9): sequencing tasks and removing the blocking one enlarges the set of situations from
//! which the robot converges.)
//!
//! A study takes a scenario, draws `K` situations per **family** — starts perturbed around the scenario's start (mild,
//! strong, wide), the goal configuration moved, the desired view turned about the target, starts drawn uniformly
//! inside the joint limits — and runs the four methods of [`RunKind`] on every draw. Draws are seeded: draw `k` of
//! the family at position `f` of the study's list under seed `s` is the same on every machine and in every thread, so
//! a study is reproducible and its draws run in parallel on all cores (rayon). The stream depends on the position,
//! not the name: a study of one family draws what the first family of any study draws.
//!
//! A draw whose situation is not a valid experiment (a start outside the limits, a target not entirely in the image at
//! the start or seen there beyond `simulation.max_incidence_deg` of its normal ([D27](crate::theory#d27)), a goal
//! outside the limits) is drawn again from the same stream, up to [`MAX_ATTEMPTS`] times; the number
//! of such rejections is reported.
//!
//! ```no_run
//! use servostack::scenario::Scenario;
//! use servostack::study::{standard_families, Study};
//! let scenario = Scenario::from_file("assets/scenarios/paper_afma6.toml")?;
//! let study = Study::new(&scenario, standard_families(), 200, 1)?.run()?;
//! print!("{study}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::robot::{JointKind, KinematicsWorkspace, SerialChain};
use crate::scenario::{
    with_joint_count, ForJointCount, PoseSpec, RunKind, Scenario, ScenarioError,
};
use crate::sim::{Outcome, Run};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

mod output;
mod shard;
mod straight;
mod summary;
pub use shard::{Shard, ShardError};
pub use straight::{straight_feasible, wilson_lower_95, STRAIGHT_PATH_SAMPLES};
use summary::summarize;

/// How many times a draw is attempted before the family is reported as unable to produce valid situations. Large
/// enough for the `feasible` family on arms whose uniform starts are rarely straight-feasible: on the zoo's UR5 one
/// attempt in about 5 400 passes, on the suite's UR5e one in about 10 000 (draws needing 46 000 were seen), which
/// 10 000 attempts could not serve. An attempt costs a perturbation and the model's checks, a few microseconds (the
/// robot is read once per draw), so a family that cannot produce a situation fails in seconds.
pub const MAX_ATTEMPTS: usize = 1_000_000;

/// Errors of a study.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// The scenario itself is invalid.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// A study parameter is out of range.
    #[error("study parameter `{name}` = {value} is invalid: {expected}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is expected.
        expected: &'static str,
    },
    /// No family of the study has this name.
    #[error("the study has no family named {name:?}")]
    UnknownFamily {
        /// The name asked for.
        name: String,
    },
    /// No valid situation was found for a draw.
    #[error("family {family}: draw {draw} found no valid situation in {MAX_ATTEMPTS} attempts (last: {last})")]
    NoValidDraw {
        /// The family.
        family: String,
        /// The draw.
        draw: usize,
        /// Why the last attempt was rejected.
        last: String,
    },
}

/// How the situations of a family are drawn from the scenario.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Perturbation {
    /// Every joint of the start moved uniformly within `±translation_m` (prismatic) or `±rotation_deg` (revolute).
    Start {
        /// Half-width for prismatic joints (m).
        translation_m: f64,
        /// Half-width for revolute joints (degrees).
        rotation_deg: f64,
    },
    /// Every joint of the goal configuration moved the same way (the target moves with the goal: it is placed so that
    /// the goal sees it as the desired view).
    Goal {
        /// Half-width for prismatic joints (m).
        translation_m: f64,
        /// Half-width for revolute joints (degrees).
        rotation_deg: f64,
    },
    /// The desired view turned about the target's centre by a rotation of uniform random axis and angle in
    /// `[0, max_angle_deg]` (the camera orbits the target at the goal).
    View {
        /// The largest angle (degrees).
        max_angle_deg: f64,
    },
    /// The start drawn uniformly inside the joint limits; an unlimited (continuous) joint is drawn uniformly in
    /// `[−π, π]`, one full turn. Only starts from which the camera sees the whole target, within the incidence bound
    /// of D27, are kept.
    Uniform,
    /// Uniform starts ([`Self::Uniform`]) kept only when they are straight-feasible ([`straight_feasible`]): the
    /// straight joint-space path to the goal keeps the target in the image, within the incidence bound, and the joints
    /// inside their limits. A denominator no method defines (issue 43).
    Feasible,
}

/// A named family of situations.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Family {
    /// Its name in tables and files.
    pub name: String,
    /// How its situations are drawn.
    pub perturbation: Perturbation,
}

impl Family {
    /// A family.
    pub fn new(name: &str, perturbation: Perturbation) -> Self {
        Self {
            name: name.into(),
            perturbation,
        }
    }
}

/// The families of the study (issue's table): starts mild (±2 cm / ±3°), strong (±4 cm / ±6°), wide (±8 cm / ±12°);
/// goal moved ±2 cm / ±2° and ±4 cm / ±4°; desired view turned ≤ 5° and ≤ 10°; starts uniform inside the limits.
pub fn standard_families() -> Vec<Family> {
    use Perturbation::*;
    vec![
        Family::new(
            "mild",
            Start {
                translation_m: 0.02,
                rotation_deg: 3.0,
            },
        ),
        Family::new(
            "strong",
            Start {
                translation_m: 0.04,
                rotation_deg: 6.0,
            },
        ),
        Family::new(
            "wide",
            Start {
                translation_m: 0.08,
                rotation_deg: 12.0,
            },
        ),
        Family::new(
            "goal_2cm",
            Goal {
                translation_m: 0.02,
                rotation_deg: 2.0,
            },
        ),
        Family::new(
            "goal_4cm",
            Goal {
                translation_m: 0.04,
                rotation_deg: 4.0,
            },
        ),
        Family::new("view_5deg", View { max_angle_deg: 5.0 }),
        Family::new(
            "view_10deg",
            View {
                max_angle_deg: 10.0,
            },
        ),
        Family::new("uniform", Uniform),
    ]
}

/// The largest draw count per family a study accepts: 100 000, five hundred times the study's tables (K = 200, which
/// take about a minute per scenario on two cores), so a few hours at most; a larger count is a typing error that would
/// start a job of months.
pub const MAX_DRAWS_PER_FAMILY: usize = 100_000;

/// The most points per axis of a [`Study::slice`]: 201 × 201 runs are as many as a study of 1 250 draws per family,
/// minutes on two cores; a thousand per axis (a million runs) would take most of a day.
pub const MAX_SLICE_POINTS: usize = 201;

/// The families run only when asked for by name: `feasible` ([`Perturbation::Feasible`]), whose draws some arms can
/// hardly produce (the straight path of a uniform start rarely keeps the target in view: on a UR5e 2 in 200).
pub fn optional_families() -> Vec<Family> {
    vec![Family::new("feasible", Perturbation::Feasible)]
}

/// A study: a scenario, families, `K` draws per family and a seed.
#[derive(Debug, Clone)]
pub struct Study<'a> {
    scenario: &'a Scenario,
    families: Vec<Family>,
    draws: usize,
    seed: u64,
    methods: Vec<RunKind>,
    shard: Option<Shard>,
}

/// An outcome's name: an alias that keeps serde's derive from borrowing the name from the text it reads (it reads
/// one of [`Outcome::NAMES`]).
type OutcomeName = &'static str;

/// What one method did on one draw.
///
/// Read back from a study's `study.json` to merge shards ([`StudyResult::merge`]): a non-finite value, written as
/// `null`, reads as `+∞`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodResult {
    /// The method.
    pub method: RunKind,
    /// The outcome's name ([`Outcome::name`]).
    #[serde(deserialize_with = "shard::outcome_name")]
    pub outcome: OutcomeName,
    /// Iterations performed.
    pub iterations: usize,
    /// Removals over the run (D6: a task taken out because the avoidance was predicted to fail; the tasks a restart
    /// takes out are counted apart, [`Self::restart_take_outs`]).
    pub removals: usize,
    /// The largest number of removals of one task.
    pub max_removals_of_a_task: usize,
    /// Tasks taken out by a restart of the sequence ([D29](crate::theory#d29); 0 when it did not restart).
    pub restart_take_outs: usize,
    /// The largest number of times one task was taken out: its removals and a restart's taking it out alike.
    pub max_take_outs_of_a_task: usize,
    /// Whether the controller fell back to the stack with gradient (D13).
    pub fallback: bool,
    /// `max_k ‖q̇_k − q̇_{k−1}‖` (D14).
    #[serde(deserialize_with = "shard::finite_or_infinity")]
    pub max_velocity_step: f64,
    /// The camera's distance to its goal at the end (m).
    #[serde(deserialize_with = "shard::finite_or_infinity")]
    pub camera_translation_error: f64,
    /// The camera's rotation to its goal at the end (degrees).
    #[serde(deserialize_with = "shard::finite_or_infinity")]
    pub camera_rotation_error_deg: f64,
    /// The smallest distance of a joint to its nearest hard limit over the run, as a fraction of the joint's range.
    #[serde(deserialize_with = "shard::finite_or_infinity")]
    pub min_normalized_margin: f64,
    /// The configuration at the end of the run (m or rad per joint).
    pub end: Vec<f64>,
    /// The reason of a `stalled` or `max_iterations` outcome.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

impl MethodResult {
    /// `true` when the run converged.
    pub fn converged(&self) -> bool {
        self.outcome == "converged"
    }

    /// `true` when the run converged, at some time within [`AT_LIMIT_MARGIN`] of a hard limit.
    pub fn converged_at_limit(&self) -> bool {
        self.converged() && self.min_normalized_margin < AT_LIMIT_MARGIN
    }
}

/// A run that came closer than this fraction of a joint's range to one of its hard limits touched it: on the UR5e's
/// ±2π joints 0.013 rad. Such a run converges with no room left: a tracking error or a measurement error of that size
/// would have taken the joint past its limit. The classical law does so when a copy of its goal configuration lies on
/// a limit (on the UR5e, a wrist or base joint's goal at 0 and its copy at 2π, which it approaches without crossing).
/// The study reports these wins apart ([`FamilyResult::baseline_wins_at_limit`]); they still count as wins.
pub const AT_LIMIT_MARGIN: f64 = 1e-3;

/// One draw: its situation and what each method did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DrawResult {
    /// The draw's index in its family.
    pub draw: usize,
    /// Invalid situations rejected before this one.
    pub rejected: usize,
    /// Whether the straight joint-space path from the start to the goal keeps the target in the image, within the
    /// incidence bound, and the joints inside their limits ([`straight_feasible`]).
    #[serde(default)]
    pub straight_feasible: bool,
    /// The start configuration.
    pub start: Vec<f64>,
    /// The goal configuration.
    pub goal: Vec<f64>,
    /// One result per method, in the study's order.
    pub methods: Vec<MethodResult>,
}

impl DrawResult {
    /// `true` when a paper baseline ([`RunKind::is_paper_baseline`]) converged on this draw, and every baseline that
    /// converged touched a hard limit on the way ([`MethodResult::converged_at_limit`]).
    pub fn baselines_converged_only_at_limit(&self) -> bool {
        let mut baselines = self
            .methods
            .iter()
            .filter(|m| m.method.is_paper_baseline() && m.converged())
            .peekable();
        baselines.peek().is_some() && baselines.all(MethodResult::converged_at_limit)
    }
}

/// Per method, over a family.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MethodSummary {
    /// The method.
    pub method: RunKind,
    /// Draws that converged.
    pub converged: usize,
    /// Draws.
    pub draws: usize,
    /// Count per outcome name.
    pub outcomes: std::collections::BTreeMap<&'static str, usize>,
    /// The median number of removals per run.
    pub median_removals: f64,
    /// The median over runs of the largest number of removals of one task in the run (how often the same task is
    /// taken out: the measure of chatter).
    pub median_removals_of_a_task: f64,
    /// The largest number of removals of one task in one run.
    pub max_removals_of_a_task: usize,
    /// Runs that fell back (D13).
    pub fallbacks: usize,
    /// Runs that restarted their sequence ([D29](crate::theory#d29)).
    pub restarts: usize,
    /// The median over runs of the largest number of times one task was taken out, counting its removals and a
    /// restart's taking it out (D29) alike.
    pub median_take_outs_of_a_task: f64,
    /// The median over runs of `max_k ‖q̇_k − q̇_{k−1}‖`.
    pub median_max_velocity_step: f64,
    /// Runs that converged with the camera within [`POSE_TOLERANCE_M`] and [`POSE_TOLERANCE_DEG`] of its goal (with a
    /// measurement model, the run converges on the noise-free errors; this says where the camera really ended).
    pub converged_within_pose_tolerance: usize,
}

/// The camera-position tolerance of [`MethodSummary::converged_within_pose_tolerance`] (m).
pub const POSE_TOLERANCE_M: f64 = 0.002;
/// The camera-orientation tolerance of [`MethodSummary::converged_within_pose_tolerance`] (degrees).
pub const POSE_TOLERANCE_DEG: f64 = 0.2;

/// A family's results.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FamilyResult {
    /// The family.
    pub family: Family,
    /// Per method.
    pub methods: Vec<MethodSummary>,
    /// Draws where at least one of the other methods converged.
    pub any_baseline_converged: usize,
    /// Of those, draws where the full method converged too.
    pub full_method_also_converged: usize,
    /// Draws where the stack with gradient converged and the full method did not.
    pub full_method_worse_than_stack_gradient: usize,
    /// Of the draws where a baseline converged, those where every baseline that converged touched a hard limit on the
    /// way ([`MethodResult::converged_at_limit`]).
    pub baseline_wins_at_limit: usize,
    /// Of those, draws where the full method converged too.
    pub full_method_also_converged_at_limit: usize,
    /// Draws that are straight-feasible ([`DrawResult::straight_feasible`]).
    pub straight_feasible: usize,
    /// Of those, draws where the full method converged.
    pub full_method_straight_feasible: usize,
    /// Every draw.
    pub draws: Vec<DrawResult>,
}

impl FamilyResult {
    /// `converged/feasible (≥ bound %)`: the full method's share of the straight-feasible draws with its Wilson 95 %
    /// lower bound ([`wilson_lower_95`]); `-` without such a draw.
    pub fn straight_feasible_text(&self) -> String {
        if self.straight_feasible == 0 {
            return "-".to_owned();
        }
        format!(
            "{}/{} (≥ {:.0} %)",
            self.full_method_straight_feasible,
            self.straight_feasible,
            100.0 * wilson_lower_95(self.full_method_straight_feasible, self.straight_feasible)
        )
    }
}

/// The outcomes over a 2-D slice of starting configurations ([`Study::slice`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Slice {
    /// The two joints varied.
    pub joints: (usize, usize),
    /// The values of the first joint (m or rad), increasing.
    pub x_values: Vec<f64>,
    /// The values of the second joint (m or rad), increasing.
    pub y_values: Vec<f64>,
    /// Per method, the outcome name of every start (row-major: the second joint outer), or `invalid`.
    pub methods: Vec<(RunKind, Vec<&'static str>)>,
}

/// The results of a study.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StudyResult {
    /// The scenario's name.
    pub scenario: String,
    /// The seed.
    pub seed: u64,
    /// Draws per family.
    pub draws_per_family: usize,
    /// The part of the draws run ([`Study::with_shard`]); absent: every draw.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shard: Option<Shard>,
    /// Per family (of a shard: over the shard's draws).
    pub families: Vec<FamilyResult>,
    /// Simulated control iterations over the study.
    pub iterations: usize,
    /// Wall-clock time of the study (s).
    pub seconds: f64,
    /// Threads used.
    pub threads: usize,
}

impl<'a> Study<'a> {
    /// A study of the four methods on `scenario`, `draws` per family, seeded by `seed`.
    ///
    /// # Errors
    /// [`StudyError::InvalidParameter`] for `draws = 0` or above [`MAX_DRAWS_PER_FAMILY`].
    pub fn new(
        scenario: &'a Scenario,
        families: Vec<Family>,
        draws: usize,
        seed: u64,
    ) -> Result<Self, StudyError> {
        if !(1..=MAX_DRAWS_PER_FAMILY).contains(&draws) {
            return Err(StudyError::InvalidParameter {
                name: "draws",
                value: draws as f64,
                expected: "from 1 to 100000 per family",
            });
        }
        for family in &families {
            family.perturbation.validate()?;
        }
        Ok(Self {
            scenario,
            families,
            draws,
            seed,
            methods: RunKind::ALL.to_vec(),
            shard: None,
        })
    }

    /// The scenario studied.
    pub fn scenario(&self) -> &Scenario {
        self.scenario
    }

    /// Restricts the methods run on every draw (the full method and its baselines by default).
    pub fn with_methods(mut self, methods: &[RunKind]) -> Self {
        self.methods = methods.to_vec();
        self
    }

    /// Runs only the draws of `shard` ([`Shard::contains`]): one job of a job array, whose results
    /// [`StudyResult::merge`] combines into those of the whole study.
    pub fn with_shard(mut self, shard: Shard) -> Self {
        self.shard = Some(shard);
        self
    }

    /// Runs every draw (of the shard, [`Self::with_shard`]) of every family on all cores, for the joint count of the scenario's robot
    /// ([`Scenario::joint_count`], 1 to [`MAX_JOINTS`](crate::scenario::MAX_JOINTS)).
    ///
    /// The runners are generic in the joint count; they are instantiated here, in the library, once for every count,
    /// so a caller (the `convergence_domain` example) does not compile them again.
    ///
    /// # Errors
    /// An invalid scenario (a joint count out of that range included), a family that cannot produce valid draws, a
    /// failure of the models (not an outcome).
    pub fn run(&self) -> Result<StudyResult, StudyError> {
        struct Work<'s, 'a>(&'s Study<'a>);
        impl ForJointCount for Work<'_, '_> {
            type Output = Result<StudyResult, StudyError>;
            fn call<const N: usize>(self) -> Self::Output {
                self.0.run_for::<N>()
            }
        }
        with_joint_count(self.scenario.joint_count()?, Work(self))?
    }

    fn run_for<const N: usize>(&self) -> Result<StudyResult, StudyError> {
        let clock = std::time::Instant::now();
        // The scenario itself must be valid.
        self.scenario.experiment::<N>()?;
        let mut families = Vec::with_capacity(self.families.len());
        let mut iterations = 0;
        for (index, family) in self.families.iter().enumerate() {
            let draws: Vec<DrawResult> = (0..self.draws)
                .filter(|&draw| self.shard.is_none_or(|shard| shard.contains(draw)))
                .collect::<Vec<_>>()
                .into_par_iter()
                .map(|draw| self.run_draw::<N>(index, draw))
                .collect::<Result<_, _>>()?;
            iterations += draws
                .iter()
                .flat_map(|d| &d.methods)
                .map(|m| m.iterations)
                .sum::<usize>();
            families.push(summarize(&self.methods, family, draws));
        }
        Ok(StudyResult {
            scenario: self.scenario.name.clone(),
            seed: self.seed,
            draws_per_family: self.draws,
            shard: self.shard,
            families,
            iterations,
            seconds: clock.elapsed().as_secs_f64(),
            threads: rayon::current_num_threads(),
        })
    }

    /// The outcomes of every method over a 2-D slice of starting configurations: the scenario's start with joints
    /// `joints.0` and `joints.1` moved over `points × points` evenly spaced offsets within `±half_widths` (m or rad of
    /// each joint), on all cores. A start outside the limits or with the target out of the image is `invalid`.
    ///
    /// For the joint count of the scenario's robot, as [`Self::run`].
    ///
    /// # Errors
    /// [`StudyError::InvalidParameter`] for a joint index beyond the robot's joints, non-finite or negative
    /// half-widths, fewer than 2 points or more than [`MAX_SLICE_POINTS`]; model failures.
    pub fn slice(
        &self,
        joints: (usize, usize),
        half_widths: (f64, f64),
        points: usize,
    ) -> Result<Slice, StudyError> {
        struct Work<'s, 'a>(&'s Study<'a>, (usize, usize), (f64, f64), usize);
        impl ForJointCount for Work<'_, '_> {
            type Output = Result<Slice, StudyError>;
            fn call<const N: usize>(self) -> Self::Output {
                self.0.slice_for::<N>(self.1, self.2, self.3)
            }
        }
        with_joint_count(
            self.scenario.joint_count()?,
            Work(self, joints, half_widths, points),
        )?
    }

    fn slice_for<const N: usize>(
        &self,
        joints: (usize, usize),
        half_widths: (f64, f64),
        points: usize,
    ) -> Result<Slice, StudyError> {
        let invalid = |name, value: f64, expected| {
            Err(StudyError::InvalidParameter {
                name,
                value,
                expected,
            })
        };
        if joints.0 >= N || joints.1 >= N || joints.0 == joints.1 {
            return invalid(
                "slice joints",
                joints.1 as f64,
                "two distinct joint indices below N",
            );
        }
        for width in [half_widths.0, half_widths.1] {
            if !(width.is_finite() && width > 0.0) {
                return invalid("slice half-width", width, "finite and > 0");
            }
        }
        if !(2..=MAX_SLICE_POINTS).contains(&points) {
            return invalid("slice points", points as f64, "2 to 201");
        }
        let offsets = |half: f64| -> Vec<f64> {
            (0..points)
                .map(|k| -half + 2.0 * half * k as f64 / (points - 1) as f64)
                .collect()
        };
        let (x_offsets, y_offsets) = (offsets(half_widths.0), offsets(half_widths.1));
        let model = self.scenario.robot_model::<N>()?;
        let cells: Vec<Vec<&'static str>> = (0..points * points)
            .into_par_iter()
            .map(|k| {
                let mut scenario = self.scenario.clone();
                scenario.start.joints[joints.0] += x_offsets[k % points];
                scenario.start.joints[joints.1] += y_offsets[k / points];
                let experiment = match scenario.experiment_on::<N>(model.clone()) {
                    Ok(experiment) => experiment,
                    Err(ScenarioError::Invalid { .. }) => {
                        return Ok(vec!["invalid"; self.methods.len()])
                    }
                    Err(error) => return Err(StudyError::from(error)),
                };
                self.methods
                    .iter()
                    .map(|&method| {
                        let run = experiment.run_with(
                            &scenario.settings(),
                            method,
                            &mut crate::sim::SummaryOnly,
                        )?;
                        Ok(run.outcome.name())
                    })
                    .collect()
            })
            .collect::<Result<_, StudyError>>()?;
        let start = |joint: usize| self.scenario.start.joints[joint];
        Ok(Slice {
            joints,
            x_values: x_offsets.iter().map(|o| start(joints.0) + o).collect(),
            y_values: y_offsets.iter().map(|o| start(joints.1) + o).collect(),
            methods: self
                .methods
                .iter()
                .enumerate()
                .map(|(m, &method)| (method, cells.iter().map(|c| c[m]).collect()))
                .collect(),
        })
    }

    /// The seeded stream of draw `draw` of family `index`: independent of the thread that runs it.
    fn stream(&self, index: usize, draw: usize) -> StdRng {
        let mixed = self
            .seed
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add((index as u64) << 32)
            .wrapping_add(draw as u64);
        StdRng::seed_from_u64(mixed)
    }

    /// The scenario of draw `draw` of the family named `family`, as the study runs it (to reproduce one draw with
    /// [`Scenario::run`] or write it to a file), with the number of invalid situations rejected before it.
    ///
    /// # Errors
    /// An unknown family name, [`StudyError::NoValidDraw`], model failures.
    pub fn situation<const N: usize>(
        &self,
        family: &str,
        draw: usize,
    ) -> Result<(Scenario, crate::scenario::Experiment<N>, usize), StudyError> {
        let index = self
            .families
            .iter()
            .position(|f| f.name == family)
            .ok_or_else(|| StudyError::UnknownFamily {
                name: family.to_owned(),
            })?;
        self.valid_situation::<N>(index, draw)
    }

    fn valid_situation<const N: usize>(
        &self,
        index: usize,
        draw: usize,
    ) -> Result<(Scenario, crate::scenario::Experiment<N>, usize), StudyError> {
        let family = &self.families[index];
        let mut rng = self.stream(index, draw);
        let mut last = String::new();
        // A perturbation moves the start, the goal or the view, never the `[robot]` table: its model is read once.
        let model = self.scenario.robot_model::<N>()?;
        for rejected in 0..MAX_ATTEMPTS {
            let scenario = family
                .perturbation
                .apply(self.scenario, &model.0, &mut rng)?;
            match scenario.experiment_on::<N>(model.clone()) {
                Ok(experiment)
                    if family.perturbation == Perturbation::Feasible
                        && !straight_feasible(&scenario, &experiment) =>
                {
                    last = "the straight path to the goal leaves the image, the incidence bound or the limits"
                        .to_owned();
                }
                Ok(experiment) => return Ok((scenario, experiment, rejected)),
                Err(ScenarioError::Invalid { field, reason }) => {
                    last = format!("{field}: {reason}");
                }
                Err(error) => return Err(error.into()),
            }
        }
        Err(StudyError::NoValidDraw {
            family: family.name.clone(),
            draw,
            last,
        })
    }

    fn run_draw<const N: usize>(
        &self,
        index: usize,
        draw: usize,
    ) -> Result<DrawResult, StudyError> {
        let (mut scenario, experiment, rejected) = self.valid_situation::<N>(index, draw)?;
        // Each draw's camera noise has its own seed, drawn from the draw's stream.
        scenario.measurement.seed = self.stream(index, draw).random();
        let mut methods = Vec::with_capacity(self.methods.len());
        for &method in &self.methods {
            // The study reads the run's summary only: no record is kept.
            let run =
                experiment.run_with(&scenario.settings(), method, &mut crate::sim::SummaryOnly)?;
            methods.push(method_result(method, &run, &experiment)?);
        }
        Ok(DrawResult {
            draw,
            rejected,
            straight_feasible: straight_feasible(&scenario, &experiment),
            start: scenario.start.joints.clone(),
            goal: scenario.desired.joints.clone(),
            methods,
        })
    }
}

impl Perturbation {
    fn validate(&self) -> Result<(), StudyError> {
        let check = |name, value: f64| {
            if value.is_finite() && value >= 0.0 {
                Ok(())
            } else {
                Err(StudyError::InvalidParameter {
                    name,
                    value,
                    expected: "finite and ≥ 0",
                })
            }
        };
        match *self {
            Self::Start {
                translation_m,
                rotation_deg,
            }
            | Self::Goal {
                translation_m,
                rotation_deg,
            } => {
                check("translation_m", translation_m)?;
                check("rotation_deg", rotation_deg)
            }
            Self::View { max_angle_deg } => check("max_angle_deg", max_angle_deg),
            Self::Uniform | Self::Feasible => Ok(()),
        }
    }

    /// The scenario with one situation of this family drawn from `rng`, on `chain`, the scenario's robot.
    fn apply<const N: usize>(
        &self,
        scenario: &Scenario,
        chain: &SerialChain<N>,
        rng: &mut StdRng,
    ) -> Result<Scenario, StudyError> {
        let mut drawn = scenario.clone();
        let kinds: Vec<JointKind> = chain.joints().iter().map(|j| j.kind()).collect();
        let jitter =
            |values: &mut Vec<f64>, rng: &mut StdRng, translation: f64, rotation_deg: f64| {
                for (value, kind) in values.iter_mut().zip(&kinds) {
                    let half = if kind.is_rotational() {
                        rotation_deg.to_radians()
                    } else {
                        translation
                    };
                    *value += rng.random_range(-1.0..=1.0) * half;
                }
            };
        match *self {
            Self::Start {
                translation_m,
                rotation_deg,
            } => jitter(&mut drawn.start.joints, rng, translation_m, rotation_deg),
            Self::Goal {
                translation_m,
                rotation_deg,
            } => jitter(&mut drawn.desired.joints, rng, translation_m, rotation_deg),
            Self::View { max_angle_deg } => {
                let axis = loop {
                    let v = Vector3::new(
                        rng.random_range(-1.0..=1.0),
                        rng.random_range(-1.0..=1.0),
                        rng.random_range(-1.0..=1.0),
                    );
                    let norm = v.norm();
                    if norm > 1e-3 && norm <= 1.0 {
                        break nalgebra::Unit::new_normalize(v);
                    }
                };
                let angle = rng.random_range(0.0..=max_angle_deg.to_radians());
                let cd_from_o = scenario
                    .desired
                    .camera_from_target
                    .to_isometry("desired.camera_from_target")?;
                // Turn the target about its own centre: the camera orbits it at the same distance.
                let turned = cd_from_o
                    * Isometry3::from_parts(
                        Translation3::identity(),
                        UnitQuaternion::from_axis_angle(&axis, angle),
                    );
                drawn.desired.camera_from_target = PoseSpec::from_isometry(&turned);
            }
            Self::Uniform | Self::Feasible => {
                for (i, value) in drawn.start.joints.iter_mut().enumerate() {
                    let (low, high) = match (chain.lower_limits()[i], chain.upper_limits()[i]) {
                        (low, high) if low.is_finite() && high.is_finite() => (low, high),
                        _ => (-std::f64::consts::PI, std::f64::consts::PI),
                    };
                    *value = rng.random_range(low..=high);
                }
            }
        }
        Ok(drawn)
    }
}

/// The summary of one run, with the camera's distance to its goal at the end.
fn method_result<const N: usize>(
    method: RunKind,
    run: &Run<N>,
    experiment: &crate::scenario::Experiment<N>,
) -> Result<MethodResult, StudyError> {
    let mut per_task = vec![0usize; run.task_names.len()];
    for event in run.events_of(crate::controller::EventKind::Remove) {
        per_task[event.task] += 1;
    }
    let mut take_outs = per_task.clone();
    for event in run.events_of(crate::controller::EventKind::Restart) {
        take_outs[event.task] += 1;
    }
    let q_end = run.last_record().map_or(experiment.start, |r| r.q);
    let (camera_translation_error, camera_rotation_error_deg) = match experiment
        .scene
        .observe(&mut KinematicsWorkspace::new(), &q_end)
    {
        Ok(view) => experiment.scene.distance_to_goal(&view.c_from_o),
        Err(_) => (f64::INFINITY, f64::INFINITY),
    };
    let reason = match &run.outcome {
        Outcome::Stalled { reason, .. } | Outcome::MaxIterations { reason } => Some(reason.clone()),
        _ => None,
    };
    Ok(MethodResult {
        method,
        outcome: run.outcome.name(),
        iterations: run.iterations(),
        removals: per_task.iter().sum(),
        max_removals_of_a_task: per_task.iter().copied().max().unwrap_or(0),
        restart_take_outs: run.events_of(crate::controller::EventKind::Restart).count(),
        max_take_outs_of_a_task: take_outs.iter().copied().max().unwrap_or(0),
        fallback: run
            .events_of(crate::controller::EventKind::Fallback)
            .next()
            .is_some(),
        max_velocity_step: run.max_velocity_step(),
        camera_translation_error,
        camera_rotation_error_deg,
        min_normalized_margin: run.min_normalized_margin(),
        end: q_end.iter().copied().collect(),
        reason,
    })
}

/// The median of `values` (`NaN` when empty).
fn median(values: impl Iterator<Item = f64>) -> f64 {
    let mut values: Vec<f64> = values.collect();
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    let mid = values.len() / 2;
    if values.len() % 2 == 1 {
        values[mid]
    } else {
        0.5 * (values[mid - 1] + values[mid])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn result(method: RunKind, outcome: &'static str, min_normalized_margin: f64) -> MethodResult {
        MethodResult {
            method,
            outcome,
            iterations: 100,
            removals: 0,
            max_removals_of_a_task: 0,
            restart_take_outs: 0,
            max_take_outs_of_a_task: 0,
            fallback: false,
            max_velocity_step: 0.0,
            camera_translation_error: 0.0,
            camera_rotation_error_deg: 0.0,
            min_normalized_margin,
            end: vec![0.0; 6],
            reason: None,
        }
    }

    fn draw(methods: Vec<MethodResult>) -> DrawResult {
        DrawResult {
            draw: 0,
            rejected: 0,
            straight_feasible: false,
            start: vec![0.0; 6],
            goal: vec![0.0; 6],
            methods,
        }
    }

    /// A win at a limit is a converged run whose margin fell below `AT_LIMIT_MARGIN`; a draw counts apart only when
    /// every baseline that converged did so, and the full method's own margin plays no part.
    #[test]
    fn a_draw_is_won_only_at_a_limit_when_every_converged_baseline_touched_one() {
        use RunKind::{Classical, FullMethod, StackGradient};
        assert!(result(Classical, "converged", 5e-4).converged_at_limit());
        assert!(!result(Classical, "converged", 2e-3).converged_at_limit());
        assert!(!result(Classical, "joint_limit", 0.0).converged_at_limit());
        let at_limit = result(Classical, "converged", 0.0);
        let clean = result(StackGradient, "converged", 0.05);
        let failed = result(StackGradient, "joint_limit", 0.0);
        let full = result(FullMethod, "converged", 0.0);
        assert!(draw(vec![at_limit.clone(), failed.clone(), full.clone()])
            .baselines_converged_only_at_limit());
        assert!(
            !draw(vec![at_limit.clone(), clean, full.clone()]).baselines_converged_only_at_limit()
        );
        let failed_classical = result(Classical, "joint_limit", 0.0);
        assert!(!draw(vec![failed_classical, failed, full]).baselines_converged_only_at_limit());
    }
}
