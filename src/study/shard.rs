//! Sharding a study: [`Shard`] and [`StudyResult::merge`] (re-exported by [`crate::study`]).

use super::{summarize, DrawResult, Family, StudyResult};
use crate::scenario::RunKind;
use crate::sim::Outcome;
use serde::{Deserialize, Deserializer, Serialize};

/// One part of a study's draws ([`super::Study::with_shard`]), for a job array (a Slurm array, a CI matrix) that runs
/// the draws of one study on several machines; [`StudyResult::merge`] combines the shards' results into those of the
/// study run whole.
///
/// Draw `d` of every family belongs to shard `d mod n` ([`Shard::contains`]): interleaved rather than in contiguous
/// blocks, so every shard gets draws from the whole index range and a study's shards take about the same time. A
/// draw's situation and seeds depend on its family's position and its index alone ([`crate::study`]), never on
/// the shard that runs it: a merged study has the draws, summaries and tables of the study run whole, byte for byte,
/// except the two fields that describe the machines rather than the result — `seconds` (the merged value is the sum of
/// the shards', the work's wall-clock time on one machine of each) and `threads` (the sum of the shards').
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "ShardFields")]
pub struct Shard {
    /// Its index, `0 ≤ index < count`.
    index: usize,
    /// The number of shards, ≥ 1.
    count: usize,
}

/// A shard as read from a file, checked by [`Shard::new`].
#[derive(Deserialize)]
struct ShardFields {
    index: usize,
    count: usize,
}

impl TryFrom<ShardFields> for Shard {
    type Error = ShardError;
    fn try_from(fields: ShardFields) -> Result<Self, ShardError> {
        Self::new(fields.index, fields.count)
    }
}

/// Errors of shards and of their merge.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum ShardError {
    /// A shard written `i/n` with `n = 0`, `i ≥ n`, or not two integers.
    #[error("shard {text:?}: expected i/n with 0 ≤ i < n (e.g. 0/4)")]
    InvalidShard {
        /// The text given.
        text: String,
    },
    /// A study file could not be read or parsed.
    #[error("study file {path}: {reason}")]
    File {
        /// The file.
        path: String,
        /// What went wrong.
        reason: String,
    },
    /// The results given to [`StudyResult::merge`] are not the shards of one study.
    #[error("cannot merge: {reason}")]
    Mismatch {
        /// What differs, is missing or is there twice.
        reason: String,
    },
}

impl Shard {
    /// Shard `index` of `count`.
    ///
    /// # Errors
    /// [`ShardError::InvalidShard`] unless `index < count`.
    pub fn new(index: usize, count: usize) -> Result<Self, ShardError> {
        if index < count {
            Ok(Self { index, count })
        } else {
            Err(ShardError::InvalidShard {
                text: format!("{index}/{count}"),
            })
        }
    }

    /// Its index.
    pub fn index(self) -> usize {
        self.index
    }

    /// The number of shards.
    pub fn count(self) -> usize {
        self.count
    }

    /// `true` when draw `draw` of a family belongs to this shard: `draw mod count = index`.
    pub fn contains(self, draw: usize) -> bool {
        draw % self.count == self.index
    }
}

impl std::str::FromStr for Shard {
    type Err = ShardError;

