//! The zoo of real arms: [`Zoo`] (re-exported by [`crate::scenario`]).

use super::generate::{generate, ArmSpec};
use super::{text_bounds, Scenario, ScenarioError};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A robot description of the package left out of the zoo.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExcludedArm {
    /// The URDF, relative to the package's robots directory.
    pub urdf: String,
    /// Why it is not in the zoo.
    pub reason: String,
}

/// The zoo of real arms: a manifest (`assets/zoo.toml`) naming, for each serial arm of a robot-description package
/// (`example-robot-data`, installed by `scripts/install_zoo.sh`, never vendored), its URDF relative to the package's
/// robots directory, base and tool links and camera mount ([`ArmSpec`]), and the package's arms left out, with why.
/// [`Zoo::scenario`] turns an arm into the paper's scenario for it ([`generate`]).
///
/// ```toml
/// package = "example-robot-data"
/// version = "6.0.0"
///
/// [[arms]]
/// name = "panda"
/// robot = { urdf = "panda_description/urdf/panda.urdf", base_link = "panda_link0", tip_link = "panda_link8",
///           camera_mount = { translation_m = [0.0, 0.0, 0.05] } }
///
/// [[excluded]]
/// urdf = "double_pendulum_description/urdf/double_pendulum.urdf"
/// reason = "two joints: no arm"
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Zoo {
    /// The package the URDFs come from.
    pub package: String,
    /// Its version, as the install script pins it.
    pub version: String,
    /// The arms, in the order of the study.
    pub arms: Vec<ArmSpec>,
    /// The package's robot descriptions left out, with why.
    #[serde(default)]
    pub excluded: Vec<ExcludedArm>,
}

impl Zoo {
    /// Parses a manifest.
    ///
    /// # Errors
    /// [`ScenarioError::TooLarge`], [`ScenarioError::TooDeep`] (the bounds of scenario text), [`ScenarioError::Syntax`]
    /// for a missing or unknown field, and [`ScenarioError::Invalid`] (field `arms`) for two arms of the same name.
    pub fn from_toml_str(text: &str) -> Result<Self, ScenarioError> {
        text_bounds::check_scenario_text(text)?;
        let zoo: Self = toml::from_str(text)?;
        for (i, arm) in zoo.arms.iter().enumerate() {
            if zoo.arms[..i].iter().any(|other| other.name == arm.name) {
                return Err(super::invalid(
                    &format!("arms[{i}].name"),
                    format!("{:?} names two arms", arm.name),
                ));
            }
        }
        Ok(zoo)
    }

    /// Reads and parses a manifest file.
    ///
    /// # Errors
    /// [`ScenarioError::Io`], then those of [`Zoo::from_toml_str`].
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self, ScenarioError> {
        Self::from_toml_str(&text_bounds::read_scenario_file(path.as_ref())?)
    }

    /// The arm named `name`.
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] (field `arms`) naming the arms there are.
    pub fn arm(&self, name: &str) -> Result<&ArmSpec, ScenarioError> {
        self.arms
            .iter()
            .find(|arm| arm.name == name)
            .ok_or_else(|| {
                let known: Vec<&str> = self.arms.iter().map(|arm| arm.name.as_str()).collect();
                super::invalid(
                    "arms",
                    format!("no arm named {name:?}; the zoo has {}", known.join(", ")),
                )
            })
    }

    /// The paper's scenario for `arm`, its URDF found in the package's robots directory `robots_dir` (the directory
    /// `scripts/install_zoo.sh` prints).
    ///
    /// # Errors
    /// Those of [`generate`].
    pub fn scenario(
        arm: &ArmSpec,
        robots_dir: impl AsRef<Path>,
    ) -> Result<Scenario, ScenarioError> {
        generate(arm, Some(robots_dir.as_ref()))
    }
}
