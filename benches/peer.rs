//! servostack on the peer scene (docs/peer_scene.md, `servostack::theory::peer_scene`), with ViSP's timing protocol, for a side-by-side comparison.
//!
//! Per variant (A points, B moments, C points + joint limits + continuity, CL: C with ViSP's large projection
//! operator, the like-for-like of ViSP's C): one untimed warm-up episode, then
//! [`EPISODES`] episodes of [`ITERATIONS`] iterations, each restarting at `q0`, `t = 0` (the reset is not timed);
//! batches of [`BATCH`] iterations are timed with `std::time::Instant`. One JSON line per variant:
//! `{"variant", "ns_per_iter_median", "ns_per_iter_min", "iters", "final_error"}`, where `final_error` is `‖e‖` after
//! the last iteration of an episode (small: the loop servos).
//!
//! Run with `cargo bench --bench peer` (all variants) or `cargo bench --bench peer -- A` (one).

#[path = "common/servo_loop.rs"]
mod servo_loop;

use servo_loop::{ServoLoop, Variant};
use std::time::Instant;

/// Timed episodes per variant.
const EPISODES: usize = 20;
/// Iterations per episode.
const ITERATIONS: usize = 1000;
/// Iterations per timed batch.
const BATCH: usize = 100;

/// Runs one episode from `q0`; returns the batch times (ns per iteration) and `‖e‖` at the end.
fn episode(servo: &mut ServoLoop, batches: &mut Vec<f64>) -> f64 {
    servo.reset();
    for _ in 0..ITERATIONS / BATCH {
        let start = Instant::now();
        for _ in 0..BATCH {
            servo.step();
        }
        batches.push(start.elapsed().as_nanos() as f64 / BATCH as f64);
    }
    servo.error_norm()
}

fn main() {
    // `cargo bench` passes `--bench`; a test run (`cargo test --benches`) passes nothing: run one short episode only.
    let benchmarking = std::env::args().any(|a| a == "--bench");
    // Other arguments select variants by name (`cargo bench --bench peer -- A C`); none selects all.
    let selected: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    for variant in Variant::ALL {
        if !(selected.is_empty() || selected.iter().any(|s| s == variant.name())) {
            continue;
        }
        let mut servo = ServoLoop::peer(variant);
        let mut batches = Vec::with_capacity(EPISODES * ITERATIONS / BATCH);
        let mut final_error = episode(&mut servo, &mut batches); // warm-up
        if benchmarking {
            batches.clear();
            for _ in 0..EPISODES {
                final_error = episode(&mut servo, &mut batches);
            }
        }
        batches.sort_by(f64::total_cmp);
        let median = batches[batches.len() / 2];
        let min = batches[0];
        println!(
            "{{\"variant\": \"{}\", \"ns_per_iter_median\": {median:.1}, \"ns_per_iter_min\": {min:.1}, \"iters\": {ITERATIONS}, \"final_error\": {final_error:.3e}}}",
            variant.name()
        );
    }
}