    /// `i/n`, as `--shard 0/4`.
    fn from_str(text: &str) -> Result<Self, ShardError> {
        let invalid = || ShardError::InvalidShard {
            text: text.to_owned(),
        };
        let (index, count) = text.split_once('/').ok_or_else(invalid)?;
        let index = index.trim().parse().map_err(|_| invalid())?;
        let count = count.trim().parse().map_err(|_| invalid())?;
        Self::new(index, count).map_err(|_| invalid())
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// What [`StudyResult::from_json`] reads of a `study.json`: the draws, and what identifies the study; the summaries
/// are recomputed from the draws.
#[derive(Deserialize)]
struct StudyFile {
    scenario: String,
    seed: u64,
    draws_per_family: usize,
    #[serde(default)]
    budget: usize,
    #[serde(default)]
    shard: Option<Shard>,
    families: Vec<FamilyFile>,
    iterations: usize,
    #[serde(deserialize_with = "finite_or_infinity")]
    seconds: f64,
    threads: usize,
}

#[derive(Deserialize)]
struct FamilyFile {
    family: Family,
    methods: Vec<MethodFile>,
    draws: Vec<DrawResult>,
}

#[derive(Deserialize)]
struct MethodFile {
    method: RunKind,
}

impl StudyResult {
    /// A study's results as the `convergence_domain` example writes them (`study.json`, `serde_json` of a
    /// [`StudyResult`]), the summaries recomputed from the draws.
    ///
    /// # Errors
    /// [`ShardError::File`] (with `path` as given) for text that is not such a file, a family of no methods or an
    /// outcome name no run has.
    pub fn from_json(text: &str, path: &str) -> Result<Self, ShardError> {
        let file: StudyFile = serde_json::from_str(text).map_err(|e| ShardError::File {
            path: path.to_owned(),
            reason: e.to_string(),
        })?;
        let families = file
            .families
            .into_iter()
            .map(|family| {
                let methods: Vec<RunKind> = family.methods.iter().map(|m| m.method).collect();
                summarize(&methods, &family.family, family.draws)
            })
            .collect();
        Ok(Self {
            scenario: file.scenario,
            seed: file.seed,
            draws_per_family: file.draws_per_family,
            budget: file.budget,
            shard: file.shard,
            families,
            iterations: file.iterations,
            seconds: file.seconds,
            threads: file.threads,
        })
    }

    /// The study whose shards are `parts` ([`super::Study::with_shard`]), in any order: every draw of every family
    /// once, the summaries recomputed over them; `seconds` and `threads` the sums of the shards' ([`Shard`]).
    ///
    /// # Errors
    /// [`ShardError::Mismatch`] when `parts` is empty, when they differ in scenario, seed, draws per family, budget, families,
    /// methods or shard count, when a shard is missing or given twice, or when a part is not a shard.
    pub fn merge(parts: &[StudyResult]) -> Result<StudyResult, ShardError> {
        let mismatch = |reason: String| ShardError::Mismatch { reason };
        let first = parts
            .first()
            .ok_or_else(|| mismatch("no study to merge".into()))?;
        let count = first
            .shard
            .ok_or_else(|| mismatch(format!("{} is not a shard", first.scenario)))?
            .count;
        let mut seen = vec![false; count];
        let methods = |result: &StudyResult| -> Vec<Vec<RunKind>> {
            result
                .families
                .iter()
                .map(|f| f.methods.iter().map(|m| m.method).collect())
                .collect()
        };
        let families = |result: &StudyResult| -> Vec<Family> {
            result.families.iter().map(|f| f.family.clone()).collect()
        };
        for part in parts {
            let same = part.scenario == first.scenario
                && part.seed == first.seed
                && part.draws_per_family == first.draws_per_family
                && part.budget == first.budget
                && families(part) == families(first)
                && methods(part) == methods(first);
            if !same {
                return Err(mismatch(format!(
                    "shard {:?} of {} (seed {}, {} draws per family) is not of the study of shard {:?} of {} \
                     (seed {}, {} draws per family), or its iteration budget, families or methods differ",
                    part.shard.map(|s| s.to_string()),
                    part.scenario,
                    part.seed,
                    part.draws_per_family,
                    first.shard.map(|s| s.to_string()),
                    first.scenario,
                    first.seed,
                    first.draws_per_family
                )));
            }
            match part.shard {
                Some(shard) if shard.count == count && !seen[shard.index] => {
                    seen[shard.index] = true
                }
                Some(shard) if shard.count == count => {
                    return Err(mismatch(format!("shard {shard} is given twice")))
                }
                other => {
                    return Err(mismatch(format!(
                        "a part is {}, not one of {count} shards",
                        other.map_or("the whole study".into(), |s| format!("shard {s}"))
                    )))
                }
            }
        }
        if let Some(missing) = seen.iter().position(|&s| !s) {
            return Err(mismatch(format!("shard {missing}/{count} is missing")));
        }
        let mut merged = Vec::with_capacity(first.families.len());
        for (f, family) in first.families.iter().enumerate() {
            let mut draws: Vec<DrawResult> = parts
                .iter()
                .flat_map(|part| part.families[f].draws.iter().cloned())
                .collect();
            draws.sort_by_key(|d| d.draw);
            if draws.len() != first.draws_per_family
                || draws.iter().enumerate().any(|(i, d)| d.draw != i)
            {
                return Err(mismatch(format!(
                    "family {}: the shards hold {} draws, not each of the {} draws once",
                    family.family.name,
                    draws.len(),
                    first.draws_per_family
                )));
            }
            let methods: Vec<RunKind> = family.methods.iter().map(|m| m.method).collect();
            merged.push(summarize(&methods, &family.family, draws));
        }
        Ok(StudyResult {
            scenario: first.scenario.clone(),
            seed: first.seed,
            draws_per_family: first.draws_per_family,
            budget: first.budget,
            shard: None,
            families: merged,
            iterations: parts.iter().map(|p| p.iterations).sum(),
            seconds: parts.iter().map(|p| p.seconds).sum(),
            threads: parts.iter().map(|p| p.threads).sum(),
        })
    }
}

/// Reads an outcome name as the `&'static str` of [`Outcome::NAMES`].
pub(super) fn outcome_name<'de, D: Deserializer<'de>>(
    deserializer: D,
) -> Result<&'static str, D::Error> {
    let name = String::deserialize(deserializer)?;
    Outcome::NAMES
        .iter()
        .copied()
        .find(|known| *known == name)
        .ok_or_else(|| {
            serde::de::Error::custom(format!(
                "unknown outcome {name:?}; the outcomes are {}",
                Outcome::NAMES.join(", ")
            ))
        })
}

/// Reads a number, or `null` (what `serde_json` writes for a non-finite value) as `+∞`.
pub(super) fn finite_or_infinity<'de, D: Deserializer<'de>>(
    deserializer: D,
) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(deserializer)?.unwrap_or(f64::INFINITY))
}
