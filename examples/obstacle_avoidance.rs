//! Obstacle avoidance with the stack controller (issue 6): the Afma6 servos towards the four-point target while a
//! world obstacle stands where the classical law and the stack with projected gradient drive a link into it; the full
//! method removes the task that blocks the avoidance, goes round, puts the task back and reaches the goal without
//! collision. Runs the paper's four runs on `assets/scenarios/obstacle_afma6.toml`, prints a table and writes the
//! figures (joints, errors, image, criteria, and the smallest link–obstacle distance over time) and `summary.json`
//! (the paper experiment's schema plus `min_obstacle_distance` and the `collision` outcome).
//!
//! `cargo run --release --example obstacle_avoidance [-- [SCENARIO.toml] [--out DIR]]` (default DIR:
//! `target/obstacle_avoidance`). Another scenario with `[[obstacles]]` runs the same way, on any robot of 1 to 12 joints
//! whose URDF gives its links collision shapes — primitives or STL/OBJ/COLLADA meshes, e.g.
//! `assets/scenarios/obstacle_mesh_afma6.toml`, whose links are STL meshes.

use servostack::report::write_scenario_experiment;
use servostack::scenario::Scenario;
use std::path::PathBuf;

fn main() -> std::process::ExitCode {
    servostack::report::exit_code(run())
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let default_scenario =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/obstacle_afma6.toml");
    let default_out = PathBuf::from("target/obstacle_avoidance");
    let (path, out) = match args.as_slice() {
        [] => (default_scenario, default_out),
        [flag, dir] if flag == "--out" => (default_scenario, PathBuf::from(dir)),
        [path] => (PathBuf::from(path), default_out),
        [path, flag, dir] if flag == "--out" => (PathBuf::from(path), PathBuf::from(dir)),
        _ => return Err("usage: obstacle_avoidance [SCENARIO.toml] [--out DIR]".into()),
    };
    let scenario = Scenario::from_file(&path)?;
    let summary = write_scenario_experiment(&scenario, &out)?;
    print!("{summary}");
    println!("figures and summary.json in {}", out.display());
    Ok(())
}
