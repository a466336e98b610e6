#!/usr/bin/env python3
"""The controller's rules and parameters judged by the study (issue 43): an ablation table (each rule switched off in
turn) or a sensitivity table (each parameter scaled by 0.7 and 1.3), on suite scenarios or on the zoo of real arms.

    scripts/controller_sweep.py ablation    [--k K] [--seed S] [--family F]... [--out DIR] (SCENARIO.toml... | --zoo [--arm A]...)
    scripts/controller_sweep.py sensitivity [same options] [--parameter NAME]...

Every variant runs the full method alone (`--method stack_controller`) on the same draws as the reference run, which
runs every method (the sensitivity's reference runs the full method alone too: only its count is compared);
`--parameter` restricts the sensitivity to the parameters named; the table gives, per scenario or arm and family, the
full method's converged draws with the rule or parameter as shipped and the change of each variant, marking a change
of at least 2 % of K (ablation: the rule earns its place there) or more than 3 % of K (sensitivity: a cliff), and the
95th percentile of the iterations of the converged runs as a share of the budget. Needs the release build of the
example (built by the script through cargo).
Standard library only.
"""

import argparse
import json
import math
import pathlib
import subprocess
import sys
import tomllib

ROOT = pathlib.Path(__file__).resolve().parent.parent

# Each rule of the controller that has a switch, with the setting that switches it off (theory, the D numbers). The
# removal itself (D6) has no switch here: a scenario's run kind sets `allow_removal`, and the full method without it
# is the `stack_gradient` baseline of every table.
RULES = [
    ("D13 fallback", "controller.stall_timeout", "86400"),
    ("D24 early escape", "controller.escape_growth_rate", "inf"),
    ("D25 braking", "controller.braking_rate", "inf"),
    ("D25 image border", "controller.brake_at_image_border", "false"),
    ("D26 lock", "controller.lock_band", "0"),
    ("D28 early push", "controller.early_push_ratio", "inf"),
    ("D29 restart", "controller.restart_rate", "0"),
    ("D29 all joints on a repeat", "controller.recentre_all_on_repeat", "false"),
    ("D5 progress window", "controller.progress_window", "inf"),
    ("D30 filter", "controller.singular_value_floor", "0"),
]

# The controller's numeric parameters (those whose default is not 0 or infinite: a scale leaves those unchanged).
PARAMETERS = [
    "settle_velocity",
    "settle_velocity_with_removal",
    "settle_transitions",
    "prediction_horizon",
    "look_ahead_transitions",
    "reinsertion_ratio",
    "reinsertion_look_ahead",
    "change_transitions",
    "reinsertion_dwell",
    "max_removals",
    "escape_achieved_error",
    "escape_error",
    "early_push_ratio",
    "braking_rate",
    "lock_band",
    "restart_rate",
    "restart_offset",
    "restart_centre_band",
    "restart_timeout",
    "progress_window",
    "singular_value_floor",
]


