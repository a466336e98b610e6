//! The fuzz harness in the test suite ([D17](servostack::theory#d17)): a bounded, seeded run of mutated URDFs,
//! mutated scenario files and random control-step inputs, and the replay of every input that once failed
//! (`tests/data/fuzz_regressions/`). Each case runs on a 2 MiB worker thread with a time limit: no panic, no hang,
//! no non-finite value inside `Ok`. Longer runs: `cargo run --release --example fuzz -- --seconds 600`.

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use servostack::fuzz::{
    calibration_case, case_from_file, mesh_case, regression_file, scenario_case, urdf_case, Case,
    Counts, Verdict, Worker,
};
use std::path::Path;
use std::time::Duration;

/// Generous on a loaded 2-core machine: a case takes milliseconds.
const LIMIT: Duration = Duration::from_secs(30);

/// Runs `cases` and asserts that none failed, naming the first failures with their regression file names.
fn run_all(label: &str, cases: impl IntoIterator<Item = Case>) -> Counts {
    let mut worker = Worker::new().unwrap();
    let mut counts = Counts::default();
    let mut failures = Vec::new();
    for case in cases {
        let verdict = worker.run(case.clone(), LIMIT);
        counts.add(verdict.as_ref());
        if verdict.as_ref().is_none_or(Verdict::is_failure) {
            failures.push(format!("{} → {verdict:?}", regression_file(&case).0));
            if verdict.is_none() {
                worker = Worker::new().unwrap();
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{label}: {counts}\n{}",
        failures.join("\n")
    );
    counts
}

#[test]
fn mutated_urdfs_neither_panic_hang_nor_return_non_finite_values() {
    let mut rng = StdRng::seed_from_u64(14);
    let counts = run_all("urdf", (0..4000).map(|_| urdf_case(&mut rng)));
    // The mutations must reach the kinematics, not only the parser's errors.
    assert!(counts.accepted > 100, "{counts}");
}

#[test]
fn mutated_scenarios_neither_panic_hang_nor_return_non_finite_values() {
    let mut rng = StdRng::seed_from_u64(15);
    let counts = run_all("scenario", (0..400).map(|_| scenario_case(&mut rng)));
    assert!(counts.accepted > 10, "{counts}");
}

#[test]
fn random_control_step_inputs_neither_panic_nor_return_non_finite_values() {
    let mut rng = StdRng::seed_from_u64(16);
    let counts = run_all(
        "control",
        (0..4000).map(|_| Case::Control { seed: rng.random() }),
    );
    assert!(counts.accepted > 100, "{counts}");
}

#[test]
fn mutated_meshes_neither_panic_hang_nor_return_non_finite_values() {
    let mut rng = StdRng::seed_from_u64(17);
    let counts = run_all("mesh", (0..2000).map(|_| mesh_case(&mut rng)));
    // The mutations must reach the convex hull and the distance query, not only the readers' errors.
    assert!(counts.accepted > 200, "{counts}");
}

#[test]
fn mutated_calibration_files_neither_panic_hang_nor_return_wrong_values() {
    let mut rng = StdRng::seed_from_u64(18);
    let counts = run_all("calibration", (0..2000).map(|_| calibration_case(&mut rng)));
    // About one mutated file in ten still loads and has its pixels undistorted and checked.
    assert!(counts.accepted > 100, "{counts}");
}

#[test]
fn corrupted_facade_sequences_neither_panic_nor_return_non_finite_values() {
    let mut rng = StdRng::seed_from_u64(19);
    let counts = run_all(
        "servo",
        (0..100).map(|_| Case::Servo { seed: rng.random() }),
    );
    assert_eq!(counts.accepted, 100, "{counts}");
}

#[test]
fn every_input_that_once_failed_passes() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/fuzz_regressions");
    let mut cases = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let content = std::fs::read(&path).unwrap();
        cases.push(case_from_file(&name, &content).unwrap_or_else(|| panic!("{name}: no case")));
    }
    assert!(!cases.is_empty());
    run_all("regressions", cases);
}
