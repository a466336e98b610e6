"""Type stubs of servostack._native (the Rust extension); the package servostack re-exports every name."""

from os import PathLike
from typing import Any, Mapping, Optional, Sequence, Tuple, TypedDict, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, PathLike[str]]
_Vector = Union[npt.ArrayLike, Sequence[float]]
_Pose = npt.ArrayLike  # a 4 × 4 homogeneous matrix
_Corner = Optional[Tuple[float, float]]
_Corners = Union[npt.NDArray[np.float64], Sequence[_Corner]]  # (4, 2) array, or four (u, v) / None

MAX_JOINTS: int
BUILTIN_ROBOTS: list[str]

class Error(ValueError): ...
class ServoError(Error): ...
class ScenarioError(Error): ...
class RobotError(Error): ...
class CameraError(Error): ...
class StudyError(Error): ...

class Event(TypedDict):
    iteration: int
    time: float
    kind: str  # push, remove, reinsert, fallback, escape, hold, restart
    task: int
    task_name: Optional[str]
    law_jump: float

class ServoOutput(TypedDict):
    velocity: npt.NDArray[np.float64]
    unscaled_velocity: npt.NDArray[np.float64]
    scale: float
    error_norm: float
    task_errors: npt.NDArray[np.float64]
    task_gains: npt.NDArray[np.float64]
    stacked: list[int]
    event: Optional[str]
    held: bool
    locked: list[bool]
    stack_velocity_norm: float
    converged: bool
    depths: npt.NDArray[np.float64]
    camera_twist: npt.NDArray[np.float64]
    new_frame: bool
    iteration: int

def pose(translation_m: Sequence[float], rpy_deg: Sequence[float] = ...) -> npt.NDArray[np.float64]:
    """The 4 × 4 transform of a translation (m) and roll–pitch–yaw (degrees), R = Rz(yaw) Ry(pitch) Rx(roll)."""

class Robot:
    @staticmethod
    def builtin(name: str) -> Robot: ...
    @staticmethod
    def from_urdf(
        path: _Path,
        base_link: str,
        tip_link: str,
        *,
        camera_link: Optional[str] = None,
        camera_mount: Optional[_Pose] = None,
    ) -> Robot: ...
    @property
    def name(self) -> str: ...
    @property
    def joint_count(self) -> int: ...
    @property
    def joint_names(self) -> list[str]: ...
    @property
    def lower_limits(self) -> npt.NDArray[np.float64]: ...
    @property
    def upper_limits(self) -> npt.NDArray[np.float64]: ...
    @property
    def camera_mount(self) -> npt.NDArray[np.float64]: ...

class Camera:
    def __init__(
        self,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
        width: float,
        height: float,
        distortion: Optional[Sequence[float]] = None,
    ) -> None: ...
    @staticmethod
    def from_file(path: _Path, image_size: Optional[Tuple[int, int]] = None) -> Camera: ...
    @property
    def intrinsics(self) -> Tuple[float, float, float, float, float, float]: ...
    @property
    def distortion(self) -> list[float]: ...
    def pixel_of(self, x: float, y: float) -> Tuple[float, float]: ...
    def normalized_of(self, u: float, v: float) -> Tuple[float, float]: ...

class VisualServo:
    def __init__(
        self,
        robot: Robot,
        camera: Camera,
        target: Tuple[float, float],
        desired_pose: Optional[_Pose] = None,
        *,
        desired_pixels: Optional[Sequence[Tuple[float, float]]] = None,
        desired_depth: Optional[float] = None,
        tasks: str = "sequence",
        gains: Sequence[float] = (0.5, 0.5, 0.5, 0.5),
        classical_gain: float = 0.5,
        depth: Union[None, str, float, Mapping[str, Any]] = None,
        avoidance_gain: float = 10.0,
        activation_ratio: float = 0.1,
        transition_gain: Optional[float] = None,
        max_joint_velocity: Optional[_Vector] = None,
        max_joint_acceleration: Optional[_Vector] = None,
        convergence_error: float = 1e-4,
        controller: Optional[Mapping[str, Any]] = None,
        protect_centroid: bool = True,
        method: str = "full_method",
        control_period: Optional[float] = None,
    ) -> None: ...
    @staticmethod
    def from_scenario(scenario: Scenario) -> VisualServo: ...
    def step(self, t: float, corners: _Corners, q: _Vector) -> npt.NDArray[np.float64]:
        """One period: time (s), corners (px), joints (rad, m) in; the joint velocity to send out."""
    def step_normalized(self, t: float, corners: _Corners, q: _Vector) -> npt.NDArray[np.float64]: ...
    @property
    def converged(self) -> bool: ...
    @property
    def joint_count(self) -> int: ...
    @property
    def task_names(self) -> list[str]: ...
    @property
    def output(self) -> ServoOutput: ...
    @property
    def events(self) -> list[Event]: ...

class Scenario:
    @staticmethod
    def from_file(path: _Path) -> Scenario: ...
    @staticmethod
    def from_toml(text: str, base_dir: Optional[_Path] = None) -> Scenario: ...
    @staticmethod
    def from_dict(sections: Mapping[str, Any], base_dir: Optional[_Path] = None) -> Scenario: ...
    def to_dict(self) -> dict[str, Any]: ...
    @property
    def name(self) -> str: ...
    @property
    def description(self) -> str: ...
    @property
    def period(self) -> float: ...
    @property
    def joint_count(self) -> int: ...
    def experiment(self) -> Experiment: ...
    def run(self, method: str) -> Run:
        """method: classical, stack, stack_gradient, full_method, sns or hqp."""

class Experiment:
    def __init__(
        self,
        robot: Robot,
        camera: Camera,
        target: Tuple[float, float],
        goal_joints: _Vector,
        goal_pose: _Pose,
        start: _Vector,
    ) -> None: ...
    @property
    def start(self) -> npt.NDArray[np.float64]: ...
    @property
    def desired_joints(self) -> npt.NDArray[np.float64]: ...
    @property
    def desired_pose(self) -> npt.NDArray[np.float64]: ...
    @property
    def joint_count(self) -> int: ...
    def corners(self, q: _Vector) -> list[_Corner]: ...
    def run(self, method: str) -> Run: ...

class Run:
    @property
    def outcome(self) -> str: ...
    @property
    def outcome_detail(self) -> str: ...
    @property
    def period(self) -> float: ...
    @property
    def task_names(self) -> list[str]: ...
    @property
    def iterations(self) -> int: ...
    @property
    def events(self) -> list[Event]: ...
    @property
    def times(self) -> npt.NDArray[np.float64]: ...
    @property
    def q(self) -> npt.NDArray[np.float64]: ...
    @property
    def velocity(self) -> npt.NDArray[np.float64]: ...
    @property
    def task_errors(self) -> npt.NDArray[np.float64]: ...
    @property
    def image(self) -> npt.NDArray[np.float64]: ...
    @property
    def cost(self) -> npt.NDArray[np.float64]: ...
    @property
    def limits(self) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    @property
    def normalized_q(self) -> npt.NDArray[np.float64]: ...
    @property
    def stacked_at_end(self) -> list[str]: ...
    @property
    def max_velocity_jump(self) -> float: ...
    @property
    def min_normalized_margin(self) -> float: ...

class StudyResult:
    def summary(self) -> dict[str, Any]: ...
    def markdown_table(self) -> str: ...
    def write_files(self, directory: _Path) -> None: ...

def run_study(
    scenario: Scenario,
    draws: int,
    seed: int = 1,
    families: Optional[Sequence[str]] = None,
    methods: Optional[Sequence[str]] = None,
) -> StudyResult: ...
