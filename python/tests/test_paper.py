"""The paper's experiment from Python: the four runs of the reference scenario, and a Python servo loop on the
same scenario that makes the full method's run step for step.

The expected iterations are the ones docs/paper_experiment.md reports for the Rust runs (classical limit at 73,
stack at 732, stack_gradient at 1088 after the fourth push at 997; the full method pushes a_n at 200 and the fourth
task at 300, removes a_n at 351, puts it back at 1268, converges at 2777).
"""

import numpy as np
import pytest

import servostack as ss

FULL_METHOD_EVENTS = [
    (0, "push", "centroid"),
    (100, "push", "angle"),
    (200, "push", "area"),
    (300, "push", "third_order"),
    (351, "remove", "area"),
    (1268, "reinsert", "area"),
]


def story(events):
    return [(e["iteration"], e["kind"], e["task_name"]) for e in events]


def test_the_baselines_hit_the_joint_2_limit_where_the_paper_experiment_says(paper):
    expected = {
        "classical": (73, ["full"]),
        "stack": (732, ["centroid", "angle", "area"]),
        "stack_gradient": (1088, ["centroid", "angle", "area", "third_order"]),
    }
    for method, (iterations, stacked) in expected.items():
        run = paper.run(method)
        assert run.outcome == "joint_limit", method
        assert "joint: 2" in run.outcome_detail, run.outcome_detail
        assert run.iterations == iterations, method
        assert run.stacked_at_end == stacked, method
    gradient = paper.run("stack_gradient")
    assert story(gradient.events)[-1] == (997, "push", "third_order")


def test_sns_holds_joint_2_on_its_limit_where_the_stack_with_gradient_passes_it(paper):
    # Saturation in the null space (theory §13): the same pushes as the stack with gradient, but every velocity stays
    # inside the box of the limits, so joint 2 is held on its lower limit and, with no removal, the fourth task stays
    # unmet until the budget ends.
    run = paper.run("sns")
    assert run.outcome == "max_iterations", run.outcome_detail
    assert run.stacked_at_end == ["centroid", "angle", "area", "third_order"]
    lower, upper = run.limits
    assert np.all(run.q >= lower) and np.all(run.q <= upper)
    assert run.normalized_q[-1, 2] < 1e-6


def test_hqp_keeps_every_joint_inside_its_limits_with_every_task_stacked(paper):
    # The hierarchical QP cascade (theory §14): the same pushes and the same box as SNS; no joint ever leaves its
    # limits and no velocity its bounds, whatever the run's outcome.
    run = paper.run("hqp")
    assert run.outcome != "joint_limit", run.outcome_detail
    assert run.stacked_at_end == ["centroid", "angle", "area", "third_order"]
    lower, upper = run.limits
    assert np.all(run.q >= lower) and np.all(run.q <= upper)
    # The Afma6's three gantry joints are prismatic (0.2 m/s), its wrist revolute (0.7 rad/s).
    assert np.all(np.abs(run.velocity[:, :3]) <= 0.2) and np.all(np.abs(run.velocity[:, 3:]) <= 0.7)


def test_full_method_run_converges_with_the_documented_events_and_its_records_as_arrays(paper):
    run = paper.run("full_method")
    assert run.outcome == "converged"
    assert run.iterations == 2777
    assert story(run.events) == FULL_METHOD_EVENTS
    assert run.max_velocity_jump <= 1e-9
    assert run.min_normalized_margin > 0.0
    # One record per iteration, k·Δt apart, inside the limits.
    assert run.q.shape == run.velocity.shape == (2777, 6)
    assert run.image.shape == (2777, 4, 2)
    assert run.task_errors.shape == (2777, len(run.task_names))
    np.testing.assert_allclose(run.times, np.arange(2777) * paper.period, atol=1e-9)
    lower, upper = run.limits
    assert np.all(run.q >= lower) and np.all(run.q <= upper)
    assert np.all((run.normalized_q >= 0.0) & (run.normalized_q <= 1.0))
    # The records integrate: q(k+1) = q(k) + Δt q̇(k) (explicit Euler).
    np.testing.assert_allclose(run.q[1:], run.q[:-1] + paper.period * run.velocity[:-1], atol=1e-12)


