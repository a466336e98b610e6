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

use crate::scenario::{with_joint_count, ForJointCount, RunKind, Scenario, ScenarioError};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;

mod family;
mod output;
mod result;
mod shard;
mod slice;
mod straight;
mod summary;
pub use family::{optional_families, standard_families, Family, Perturbation};
use result::method_result;
pub use result::{
    DrawResult, FamilyResult, MethodResult, MethodSummary, StudyResult, AT_LIMIT_MARGIN,
    POSE_TOLERANCE_DEG, POSE_TOLERANCE_M,
};
pub use shard::{Shard, ShardError};
pub use slice::{Slice, MAX_SLICE_POINTS};
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

/// The largest draw count per family a study accepts: 100 000, five hundred times the study's tables (K = 200, which
/// take about a minute per scenario on two cores), so a few hours at most; a larger count is a typing error that would
/// start a job of months.
pub const MAX_DRAWS_PER_FAMILY: usize = 100_000;

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
            budget: self.scenario.simulation.max_iterations,
            shard: self.shard,
            families,
            iterations,
            seconds: clock.elapsed().as_secs_f64(),
            threads: rayon::current_num_threads(),
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
