//! The models a servo or an experiment is built from: [`Robot`] (a built-in arm or a URDF chain with its camera
//! mount) and [`Camera`] (intrinsics and lens distortion), and [`pose`], a rigid transform from a translation and
//! roll–pitch–yaw angles as scenario files write it.

use crate::convert::{pose_to_py, raise};
use crate::{CameraError, Error, RobotError};
use numpy::PyArray2;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use servostack::camera::{
    BrownConrady, CalibratedCamera, CalibrationOptions, CameraIntrinsics, EyeInHand,
};
use servostack::robot::{builtin, RobotError as RustRobotError, SerialChain};
use servostack::scenario::{with_joint_count, ForJointCount, PoseSpec};
use std::any::Any;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The rigid transform (4 × 4 homogeneous matrix) of a translation (m) and roll–pitch–yaw angles (degrees),
/// `R = Rz(yaw) Ry(pitch) Rx(roll)`: the `{ translation_m, rpy_deg }` of scenario files.
#[pyfunction]
#[pyo3(signature = (translation_m, rpy_deg = [0.0; 3]))]
pub fn pose(
    py: Python<'_>,
    translation_m: [f64; 3],
    rpy_deg: [f64; 3],
) -> PyResult<Bound<'_, PyArray2<f64>>> {
    let spec = PoseSpec {
        translation_m,
        rpy_deg,
    };
    let isometry = spec.to_isometry("pose").map_err(raise::<Error>)?;
    Ok(pose_to_py(py, &isometry))
}

/// A robot: its kinematic chain (`SerialChain<N>`, kept with its joint count `N`) and camera mount (`eMc`).
#[pyclass(frozen, module = "servostack")]
pub struct Robot {
    name: String,
    joint_count: usize,
    /// The `SerialChain<N>` of `N = joint_count`.
    chain: Arc<dyn Any + Send + Sync>,
    pub mount: EyeInHand,
    joint_names: Vec<String>,
    lower: Vec<f64>,
    upper: Vec<f64>,
}

impl Robot {
    /// A robot of this chain and mount.
    pub fn new<const N: usize>(name: String, chain: SerialChain<N>, mount: EyeInHand) -> Self {
        Self {
            name,
            joint_count: N,
            joint_names: chain.joint_names().iter().map(|s| s.to_string()).collect(),
            lower: chain.lower_limits().as_slice().to_vec(),
            upper: chain.upper_limits().as_slice().to_vec(),
            chain: Arc::new(chain),
            mount,
        }
    }

    /// The chain, when this robot has `N` joints.
    pub fn chain<const N: usize>(&self) -> PyResult<&SerialChain<N>> {
        self.chain.downcast_ref().ok_or_else(|| {
            PyValueError::new_err(format!(
                "the robot has {} joints, not {N}",
                self.joint_count
            ))
        })
    }

    /// The number of joints.
    pub fn joints(&self) -> usize {
        self.joint_count
    }
}

/// Where a robot comes from.
enum Source<'a> {
    Builtin(&'a str),
    Urdf {
        path: &'a Path,
        base_link: &'a str,
        tip_link: &'a str,
        mount: Box<EyeInHand>,
    },
}

impl Source<'_> {
    /// The chain with `N` joints and the camera mount.
    fn model<const N: usize>(&self) -> Result<(SerialChain<N>, EyeInHand), RustRobotError> {
        match self {
            Self::Builtin(name) => {
                builtin::by_name::<N>(name).map(|robot| (robot.chain, robot.mount))
            }
            Self::Urdf {
                path,
                base_link,
                tip_link,
                mount,
            } => Ok((
                SerialChain::from_urdf_file(path, base_link, tip_link)?,
                **mount,
            )),
        }
    }
}

/// [`Robot::new`] for the joint count read at run time.
struct Load<'a> {
    name: String,
    source: Source<'a>,
}

impl ForJointCount for Load<'_> {
    type Output = Result<Robot, RustRobotError>;
    fn call<const N: usize>(self) -> Self::Output {
        let (chain, mount) = self.source.model::<N>()?;
        Ok(Robot::new(self.name, chain, mount))
    }
}

/// The robot of `source`, its joint count read from the chain (the error of a 0-joint chain says how many it has).
fn load(name: String, source: Source<'_>) -> PyResult<Robot> {
    let joints = match source.model::<0>() {
        Ok(_) => 0,
        Err(RustRobotError::JointCount { found, .. }) => found,
        Err(error) => return Err(raise::<RobotError>(error)),
    };
    with_joint_count(joints, Load { name, source })
        .map_err(raise::<RobotError>)?
        .map_err(raise::<RobotError>)
}

#[pymethods]
impl Robot {
    /// A built-in robot by name (`servostack.BUILTIN_ROBOTS`), with its camera mount.
    #[staticmethod]
    fn builtin(name: &str) -> PyResult<Self> {
        load(name.to_owned(), Source::Builtin(name))
    }

