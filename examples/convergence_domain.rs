//! The convergence-domain study (the paper's claim: task sequencing enlarges the set of situations from which the
//! robot reaches its goal): the four methods on `K` seeded draws of each family of situations, in parallel on all
//! cores. Prints the success table and writes `study.json` (every draw) and `summary.json` (per family and method).
//!
//! `cargo run --release --example convergence_domain -- SCENARIO.toml [--family NAME]... [--k K] [--seed S]
//! [--out DIR] [--noise PX] [--calib FRAC] [--dump FAMILY:DRAW] [--shard I/N]` (defaults: every standard family,
//! K = 200, seed 1, DIR = `target/convergence_domain/<scenario>`; `--family feasible` adds the uniform starts whose
//! straight joint path to the goal keeps the target in view, a family run only when named). `--noise` and `--calib` add uniform pixel noise and
//! an intrinsics error to every draw; `--dump` writes one draw as a scenario file `<scenario>_<family>_<draw>.toml` into
//! DIR (with `--zoo`, into each arm's directory) instead of running the study, to rerun with `run_scenario`.
//!
//! The zoo of real arms: `--zoo [--zoo-dir DIR] [--arm NAME]...` runs the study on the paper's scenario generated for
//! every arm of `assets/zoo.toml` (or the arms named), with the URDFs of `example-robot-data` in DIR (default: the
//! directory `scripts/install_zoo.sh` installs under the target directory); it writes per arm a directory with the
//! study's files and the generated `scenario.toml`, and `zoo.md`, the tables of every arm (`docs/zoo.md`).
//!
//! Variants, for the controller's ablation and sensitivity tables (`scripts/controller_sweep.py`): `--set PATH=VALUE`
//! sets a field of the scenario (of every arm's, with `--zoo`) by its dotted path, `--scale PATH=FACTOR` multiplies a
//! number (its default when the file leaves it out), `--method NAME` runs only the methods named (`classical`,
//! `stack`, `stack_gradient`, `stack_controller`, and `sns`, saturation in the null space, and `hqp`, the hierarchical
//! QP cascade, which run only when named).
//!
//! Sharding: `--shard I/N` runs only the draws `d` with `d mod N = I` of every family (of every arm), as one job of a
//! job array, without the slice; `--merge DIR... [--out OUT]` combines the shards' directories (a study's, or a zoo
//! run's with one directory per arm) into the files the study run whole writes (`StudyResult::merge`).

use servostack::scenario::{with_joint_count, ForJointCount, RunKind, Scenario, Zoo};
use servostack::study::{
    optional_families, standard_families, Shard, Slice, Study, StudyError, StudyResult,
};
use std::path::{Path, PathBuf};

struct Options {
    scenario: Option<PathBuf>,
    zoo: bool,
    zoo_dir: Option<PathBuf>,
    arms: Vec<String>,
    shard: Option<Shard>,
    merge: Option<Vec<PathBuf>>,
    families: Vec<String>,
    draws: usize,
    seed: u64,
    out: Option<PathBuf>,
    dump: Option<(String, usize)>,
    noise_px: Option<f64>,
    calib: Option<f64>,
    slice: (usize, usize),
    grid: usize,
    changes: Vec<Change>,
    methods: Vec<RunKind>,
}

/// A change of one field of the scenario studied (`--set`, `--scale`).
enum Change {
    /// The field at the path set to a TOML value.
    Set(String, String),
    /// The number at the path multiplied by a factor.
    Scale(String, f64),
}

const USAGE: &str =
    "usage: convergence_domain (SCENARIO.toml | --zoo [--zoo-dir DIR] [--arm NAME]...) [--family NAME]... [--k K] \
     [--seed S] [--out DIR] [--noise PX] [--calib FRAC] [--slice J1,J2] [--grid N] [--dump FAMILY:DRAW] \
     [--shard I/N] [--set PATH=VALUE]... [--scale PATH=FACTOR]... [--method NAME]...\n       \
     convergence_domain --merge DIR... [--out OUT]";