def test_python_servo_loop_makes_the_full_method_run(paper):
    """VisualServo.step drives the simulated robot of the scenario; same outcome and event iterations as the run."""
    run = paper.run("full_method")
    world, servo = paper.experiment(), ss.VisualServo.from_scenario(paper)
    q, dt = world.start, paper.period
    lower, upper = run.limits
    converged_at = None
    for k in range(10_000):
        v = servo.step(k * dt, world.corners(q), q)
        if servo.converged:
            converged_at = k
            break
        q = q + v * dt
        assert np.all(q >= lower) and np.all(q <= upper), f"joint limit at iteration {k}"
    assert converged_at is not None
    # The run's iterations count the converged one: its index plus one.
    assert converged_at + 1 == run.iterations == 2777
    assert story(servo.events) == story(run.events) == FULL_METHOD_EVENTS
    # The velocities sent agree with the run's records up to the depths' rounding (the servo reads them from the
    # target's pose in the image, the simulation knows them).
    assert servo.output["iteration"] == converged_at
    np.testing.assert_allclose(q, run.q[-1], atol=1e-9)


def test_acceleration_limits_of_the_scenario_reach_the_servo_and_keep_its_steps_within_them(paper):
    """A scenario with an industrial arm's acceleration limits (1 m/s² on the Afma6's three prismatic axes, 3 rad/s² on
    its revolute joints): from_scenario takes them, every velocity the servo sends changes by at most a_i Δt from the
    one before, the limits act (the start from rest asks for more), and the servo loop makes the simulation's run."""
    sections = paper.to_dict()
    sections["simulation"]["max_prismatic_acceleration_m_s2"] = 1.0
    sections["simulation"]["max_revolute_acceleration_rad_s2"] = 3.0
    scenario = ss.Scenario.from_dict(sections)
    run = scenario.run("full_method")
    assert run.outcome == "converged"
    world, servo = scenario.experiment(), ss.VisualServo.from_scenario(scenario)
    q, dt = world.start, scenario.period
    allowance = np.array([1.0, 1.0, 1.0, 3.0, 3.0, 3.0]) * dt
    previous, largest = np.zeros(6), 0.0
    for k in range(10_000):
        v = servo.step(k * dt, world.corners(q), q)
        if servo.converged:
            break
        ratio = np.max(np.abs(v - previous) / allowance)
        assert ratio <= 1.0 + 1e-9, f"iteration {k}: {ratio}"
        largest = max(largest, ratio)
        previous = v
        q = q + v * dt
    assert servo.converged and largest > 0.99
    assert k + 1 == run.iterations
    assert story(servo.events) == story(run.events)
    np.testing.assert_allclose(q, run.q[-1], atol=1e-6)


def test_readme_first_loop_converges_after_15_9_s(repo):
    """The README's first loop (Rust) in Python: same models, same 100 Hz loop, the same printed time."""
    robot = ss.Robot.builtin("afma6")
    camera = ss.Camera.from_file(repo / "tests/data/ros_camera_info.yaml")
    goal = ss.pose([0.0, 0.0, 0.5])
    servo = ss.VisualServo(robot, camera, (0.2, 0.1), goal)
    q_goal = np.array([0.0, 0.0, 0.0, 0.0, 1.2, 0.0])
    q = q_goal + np.array([0.05, -0.04, 0.03, 0.05, -0.05, 0.1])
    world = ss.Experiment(robot, camera, (0.2, 0.1), q_goal, goal, q)
    for i in range(6000):
        t = i * 0.01
        v = servo.step(t, world.corners(q), q)
        if servo.converged:
            break
        q = q + v * 0.01
    assert servo.converged
    assert f"{t:.1f}" == "15.9"


