"""The paper's four runs on the reference scenario, with matplotlib figures (the Rust example's, from Python).

    python python/examples/paper_experiment.py [--out DIR]     # from the repository's root; needs matplotlib

Prints one line per method (outcome, iterations, stack events) and writes per method the normalised joints over
time with the stack events (the paper's Fig. 5-7) and the task errors, and the four image trajectories, as PNG.
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import servostack as ss  # noqa: E402

EVENT_STYLE = {"push": ("tab:green", "-"), "remove": ("tab:red", "--"), "reinsert": ("tab:blue", "-.")}


def joints_figure(run, title, path):
    fig, (joints, errors) = plt.subplots(2, 1, sharex=True, figsize=(9, 6))
    for j in range(run.q.shape[1]):
        joints.plot(run.times, run.normalized_q[:, j], label=f"q{j}")
    for bound in (0.0, 1.0):
        joints.axhline(bound, color="black", lw=1)
    for bound in (0.1, 0.9):  # the activation thresholds of the joint-limit cost (rho = 0.1)
        joints.axhline(bound, color="grey", lw=0.8, ls=":")
    for event in run.events:
        color, style = EVENT_STYLE.get(event["kind"], ("grey", ":"))
        for axis in (joints, errors):
            axis.axvline(event["time"], color=color, ls=style, lw=1)
        joints.annotate(f"{event['kind']} {event['task_name']}", (event["time"], 1.02), fontsize=7, rotation=30)
    joints.set_ylabel("normalised joint position")
    joints.legend(loc="lower right", fontsize=7, ncol=3)
    for i, name in enumerate(run.task_names):
        errors.semilogy(run.times, run.task_errors[:, i], label=name)
    errors.set_xlabel("time (s)")
    errors.set_ylabel("task error")
    errors.legend(fontsize=7)
    fig.suptitle(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def image_figure(runs, path):
    fig, axes = plt.subplots(1, len(runs), figsize=(4 * len(runs), 4), sharex=True, sharey=True)
    for axis, (method, run) in zip(axes, runs.items()):
        for corner in range(4):
            axis.plot(run.image[:, corner, 0], run.image[:, corner, 1], lw=1)
            axis.plot(*run.image[0, corner], "o", color="grey")
            axis.plot(*run.image[-1, corner], "x", color="black")
        axis.set_title(f"{method}: {run.outcome}", fontsize=9)
        axis.set_xlabel("x (normalised)")
        axis.invert_yaxis()  # y down, as in the image
    axes[0].set_ylabel("y (normalised)")
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("target/python_paper_experiment"))
    out = parser.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    scenario = ss.Scenario.from_file("assets/scenarios/paper_afma6.toml")
    runs = {method: scenario.run(method) for method in ss.METHODS}
    for method, run in runs.items():
        story = ", ".join(f"{e['kind']} {e['task_name']} at {e['iteration']}" for e in run.events)
        print(f"{method:15} {run.outcome:12} {run.iterations:5} iterations: {story}")
        joints_figure(run, f"{scenario.name}: {method} ({run.outcome})", out / f"{method}_joints.png")
    image_figure(runs, out / "image_trajectories.png")
    print(f"figures in {out}")


if __name__ == "__main__":
    main()
