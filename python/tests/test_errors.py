"""Bad input is a Python exception with the Rust message, never a crash; a bad period leaves the servo as it was."""

import numpy as np
import pytest

import servostack as ss


@pytest.fixture()
def loop(paper):
    return paper.experiment(), ss.VisualServo.from_scenario(paper)


def test_exception_classes_are_value_errors():
    for cls in (ss.ServoError, ss.ScenarioError, ss.RobotError, ss.CameraError, ss.StudyError):
        assert issubclass(cls, ss.Error) and issubclass(cls, ValueError)


def test_bad_periods_raise_servo_error_naming_the_fault(loop):
    world, servo = loop
    q = world.start
    corners = world.corners(q)
    servo.step(0.0, corners, q)
    with pytest.raises(ss.ServoError, match="time"):
        servo.step(0.0, corners, q)  # not after the last accepted time
    with pytest.raises(ss.ServoError, match="corner 2"):
        servo.step(0.01, [corners[0], corners[1], None, corners[3]], q)
    with pytest.raises(ss.ServoError, match="outside"):
        servo.step(0.01, [(-5.0, 10.0)] + corners[1:], q)
    with pytest.raises(ss.ServoError, match="joint 3"):
        servo.step(0.01, corners, np.where(np.arange(6) == 3, np.nan, q))
    with pytest.raises(ValueError, match="q: 5 values, expected 6"):
        servo.step(0.01, corners, q[:5])
    with pytest.raises(ValueError, match=r"\(4, 2\)"):
        servo.step(0.01, np.zeros((3, 2)), q)
    with pytest.raises(TypeError, match="q"):
        servo.step(0.01, corners, "abc")


def test_a_bad_period_leaves_no_trace(paper, loop):
    """The same loop with and without a bad call before every tenth period: the same velocities."""
    world, servo = loop
    clean = ss.VisualServo.from_scenario(paper)
    q, dt = world.start, paper.period
    for k in range(60):
        corners = world.corners(q)
        if k % 10 == 0:
            with pytest.raises(ss.ServoError):
                servo.step(k * dt, corners[:3] + [None], q)
        v = servo.step(k * dt, corners, q)
        np.testing.assert_array_equal(v, clean.step(k * dt, corners, q))
        q = q + v * dt


def test_models_and_files_raise_their_own_errors(repo, tmp_path):
    with pytest.raises(ss.RobotError, match="no_such_arm"):
        ss.Robot.builtin("no_such_arm")
    with pytest.raises(ss.RobotError):
        ss.Robot.from_urdf(tmp_path / "missing.urdf", "base_link", "tool0", camera_mount=np.eye(4))
    with pytest.raises(ValueError, match="camera_link"):
        ss.Robot.from_urdf(repo / "assets/urdf/ur5e.urdf", "base_link", "tool0")
    with pytest.raises(ss.CameraError):
        ss.Camera(-600.0, 600.0, 320.0, 240.0, 640.0, 480.0)
    with pytest.raises(ss.CameraError):
        ss.Camera.from_file(tmp_path / "missing.yaml")
    with pytest.raises(ss.ScenarioError):
        ss.Scenario.from_file(tmp_path / "missing.toml")
    with pytest.raises(ss.ScenarioError, match="line"):
        ss.Scenario.from_toml("name = [")


def test_bad_poses_and_parameters_are_value_errors(paper):
    robot = ss.Robot.builtin("afma6")
    camera = ss.Camera(600.0, 600.0, 320.0, 240.0, 640.0, 480.0)
    not_rotation = np.eye(4)
    not_rotation[0, 0] = 2.0
    with pytest.raises(ValueError, match="not a rotation"):
        ss.VisualServo(robot, camera, (0.2, 0.1), not_rotation)
    with pytest.raises(ValueError, match="4 × 4"):
        ss.VisualServo(robot, camera, (0.2, 0.1), np.eye(3))
    goal = ss.pose([0.0, 0.0, 0.5])
    with pytest.raises(ValueError, match="no_such_key"):
        ss.VisualServo(robot, camera, (0.2, 0.1), goal, controller={"no_such_key": 1.0})
    with pytest.raises(ss.ServoError, match="convergence_error"):
        ss.VisualServo(robot, camera, (0.2, 0.1), goal, convergence_error=-1.0)
    with pytest.raises(ValueError, match="max_joint_velocity: 2 values"):
        ss.VisualServo(robot, camera, (0.2, 0.1), goal, max_joint_velocity=[1.0, 1.0])
    with pytest.raises(ValueError, match="max_joint_acceleration: 7 values"):
        ss.VisualServo(robot, camera, (0.2, 0.1), goal, max_joint_acceleration=[1.0] * 7)
    for bad in [0.0, -3.0, float("nan")]:
        with pytest.raises(ss.ServoError, match="max_joint_acceleration"):
            ss.VisualServo(robot, camera, (0.2, 0.1), goal, max_joint_acceleration=[1.0] * 5 + [bad])
    with pytest.raises(ValueError, match='method = "qp"'):
        ss.VisualServo(robot, camera, (0.2, 0.1), goal, method="qp")
    with pytest.raises(ss.ServoError, match="control_period"):
        ss.VisualServo(robot, camera, (0.2, 0.1), goal, method="sns")
    with pytest.raises(ss.ServoError, match="control_period_s"):
        ss.VisualServo(robot, camera, (0.2, 0.1), goal, method="hqp", control_period=0.0)
    with pytest.raises(ValueError, match="unknown method"):
        paper.run("gradient")
    with pytest.raises(ss.Error, match="rpy_deg"):
        ss.pose([0.0, 0.0, 0.5], [1e9, 0.0, 0.0])


def test_a_scenario_dict_with_a_bad_field_names_it(paper):
    sections = paper.to_dict()
    sections["start"]["joints"][2] = -10.0
    with pytest.raises(ss.ScenarioError, match="start.joints"):
        ss.Scenario.from_dict(sections).experiment()
    sections = paper.to_dict()
    sections["tasks"]["no_such_key"] = 1
    with pytest.raises(ValueError, match="no_such_key"):
        ss.Scenario.from_dict(sections)
