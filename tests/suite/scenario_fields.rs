//! One source of truth (issue 45): every field of a scenario file changes the runs or is refused, and each reaches
//! the run through exactly one of the two parts a code path holds — the world ([`Experiment`]) or the method's
//! [`Settings`] — so that running a world with settings never ignores a field.
//!
//! The test walks every leaf of the serialised scenario (each number of an array, each string and flag, every
//! section of three base scenarios that between them fill every section: the paper's, its real camera with a depth
//! source, and an obstacle with a visibility cost; plus the paper's with every optional value written out), perturbs
//! it and checks:
//!
//! 1. **it counts**: the perturbed scenario's four runs differ from the base's (outcome, iterations, events, final
//!    joints), or the scenario is refused with an error that names the field;
//! 2. **it has one home**: a world field's perturbed [`Experiment`] run with the base's settings, or the base's
//!    experiment run with a settings field's perturbed [`Settings`], gives exactly the perturbed scenario's runs.
//!
//! The conflicts a code path can meet (a lens given both with the camera and in the settings, a visibility cost
//! both in the scene and in the settings, a missing goal) are refused with the field named.

use servostack::camera::{BrownConrady, CalibratedCamera, CameraIntrinsics};
use servostack::prelude::*;
use servostack::scenario::{ScenarioError, VisibilitySpec};
use std::path::PathBuf;
use toml::Value;

fn assets(file: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("assets/scenarios")
        .join(file)
}

/// Labels, not inputs of a run: they name the scenario in summaries and explain it.
const LABELS: [&str; 2] = ["name", "description"];

/// The sections of the method's settings ([`Scenario::settings`]); the others are the world.
const SETTINGS: [&str; 7] = [
    "tasks",
    "avoidance",
    "controller",
    "simulation",
    "visibility",
    "measurement",
    "depth",
];

/// What a run is, compared exactly (f64 printed to round trip).
fn fingerprint(run: &Run<6>) -> String {
    format!(
        "{:?} {} {:?} {:?}",
        run.outcome,
        run.iterations(),
        run.events,
        run.last_record().map(|r| r.q)
    )
}

/// The full method first; the three others when it alone does not tell.
const KINDS: [&[RunKind]; 2] = [
    &[RunKind::FullMethod],
    &[RunKind::Classical, RunKind::Stack, RunKind::StackGradient],
];

/// The runs of a scenario, or its error's message.
fn runs(scenario: &Scenario, kinds: &[RunKind]) -> Result<Vec<String>, String> {
    kinds
        .iter()
        .map(|&kind| scenario.run::<6>(kind).map(|run| fingerprint(&run)))
        .collect::<Result<_, ScenarioError>>()
        .map_err(|e| e.to_string())
}

/// The runs of a world (or its error) with settings.
fn runs_of(
    experiment: Result<Experiment<6>, ScenarioError>,
    settings: &Settings,
    kinds: &[RunKind],
) -> Result<Vec<String>, String> {
    let experiment = experiment.map_err(|e| e.to_string())?;
    kinds
        .iter()
        .map(|&kind| experiment.run(settings, kind).map(|run| fingerprint(&run)))
        .collect::<Result<_, ScenarioError>>()
        .map_err(|e| e.to_string())
}

/// How a perturbation of a leaf counted.
enum Counted {
    /// The runs of these kinds changed, and the field's part alone changes them so.
    Changed,
    /// Refused, the error naming the field.
    Refused,
    /// Neither.
    No,
}

/// Whether `scenario`, `path` of `base` perturbed, counts: its runs differ from the base's (`base_runs`, per set of
/// kinds) and its part alone makes the same runs, or it is refused naming the field.
fn counts(
    base: &Scenario,
    base_runs: &[Vec<String>; 2],
    scenario: &Scenario,
    path: &str,
) -> Counted {
    let section = path.split(['.', '[']).next().unwrap();
    for (kinds, base_runs) in KINDS.iter().zip(base_runs) {
        let perturbed = runs(scenario, kinds);
        if let Err(message) = &perturbed {
            let field = path.split('[').next().unwrap();
            if message.contains(field) || message.contains(field.rsplit('.').next().unwrap()) {
                return Counted::Refused;
            }
        }
        if perturbed.as_ref() == Ok(base_runs) {
            continue;
        }
        // One home: the perturbed part alone, with the base's other part, gives the perturbed runs (or error).
        let alone = if SETTINGS.contains(&section) {
            runs_of(base.experiment::<6>(), &scenario.settings(), kinds)
        } else {
            runs_of(scenario.experiment::<6>(), &base.settings(), kinds)
        };
        assert_eq!(
            alone, perturbed,
            "{path} is not carried by `{section}` alone"
        );
        return Counted::Changed;
    }
    Counted::No
}

