//! Runs the four runs of theory §9 (and SNS, theory §13, and the QP cascade, theory §14, as extra rows) on any scenario file and writes the same outputs as `paper_experiment`: a table
//! (its columns explained under it and in `docs/guide/reading_results.md`), the figures and `summary.json`.
//!
//! `cargo run --release --example run_scenario -- SCENARIO.toml [--out DIR] [--size WxH] [--scale S]` (default DIR:
//! `target/<scenario name>`; `--size` and `--scale` as for `paper_experiment`: the figures' layout size, default
//! 1024x640, and the PNG's pixels per layout pixel, default 1).
//! Robots with 1 to 12 joints are supported (`servostack::scenario::MAX_JOINTS`): the joint count is read from the
//! scenario's robot.

use servostack::report::{write_scenario_experiment_with, ReportOptions};
use servostack::scenario::Scenario;
use std::path::PathBuf;

#[path = "common/figure_args.rs"]
mod figure_args;

fn main() -> std::process::ExitCode {
    servostack::report::exit_code(run())
}

const USAGE: &str = "usage: run_scenario SCENARIO.toml [--out DIR] [--size WxH] [--scale S]";

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (path, flags) = args.split_first().ok_or(USAGE)?;
    let mut out = None;
    let mut options = ReportOptions::default();
    for pair in flags.chunks(2) {
        match pair {
            [flag, dir] if flag == "--out" => out = Some(PathBuf::from(dir)),
            [flag, value] if flag == "--size" || flag == "--scale" => {
                options = figure_args::figure_option(options, flag, value, USAGE)?;
            }
            _ => return Err(USAGE.into()),
        }
    }
    let path = PathBuf::from(path);
    let scenario = Scenario::from_file(&path)?;
    let out = out.unwrap_or_else(|| PathBuf::from("target").join(&scenario.name));
    let summary = write_scenario_experiment_with(&scenario, &out, &options)?;
    print!("{summary}");
    println!("figures and summary.json in {}", out.display());
    Ok(())
}