@pytest.mark.parametrize("method", ["sns", "hqp"])
@pytest.mark.parametrize("sequencing", ["one_by_one", "all_at_once"])
def test_the_boxed_laws_converge_from_the_readme_start_inside_their_box(repo, method, sequencing):
    """SNS and the QP cascade in the servo: the README's first loop converges, each velocity keeps q + v dt inside the
    limits, and all at once the four tasks are stacked from the first period."""
    robot = ss.Robot.builtin("afma6")
    camera = ss.Camera.from_file(repo / "tests/data/ros_camera_info.yaml")
    goal = ss.pose([0.0, 0.0, 0.5])
    dt = 0.01
    servo = ss.VisualServo(
        robot, camera, (0.2, 0.1), goal, method=method, control_period=dt, controller={"sequencing": sequencing}
    )
    q_goal = np.array([0.0, 0.0, 0.0, 0.0, 1.2, 0.0])
    q = q_goal + np.array([0.05, -0.04, 0.03, 0.05, -0.05, 0.1])
    world = ss.Experiment(robot, camera, (0.2, 0.1), q_goal, goal, q)
    lower, upper = robot.lower_limits, robot.upper_limits
    for i in range(6000):
        v = servo.step(i * dt, world.corners(q), q)
        if i == 0:
            assert len(servo.output["stacked"]) == (4 if sequencing == "all_at_once" else 1)
        if servo.converged:
            break
        q = q + v * dt
        assert np.all(q >= lower) and np.all(q <= upper)
    assert servo.converged
    assert all(e["kind"] == "push" for e in servo.events)


def test_readme_your_robot_converges_after_1598_iterations(repo):
    """The README's 'Your robot' program in Python: a URDF arm, its mount, the full method with the paper's settings."""
    robot = ss.Robot.from_urdf(
        repo / "assets/urdf/ur5e.urdf", "base_link", "tool0", camera_mount=ss.pose([0.0, -0.06, 0.03])
    )
    camera = ss.Camera.from_file(repo / "tests/data/ros_camera_info.yaml")
    experiment = ss.Experiment(
        robot,
        camera,
        (0.2, 0.1),
        [0.0, -1.9, 1.9, -1.571, -1.571, 0.0],
        ss.pose([0.0, 0.0, 0.45]),
        [0.12, -1.8, 1.8, -1.45, -1.68, 0.3],
    )
    run = experiment.run("full_method")
    assert (run.outcome, run.iterations) == ("converged", 1598)
    assert [e["kind"] for e in run.events] == ["push"] * 4


def test_seven_joints_the_loop_makes_the_run_and_the_full_method_converges(repo):
    """rail7_limits.toml (7 joints): the classical law hits a limit, the full method removes a task, puts it back and
    converges (docs/paper_experiment.md), and the Python loop makes that run step for step."""
    scenario = ss.Scenario.from_file(repo / "assets/scenarios/rail7_limits.toml")
    assert scenario.joint_count == 7
    assert scenario.run("classical").outcome == "joint_limit"
    run = scenario.run("full_method")
    assert run.outcome == "converged" and run.q.shape == (run.iterations, 7)
    kinds = [e["kind"] for e in run.events]
    assert "remove" in kinds and "reinsert" in kinds
    world, servo = scenario.experiment(), ss.VisualServo.from_scenario(scenario)
    q, dt = world.start, scenario.period
    for k in range(10_000):
        v = servo.step(k * dt, world.corners(q), q)
        if servo.converged:
            break
        q = q + v * dt
    assert servo.converged and k + 1 == run.iterations
    assert story(servo.events) == story(run.events)


def test_a_scenario_the_servo_does_not_model_is_refused_by_name(repo):
    for name, section in [("obstacle_afma6.toml", "obstacles"), ("paper_afma6_noisy_camera.toml", "measurement")]:
        scenario = ss.Scenario.from_file(repo / "assets/scenarios" / name)
        with pytest.raises(ss.ServoError, match=section):
            ss.VisualServo.from_scenario(scenario)