fn parse(args: &[String]) -> Result<Options, Box<dyn std::error::Error>> {
    let mut options = Options {
        scenario: None,
        zoo: false,
        zoo_dir: None,
        arms: Vec::new(),
        shard: None,
        merge: None,
        families: Vec::new(),
        draws: 200,
        seed: 1,
        out: None,
        dump: None,
        noise_px: None,
        calib: None,
        slice: (0, 1),
        grid: 21,
        changes: Vec::new(),
        methods: Vec::new(),
    };
    let mut args = args.iter();
    while let Some(arg) = args.next() {
        let mut value = |flag: &str| {
            args.next()
                .cloned()
                .ok_or_else(|| format!("{flag} needs a value; {USAGE}"))
        };
        match arg.as_str() {
            "--family" => options.families.push(value("--family")?),
            "--set" => {
                let v = value("--set")?;
                let (path, field) = v
                    .split_once('=')
                    .ok_or_else(|| format!("--set {v}: expected PATH=VALUE"))?;
                options
                    .changes
                    .push(Change::Set(path.to_owned(), field.to_owned()));
            }
            "--scale" => {
                let v = value("--scale")?;
                let (path, factor) = v
                    .split_once('=')
                    .and_then(|(p, f)| Some((p, f.parse().ok()?)))
                    .ok_or_else(|| format!("--scale {v}: expected PATH=FACTOR"))?;
                options.changes.push(Change::Scale(path.to_owned(), factor));
            }
            "--method" => {
                let v = value("--method")?;
                let kind =
                    RunKind::from_name(&v).ok_or_else(|| format!("--method {v}: not a method"))?;
                options.methods.push(kind);
            }
            "--zoo" => options.zoo = true,
            "--zoo-dir" => options.zoo_dir = Some(PathBuf::from(value("--zoo-dir")?)),
            "--arm" => options.arms.push(value("--arm")?),
            "--shard" => options.shard = Some(value("--shard")?.parse()?),
            "--merge" => options.merge = Some(Vec::new()),
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
            path if !path.starts_with("--") => match (&mut options.merge, &options.scenario) {
                (Some(dirs), _) => dirs.push(PathBuf::from(path)),
                (None, None) => options.scenario = Some(PathBuf::from(path)),
                (None, Some(_)) => {
                    return Err(format!("unexpected argument {path}; {USAGE}").into())
                }
            },
            other => return Err(format!("unexpected argument {other}; {USAGE}").into()),
        }
    }
    let modes = [
        options.scenario.is_some(),
        options.zoo,
        options.merge.is_some(),
    ];
    if modes.iter().filter(|&&m| m).count() != 1 {
        return Err(format!("give one of SCENARIO.toml, --zoo and --merge; {USAGE}").into());
    }
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
    if let Some(dirs) = &options.merge {
        return merge(dirs, &options);
    }
    if options.zoo {
        return zoo(&options);
    }
    let path = options.scenario.clone().ok_or(USAGE)?;
    let scenario = Scenario::from_file(&path)?;
    let out = options
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("target/convergence_domain").join(&scenario.name));
    study(scenario, &path.display().to_string(), &options, &out, true)
}

/// The study of one scenario (with the slice and the figures when `slice` is set and the study is not sharded), its
/// files written into `out`.
fn study(
    mut scenario: Scenario,
    label: &str,
    options: &Options,
    out: &Path,
    slice: bool,
) -> Result<(), Box<dyn std::error::Error>> {
    for change in &options.changes {
        scenario = match change {
            Change::Set(path, value) => scenario.with_field(path, value)?,
            Change::Scale(path, factor) => scenario.with_field_scaled(path, *factor)?,
        };
    }
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
                "note: {label} has no filter of the measured points or no gain lower at the goal; under pixel noise \
                 the full method then chatters and ends far from the goal pose. \
                 assets/scenarios/paper_afma6_pixel_noise.toml is the reference scenario with both (docs/convergence_domain.md)."
            );
        }
    }
    let mut families = standard_families();
    if !options.families.is_empty() {
        // The optional families (`feasible`) run when named.
        families.extend(optional_families());
        for name in &options.families {
            if !families.iter().any(|f| &f.name == name) {
                let known: Vec<_> = families.iter().map(|f| f.name.as_str()).collect();
                return Err(format!("unknown family {name}; known: {}", known.join(", ")).into());
            }
        }
        families.retain(|f| options.families.contains(&f.name));
    }
    let mut study = Study::new(&scenario, families, options.draws, options.seed)?;
    if !options.methods.is_empty() {
        study = study.with_methods(&options.methods);
    }
    if let Some((family, draw)) = &options.dump {
        // One draw as a scenario file, to rerun it with `run_scenario` and read its event log and figures.
        let mut situation =
            with_joint_count(scenario.joint_count()?, DrawScenario(&study, family, *draw))??;
        situation.name = format!("{}_{family}_{draw}", scenario.name);
        let text = toml::to_string(&situation)?;
        std::fs::create_dir_all(out)?;
        let path = out.join(format!("{}.toml", situation.name));
        std::fs::write(&path, text)?;
        println!("wrote {}", path.display());
        return Ok(());
    }
    if options.shard.is_some() || !slice {
        // A shard has its draws alone and no slice (the merge has no slice to combine); a zoo run has no slice (it
        // would take most of the time).
        if let Some(shard) = options.shard {
            study = study.with_shard(shard);
        }
        let result = study.run()?;
        print!("{result}");
        result.write_files(out)?;
        println!("study.json and summary.json in {}", out.display());
        return Ok(());
    }
    let (result, slice) = run(&study, options)?;
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
    result.write_files(out)?;
    std::fs::write(out.join("slice.json"), serde_json::to_string(&slice)?)?;
    #[cfg(feature = "plot")]
    figures::write(&result, &slice, out)?;
    println!(
        "study.json, summary.json, slice.json and the figures in {}",
        out.display()
    );
    Ok(())
}

