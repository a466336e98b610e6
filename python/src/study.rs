//! The convergence-domain study (`servostack.run_study`): the four methods over families of situations drawn around
//! a scenario, on all cores, with its summary as a dict.

use crate::convert::{raise, run_kind, to_py};
use crate::scenario::Scenario;
use crate::StudyError;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use servostack::scenario::RunKind;
use servostack::study::{
    optional_families, standard_families, Study, StudyResult as RustStudyResult,
};
use std::path::PathBuf;

/// Runs the study of `scenario`: `draws` situations per family (`families`: names among the standard ones, `mild`,
/// `strong`, `wide`, `goal_2cm`, `goal_4cm`, `view_5deg`, `view_10deg`, `uniform`, and the optional `feasible`;
/// default the standard ones), seeded by `seed`, each run with `methods` (default the four). The GIL is released
/// while it runs.
#[pyfunction]
#[pyo3(signature = (scenario, draws, seed = 1, families = None, methods = None))]
pub fn run_study(
    py: Python<'_>,
    scenario: &Scenario,
    draws: usize,
    seed: u64,
    families: Option<Vec<String>>,
    methods: Option<Vec<String>>,
) -> PyResult<StudyResult> {
    let chosen = match families {
        None => standard_families(),
        Some(names) => {
            let known: Vec<_> = standard_families()
                .into_iter()
                .chain(optional_families())
                .collect();
            names
                .iter()
                .map(|name| {
                    known
                        .iter()
                        .find(|f| &f.name == name)
                        .cloned()
                        .ok_or_else(|| {
                            let all: Vec<_> = known.iter().map(|f| f.name.as_str()).collect();
                            PyValueError::new_err(format!(
                                "unknown family {name:?}: expected one of {all:?}"
                            ))
                        })
                })
                .collect::<PyResult<_>>()?
        }
    };
    let methods: Vec<RunKind> = match methods {
        None => RunKind::ALL.to_vec(),
        Some(names) => names
            .iter()
            .map(|name| run_kind(name))
            .collect::<PyResult<_>>()?,
    };
    let study = Study::new(scenario.inner(), chosen, draws, seed)
        .map_err(raise::<StudyError>)?
        .with_methods(&methods);
    let result = py.detach(|| study.run()).map_err(raise::<StudyError>)?;
    Ok(StudyResult { result })
}

/// A study's result: the summary per family and method, its tables and files.
#[pyclass(frozen, module = "servostack")]
pub struct StudyResult {
    result: RustStudyResult,
}

#[pymethods]
impl StudyResult {
    /// The per-family summary (`summary.json`): scenario, seed, draws per family, per family each method's counts
    /// and rates, then iterations, seconds and threads.
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.result.summary_json())
    }

    /// The success table in Markdown (as in docs/convergence_domain.md).
    fn markdown_table(&self) -> String {
        self.result.markdown_table()
    }

    /// Writes `study.json` (every draw) and `summary.json` into `directory`, creating it.
    fn write_files(&self, directory: PathBuf) -> PyResult<()> {
        self.result
            .write_files(&directory)
            .map_err(|e| raise::<StudyError>(format!("{}: {e}", directory.display())))
    }

    fn __str__(&self) -> String {
        self.result.to_string()
    }
}