/// Every leaf of a TOML value, with its dotted path (`tasks.gains[2]`).
fn leaves(value: &Value, path: String, out: &mut Vec<String>) {
    match value {
        Value::Table(table) => {
            for (key, value) in table {
                let path = if path.is_empty() {
                    key.clone()
                } else {
                    format!("{path}.{key}")
                };
                leaves(value, path, out);
            }
        }
        Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                leaves(item, format!("{path}[{i}]"), out);
            }
        }
        _ => out.push(path),
    }
}

/// The leaf at `path`, mutable.
fn leaf<'v>(value: &'v mut Value, path: &str) -> &'v mut Value {
    let mut value = value;
    for part in path.split('.') {
        let (key, indices) = part.split_once('[').map_or((part, ""), |(k, i)| (k, i));
        value = value.get_mut(key).unwrap();
        for index in indices.split('[').filter(|i| !i.is_empty()) {
            let i: usize = index.trim_end_matches(']').parse().unwrap();
            value = value.get_mut(i).unwrap();
        }
    }
    value
}

/// The values tried in place of a leaf, in order.
fn candidates(value: &Value) -> Vec<Value> {
    const WORDS: [&[&str]; 9] = [
        &["desired", "previous_plane", "target_pose"],
        &["exact", "paper_approx", "desired"],
        &["auto", "paper_invariants", "side_ratios"],
        &["combined", "normalized_direction", "kernel_projection"],
        &["robust", "paper"],
        &["hold", "predict"],
        &["afma6", "afma6_coupled"],
        &["brake_and_lock", "saturate_in_null_space"],
        &["one_by_one", "all_at_once"],
    ];
    match value {
        Value::Float(x) => [
            x * 1.1,
            x * 0.9,
            x + 0.01,
            x * 0.1,
            x * 10.0,
            -x,
            1.0,
            x + 100.0,
        ]
        .into_iter()
        .filter(|y| y != x)
        .map(Value::Float)
        .collect(),
        Value::Integer(n) => [n + 1, n / 10, n * 10, 1, 0]
            .into_iter()
            .filter(|m| m != n)
            .map(Value::Integer)
            .collect(),
        Value::Boolean(b) => vec![Value::Boolean(!b)],
        Value::String(s) => {
            let mut words: Vec<Value> = WORDS
                .iter()
                .filter(|w| w.contains(&s.as_str()))
                .flat_map(|w| {
                    w.iter()
                        .filter(|&&o| o != s)
                        .map(|o| Value::String((*o).into()))
                })
                .collect();
            // Names of links and obstacles: another one of the file, or one that does not exist.
            words.push(Value::String("afma6_base".into()));
            words.push(Value::String(format!("{s}_renamed")));
            words
        }
        other => panic!("no perturbation of {other:?}"),
    }
}