/// The zoo manifest of the repository.
fn zoo_manifest() -> Result<Zoo, Box<dyn std::error::Error>> {
    Ok(Zoo::from_file(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/zoo.toml"),
    )?)
}

/// Where `scripts/install_zoo.sh` puts the package's robots: `<target>/zoo-venv/lib/python*/site-packages/...`.
fn default_zoo_dir() -> Result<PathBuf, Box<dyn std::error::Error>> {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target"));
    let lib = target.join("zoo-venv/lib");
    let found = std::fs::read_dir(&lib).ok().and_then(|entries| {
        entries.filter_map(Result::ok).find_map(|entry| {
            let robots = entry
                .path()
                .join("site-packages/cmeel.prefix/share/example-robot-data/robots");
            robots.is_dir().then_some(robots)
        })
    });
    found.ok_or_else(|| {
        format!(
            "no example-robot-data under {}: run scripts/install_zoo.sh, or give --zoo-dir",
            lib.display()
        )
        .into()
    })
}

/// The study on every arm of the zoo (or those of `--arm`): per arm a directory of files, then `zoo.md` (unless
/// sharded). An arm whose scenario cannot be generated gets `error.txt` and a line in `zoo.md`, and fails the run.
fn zoo(options: &Options) -> Result<(), Box<dyn std::error::Error>> {
    let zoo = zoo_manifest()?;
    let dir = match &options.zoo_dir {
        Some(dir) => dir.clone(),
        None => default_zoo_dir()?,
    };
    for name in &options.arms {
        zoo.arm(name)?;
    }
    let out = options
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("target/convergence_domain/zoo"));
    let mut failed = Vec::new();
    for arm in &zoo.arms {
        if !options.arms.is_empty() && !options.arms.contains(&arm.name) {
            continue;
        }
        let arm_out = out.join(&arm.name);
        std::fs::create_dir_all(&arm_out)?;
        let _ = std::fs::remove_file(arm_out.join("error.txt"));
        println!("== {}", arm.name);
        let outcome = Zoo::scenario(arm, &dir).map_err(Box::<dyn std::error::Error>::from);
        let outcome = outcome.and_then(|scenario| {
            std::fs::write(arm_out.join("scenario.toml"), toml::to_string(&scenario)?)?;
            println!("{}", scenario.description);
            study(scenario, &arm.name, options, &arm_out, false)
        });
        if let Err(error) = outcome {
            eprintln!("{}: {error}", arm.name);
            std::fs::write(arm_out.join("error.txt"), format!("{error}\n"))?;
            failed.push(arm.name.clone());
        }
    }
    // A shard's or a dump's directories hold no whole study to tabulate.
    if options.shard.is_none() && options.dump.is_none() {
        std::fs::write(out.join("zoo.md"), zoo_markdown(&zoo, &out, &options.arms)?)?;
        println!("zoo.md in {}", out.display());
    }
    if failed.is_empty() {
        Ok(())
    } else {
        Err(format!("no study for {}", failed.join(", ")).into())
    }
}

