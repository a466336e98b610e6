//! The paper's four runs on the reference scenario (theory §9, D12): classical servoing, the stack, the stack with
//! projected-gradient avoidance, and the full method with the stack controller. Prints a table and writes the figures
//! (PNG and SVG) and `summary.json`.
//!
//! `cargo run --release --example paper_experiment [-- --out DIR]` (default DIR: `target/paper_experiment`)

use servostack::report::write_experiment;
use servostack::scenario::Scenario;
use std::path::PathBuf;

fn main() -> std::process::ExitCode {
    servostack::report::exit_code(run())
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = match args.as_slice() {
        [] => PathBuf::from("target/paper_experiment"),
        [flag, dir] if flag == "--out" => PathBuf::from(dir),
        _ => return Err("usage: paper_experiment [--out DIR]".into()),
    };
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/paper_afma6.toml");
    let scenario = Scenario::from_file(&path)?;
    let summary = write_experiment::<6>(&scenario, &out)?;
    print!("{summary}");
    println!("figures and summary.json in {}", out.display());
    Ok(())
}