/// The base scenarios: between them, every section and every optional value.
fn bases() -> Vec<(&'static str, Scenario)> {
    let paper = Scenario::from_file(assets("paper_afma6.toml")).unwrap();
    let mut explicit = paper.clone();
    // Every optional value of the paper's scenario written out at the value it defaults to (the same runs).
    explicit.tasks.a_priori_depth_m = Some(0.5);
    explicit.tasks.area_depth_m = Some(0.5);
    explicit.avoidance.transition_gain = Some(5.0);
    explicit.tasks.adaptive_gain = Some(servostack::scenario::AdaptiveGainSpec {
        at_zero: 0.5,
        at_infinity: 0.6,
        slope_at_zero: -0.1,
    });
    let mut approx = paper.clone();
    approx.tasks.interaction = servostack::scenario::InteractionKind::PaperApprox;
    approx.tasks.a_priori_depth_m = Some(0.5);
    let obstacle = Scenario::from_file(assets("obstacle_afma6.toml")).unwrap();
    // A box turned about each axis: its orientation counts, as a ball's does not.
    let mut turned = obstacle.clone();
    turned.obstacles[0].shape = servostack::avoidance::Geometry::Box {
        size_m: [0.06, 0.05, 0.04],
    };
    turned.obstacles[0].pose.rpy_deg = [20.0, 30.0, 40.0];
    let data = |file: &str| {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/scenarios")
            .join(file);
        Scenario::from_file(path).unwrap()
    };
    // A start from which the full method falls back near a limit (D13), where `hold_before_limit` decides.
    let mut held = Scenario::from_file(assets("ur5e_limits.toml")).unwrap();
    held.start.joints = vec![
        0.3560873414373177,
        -1.5739632051254162,
        1.95,
        -1.899299563923933,
        -1.7223120207615334,
        1.5537935128636933,
    ];
    vec![
        ("paper", paper),
        ("paper, optional values written", explicit),
        ("paper, paper_approx", approx),
        (
            "real camera",
            Scenario::from_file(assets("paper_afma6_real_camera.toml")).unwrap(),
        ),
        ("obstacle", obstacle),
        ("obstacle, a turned box", turned),
        ("false equilibrium", data("afma6_false_equilibrium.toml")),
        ("view turned", data("afma6_view_turned.toml")),
        ("ur5e limits, a fallback", held),
        // A replay that comes back to the rest it restarted from, where `recentre_all_on_repeat` decides (D29).
        (
            "ur5e, a repeated restart",
            data("ur5e_repeated_restart.toml"),
        ),
        // A start from which the target leaves the image unless braked before its border (D25).
        ("afma6, the image border", data("afma6_image_border.toml")),
    ]
}

#[test]
fn every_scenario_field_changes_the_runs_or_is_refused_and_has_one_home() {
    let mut seen = std::collections::BTreeSet::new();
    let mut counted = std::collections::BTreeMap::new();
    let mut refused = std::collections::BTreeMap::new();
    for (base_name, base) in bases() {
        let base_runs = KINDS.map(|kinds| runs(&base, kinds).unwrap());
        let value = Value::try_from(&base).unwrap();
        let mut paths = Vec::new();
        leaves(&value, String::new(), &mut paths);
        for path in paths {
            let section = path.split(['.', '[']).next().unwrap();
            if LABELS.contains(&section) || counted.contains_key(&path) {
                continue;
            }
            seen.insert(path.clone());
            for candidate in candidates(leaf(&mut value.clone(), &path)) {
                let mut changed = value.clone();
                *leaf(&mut changed, &path) = candidate.clone();
                let Ok(scenario) = changed.try_into::<Scenario>() else {
                    continue; // not a value of the field's type (another enumeration's word)
                };
                let scenario = Scenario {
                    base_dir: base.base_dir.clone(),
                    ..scenario
                };
                // A value that changes the runs is looked for first; a refusal (an invalid value named) is kept
                // only when no value of any base changes them.
                match counts(&base, &base_runs, &scenario, &path) {
                    Counted::No => continue,
                    Counted::Changed => {
                        let how = format!("{base_name}: {candidate} changes the runs");
                        counted.insert(path.clone(), how);
                        refused.remove(&path);
                        break;
                    }
                    Counted::Refused => {
                        let how = format!("{base_name}: {candidate} is refused");
                        refused.entry(path.clone()).or_insert(how);
                    }
                }
            }
        }
    }
    counted.extend(refused);
    let inert: Vec<_> = seen.iter().filter(|p| !counted.contains_key(*p)).collect();
    assert!(
        inert.is_empty(),
        "fields that neither change a run nor are refused: {inert:?}"
    );
    // Every section of a scenario file is among those walked.
    let sections = ["robot", "camera", "target", "desired", "start", "obstacles"];
    for section in sections.iter().chain(&SETTINGS) {
        assert!(
            seen.iter().any(|p| p.starts_with(section)),
            "no field of `{section}` walked"
        );
    }
    println!("{counted:#?}");
}

