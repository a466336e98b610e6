//! The convergence-domain study (the paper's claim: task sequencing enlarges the set of situations from which the
//! robot reaches its goal): the four methods on `K` seeded draws of each family of situations, in parallel on all
//! cores. Prints the success table and writes `study.json` (every draw) and `summary.json` (per family and method).
//!
//! `cargo run --release --example convergence_domain -- SCENARIO.toml [--family NAME]... [--k K] [--seed S]
//! [--out DIR] [--noise PX] [--calib FRAC] [--dump FAMILY:DRAW]` (defaults: every standard family, K = 200, seed 1,
//! DIR = `target/convergence_domain/<scenario>`). `--noise` and `--calib` add uniform pixel noise and an intrinsics
//! error to every draw; `--dump` writes one draw as a scenario file, to rerun with `run_scenario`.

use servostack::scenario::{Scenario, ScenarioError};
use servostack::study::{standard_families, Study, StudyError, StudyResult};
use std::path::PathBuf;

struct Options {
    scenario: PathBuf,
    families: Vec<String>,
    draws: usize,
    seed: u64,
    out: Option<PathBuf>,
    dump: Option<(String, usize)>,
    noise_px: Option<f64>,
    calib: Option<f64>,
}

const USAGE: &str =
    "usage: convergence_domain SCENARIO.toml [--family NAME]... [--k K] [--seed S] [--out DIR] \
                     [--noise PX] [--calib FRAC] [--dump FAMILY:DRAW]";

fn parse(args: &[String]) -> Result<Options, String> {
    let mut options = Options {
        scenario: PathBuf::new(),
        families: Vec::new(),
        draws: 200,
        seed: 1,
        out: None,
        dump: None,
        noise_px: None,
        calib: None,
    };
    let mut scenario = None;
    let mut args = args.iter();
    while let Some(arg) = args.next() {
        let mut value = |flag: &str| {
            args.next()
                .cloned()
                .ok_or_else(|| format!("{flag} needs a value; {USAGE}"))
        };
        match arg.as_str() {
            "--family" => options.families.push(value("--family")?),
            "--k" => {
                let v = value("--k")?;
                options.draws = v.parse().map_err(|_| format!("--k {v}: not a count"))?;
            }
            "--seed" => {
                let v = value("--seed")?;
                options.seed = v
                    .parse()
                    .map_err(|_| format!("--seed {v}: not an integer"))?;
            }
            "--out" => options.out = Some(PathBuf::from(value("--out")?)),
            "--noise" => {
                let v = value("--noise")?;
                options.noise_px = Some(
                    v.parse()
                        .map_err(|_| format!("--noise {v}: not a number of pixels"))?,
                );
            }
            "--calib" => {
                let v = value("--calib")?;
                options.calib = Some(
                    v.parse()
                        .map_err(|_| format!("--calib {v}: not a fraction"))?,
                );
            }
            "--dump" => {
                let v = value("--dump")?;
                let (family, draw) = v
                    .split_once(':')
                    .and_then(|(f, d)| Some((f.to_owned(), d.parse().ok()?)))
                    .ok_or_else(|| format!("--dump {v}: expected FAMILY:DRAW"))?;
                options.dump = Some((family, draw));
            }
            path if scenario.is_none() && !path.starts_with("--") => {
                scenario = Some(PathBuf::from(path))
            }
            other => return Err(format!("unexpected argument {other}; {USAGE}")),
        }
    }
    options.scenario = scenario.ok_or(USAGE)?;
    Ok(options)
}

fn run(scenario: &Scenario, study: &Study<'_>) -> Result<StudyResult, StudyError> {
    match study.run::<6>() {
        Err(StudyError::Scenario(ScenarioError::Robot(
            servostack::robot::RobotError::JointCount { found: 7, .. },
        ))) => study.run::<7>(),
        other => {
            let _ = scenario;
            other
        }
    }
}

fn main() {
    if let Err(error) = try_main() {
        eprintln!("convergence_domain: {error}");
        std::process::exit(1);
    }
}

fn try_main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let options = parse(&args)?;
    let mut scenario = Scenario::from_file(&options.scenario)?;
    // Measurement errors on every draw: uniform pixel noise of ±PX and an intrinsics error of ±FRAC (each draw has its
    // own noise seed). Converged then means the noise-free task errors below 1e−3 (at least); the study also counts
    // the runs whose camera ends within 2 mm / 0.2° of its goal.
    if let Some(noise) = options.noise_px {
        scenario.measurement.pixel_noise_uniform_px = noise;
    }
    if let Some(calib) = options.calib {
        scenario.measurement.intrinsics_error_fraction = calib;
    }
    if options.noise_px.is_some() || options.calib.is_some() {
        scenario.simulation.convergence_error = scenario.simulation.convergence_error.max(1e-3);
    }
    let mut families = standard_families();
    if !options.families.is_empty() {
        for name in &options.families {
            if !families.iter().any(|f| &f.name == name) {
                let known: Vec<_> = families.iter().map(|f| f.name.as_str()).collect();
                return Err(format!("unknown family {name}; known: {}", known.join(", ")).into());
            }
        }
        families.retain(|f| options.families.contains(&f.name));
    }
    let study = Study::new(&scenario, families, options.draws, options.seed)?;
    if let Some((family, draw)) = &options.dump {
        // One draw as a scenario file, to rerun it with `run_scenario` and read its event log and figures.
        let situation = match study.situation::<6>(family, *draw) {
            Ok((situation, ..)) => situation,
            Err(_) => study.situation::<7>(family, *draw)?.0,
        };
        let mut situation = situation;
        situation.name = format!("{}_{family}_{draw}", scenario.name);
        let text = toml::to_string(&situation)?;
        let path = PathBuf::from(format!("{}.toml", situation.name));
        std::fs::write(&path, text)?;
        println!("wrote {}", path.display());
        return Ok(());
    }
    let result = run(&scenario, &study)?;
    print!("{result}");
    let out = options
        .out
        .unwrap_or_else(|| PathBuf::from("target/convergence_domain").join(&scenario.name));
    std::fs::create_dir_all(&out)?;
    std::fs::write(out.join("study.json"), serde_json::to_string(&result)?)?;
    let summary: Vec<_> = result
        .families
        .iter()
        .map(|f| {
            serde_json::json!({
                "family": f.family,
                "methods": f.methods,
                "any_baseline_converged": f.any_baseline_converged,
                "full_method_also_converged": f.full_method_also_converged,
                "full_method_worse_than_stack_gradient": f.full_method_worse_than_stack_gradient,
            })
        })
        .collect();
    std::fs::write(
        out.join("summary.json"),
        serde_json::to_string_pretty(&serde_json::json!({
            "scenario": result.scenario,
            "seed": result.seed,
            "draws_per_family": result.draws_per_family,
            "families": summary,
            "iterations": result.iterations,
            "seconds": result.seconds,
            "threads": result.threads,
        }))?,
    )?;
    println!("study.json and summary.json in {}", out.display());
    Ok(())
}
