//! The simulation's run logs ([D17](servostack::theory#d17)): a run of any length in bounded memory, with the same
//! summary as with every record kept.

use servostack::scenario::{RunKind, Scenario};
use servostack::sim::{Decimated, JsonLines, Run, RunLog, SummaryOnly};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Counts the bytes live on the heap and their peak (all threads), then delegates to the system allocator.
struct PeakAllocator;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grow(bytes: usize) {
    let live = LIVE.fetch_add(bytes, Ordering::Relaxed) + bytes;
    PEAK.fetch_max(live, Ordering::Relaxed);
}

#[allow(unsafe_code)]
unsafe impl GlobalAlloc for PeakAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        grow(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        grow(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: PeakAllocator = PeakAllocator;

/// The UR5e scenario with an unreachable convergence threshold: every run spends its whole budget.
fn endless(iterations: usize) -> Scenario {
    let mut scenario =
        Scenario::from_toml_str(include_str!("../assets/scenarios/ur5e.toml"), None).unwrap();
    scenario.simulation.max_iterations = iterations;
    scenario.simulation.convergence_error = f64::MIN_POSITIVE;
    scenario
}

/// The peak heap growth (bytes) of a run of `iterations` into `log`, and the run.
fn peak_growth(iterations: usize, log: &mut dyn RunLog<6>) -> (usize, Run<6>) {
    let scenario = endless(iterations);
    let experiment = scenario.experiment::<6>().unwrap();
    let before = LIVE.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    let run = experiment
        .run_with(&scenario.settings(), RunKind::Stack, log)
        .unwrap();
    (PEAK.load(Ordering::Relaxed) - before, run)
}

// One test function: the peak counter is global, so the measurements must not overlap with other tests' runs.
#[test]
fn memory_is_bounded_and_the_summary_exact_whatever_the_log_keeps() {
    // Summary only: ten times the iterations, the same peak (the full log of the same runs grows ~1 KB an iteration).
    let (short, short_run) = peak_growth(1_000, &mut SummaryOnly);
    let (long, long_run) = peak_growth(10_000, &mut SummaryOnly);
    assert_eq!(long_run.iterations(), 10_000);
    assert_eq!(long_run.outcome.name(), "max_iterations");
    assert!(
        long <= short + 4096,
        "peak {short} B for 1,000 iterations, {long} B for 10,000"
    );
    let mut records = Vec::new();
    let (full, _) = peak_growth(10_000, &mut records);
    assert!(
        full > long + 5_000_000,
        "the full log peaks at {full} B, the summary at {long} B"
    );

    // The summary without the records is the one computed with them.
    let full_run = endless(10_000).run::<6>(RunKind::Stack).unwrap();
    assert_eq!(full_run.records, records);
    assert_eq!(long_run.iterations(), full_run.records.len());
    assert_eq!(long_run.last_record(), full_run.records.last());
    assert_eq!(long_run.final_error_norm(), full_run.final_error_norm());
    let steps = full_run.velocity_steps();
    assert_eq!(
        long_run.max_velocity_step(),
        steps.iter().copied().fold(0.0, f64::max)
    );
    assert_eq!(long_run.event_continuity(), full_run.event_continuity());
    assert!(!long_run.event_continuity().is_empty());
    for change in long_run.event_continuity() {
        // The jump is the velocity step at the change's iteration (D14).
        assert_eq!(change.jump, steps[change.iteration]);
    }
    assert_eq!(
        long_run.min_normalized_margin(),
        full_run.min_normalized_margin()
    );
    drop(short_run);

    // Decimated: at most its capacity, evenly spaced, the first iteration kept.
    let mut decimated = Decimated::new(64);
    let (_, run) = peak_growth(10_000, &mut decimated);
    let kept: Vec<usize> = decimated.records().iter().map(|r| r.iteration).collect();
    assert!(
        kept.len() <= 64 && kept.len() >= 32,
        "{} records",
        kept.len()
    );
    let stride = decimated.stride();
    assert!(kept.iter().enumerate().all(|(i, &k)| k == i * stride));
    assert_eq!(run.iterations(), 10_000);

    // JSON lines: one record per iteration, streamed to the writer.
    let scenario = endless(50);
    let experiment = scenario.experiment::<6>().unwrap();
    let mut log = JsonLines::new(Vec::new());
    experiment
        .run_with(&scenario.settings(), RunKind::Classical, &mut log)
        .unwrap();
    let text = String::from_utf8(log.into_inner().unwrap()).unwrap();
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(|line| serde_json::from_str(line).unwrap())
        .collect();
    assert_eq!(lines.len(), 50);
    assert_eq!(lines[49]["iteration"], 49);
    assert_eq!(lines[0]["q"].as_array().unwrap().len(), 6);
}