/// A code path that is given a value twice, in the world and in the settings, is refused with the field named.
#[test]
fn conflicts_between_the_world_and_the_settings_are_refused() {
    let paper = Scenario::from_file(assets("paper_afma6.toml")).unwrap();
    let world = paper.experiment::<6>().unwrap();
    let settings = paper.settings();
    let intrinsics = *world.scene.intrinsics();
    let lens = BrownConrady::new(-0.1, 0.02, 0.0, 0.0, 0.0).unwrap();
    let robot = builtin::afma6().unwrap();
    let builder = || {
        let camera = CalibratedCamera {
            intrinsics,
            distortion: lens,
        };
        Experiment::builder(
            robot.chain.clone(),
            robot.mount,
            camera,
            *world.scene.target(),
        )
    };
    let distorted = builder()
        .goal(world.desired_joints, world.desired_camera_from_target)
        .start(world.start)
        .build()
        .unwrap();

    // The lens: from the camera, or the same in the settings; another one is refused.
    let mut same = settings;
    same.measurement.distortion_coefficients = [-0.1, 0.02, 0.0, 0.0, 0.0];
    let from_camera = fingerprint(&distorted.run(&settings, RunKind::FullMethod).unwrap());
    assert_eq!(
        from_camera,
        fingerprint(&distorted.run(&same, RunKind::FullMethod).unwrap())
    );
    assert_eq!(
        from_camera,
        fingerprint(&world.run(&same, RunKind::FullMethod).unwrap())
    );
    let mut other = settings;
    other.measurement.distortion_coefficients = [-0.2, 0.0, 0.0, 0.0, 0.0];
    let error = distorted.run(&other, RunKind::FullMethod).unwrap_err();
    assert!(
        error
            .to_string()
            .contains("measurement.distortion_coefficients"),
        "{error}"
    );

    // A rational lens: the simulated measurement takes the five plumb-bob coefficients, so the run is refused.
    let rational = CalibratedCamera {
        intrinsics,
        distortion: BrownConrady::from_coefficients(&[-0.1, 0.02, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0])
            .unwrap(),
    };
    let error = Experiment::builder(
        robot.chain.clone(),
        robot.mount,
        rational,
        *world.scene.target(),
    )
    .goal(world.desired_joints, world.desired_camera_from_target)
    .start(world.start)
    .build()
    .unwrap()
    .run(&settings, RunKind::FullMethod)
    .unwrap_err();
    assert!(error.to_string().contains("plumb-bob lens"), "{error}");

    // A visibility cost in the scene and in the settings.
    let mut seen = world.clone();
    seen.scene = seen.scene.with_visibility_margin(30.0).unwrap();
    let twice = Settings {
        visibility: Some(VisibilitySpec { margin_px: 30.0 }),
        ..settings
    };
    let error = seen.run(&twice, RunKind::FullMethod).unwrap_err();
    assert!(error.to_string().contains("`visibility`"), "{error}");

    // A builder without a goal or a start, or with a start outside the limits.
    let error = builder().start(world.start).build().unwrap_err();
    assert!(error.to_string().contains("`desired`"), "{error}");
    let error = builder()
        .goal(world.desired_joints, world.desired_camera_from_target)
        .build()
        .unwrap_err();
    assert!(error.to_string().contains("`start`"), "{error}");
    let outside = world.start + JointVector::<6>::from([0.0, 0.0, -10.0, 0.0, 0.0, 0.0]);
    let error = builder()
        .goal(world.desired_joints, world.desired_camera_from_target)
        .start(outside)
        .build()
        .unwrap_err();
    assert!(error.to_string().contains("start.joints"), "{error}");

    // Intrinsics are a camera too: the same runs as the scenario's.
    let pinhole = Experiment::builder(robot.chain, robot.mount, intrinsics, *world.scene.target())
        .goal(world.desired_joints, world.desired_camera_from_target)
        .start(world.start)
        .build()
        .unwrap();
    let _: CameraIntrinsics = intrinsics;
    for kind in RunKind::ALL {
        assert_eq!(
            fingerprint(&pinhole.run(&settings, kind).unwrap()),
            fingerprint(&paper.run(kind).unwrap()),
            "{}",
            kind.name()
        );
    }
}

/// [`Settings::default`] is the paper scenario's settings, and the scenario's runs are its world's with them.
#[test]
fn the_default_settings_are_the_papers() {
    let paper = Scenario::from_file(assets("paper_afma6.toml")).unwrap();
    assert_eq!(Settings::default(), paper.settings());
    let mut copy = paper.clone();
    copy.set_settings(Settings::default());
    assert_eq!(copy, paper);
}