    /// The chain of a URDF file from `base_link` to `tip_link`, with the camera at the URDF link `camera_link`
    /// (fixed to the tip; z forward, x right, y down: a ROS optical frame) or at `camera_mount`, its pose in the tip
    /// frame (`eMc`, a 4 × 4 matrix). Give exactly one of the two.
    #[staticmethod]
    #[pyo3(signature = (path, base_link, tip_link, *, camera_link = None, camera_mount = None))]
    fn from_urdf(
        path: PathBuf,
        base_link: &str,
        tip_link: &str,
        camera_link: Option<&str>,
        camera_mount: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let tip_from_camera = match (camera_link, camera_mount) {
            (Some(link), None) => *SerialChain::<0>::from_urdf_file(&path, tip_link, link)
                .map_err(raise::<RobotError>)?
                .segment_from_tip(),
            (None, Some(mount)) => crate::convert::pose(mount, "camera_mount")?,
            _ => {
                return Err(PyValueError::new_err(
                    "give the camera as camera_link (a URDF link) or camera_mount (its pose in the tip frame)",
                ))
            }
        };
        let mount = EyeInHand::new(tip_from_camera).map_err(raise::<CameraError>)?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let source = Source::Urdf {
            path: &path,
            base_link,
            tip_link,
            mount: Box::new(mount),
        };
        load(name, source)
    }

    /// The robot's name (the built-in's, or the URDF file's stem).
    #[getter]
    fn name(&self) -> &str {
        &self.name
    }

    /// The number of joints `N`.
    #[getter]
    fn joint_count(&self) -> usize {
        self.joint_count
    }

    /// The joints' names, base to tip.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.joint_names.clone()
    }

    /// The lower joint limits (rad, m).
    #[getter]
    fn lower_limits<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        crate::convert::array1(py, &self.lower)
    }

    /// The upper joint limits (rad, m).
    #[getter]
    fn upper_limits<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        crate::convert::array1(py, &self.upper)
    }

    /// The camera's pose in the tip frame (`eMc`, 4 × 4).
    #[getter]
    fn camera_mount<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        pose_to_py(py, self.mount.e_from_c())
    }

    fn __repr__(&self) -> String {
        format!("Robot({:?}, {} joints)", self.name, self.joint_count)
    }
}

/// A calibrated camera: pinhole intrinsics (px) and Brown–Conrady lens distortion.
#[pyclass(frozen, module = "servostack")]
pub struct Camera {
    pub camera: CalibratedCamera,
}

#[pymethods]
impl Camera {
    /// Intrinsics `fx, fy, cx, cy` (px), the image size (px) and, optionally, the distortion coefficients in OpenCV's
    /// order: 4 or 5 (`k1, k2, p1, p2[, k3]`), 8 (rational), 12 (thin prism) or 14 (zero tilt).
    #[new]
    #[pyo3(signature = (fx, fy, cx, cy, width, height, distortion = None))]
    fn new(
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        width: f64,
        height: f64,
        distortion: Option<Vec<f64>>,
    ) -> PyResult<Self> {
        let intrinsics =
            CameraIntrinsics::new(fx, fy, cx, cy, width, height).map_err(raise::<CameraError>)?;
        let distortion = match distortion {
            Some(coefficients) => {
                BrownConrady::from_coefficients(&coefficients).map_err(raise::<CameraError>)?
            }
            None => BrownConrady::default(),
        };
        Ok(Self {
            camera: CalibratedCamera {
                intrinsics,
                distortion,
            },
        })
    }

    /// A calibration file: ROS `camera_info` or OpenCV YAML; `image_size = (width, height)` (px) for a file that does
    /// not give it (OpenCV's ArUco samples), and if given for a file that does, it must be the same.
    #[staticmethod]
    #[pyo3(signature = (path, image_size=None))]
    fn from_file(path: PathBuf, image_size: Option<(u32, u32)>) -> PyResult<Self> {
        let options = match image_size {
            Some((width, height)) => CalibrationOptions::default().with_image_size(width, height),
            None => CalibrationOptions::default(),
        };
        let camera =
            CalibratedCamera::from_yaml_file_with(path, options).map_err(raise::<CameraError>)?;
        Ok(Self { camera })
    }

    /// `(fx, fy, cx, cy, width, height)` (px).
    #[getter]
    fn intrinsics(&self) -> (f64, f64, f64, f64, f64, f64) {
        let i = &self.camera.intrinsics;
        (i.fx(), i.fy(), i.cx(), i.cy(), i.width(), i.height())
    }

    /// The distortion coefficients in OpenCV's order: `(k1, k2, p1, p2, k3)`, with `k4, k5, k6` for a rational lens
    /// and `s1 … s4` for a thin-prism lens.
    #[getter]
    fn distortion(&self) -> Vec<f64> {
        self.camera.distortion.coefficients().to_vec()
    }

    /// The pixel `(u, v)` at which the point of normalised coordinates `(x, y)` is imaged (through the lens).
    fn pixel_of(&self, x: f64, y: f64) -> (f64, f64) {
        self.camera.pixel_of(x, y)
    }

    /// The undistorted normalised coordinates `(x, y)` of the pixel `(u, v)`.
    fn normalized_of(&self, u: f64, v: f64) -> PyResult<(f64, f64)> {
        self.camera
            .normalized_of(u, v)
            .map_err(raise::<CameraError>)
    }

    fn __repr__(&self) -> String {
        let (fx, fy, cx, cy, w, h) = self.intrinsics();
        format!(
            "Camera(fx={fx}, fy={fy}, cx={cx}, cy={cy}, width={w}, height={h}, distortion={:?})",
            self.distortion()
        )
    }
}
