#!/usr/bin/env bash
# Regenerates docs/zoo.md, the convergence-domain tables of every arm of the zoo (assets/zoo.toml): installs the
# robots (scripts/install_zoo.sh), runs `convergence_domain --zoo` on all of them and copies its zoo.md.
#
#   scripts/zoo_study.sh [K] [SEED]      # draws per family (default 200) and seed (default 1)
#
# The study of K = 200 draws of the eight families on the 17 arms is long on a small machine: run it as a job array
# instead, one `convergence_domain --zoo --shard I/N --out DIR_I` per job, then `convergence_domain --merge DIR_0 ...
# DIR_{N-1} --out DIR` and copy DIR/zoo.md (the same text, byte for byte).
set -euo pipefail

K=${1:-200}
SEED=${2:-1}
REPO=$(cd "$(dirname "$0")/.." && pwd)
TARGET=${CARGO_TARGET_DIR:-$REPO/target}
OUT=$TARGET/convergence_domain/zoo

ZOO_DIR=$("$REPO/scripts/install_zoo.sh")
cd "$REPO"
rm -rf "$OUT"
cargo run --release --example convergence_domain -- --zoo --zoo-dir "$ZOO_DIR" --k "$K" --seed "$SEED" --out "$OUT"
cp "$OUT/zoo.md" docs/zoo.md
echo "docs/zoo.md: $K draws per family, seed $SEED"
