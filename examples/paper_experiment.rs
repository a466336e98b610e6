//! The paper's four runs on the reference scenario (theory §9, D12): classical servoing, the stack, the stack with
//! projected-gradient avoidance, and the full method with the stack controller; then, as extra rows not from the
//! paper, saturation in the null space (`sns`, theory §13) and the hierarchical QP cascade (`hqp`, theory §14). Prints
//! a table (its columns
//! explained under it and in `docs/guide/reading_results.md`) and writes the figures (PNG and SVG, over time in
//! seconds) and `summary.json`.
//!
//! `cargo run --release --example paper_experiment [-- --out DIR] [--size WxH] [--scale S]`
//!
//! * `--out DIR`: where to write (default `target/paper_experiment`);
//! * `--size WxH`: the figures' layout size in pixels (default 1024x640), also the SVG's size;
//! * `--scale S`: the PNG's pixels per layout pixel (default 1; 2 doubles the resolution, same figure).

use servostack::report::{write_experiment_with, ReportOptions};
use servostack::scenario::Scenario;
use std::path::PathBuf;

#[path = "common/figure_args.rs"]
mod figure_args;

fn main() -> std::process::ExitCode {
    servostack::report::exit_code(run())
}

const USAGE: &str = "usage: paper_experiment [--out DIR] [--size WxH] [--scale S]";

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let mut out = PathBuf::from("target/paper_experiment");
    let mut options = ReportOptions::default();
    let args: Vec<String> = std::env::args().skip(1).collect();
    for pair in args.chunks(2) {
        match pair {
            [flag, dir] if flag == "--out" => out = PathBuf::from(dir),
            [flag, value] if flag == "--size" || flag == "--scale" => {
                options = figure_args::figure_option(options, flag, value, USAGE)?;
            }
            _ => return Err(USAGE.into()),
        }
    }
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/paper_afma6.toml");
    let scenario = Scenario::from_file(&path)?;
    let summary = write_experiment_with::<6>(&scenario, &out, &options)?;
    print!("{summary}");
    println!("figures and summary.json in {}", out.display());
    Ok(())
}
