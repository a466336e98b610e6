#!/usr/bin/env bash
# Same-run ratios against ViSP: alternates rounds of servostack's `cargo bench --bench peer` and ViSP's `loop_bench`
# (the shared peer harness, never copied into this repository) on this machine, and prints min and median per variant
# for each side, their ratios, the machine and the load, as a Markdown table ready for docs/performance.md.
#
#   scripts/peer_ratio.sh [rounds]          # default 5 rounds
#
# Environment:
#   VISP_PEER_DIR   the harness folder (loop_bench.cpp, build.sh); default: ../shared/peers/visp next to the repository.
#   VISP_LOOP_BENCH an already built loop_bench; default: $VISP_PEER_DIR/bin/loop_bench if it exists, otherwise the
#                   script compiles loop_bench.cpp with build.sh's flags into the cargo target directory (the harness
#                   folder may be read-only). Needs ViSP 3.5 (`pkg-config visp`): run the harness's build.sh once.
#   PEER_RAW_DIR    where the raw JSON lines of every round go; default: <target dir>/peer-ratio.
#
# Without the harness (or without ViSP) it says so and exits with status 0: nothing is measured.
set -euo pipefail

ROUNDS=${1:-5}
REPO=$(cd "$(dirname "$0")/.." && pwd)
VISP_PEER_DIR=${VISP_PEER_DIR:-$REPO/../shared/peers/visp}
TARGET_DIR=${CARGO_TARGET_DIR:-$REPO/target}
RAW=${PEER_RAW_DIR:-$TARGET_DIR/peer-ratio}

if [ ! -f "$VISP_PEER_DIR/loop_bench.cpp" ]; then
  echo "peer_ratio: no ViSP peer harness at $VISP_PEER_DIR (set VISP_PEER_DIR); nothing measured." >&2
  exit 0
fi
VISP_PEER_DIR=$(cd "$VISP_PEER_DIR" && pwd)

LOOP_BENCH=${VISP_LOOP_BENCH:-}
if [ -z "$LOOP_BENCH" ] && [ -x "$VISP_PEER_DIR/bin/loop_bench" ]; then
  LOOP_BENCH=$VISP_PEER_DIR/bin/loop_bench
fi
if [ -z "$LOOP_BENCH" ]; then
  if ! pkg-config --exists visp 2>/dev/null; then
    echo "peer_ratio: ViSP is not installed (pkg-config visp); run $VISP_PEER_DIR/build.sh first. Nothing measured." >&2
    exit 0
  fi
  # build.sh's own command, with the binary written into the target directory.
  LOOP_BENCH=$TARGET_DIR/visp-peer/loop_bench
  if [ ! -x "$LOOP_BENCH" ] || [ "$VISP_PEER_DIR/loop_bench.cpp" -nt "$LOOP_BENCH" ]; then
    mkdir -p "$(dirname "$LOOP_BENCH")"
    echo "peer_ratio: building $LOOP_BENCH" >&2
    # shellcheck disable=SC2046 # pkg-config's flags are meant to split
    ${CXX:-g++} -O3 -march=native -DNDEBUG $(pkg-config --cflags visp) "$VISP_PEER_DIR/loop_bench.cpp" \
      -I"$VISP_PEER_DIR" -o "$LOOP_BENCH" -lvisp_vs -lvisp_visual_features -lvisp_robot -lvisp_core
  fi
fi

cd "$REPO"
echo "peer_ratio: building the peer bench" >&2
cargo bench --bench peer --no-run >&2

mkdir -p "$RAW"
rm -f "$RAW"/round*.jsonl "$RAW"/load.txt
for r in $(seq 1 "$ROUNDS"); do
  echo "peer_ratio: round $r/$ROUNDS (load $(cut -d' ' -f1-3 /proc/loadavg))" >&2
  echo "$r servostack $(cut -d' ' -f1 /proc/loadavg)" >> "$RAW/load.txt"
  cargo bench --bench peer 2>/dev/null | grep '^{' > "$RAW/round$r.servostack.jsonl"
  echo "$r visp $(cut -d' ' -f1 /proc/loadavg)" >> "$RAW/load.txt"
  "$LOOP_BENCH" 2>/dev/null | grep '^{' > "$RAW/round$r.visp.jsonl"
done

python3 - "$RAW" "$ROUNDS" <<'PY'
import json, platform, statistics, subprocess, sys, datetime

raw, rounds = sys.argv[1], int(sys.argv[2])

def lines(side):
    out = []
    for r in range(1, rounds + 1):
        out += [json.loads(l) for l in open(f"{raw}/round{r}.{side}.jsonl")]
    return out

def sh(cmd):
    try:
        return subprocess.check_output(cmd, shell=True, text=True).strip()
    except Exception:
        return "?"

ours, theirs = lines("servostack"), lines("visp")
loads = [float(l.split()[2]) for l in open(f"{raw}/load.txt")]
background = [d.get("background_cpu_cores_during_timing", 0.0) for d in theirs]

def stats(rows, variant):
    rows = [d for d in rows if d["variant"] == variant]
    if not rows:
        return None
    medians = [d["ns_per_iter_median"] for d in rows]
    return {"min": min(d["ns_per_iter_min"] for d in rows), "median": statistics.median(medians),
            "medians": (min(medians), max(medians))}

# Which ViSP variant each servostack variant is set against (docs/peer_scene.md): CL is our comparable-work variant
# of C, which ViSP's harness does not have; its closest ViSP counterpart is C.
counterpart = {"A": "A", "B": "B", "C": "C", "CL": "C"}
names = {"A": "A points (8 rows)", "B": "B ViSP moments (6 rows)", "C": "C points + joint limits + continuity",
         "CL": "CL C with ViSP's large projection (comparable work)"}

def us(ns):
    return f"{ns / 1000:.2f} µs" if ns < 10000 else f"{ns / 1000:.1f} µs"

variants = sorted({d["variant"] for d in ours}, key=lambda v: list(counterpart).index(v) if v in counterpart else 99)
print(f"Same-run peer comparison, {rounds} alternating rounds ({datetime.datetime.utcnow():%Y-%m-%d %H:%M} UTC)")
cpu = sh("lscpu | sed -n 's/^Model name: *//p'")
print(f"machine: {platform.node()}, CPU \"{cpu}\", nproc {sh('nproc')}, kernel {platform.release()}")
print(f"load average (1 min) at the start of each run: {min(loads):.2f} – {max(loads):.2f}; "
      f"ViSP's background CPU during its timing: {min(background):.2f} – {max(background):.2f} cores")
print()
print("| variant | servostack min | servostack median (range) | ViSP min | ViSP median (range) | ratio min / min | ratio median / median |")
print("|---|---|---|---|---|---|---|")
for v in variants:
    a, b = stats(ours, v), stats(theirs, counterpart.get(v, v))
    if a is None or b is None:
        continue
    against = "" if counterpart.get(v, v) == v else f" (ViSP {counterpart[v]})"
    print(f"| {names.get(v, v)}{against} | {us(a['min'])} | {us(a['median'])} ({us(a['medians'][0])} – {us(a['medians'][1])}) "
          f"| {us(b['min'])} | {us(b['median'])} ({us(b['medians'][0])} – {us(b['medians'][1])}) "
          f"| {b['min'] / a['min']:.1f}× | {b['median'] / a['median']:.1f}× |")
print()
print(f"min = smallest batch over all rounds; median = median of the per-round medians (ns per iteration over batches "
      f"of 100). Raw lines: {raw}")
PY