/// The tables of the arms of `zoo` (or of `arms`) whose directories `out` holds, in the manifest's order, from their
/// files alone: a run whole and a merge of shards give the same text.
fn zoo_markdown(
    zoo: &Zoo,
    out: &Path,
    arms: &[String],
) -> Result<String, Box<dyn std::error::Error>> {
    let mut text = format!(
        "# The zoo: the convergence domain on the arms of {} {}\n\n\
         Written by `scripts/zoo_study.sh` (`convergence_domain --zoo`): per arm, the paper's scenario generated by \
         `servostack::scenario::generate` (the arm, its links and camera mount in `assets/zoo.toml`), and the draws \
         each method converged in, per family. *covered*: draws where the full method converged among those where a \
         baseline did; *worse*: draws where `stack_gradient` converged and the full method did not; *off goal*: runs of \
         the full method that settled away from the goal pose; *straight-feasible*: the draws the full method converged in \
         among those whose straight joint path to the goal keeps the target in view and the joints in their limits (with \
         the 95 % lower confidence bound of that share); *p95 / budget*: the 95th percentile of the iterations the full \
         method's converged runs took, as a share of each run's budget.\n",
        zoo.package, zoo.version
    );
    for arm in &zoo.arms {
        if !arms.is_empty() && !arms.contains(&arm.name) {
            continue;
        }
        let dir = out.join(&arm.name);
        text.push_str(&format!("\n## {}\n\n", arm.name));
        if let Ok(error) = std::fs::read_to_string(dir.join("error.txt")) {
            text.push_str(&format!("No study: {}\n", error.trim()));
            continue;
        }
        let path = dir.join("study.json");
        let result = StudyResult::from_json(
            &std::fs::read_to_string(&path)?,
            &path.display().to_string(),
        )?;
        let scenario = Scenario::from_file(dir.join("scenario.toml"))?;
        text.push_str(&format!(
            "{} joints. {}\n\n{} draws per family, seed {}.\n\n{}",
            scenario.joint_count()?,
            scenario.description,
            result.draws_per_family,
            result.seed,
            result.markdown_table()
        ));
    }
    Ok(text)
}

/// Merges the shards' directories: each holds `study.json` (one study) or one directory per arm (a zoo run).
fn merge(dirs: &[PathBuf], options: &Options) -> Result<(), Box<dyn std::error::Error>> {
    let first = dirs
        .first()
        .ok_or_else(|| format!("--merge needs the shards' directories; {USAGE}"))?;
    let out = options
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("target/convergence_domain/merged"));
    let read = |dir: &Path| -> Result<StudyResult, Box<dyn std::error::Error>> {
        let path = dir.join("study.json");
        let text = std::fs::read_to_string(&path)
            .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        Ok(StudyResult::from_json(&text, &path.display().to_string())?)
    };
    if first.join("study.json").is_file() {
        let parts = dirs
            .iter()
            .map(|d| read(d))
            .collect::<Result<Vec<_>, _>>()?;
        let merged = StudyResult::merge(&parts)?;
        print!("{merged}");
        merged.write_files(&out)?;
        println!("merged study.json and summary.json in {}", out.display());
        return Ok(());
    }
    // A zoo run: the arms of the manifest that the first shard has, each merged over the shards.
    let zoo = zoo_manifest()?;
    let mut arms = Vec::new();
    for arm in &zoo.arms {
        let arm_dir = first.join(&arm.name);
        if !arm_dir.is_dir() {
            continue;
        }
        arms.push(arm.name.clone());
        let arm_out = out.join(&arm.name);
        std::fs::create_dir_all(&arm_out)?;
        if let Ok(error) = std::fs::read_to_string(arm_dir.join("error.txt")) {
            std::fs::write(arm_out.join("error.txt"), error)?;
            continue;
        }
        std::fs::copy(arm_dir.join("scenario.toml"), arm_out.join("scenario.toml"))?;
        let parts = dirs
            .iter()
            .map(|d| read(&d.join(&arm.name)))
            .collect::<Result<Vec<_>, _>>()?;
        let merged = StudyResult::merge(&parts)?;
        println!("== {}", arm.name);
        print!("{merged}");
        merged.write_files(&arm_out)?;
    }
    if arms.is_empty() {
        return Err(format!(
            "{} holds neither study.json nor a directory of a zoo arm",
            first.display()
        )
        .into());
    }
    std::fs::write(out.join("zoo.md"), zoo_markdown(&zoo, &out, &arms)?)?;
    println!("merged files and zoo.md in {}", out.display());
    Ok(())
}

#[cfg(feature = "plot")]
mod figures {
    use servostack::plot::{FigureStyle, LinePlot, Marker, OutcomeMap, Series};
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
            style: FigureStyle::new(1800, 520),
        };
        map.render(out, "slice")?;
        Ok(())
    }
}
