"""The cost of VisualServo.step called from Python, on the episode `cargo bench --bench servo` replays.

    python python/benchmarks/step_overhead.py [--repeats 50]

The peer scene of benches/servo.rs (Afma6, 600 px camera with Brown-Conrady distortion, 0.2 x 0.1 m target seen
head-on at 0.5 m from q_d, start q_d + dq, velocity limits 0.2): one closed-loop episode of 1000 periods at 100 Hz
is recorded, then replayed into fresh servos (built outside the timing), so only `step` is timed, as in the Rust
bench. Prints the median and the best time per step over the replays, for corners given as a (4, 2) NumPy array and
as a list of tuples; the Python overhead is that minus the Rust step's time from the criterion bench.
"""

import argparse
import statistics
import time

import numpy as np

import servostack as ss

EPISODE, PERIOD = 1000, 0.01


def peer():
    robot = ss.Robot.builtin("afma6")
    camera = ss.Camera(600.0, 600.0, 320.0, 240.0, 640.0, 480.0, distortion=(-0.12, 0.03, 4e-4, -3e-4, 0.0))
    goal, q_d = ss.pose([0.0, 0.0, 0.5]), np.array([0.0, 0.0, 0.0, 0.0, 0.3, 0.0])
    start = q_d + np.array([0.05, -0.04, -0.10, 0.25, -0.18, 0.12])
    world = ss.Experiment(robot, camera, (0.2, 0.1), q_d, goal, start)

    def make():
        return ss.VisualServo(robot, camera, (0.2, 0.1), goal, max_joint_velocity=[0.2] * 6)

    servo, q, episode = make(), start, []
    for k in range(EPISODE):
        corners = world.corners(q)
        v = servo.step(k * PERIOD, corners, q)
        episode.append((k * PERIOD, corners, q))
        q = q + v * PERIOD
    return make, episode


def replay(make, episode, repeats):
    per_step = []
    for _ in range(repeats):
        servo = make()
        step = servo.step
        start = time.perf_counter()
        for t, corners, q in episode:
            step(t, corners, q)
        per_step.append((time.perf_counter() - start) / len(episode))
    return statistics.median(per_step), min(per_step)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=50)
    repeats = parser.parse_args().repeats
    make, episode = peer()
    as_arrays = [(t, np.array(c, dtype=float), q) for t, c, q in episode]
    for name, data in (("corners as a (4, 2) array", as_arrays), ("corners as a list of tuples", episode)):
        median, best = replay(make, data, repeats)
        print(f"{name:28}: {median * 1e6:6.2f} us per step (median of {repeats} replays), best {best * 1e6:6.2f} us")


if __name__ == "__main__":
    main()
