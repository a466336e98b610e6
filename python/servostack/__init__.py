"""servostack from Python: stacked-task visual servoing (Mansard & Chaumette).

The classes and functions are the Rust crate's, through PyO3 (``servostack._native``): no part of the method is
written in Python. See docs/python.md in the repository for a tutorial.
"""

from ._native import (
    BUILTIN_ROBOTS,
    MAX_JOINTS,
    Camera,
    CameraError,
    Error,
    Experiment,
    Robot,
    Run,
    RobotError,
    Scenario,
    ScenarioError,
    ServoError,
    StudyError,
    StudyResult,
    VisualServo,
    pose,
    run_study,
)

#: The paper's four methods, in its order (``Scenario.run`` and ``Experiment.run`` take these names).
METHODS = ("classical", "stack", "stack_gradient", "full_method")

__all__ = [
    "BUILTIN_ROBOTS",
    "MAX_JOINTS",
    "METHODS",
    "Camera",
    "CameraError",
    "Error",
    "Experiment",
    "Robot",
    "Run",
    "RobotError",
    "Scenario",
    "ScenarioError",
    "ServoError",
    "StudyError",
    "StudyResult",
    "VisualServo",
    "pose",
    "run_study",
]
