#!/usr/bin/env bash
# The simulation's overhead beyond the control step it wraps, measured on the same work in one run: `perf` samples
# of `cargo bench --bench throughput -- sim_overhead`, of which those inside `sim::simulate_with` are split by the
# frame right under it into
#   * the control step: the scene's observation (`Scene::observe_into`, `View::observation`), the tasks
#     (`evaluate_all`) and the controller (`StackController::step_guarded`), what a robot runs every period;
#   * the simulation's own work: every other frame (the image and incidence checks, records and log, the saturation
#     and braking of the velocity sent, the Euler step, the obstacle distances, the convergence test).
# Prints both counts and the overhead `own / step`. Samples outside `simulate_with` (the bench's other loops) are not
# counted.
#
#   scripts/sim_overhead.sh [frequency]     # default 20000 samples/s
#
# Needs `perf` (linux-perf) allowed to sample user code; builds the bench with line tables (CARGO_PROFILE_BENCH_DEBUG,
# codegen unchanged) in <target dir>/sim-overhead, where perf.data is written too.
set -euo pipefail

FREQUENCY=${1:-20000}
REPO=$(cd "$(dirname "$0")/.." && pwd)
TARGET_DIR=${CARGO_TARGET_DIR:-$REPO/target}/sim-overhead
mkdir -p "$TARGET_DIR"

if ! command -v perf >/dev/null; then
  echo "sim_overhead: perf is not installed (Debian: linux-perf); nothing measured." >&2
  exit 0
fi

cd "$REPO"
BENCH=$(CARGO_PROFILE_BENCH_DEBUG=line-tables-only CARGO_TARGET_DIR=$TARGET_DIR \
  cargo bench --bench throughput --no-run 2>&1 | sed -n 's/.*Executable .*(\(.*\))$/\1/p')
if [ ! -x "$BENCH" ]; then
  echo "sim_overhead: the throughput bench did not build" >&2
  exit 1
fi

echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'); load: $(cut -d' ' -f1-3 /proc/loadavg)"
perf record -q -F "$FREQUENCY" --call-graph dwarf,32768 -o "$TARGET_DIR/perf.data" "$BENCH" sim_overhead --bench
perf script -i "$TARGET_DIR/perf.data" -F ip,sym --no-demangle 2>/dev/null | awk '
  # One sample per block of frames (address, symbol), innermost first; the block ends with an empty line. The bench
  # runs the scenario twice: through `Scenario::run_experiment` (every record kept) and through
  # `Scenario::run_experiment_with` with the summary-only log the study uses.
  function classify(   i, outer, frame, run) {
    outer = 0
    run = "summary only"
    for (i = 1; i <= n; i++) {
      if (frames[i] ~ /simulate_with/ && frames[i] !~ /closure/) outer = i
      if (frames[i] ~ /14run_experiment17h/) run = "every record"
    }
    if (outer == 0) return
    frame = outer > 1 ? frames[outer - 1] : ""
    if (!(run in step) && !(run in own)) runs++
    if (frame ~ /step_guarded|evaluate_all|observe_into|[Oo]bservation/) step[run]++
    else own[run]++
  }
  NF == 0 { if (n) classify(); n = 0; next }
  { frames[++n] = $2 }
  END {
    if (n) classify()
    if (runs == 0) { print "sim_overhead: no sample inside simulate_with (perf allowed? line tables?)"; exit 1 }
    for (run in step) {
      total = step[run] + own[run]
      printf "%s: %d samples in the simulation; control step %d (%.1f %%), own work %d (%.1f %%); overhead %.1f %%\n",
        run, total, step[run], 100 * step[run] / total, own[run], 100 * own[run] / total, 100 * own[run] / step[run]
    }
  }'
