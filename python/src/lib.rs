//! Python bindings of servostack (the module `servostack._native`, re-exported by the package `servostack`).
//!
//! Everything here converts: Python objects and NumPy arrays in, the Rust API's calls, NumPy arrays, dicts and
//! exceptions out. The joint count `N`, a const generic of the Rust API, is read at run time (from the robot) and
//! dispatched once with [`servostack::scenario::with_joint_count`]; each generic object is kept behind a small trait
//! object, written once for every `N`.
//!
//! Errors: each Rust error becomes an exception of the class named after its module (`ServoError`, `ScenarioError`,
//! `RobotError`, `CameraError`, `StudyError`), all subclasses of `servostack.Error` (itself a `ValueError`), with the
//! Rust error's message. Input of the wrong shape or type is a `ValueError` or `TypeError` raised before any Rust call.

use pyo3::prelude::*;

mod convert;
mod model;
mod scenario;
mod servo;
mod study;

pyo3::create_exception!(
    _native,
    Error,
    pyo3::exceptions::PyValueError,
    "An error of servostack."
);
pyo3::create_exception!(
    _native,
    ServoError,
    Error,
    "A servo error (bad configuration or a bad period)."
);
pyo3::create_exception!(
    _native,
    ScenarioError,
    Error,
    "A scenario, experiment or run error."
);
pyo3::create_exception!(
    _native,
    RobotError,
    Error,
    "A robot model error (URDF, built-in, joints)."
);
pyo3::create_exception!(
    _native,
    CameraError,
    Error,
    "A camera model or calibration file error."
);
pyo3::create_exception!(
    _native,
    StudyError,
    Error,
    "A convergence-domain study error."
);

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("Error", py.get_type::<Error>())?;
    m.add("ServoError", py.get_type::<ServoError>())?;
    m.add("ScenarioError", py.get_type::<ScenarioError>())?;
    m.add("RobotError", py.get_type::<RobotError>())?;
    m.add("CameraError", py.get_type::<CameraError>())?;
    m.add("StudyError", py.get_type::<StudyError>())?;
    m.add("MAX_JOINTS", servostack::scenario::MAX_JOINTS)?;
    m.add("BUILTIN_ROBOTS", servostack::robot::builtin::NAMES.to_vec())?;
    m.add_function(wrap_pyfunction!(model::pose, m)?)?;
    m.add_class::<model::Robot>()?;
    m.add_class::<model::Camera>()?;
    m.add_class::<servo::VisualServo>()?;
    m.add_class::<scenario::Scenario>()?;
    m.add_class::<scenario::Experiment>()?;
    m.add_class::<scenario::Run>()?;
    m.add_class::<study::StudyResult>()?;
    m.add_function(wrap_pyfunction!(study::run_study, m)?)?;
    Ok(())
}
