//! Runs the four runs of theory §9 on any scenario file and writes the same outputs as `paper_experiment`.
//!
//! `cargo run --release --example run_scenario -- SCENARIO.toml [--out DIR]` (default DIR: `target/<scenario name>`).
//! Robots with 6 or 7 joints are supported.

use servostack::report::{write_experiment, ReportError};
use servostack::robot::RobotError;
use servostack::scenario::{Scenario, ScenarioError};
use std::path::PathBuf;

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
    let summary = match write_experiment::<6>(&scenario, &out) {
        Err(ReportError::Scenario(ScenarioError::Robot(RobotError::JointCount {
            found: 7,
            ..
        }))) => write_experiment::<7>(&scenario, &out)?,
        other => other?,
    };
    print!("{summary}");
    println!("figures and summary.json in {}", out.display());
    Ok(())
}
