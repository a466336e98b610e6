//! The convergence-domain study (the paper's claim: task sequencing enlarges the set of situations from which the
//! robot reaches its goal): the four methods on `K` seeded draws of each family of situations, in parallel on all
//! cores. Prints the success table and writes `study.json` (every draw) and `summary.json` (per family and method).
//!
//! `cargo run --release --example convergence_domain -- SCENARIO.toml [--family NAME]... [--k K] [--seed S]
//! [--out DIR] [--noise PX] [--calib FRAC] [--dump FAMILY:DRAW]` (defaults: every standard family, K = 200, seed 1,
//! DIR = `target/convergence_domain/<scenario>`). `--noise` and `--calib` add uniform pixel noise and an intrinsics
//! error to every draw; `--dump` writes one draw as a scenario file, to rerun with `run_scenario`.

use servostack::scenario::{with_joint_count, ForJointCount, Scenario};
use servostack::study::{standard_families, Slice, Study, StudyError, StudyResult};
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
    slice: (usize, usize),
    grid: usize,
}

const USAGE: &str =
    "usage: convergence_domain SCENARIO.toml [--family NAME]... [--k K] [--seed S] [--out DIR] \
                     [--noise PX] [--calib FRAC] [--slice J1,J2] [--grid N] [--dump FAMILY:DRAW]";

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
        slice: (0, 1),
        grid: 21,
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
            "--slice" => {
                let v = value("--slice")?;
                options.slice = v
                    .split_once(',')
                    .and_then(|(a, b)| Some((a.parse().ok()?, b.parse().ok()?)))
                    .ok_or_else(|| format!("--slice {v}: expected J1,J2 (joint indices)"))?;
            }
            "--grid" => {
                let v = value("--grid")?;
                options.grid = v.parse().map_err(|_| format!("--grid {v}: not a count"))?;
            }
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

/// One draw of a family as a scenario, for the joint count of the scenario's robot.
struct DrawScenario<'a>(&'a Study<'a>, &'a str, usize);

impl ForJointCount for DrawScenario<'_> {
    type Output = Result<Scenario, StudyError>;
    fn call<const N: usize>(self) -> Self::Output {
        Ok(self.0.situation::<N>(self.1, self.2)?.0)
    }
}

/// The study and the slice.
fn run(
    study: &Study<'_>,
    options: &Options,
) -> Result<(StudyResult, Slice), Box<dyn std::error::Error>> {
    let result = study.run()?;
    // The slice spans the wide family's perturbation: ±8 cm for a prismatic joint, ±12° for a revolute one.
    let kinds = study.scenario().joint_kinds()?;
    let half_width = |joint: usize| match kinds.get(joint) {
        Some(kind) if !kind.is_rotational() => 0.08,
        _ => 12f64.to_radians(),
    };
    let slice = study.slice(
        options.slice,
        (half_width(options.slice.0), half_width(options.slice.1)),
        options.grid,
    )?;
    Ok((result, slice))
}

