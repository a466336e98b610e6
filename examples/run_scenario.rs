//! Runs the four runs of theory §9 on any scenario file and writes the same outputs as `paper_experiment`.
//!
//! `cargo run --release --example run_scenario -- SCENARIO.toml [--out DIR]` (default DIR: `target/<scenario name>`).
//! Robots with 1 to 12 joints are supported (`servostack::scenario::MAX_JOINTS`): the joint count is read from the
//! scenario's robot.

use servostack::report::{write_experiment, ReportError, Summary};
use servostack::scenario::{with_joint_count, ForJointCount, Scenario};
use std::path::{Path, PathBuf};

/// `write_experiment::<N>` for the joint count of the scenario's robot.
struct WriteExperiment<'a> {
    scenario: &'a Scenario,
    out: &'a Path,
}

impl ForJointCount for WriteExperiment<'_> {
    type Output = Result<Summary, ReportError>;
    fn call<const N: usize>(self) -> Self::Output {
        write_experiment::<N>(self.scenario, self.out)
    }
}

fn main() -> std::process::ExitCode {
    servostack::report::exit_code(run())
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (path, out) = match args.as_slice() {
        [path] => (PathBuf::from(path), None),
        [path, flag, dir] if flag == "--out" => (PathBuf::from(path), Some(PathBuf::from(dir))),
        _ => return Err("usage: run_scenario SCENARIO.toml [--out DIR]".into()),
    };
    let scenario = Scenario::from_file(&path)?;
    let out = out.unwrap_or_else(|| PathBuf::from("target").join(&scenario.name));
    let work = WriteExperiment {
        scenario: &scenario,
        out: &out,
    };
    let summary = with_joint_count(scenario.joint_count()?, work)??;
    print!("{summary}");
    println!("figures and summary.json in {}", out.display());
    Ok(())
}