def study(binary, target, options, out, extra):
    """Runs the study into `out` and returns {scenario name: (summary, study, budget)}."""
    command = [str(binary)] + target + ["--k", str(options.k), "--seed", str(options.seed), "--out", str(out)]
    for family in options.family:
        command += ["--family", family]
    command += extra
    result = subprocess.run(command, cwd=ROOT, capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit(f"{' '.join(command)} failed:\n{result.stdout}\n{result.stderr}")
    found = {}
    for summary_path in sorted(pathlib.Path(out).rglob("summary.json")):
        summary = json.loads(summary_path.read_text())
        draws = json.loads((summary_path.parent / "study.json").read_text())
        budget = summary.get("budget") or budget_of(summary_path.parent, target)
        found[summary["scenario"]] = (summary, draws, budget)
    return found


def budget_of(directory, target):
    """The iteration budget of the scenario studied in `directory` (the zoo writes its generated scenario there), for
    a summary.json written before it gave the budget."""
    for candidate in [directory / "scenario.toml"] + [pathlib.Path(t) for t in target if t.endswith(".toml")]:
        path = candidate if candidate.is_absolute() else ROOT / candidate
        if path.exists():
            return tomllib.loads(path.read_text()).get("simulation", {}).get("max_iterations", 10000)
    return 10000


def full_method(summary):
    """{family: converged draws of the full method}."""
    return {
        f["family"]["name"]: next(m["converged"] for m in f["methods"] if m["method"] == "stack_controller")
        for f in summary["families"]
    }


def p95_share(draws, budget):
    """{family: the 95th percentile of the full method's iterations to converge, as a share of the budget}."""
    shares = {}
    for family in draws["families"]:
        iterations = sorted(
            m["iterations"]
            for d in family["draws"]
            for m in d["methods"]
            if m["method"] == "stack_controller" and m["outcome"] == "converged"
        )
        if iterations:
            shares[family["family"]["name"]] = iterations[min(len(iterations) - 1, math.ceil(0.95 * len(iterations)) - 1)] / budget
    return shares


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("kind", choices=["ablation", "sensitivity"])
    parser.add_argument("scenarios", nargs="*")
    parser.add_argument("--zoo", action="store_true")
    parser.add_argument("--arm", action="append", default=[])
    parser.add_argument("--k", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--family", action="append", default=[])
    parser.add_argument("--out", default=str(ROOT / "target" / "controller_sweep"))
    parser.add_argument("--parameter", action="append", default=[], choices=PARAMETERS)
    options = parser.parse_args()
    if not options.family:
        options.family = ["uniform", "goal_4cm"]
    if not options.scenarios and not options.zoo:
        parser.error("give scenario files or --zoo")
    subprocess.run(["cargo", "build", "--release", "--quiet", "--example", "convergence_domain"], cwd=ROOT, check=True)
    binary = ROOT / "target" / "release" / "examples" / "convergence_domain"
    # A single scenario's study also computes a slice: two points per axis keep it negligible.
    targets = [[s, "--grid", "2"] for s in options.scenarios]
    if options.zoo:
        targets.append(["--zoo"] + [x for a in options.arm for x in ("--arm", a)])
    out = pathlib.Path(options.out) / options.kind
    if options.kind == "ablation":
        variants = [(name, ["--set", f"{path}={value}"]) for name, path, value in RULES]
    else:
        variants = [
            (f"{p} × {f}", ["--scale", f"controller.{p}={f}"])
            for p in (options.parameter or PARAMETERS)
            for f in (0.7, 1.3)
        ]
    mark = 0.02 if options.kind == "ablation" else 0.03
    rows = []
    for t, target in enumerate(targets):
        # One directory per target: a study's files are found by walking its directory.
        where = out / f"target{t}"
        only_full = [] if options.kind == "ablation" else ["--method", "stack_controller"]
        reference = study(binary, target, options, where / "reference", only_full)
        changes = {name: study(binary, target, options, where / str(i), extra + ["--method", "stack_controller"])
                   for i, (name, extra) in enumerate(variants)}
        for scenario, (summary, draws, budget) in reference.items():
            base = full_method(summary)
            shares = p95_share(draws, budget)
            for family, converged in base.items():
                row = [scenario, family, str(converged), f"{shares.get(family, 0):.2f}"]
                for name, _ in variants:
                    delta = full_method(changes[name][scenario][0])[family] - converged
                    marked = abs(delta) >= mark * options.k if options.kind == "ablation" else abs(delta) > mark * options.k
                    flag = "**" if marked else ""
                    row.append(f"{flag}{delta:+d}{flag}")
                rows.append(row)
    header = ["scenario", "family", f"full method (K = {options.k})", "p95 iterations / budget"] + [n for n, _ in variants]
    print(f"{options.kind}, seed {options.seed}, K = {options.k}: change of the full method's converged draws "
          f"(bold: |change| {'≥ 2' if options.kind == 'ablation' else '> 3'} % of K)\n")
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for row in rows:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
