//! Runs the four runs of theory §9 on any scenario file and writes the same outputs as `paper_experiment`.
//!
//! `cargo run --release --example run_scenario -- SCENARIO.toml [--out DIR]` (default DIR: `target/<scenario name>`).
//! Robots with 1 to 12 joints are supported (`servostack::scenario::MAX_JOINTS`): the joint count is read from the
//! scenario's robot.

use servostack::report::write_scenario_experiment;
use servostack::scenario::Scenario;
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
    let summary = write_scenario_experiment(&scenario, &out)?;
    print!("{summary}");
    println!("figures and summary.json in {}", out.display());
    Ok(())
}
