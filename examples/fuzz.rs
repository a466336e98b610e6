//! The fuzz harness for as long as asked: mutated URDFs, scenario files, mesh files and calibration files, random
//! control-step inputs and random façade sequences in turn, each case on a 2 MiB worker thread with a time limit;
//! prints the counts per kind and saves every failing input (panic, non-finite or wrong value inside `Ok`, hang) to
//! `tests/data/fuzz_regressions/`, which `tests/suite/fuzz.rs` replays.
//!
//! `cargo run --release --example fuzz -- [--seconds S] [--cases N] [--seed SEED] [--limit-seconds L] [--kind K]...`
//! (defaults: 60 s, no case limit, seed 1, 20 s per case, every kind; stops at the first of `--seconds` and `--cases`
//! per kind). Kinds: urdf, scenario, control, mesh, calibration, servo. Exits with failure when a case failed.

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use servostack::fuzz::{
    calibration_case, mesh_case, regression_file, scenario_case, urdf_case, Case, Counts, Worker,
};
use std::path::PathBuf;
use std::time::{Duration, Instant};

const USAGE: &str =
    "usage: fuzz [--seconds S] [--cases N] [--seed SEED] [--limit-seconds L] [--kind K]...";

/// A generator of cases of one kind.
type Generate = fn(&mut StdRng) -> Case;

/// The kinds of input, by name, with their case generators.
const KINDS: [(&str, Generate); 6] = [
    ("urdf", urdf_case),
    ("scenario", scenario_case),
    ("control", |rng| Case::Control { seed: rng.random() }),
    ("mesh", mesh_case),
    ("calibration", calibration_case),
    ("servo", |rng| Case::Servo { seed: rng.random() }),
];

fn main() -> std::process::ExitCode {
    servostack::report::exit_code(run())
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let (mut seconds, mut cases, mut seed, mut limit) = (60.0, usize::MAX, 1u64, 20.0);
    let mut chosen: Vec<String> = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let value = args.next().ok_or(USAGE)?;
        match arg.as_str() {
            "--seconds" => seconds = value.parse()?,
            "--cases" => cases = value.parse()?,
            "--seed" => seed = value.parse()?,
            "--limit-seconds" => limit = value.parse()?,
            "--kind" if KINDS.iter().any(|(name, _)| *name == value) => chosen.push(value),
            other => return Err(format!("unexpected argument {other} {value}; {USAGE}").into()),
        }
    }
    let kinds: Vec<_> = KINDS
        .iter()
        .filter(|(name, _)| chosen.is_empty() || chosen.iter().any(|c| c == name))
        .collect();
    // Panics are counted and their inputs saved: their messages on stderr would only hide the counts.
    std::panic::set_hook(Box::new(|_| {}));
    let regressions = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/fuzz_regressions");
    let limit = Duration::from_secs_f64(limit);
    let mut rng = StdRng::seed_from_u64(seed);
    let mut worker = Worker::new()?;
    let mut counts = vec![Counts::default(); kinds.len()];
    let started = Instant::now();
    let mut next_report = 10.0;
    while started.elapsed().as_secs_f64() < seconds && counts.iter().any(|c| c.cases < cases) {
        for ((_, generate), counts) in kinds.iter().zip(counts.iter_mut()) {
            let case = generate(&mut rng);
            if counts.cases >= cases {
                continue;
            }
            let verdict = worker.run(case.clone(), limit);
            counts.add(verdict.as_ref());
            let failed = verdict.as_ref().is_none_or(|v| v.is_failure());
            if failed {
                let (name, content) = regression_file(&case);
                std::fs::create_dir_all(&regressions)?;
                std::fs::write(regressions.join(&name), content)?;
                eprintln!("failure {verdict:?}: saved tests/data/fuzz_regressions/{name}");
            }
            if verdict.is_none() {
                // The hung worker is abandoned; the next cases run on a new one.
                worker = Worker::new()?;
            }
        }
        if started.elapsed().as_secs_f64() > next_report {
            next_report += 10.0;
            let done: Vec<String> = kinds
                .iter()
                .zip(&counts)
                .map(|((name, _), c)| format!("{name} {}", c.cases))
                .collect();
            eprintln!(
                "{:.0} s: {}",
                started.elapsed().as_secs_f64(),
                done.join(", ")
            );
        }
    }
    println!("seed {seed}, {:.0} s", started.elapsed().as_secs_f64());
    for ((name, _), counts) in kinds.iter().zip(&counts) {
        println!("{name:<12} {counts}");
    }
    let failures: usize = counts.iter().map(Counts::failures).sum();
    if failures > 0 {
        return Err(
            format!("{failures} failing cases (saved in tests/data/fuzz_regressions)").into(),
        );
    }
    Ok(())
}
