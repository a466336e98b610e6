//! Obstacle avoidance with the stack controller (issue 6): the Afma6 servos towards the four-point target while a
//! world obstacle stands where the classical law and the stack with projected gradient drive a link into it; the full
//! method removes the task that blocks the avoidance, goes round, puts the task back and reaches the goal without
//! collision. Runs the paper's four runs on `assets/scenarios/obstacle_afma6.toml`, prints a table and writes the
//! figures (joints, errors, image, criteria, and the smallest link–obstacle distance over time) and `summary.json`
//! (the paper experiment's schema plus `min_obstacle_distance` and the `collision` outcome).
//!
//! `cargo run --release --example obstacle_avoidance [-- --out DIR]` (default DIR: `target/obstacle_avoidance`)

use servostack::report::write_experiment;
use servostack::scenario::Scenario;
use std::path::PathBuf;

fn main() -> std::process::ExitCode {
    servostack::report::exit_code(run())
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = match args.as_slice() {
        [] => PathBuf::from("target/obstacle_avoidance"),
        [flag, dir] if flag == "--out" => PathBuf::from(dir),
        _ => return Err("usage: obstacle_avoidance [--out DIR]".into()),
    };
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/obstacle_afma6.toml");
    let scenario = Scenario::from_file(&path)?;
    let summary = write_experiment::<6>(&scenario, &out)?;
    print!("{summary}");
    println!("figures and summary.json in {}", out.display());
    Ok(())
}