fn main() -> std::process::ExitCode {
    servostack::report::exit_code(try_main())
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
        if options.noise_px.is_some_and(|noise| noise > 0.0)
            && (scenario.measurement.filter_time_constant_s == 0.0
                || scenario.tasks.adaptive_gain.is_none())
        {
            // The study runs the scenario as written; say what the noise-ready settings are.
            eprintln!(
                "note: {} has no filter of the measured points or no gain lower at the goal; under pixel noise the \
                 full method then chatters and ends far from the goal pose. \
                 assets/scenarios/paper_afma6_pixel_noise.toml is the reference scenario with both (docs/convergence_domain.md).",
                options.scenario.display()
            );
        }
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
        let mut situation =
            with_joint_count(scenario.joint_count()?, DrawScenario(&study, family, *draw))??;
        situation.name = format!("{}_{family}_{draw}", scenario.name);
        let text = toml::to_string(&situation)?;
        let path = PathBuf::from(format!("{}.toml", situation.name));
        std::fs::write(&path, text)?;
        println!("wrote {}", path.display());
        return Ok(());
    }
    let (result, slice) = run(&study, &options)?;
    print!("{result}");
    for (method, outcomes) in &slice.methods {
        let converged = outcomes.iter().filter(|&&o| o == "converged").count();
        let valid = outcomes.iter().filter(|&&o| o != "invalid").count();
        println!(
            "slice of joints {} and {}: {:<17} converged from {converged} of {valid} valid starts",
            slice.joints.0,
            slice.joints.1,
            method.name()
        );
    }
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
                "baseline_wins_at_limit": f.baseline_wins_at_limit,
                "full_method_also_converged_at_limit": f.full_method_also_converged_at_limit,
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
    std::fs::write(out.join("slice.json"), serde_json::to_string(&slice)?)?;
    #[cfg(feature = "plot")]
    figures::write(&result, &slice, &out)?;
    println!(
        "study.json, summary.json, slice.json and the figures in {}",
        out.display()
    );
    Ok(())
}

#[cfg(feature = "plot")]
mod figures {
    use servostack::plot::{LinePlot, Marker, OutcomeMap, Series};
    use servostack::study::{Slice, StudyResult};
    use std::path::Path;

    /// Every outcome name, in the colour order of the map's legend.
    const CATEGORIES: [&str; 9] = [
        "converged",
        "off_goal",
        "joint_limit",
        "feature_lost",
        "stalled",
        "max_iterations",
        "image_degenerate",
        "collision",
        "invalid",
    ];

    /// `success_rate.{png,svg}`: the share of converged draws per method (one curve) and family (abscissa);
    /// `slice.{png,svg}`: the outcome of every start of the slice, one panel per method.
    pub fn write(
        result: &StudyResult,
        slice: &Slice,
        out: &Path,
    ) -> Result<(), Box<dyn std::error::Error>> {
        let Some(first) = result.families.first() else {
            return Ok(());
        };
        let rates = LinePlot {
            title: format!(
                "Convergence domain of {} ({} draws per family)",
                result.scenario, result.draws_per_family
            ),
            x_label: "family".into(),
            y_label: "converged (% of draws)".into(),
            series: (0..first.methods.len())
                .map(|m| {
                    Series::new(
                        first.methods[m].method.name(),
                        result.families.iter().enumerate().map(|(i, f)| {
                            let s = &f.methods[m];
                            (i as f64, 100.0 * s.converged as f64 / s.draws.max(1) as f64)
                        }),
                    )
                })
                .collect(),
            markers: result
                .families
                .iter()
                .enumerate()
                .map(|(i, f)| Marker::new(i as f64, f.family.name.clone()))
                .collect(),
            y_range: Some((0.0, 100.0)),
            ..LinePlot::default()
        };
        rates.render(out, "success_rate")?;
        let map = OutcomeMap {
            title: format!(
                "Outcomes over starts: joints {} and {} of {}",
                slice.joints.0, slice.joints.1, result.scenario
            ),
            x_label: format!("q{} (m or rad)", slice.joints.0),
            y_label: format!("q{} (m or rad)", slice.joints.1),
            x_values: slice.x_values.clone(),
            y_values: slice.y_values.clone(),
            categories: CATEGORIES.iter().map(|c| c.to_string()).collect(),
            panels: slice
                .methods
                .iter()
                .map(|(method, outcomes)| {
                    let cells = outcomes
                        .iter()
                        .map(|o| {
                            CATEGORIES
                                .iter()
                                .position(|c| c == o)
                                .unwrap_or(CATEGORIES.len() - 1)
                        })
                        .collect();
                    (method.name().to_owned(), cells)
                })
                .collect(),
            size: (1800, 520),
        };
        map.render(out, "slice")?;
        Ok(())
    }
}
