//! Study throughput on 1 and on all cores, and the simulation's cost per iteration beside the controller step it wraps.
//!
//! * `study`: the convergence-domain study of the four methods on `assets/scenarios/paper_afma6.toml`, the eight
//!   standard families, [`DRAWS`] draws per family, seed 1, run in a rayon pool of 1 thread, then of every core
//!   (`available_parallelism`). One JSON line per pool: draws, simulated control iterations, seconds, draws/s,
//!   iterations/s; a last line gives the scaling (rate on all cores / rate on one).
//! * `sim_overhead`: the full method (`RunKind::FullMethod`) on the paper scenario through `Experiment::run`
//!   (simulation: sensing, tasks, controller, saturation, every record kept) and through
//!   `Experiment::run_with` and a `SummaryOnly` log (as the study runs it), ns per simulated iteration, beside the controller step of
//!   the `control_loop` bench (`step/paper_four_tasks_controller`: observation, the four paper tasks, controller with
//!   avoidance, prediction and criteria, Euler step; no log, no saturation) on the peer scene, ns per step, and the
//!   overheads `sim / step − 1`; then the same against the step with the full method's costs
//!   (`step/paper_full_method`: the visibility of the target in the avoidance cost and as the removal guard, as
//!   `sim::simulate_with` does). The runs do different work (the scenario's episode, with its pushes and removals,
//!   its reserve task and its joint locks, against the steady peer episode), so these ratios are indicative. The
//!   overhead on the same work comes from `scripts/sim_overhead.sh`, which samples this bench with `perf` and splits
//!   the simulation's own time from that of the control step inside it. The best of [`REPEATS`] runs of each.
//!
//! Run with `cargo bench --bench throughput` (both) or `cargo bench --bench throughput -- study` (one). Under
//! `cargo test --benches` (no `--bench` argument) it runs one draw per family and one repeat: a smoke test.

#[path = "common/servo_loop.rs"]
mod servo_loop;

use servo_loop::ServoLoop;
use servostack::scenario::{RunKind, Scenario};
use servostack::sim::SummaryOnly;
use servostack::study::{standard_families, Study};
use std::path::Path;
use std::time::Instant;

/// Draws per family of the study benchmark.
const DRAWS: usize = 4;
/// Repeats of the simulation and of the controller episode (the best is kept).
const REPEATS: usize = 5;
/// Steps per controller episode (as the peer protocol).
const EPISODE: usize = 1000;

fn scenario() -> Scenario {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/scenarios/paper_afma6.toml");
    Scenario::from_file(&path).expect("paper scenario")
}

fn study(draws: usize) {
    let scenario = scenario();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut rates = Vec::new();
    for threads in [1, cores] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        let study = Study::new(&scenario, standard_families(), draws, 1).expect("study");
        let start = Instant::now();
        let result = pool.install(|| study.run()).expect("study run");
        let seconds = start.elapsed().as_secs_f64();
        let total_draws = draws * result.families.len();
        let rate = result.iterations as f64 / seconds;
        rates.push(rate);
        println!(
            "{{\"bench\": \"study\", \"threads\": {threads}, \"draws\": {total_draws}, \"iterations\": {}, \"seconds\": {seconds:.3}, \"draws_per_s\": {:.2}, \"iterations_per_s\": {rate:.0}}}",
            result.iterations,
            total_draws as f64 / seconds
        );
    }
    println!(
        "{{\"bench\": \"study_scaling\", \"cores\": {cores}, \"speedup\": {:.2}}}",
        rates[1] / rates[0]
    );
}

fn sim_overhead(repeats: usize) {
    let scenario = scenario();
    let experiment = scenario.experiment::<6>().expect("experiment");
    // ns per simulated iteration, best of `repeats`, with every record kept or with the summary only.
    let mut iterations = 0;
    let mut per_iteration = |keep_records: bool| {
        let mut best = f64::INFINITY;
        for _ in 0..repeats {
            let start = Instant::now();
            let run = if keep_records {
                experiment.run(&scenario.settings(), RunKind::FullMethod)
            } else {
                experiment.run_with(&scenario.settings(), RunKind::FullMethod, &mut SummaryOnly)
            }
            .expect("run");
            let elapsed = start.elapsed().as_nanos() as f64;
            iterations = run.iterations();
            best = best.min(elapsed / iterations as f64);
        }
        best
    };
    let sim_ns = per_iteration(true);
    let summary_ns = per_iteration(false);
    // The controller step alone, on the peer scene: the paper's (joint limits only) and the full method's as the
    // simulation runs it (visibility in the avoidance cost and as the removal guard).
    let step_ns = |mut servo: ServoLoop| {
        let mut best = f64::INFINITY;
        for _ in 0..repeats {
            servo.reset();
            servo.settle();
            let start = Instant::now();
            for _ in 0..EPISODE {
                servo.step();
            }
            best = best.min(start.elapsed().as_nanos() as f64 / EPISODE as f64);
        }
        best
    };
    let paper_ns = step_ns(ServoLoop::paper());
    let full_ns = step_ns(ServoLoop::paper_full_method());
    println!(
        "{{\"bench\": \"sim_overhead\", \"sim_iterations\": {iterations}, \"sim_ns_per_iteration\": {sim_ns:.0}, \"summary_only_ns_per_iteration\": {summary_ns:.0}, \"controller_step_ns\": {paper_ns:.0}, \"overhead\": {:.2}, \"overhead_summary_only\": {:.2}, \"full_method_step_ns\": {full_ns:.0}, \"overhead_vs_full_method_step\": {:.2}, \"overhead_summary_only_vs_full_method_step\": {:.2}}}",
        sim_ns / paper_ns - 1.0,
        summary_ns / paper_ns - 1.0,
        sim_ns / full_ns - 1.0,
        summary_ns / full_ns - 1.0
    );
}

fn main() {
    let benchmarking = std::env::args().any(|a| a == "--bench");
    let selected: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let wanted = |name: &str| selected.is_empty() || selected.iter().any(|s| s == name);
    if wanted("study") {
        study(if benchmarking { DRAWS } else { 1 });
    }
    if wanted("sim_overhead") {
        sim_overhead(if benchmarking { REPEATS } else { 1 });
    }
}
