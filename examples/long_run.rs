//! A run of any length in bounded memory: one run of a scenario with an unreachable convergence threshold, its
//! records given to a summary-only log (or streamed to a JSON-lines file), so that it ends as `max_iterations` (or
//! `stalled`) after its whole budget with the summary of the run exact and memory constant.
//!
//! `cargo run --release --example long_run -- [--iterations N] [--kind KIND] [--jsonl FILE] [SCENARIO.toml]`
//! (defaults: 10⁸ iterations, `stack_controller`, `assets/scenarios/paper_afma6.toml`; a 6-joint robot).
//! Measure its memory with `/usr/bin/time -v` (maximum resident set size).

use servostack::scenario::{RunKind, Scenario};
use servostack::sim::{JsonLines, RunLog, SummaryOnly};
use std::io::BufWriter;
use std::path::PathBuf;
use std::time::Instant;

const USAGE: &str = "usage: long_run [--iterations N] [--kind KIND] [--jsonl FILE] [SCENARIO.toml]";

fn main() -> std::process::ExitCode {
    servostack::report::exit_code(run())
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let mut iterations = 100_000_000usize;
    let mut kind = RunKind::FullMethod;
    let mut jsonl = None;
    let mut path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/paper_afma6.toml");
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = || args.next().ok_or(USAGE);
        match arg.as_str() {
            "--iterations" => iterations = value()?.parse()?,
            "--kind" => {
                let name = value()?;
                kind = RunKind::from_name(&name)
                    .ok_or_else(|| format!("unknown run kind {name}; {USAGE}"))?;
            }
            "--jsonl" => jsonl = Some(PathBuf::from(value()?)),
            other if !other.starts_with('-') => path = PathBuf::from(other),
            other => return Err(format!("unexpected argument {other}; {USAGE}").into()),
        }
    }
    let mut scenario = Scenario::from_file(&path)?;
    scenario.simulation.max_iterations = iterations;
    // Unreachable: the errors never get this small, so the run spends its whole budget.
    scenario.simulation.convergence_error = f64::MIN_POSITIVE;
    let experiment = scenario.experiment::<6>()?;
    let started = Instant::now();
    let mut file_log;
    let log: &mut dyn RunLog<6> = match &jsonl {
        Some(file) => {
            file_log = JsonLines::new(BufWriter::new(std::fs::File::create(file)?));
            &mut file_log
        }
        None => &mut SummaryOnly,
    };
    let run = experiment.run_with(&scenario.settings(), kind, log)?;
    println!(
        "{} on {}: outcome {} after {} iterations in {:.1} s",
        kind.name(),
        scenario.name,
        run.outcome.name(),
        run.iterations(),
        started.elapsed().as_secs_f64()
    );
    let final_error = run
        .final_error_norm()
        .map_or("-".to_owned(), |e| format!("{e:.3e}"));
    println!(
        "final ‖e‖ {final_error}, largest velocity step {:.3e}, smallest joint-limit margin {:.3}, {} stack events",
        run.max_velocity_step(),
        run.min_normalized_margin(),
        run.events.len()
    );
    Ok(())
}
