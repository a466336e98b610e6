"""Robots, cameras, poses, scenarios as dicts, and the study, from Python."""

import math

import numpy as np
import pytest

import servostack as ss


def test_builtin_robots_have_their_joint_counts():
    assert set(ss.BUILTIN_ROBOTS) == {"afma6", "afma6_coupled", "ur5e", "rail7"}
    assert ss.Robot.builtin("afma6").joint_count == 6
    rail = ss.Robot.builtin("rail7")
    assert rail.joint_count == len(rail.joint_names) == 7
    assert np.all(rail.lower_limits < rail.upper_limits)


def test_urdf_robot_with_a_camera_mount(repo):
    mount = ss.pose([0.0, -0.06, 0.03])
    robot = ss.Robot.from_urdf(repo / "assets/urdf/ur5e.urdf", "base_link", "tool0", camera_mount=mount)
    assert robot.joint_count == 6
    np.testing.assert_allclose(robot.camera_mount, mount)


def test_pose_is_the_scenario_files_roll_pitch_yaw():
    # R = Rz(yaw) Ry(pitch) Rx(roll): a yaw of 90° turns x onto y.
    m = ss.pose([1.0, 2.0, 3.0], [0.0, 0.0, 90.0])
    np.testing.assert_allclose(m[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)
    np.testing.assert_allclose(m[:3, 3], [1, 2, 3])
    np.testing.assert_allclose(m[3], [0, 0, 0, 1])


def test_a_calibration_file_without_image_size_needs_one(repo):
    path = repo / "tests/data/opencv_aruco_no_size.yml"
    with pytest.raises(ss.CameraError, match="image size"):
        ss.Camera.from_file(path)
    camera = ss.Camera.from_file(path, image_size=(640, 480))
    # The numbers written in the file, and the size given.
    assert camera.intrinsics == pytest.approx((628.71534, 626.93217, 324.156, 238.987, 640.0, 480.0))
    assert camera.distortion == pytest.approx([-0.41287, 0.23109, -0.00076, 0.00118, -0.08543])
    with pytest.raises(ss.CameraError):
        ss.Camera.from_file(path, image_size=(0, 480))


def test_a_camera_takes_opencv_coefficient_lists():
    rational = [-0.3, 0.12, 0.004, -0.003, -0.02, 0.2, -0.05, 0.01]
    camera = ss.Camera(600.0, 600.0, 320.0, 240.0, 640.0, 480.0, rational)
    assert camera.distortion == pytest.approx(rational)
    u, v = camera.pixel_of(0.1, -0.05)
    assert camera.normalized_of(u, v) == pytest.approx((0.1, -0.05), abs=1e-9)
    with pytest.raises(ss.CameraError, match="distortion coefficients"):
        ss.Camera(600.0, 600.0, 320.0, 240.0, 640.0, 480.0, [0.1, 0.2, 0.3])


def test_camera_from_a_calibration_file_round_trips_pixels(repo):
    camera = ss.Camera.from_file(repo / "tests/data/ros_camera_info.yaml")
    assert camera.intrinsics == (612.5, 611.75, 318.25, 241.5, 640.0, 480.0)
    assert camera.distortion == pytest.approx([-0.2875, 0.0812, 0.00041, -0.00073, -0.0104])
    u, v = camera.pixel_of(0.1, -0.05)
    assert camera.normalized_of(u, v) == pytest.approx((0.1, -0.05), abs=1e-9)


def test_scenario_dict_round_trip_runs_the_same(paper):
    copy = ss.Scenario.from_dict(paper.to_dict())
    assert copy.name == "paper_afma6"
    run, original = copy.run("stack"), paper.run("stack")
    assert (run.outcome, run.iterations) == (original.outcome, original.iterations)


def test_a_field_changed_in_the_dict_changes_the_run(paper):
    """Half the classical gain: the same path (classical IBVS's path does not depend on its gain while no velocity
    limit acts) at half the speed, so the limit is hit at about twice the documented 73 iterations."""
    sections = paper.to_dict()
    sections["tasks"]["classical_gain"] = 0.25
    changed = ss.Scenario.from_dict(sections).run("classical")
    assert changed.outcome == "joint_limit"
    assert abs(changed.iterations - 2 * 73) <= 5


def test_study_summary_is_a_dict(paper):
    result = ss.run_study(paper, draws=2, seed=1, families=["mild"], methods=["stack_gradient", "full_method"])
    summary = result.summary()
    assert summary["scenario"] == "paper_afma6"
    assert summary["draws_per_family"] == 2
    (family,) = summary["families"]
    assert family["family"]["name"] == "mild"
    methods = {m["method"]: m for m in family["methods"]}
    assert set(methods) == {"stack_gradient", "stack_controller"}
    # The README's result: the full method converges from every perturbed start.
    assert methods["stack_controller"]["draws"] == methods["stack_controller"]["converged"] == 2
    assert "mild" in result.markdown_table()
    with pytest.raises(ValueError, match="unknown family"):
        ss.run_study(paper, draws=1, families=["nope"])
    with pytest.raises(ss.StudyError, match="draws"):
        ss.run_study(paper, draws=0)


def test_corners_as_arrays_tuples_or_lists_give_the_same_step(paper):
    world = paper.experiment()
    q = world.start
    corners = world.corners(q)
    forms = [corners, [list(c) for c in corners], np.array(corners), tuple(corners)]
    velocities = [ss.VisualServo.from_scenario(paper).step(0.0, form, q) for form in forms]
    for v in velocities[1:]:
        np.testing.assert_array_equal(v, velocities[0])


def test_infinite_values_pass_through_dicts(paper):
    """+inf is meaningful in the file format (no velocity limit, the escape switched off) and survives a dict."""
    sections = paper.to_dict()
    sections["simulation"]["max_prismatic_velocity_m_s"] = math.inf
    assert ss.Scenario.from_dict(sections).to_dict()["simulation"]["max_prismatic_velocity_m_s"] == math.inf
    robot, camera = ss.Robot.builtin("afma6"), ss.Camera(600.0, 600.0, 320.0, 240.0, 640.0, 480.0)
    ss.VisualServo(robot, camera, (0.2, 0.1), ss.pose([0.0, 0.0, 0.5]), controller={"escape_error": math.inf})
