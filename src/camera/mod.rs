//! Camera: pinhole intrinsics, lens distortion, calibration files, pixel ↔ normalised coordinates, projection of 3-D
//! points ([theory §7.1](crate::theory#s7-1), [§8](crate::theory#s8)).
//!
//! Frames: the camera frame `c` has z forward along the optical axis, x right, y down. Projection gives normalised
//! image coordinates `x = X/Z`, `y = Y/Z` (metric, not pixels) and the depth `Z` (m) of each point.
//!
//! Parts: [`CameraIntrinsics`] (pinhole, pixels), [`BrownConrady`] (lens distortion on normalised coordinates:
//! Brown–Conrady with OpenCV's rational and thin-prism terms, `distortion`), [`CalibratedCamera`] (both: measured
//! pixel ↔ undistorted normalised point) and its loading from ROS `camera_info` and OpenCV YAML calibration files under
//! the keys OpenCV's samples and tutorials write ([`CalibratedCamera::from_yaml_file`]; [`CalibrationOptions`] for the
//! image size a file leaves out; `calibration`).

mod calibration;
mod distortion;

pub use calibration::{
    CalibrationError, CalibrationFormat, CalibrationOptions, MAX_CALIBRATION_BYTES,
    MAX_CALIBRATION_DEPTH,
};
pub use distortion::{BrownConrady, UNDISTORTION_MAX_ITERATIONS, UNDISTORTION_TOLERANCE};

use crate::math::{all_finite, twist_transform, KinematicJacobian, TwistTransform};
use nalgebra::{Isometry3, Point3};

/// A point seen by the camera: normalised image coordinates `x = X/Z`, `y = Y/Z` (dimensionless) and its depth `Z`
/// (m, along the optical axis, strictly positive for a visible point), all in the camera frame `c`.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct ImagePoint {
    /// Normalised abscissa `X/Z`.
    pub x: f64,
    /// Normalised ordinate `Y/Z`.
    pub y: f64,
    /// Depth `Z` in metres.
    pub depth: f64,
}

impl ImagePoint {
    /// A point from its normalised coordinates and depth (m).
    pub const fn new(x: f64, y: f64, depth: f64) -> Self {
        Self { x, y, depth }
    }
}

/// Smallest depth `Z` (m) a projected point may have: points at or behind it are rejected (a point at or behind the
/// optical centre has no image; close to it, `x = X/Z` blows up).
pub const MIN_DEPTH: f64 = 1e-6;

/// Errors of the camera model. Each variant carries the offending values.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CameraError {
    /// An intrinsic parameter is outside its physical range ([`crate::bounds::FOCAL_LENGTH_PX`],
    /// [`crate::bounds::PRINCIPAL_POINT_PX`], [`crate::bounds::IMAGE_SIZE_PX`]).
    #[error("invalid camera intrinsic {name} = {value}: expected {expected}")]
    InvalidIntrinsic {
        /// The parameter (`"fx"`, `"fy"`, `"cx"`, `"cy"`, `"width"`, `"height"`).
        name: &'static str,
        /// Its value.
        value: f64,
        /// Its range.
        expected: &'static str,
    },
    /// A point to project lies at or behind the camera: its depth is not above [`MIN_DEPTH`].
    #[error("point {index} is at or behind the camera (depth {depth} m)")]
    PointBehindCamera {
        /// Index of the point in the input slice.
        index: usize,
        /// Its depth `Z` in the camera frame (m).
        depth: f64,
    },
    /// A point or a pose given to the camera has a NaN or infinite coordinate.
    #[error("non-finite {what}")]
    NonFinite {
        /// What was not finite (`"point 2"`, `"c_from_o"`, `"e_from_c"`).
        what: String,
    },
    /// A distortion coefficient is outside [`crate::bounds::DISTORTION_COEFFICIENT`] (±1e4, finite).
    #[error("invalid distortion coefficient {name} = {value}: expected finite, within ±1e4")]
    InvalidDistortion {
        /// The coefficient (`"k1"`, `"k2"`, `"p1"`, `"p2"`, `"k3"`, `"k4"` … `"s4"`, `"tau_x"`, `"tau_y"`).
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// OpenCV's tilted distortion model (14 coefficients) with a non-zero tilt `τx` or `τy`, which is not supported
    /// (with zero tilt it is the thin-prism model, which is).
    #[error("distortion tilt tau_x = {tau_x}, tau_y = {tau_y}: OpenCV's tilted sensor model is not supported (only with zero tilt)")]
    TiltedDistortion {
        /// `τx` (rad).
        tau_x: f64,
        /// `τy` (rad).
        tau_y: f64,
    },
    /// A distortion coefficient list whose length is none of OpenCV's: 4, 5, 8, 12 or 14.
    #[error(
        "{count} distortion coefficients: expected 4 or 5 (k1, k2, p1, p2[, k3]), 8 (rational: + k4, k5, k6), 12 (thin prism: + s1 … s4) or 14 (+ tau_x, tau_y, zero)"
    )]
    DistortionCoefficientCount {
        /// Number of coefficients given.
        count: usize,
    },
    /// An image point (pixel or normalised coordinates) is NaN or infinite.
    #[error("non-finite image point ({x}, {y})")]
    NonFiniteImagePoint {
        /// Abscissa (px or normalised, as given).
        x: f64,
        /// Ordinate.
        y: f64,
    },
    /// Undistortion did not converge: the distorted normalised point has no undistorted preimage within the lens
    /// model's invertible radius, or Newton's method ran out of steps.
    #[error(
        "undistortion of ({x_distorted}, {y_distorted}) did not converge: residual {residual} after {iterations} steps"
    )]
    UndistortionFailed {
        /// Distorted normalised abscissa.
        x_distorted: f64,
        /// Distorted normalised ordinate.
        y_distorted: f64,
        /// Last residual `‖d(x, y) − (x_d, y_d)‖∞` (normalised units).
        residual: f64,
        /// Newton steps taken.
        iterations: usize,
    },
    /// Undistortion found a preimage at or past the lens model's fold radius, where the model is not one-to-one.
    #[error(
        "undistortion of ({x_distorted}, {y_distorted}) lands at radius {radius}, at or past the lens model's fold radius {fold_radius}"
    )]
    BeyondFold {
        /// Distorted normalised abscissa.
        x_distorted: f64,
        /// Distorted normalised ordinate.
        y_distorted: f64,
        /// Radius of the preimage found (normalised units).
        radius: f64,
        /// The fold radius (normalised units).
        fold_radius: f64,
    },
    /// The output slice does not have one entry per input point.
    #[error("{points} points but an output slice of {outputs}")]
    LengthMismatch {
        /// Number of points to project.
        points: usize,
        /// Length of the output slice.
        outputs: usize,
    },
}

/// Pinhole intrinsics in pixels: focal lengths `fx`, `fy`, principal point `(cx, cy)`, image size `width × height`.
///
/// A pixel `(u, v)` and the normalised coordinates `(x, y)` of [theory §7.1](crate::theory#s7-1) are related by `u = cx + fx x`,
/// `v = cy + fy y` (no distortion).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraIntrinsics {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    width: f64,
    height: f64,
}

impl CameraIntrinsics {
    /// Intrinsics from focal lengths `fx`, `fy` (px), principal point `cx`, `cy` (px) and image size `width`,
    /// `height` (px).
    ///
    /// # Errors
    /// [`CameraError::InvalidIntrinsic`] when a focal length is outside [`FOCAL_LENGTH_PX`](crate::bounds::FOCAL_LENGTH_PX)
    /// (`1e−300` px would scale every normalised coordinate by `1e300`), the principal point outside
    /// [`PRINCIPAL_POINT_PX`](crate::bounds::PRINCIPAL_POINT_PX) or a size outside
    /// [`IMAGE_SIZE_PX`](crate::bounds::IMAGE_SIZE_PX) (NaN and infinities never pass).
    pub fn new(
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        width: f64,
        height: f64,
    ) -> Result<Self, CameraError> {
        use crate::bounds::{FOCAL_LENGTH_PX, IMAGE_SIZE_PX, PRINCIPAL_POINT_PX};
        let checked = [
            ("fx", fx, FOCAL_LENGTH_PX),
            ("fy", fy, FOCAL_LENGTH_PX),
            ("cx", cx, PRINCIPAL_POINT_PX),
            ("cy", cy, PRINCIPAL_POINT_PX),
            ("width", width, IMAGE_SIZE_PX),
            ("height", height, IMAGE_SIZE_PX),
        ];
        match checked.iter().find(|(_, v, range)| !range.contains(*v)) {
            Some(&(name, value, range)) => Err(CameraError::InvalidIntrinsic {
                name,
                value,
                expected: range.text,
            }),
            None => Ok(Self {
                fx,
                fy,
                cx,
                cy,
                width,
                height,
            }),
        }
    }

    /// Horizontal focal length (px).
    pub fn fx(&self) -> f64 {
        self.fx
    }

    /// Vertical focal length (px).
    pub fn fy(&self) -> f64 {
        self.fy
    }

    /// Principal point abscissa (px).
    pub fn cx(&self) -> f64 {
        self.cx
    }

    /// Principal point ordinate (px).
    pub fn cy(&self) -> f64 {
        self.cy
    }

    /// Image width (px).
    pub fn width(&self) -> f64 {
        self.width
    }

    /// Image height (px).
    pub fn height(&self) -> f64 {
        self.height
    }

    /// Pixel `(u, v)` of normalised coordinates `(x, y)`: `(cx + fx x, cy + fy y)`.
    pub fn normalized_to_pixel(&self, x: f64, y: f64) -> (f64, f64) {
        (self.cx + self.fx * x, self.cy + self.fy * y)
    }

    /// Normalised coordinates `(x, y)` of pixel `(u, v)`: `((u − cx)/fx, (v − cy)/fy)`.
    pub fn pixel_to_normalized(&self, u: f64, v: f64) -> (f64, f64) {
        ((u - self.cx) / self.fx, (v - self.cy) / self.fy)
    }

    /// `true` when the point's pixel lies in the image shrunk by `margin` pixels on every side:
    /// `margin ≤ u ≤ width − margin` and `margin ≤ v ≤ height − margin`. Points behind the camera (depth ≤
    /// [`MIN_DEPTH`]) and non-finite points are never in the field of view.
    pub fn in_field_of_view(&self, point: &ImagePoint, margin: f64) -> bool {
        let (u, v) = self.normalized_to_pixel(point.x, point.y);
        point.depth > MIN_DEPTH
            && (margin..=self.width - margin).contains(&u)
            && (margin..=self.height - margin).contains(&v)
    }

    /// `true` when every point is in the field of view with this margin (px), see [`Self::in_field_of_view`].
    pub fn all_in_field_of_view(&self, points: &[ImagePoint], margin: f64) -> bool {
        points.iter().all(|p| self.in_field_of_view(p, margin))
    }
}

/// A calibrated camera: pinhole intrinsics and lens distortion (Brown–Conrady with OpenCV's rational and thin-prism
/// terms), as a calibration tool delivers them.
///
/// A point at undistorted normalised coordinates `(x, y)` is measured at the pixel
/// `(u, v) = (cx + fx x_d, cy + fy y_d)` with `(x_d, y_d) = distort(x, y)` ([`BrownConrady::distort`]); the way back
/// is `(x_d, y_d) = ((u − cx)/fx, (v − cy)/fy)`, then [`BrownConrady::undistort`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibratedCamera {
    /// The pinhole intrinsics (px).
    pub intrinsics: CameraIntrinsics,
    /// The lens distortion (dimensionless coefficients on normalised coordinates).
    pub distortion: BrownConrady,
}

impl CalibratedCamera {
    /// A camera without distortion.
    pub fn pinhole(intrinsics: CameraIntrinsics) -> Self {
        Self {
            intrinsics,
            distortion: BrownConrady::default(),
        }
    }

    /// The pixel `(u, v)` at which the point of undistorted normalised coordinates `(x, y)` is imaged.
    pub fn pixel_of(&self, x: f64, y: f64) -> (f64, f64) {
        let (xd, yd) = self.distortion.distort(x, y);
        self.intrinsics.normalized_to_pixel(xd, yd)
    }

    /// The undistorted normalised coordinates `(x, y)` of a measured pixel `(u, v)`. Allocates nothing.
    ///
    /// # Errors
    /// [`CameraError::NonFiniteImagePoint`] for a non-finite pixel; [`CameraError::UndistortionFailed`] (see
    /// [`BrownConrady::undistort`]).
    pub fn normalized_of(&self, u: f64, v: f64) -> Result<(f64, f64), CameraError> {
        if !(u.is_finite() && v.is_finite()) {
            return Err(CameraError::NonFiniteImagePoint { x: u, y: v });
        }
        let (xd, yd) = self.intrinsics.pixel_to_normalized(u, v);
        self.distortion.undistort(xd, yd)
    }
}

impl From<CameraIntrinsics> for CalibratedCamera {
    /// [`CalibratedCamera::pinhole`].
    fn from(intrinsics: CameraIntrinsics) -> Self {
        Self::pinhole(intrinsics)
    }
}

/// Projects a point given in the camera frame (m): `(X/Z, Y/Z, Z)` ([theory §7.1](crate::theory#s7-1)).
///
/// # Errors
/// [`CameraError::NonFinite`] for a non-finite point, [`CameraError::PointBehindCamera`] (with `index` 0) when
/// `Z ≤ MIN_DEPTH`.
pub fn project_point(point_in_camera: &Point3<f64>) -> Result<ImagePoint, CameraError> {
    project_indexed(0, point_in_camera)
}

fn project_indexed(index: usize, p: &Point3<f64>) -> Result<ImagePoint, CameraError> {
    if !all_finite(&p.coords) {
        return Err(CameraError::NonFinite {
            what: format!("point {index}"),
        });
    }
    if p.z <= MIN_DEPTH {
        return Err(CameraError::PointBehindCamera { index, depth: p.z });
    }
    Ok(ImagePoint::new(p.x / p.z, p.y / p.z, p.z))
}

/// Projects points given in the object frame `o` (m), seen from a camera at `c_from_o` (pose of `o` in `c`, ViSP
/// `cMo`), into `out` (one [`ImagePoint`] per point, normalised coordinates and depth). Allocates nothing.
///
/// # Errors
/// [`CameraError::LengthMismatch`] when `out.len() != points_in_object.len()`; [`CameraError::NonFinite`] for a
/// non-finite pose or point; [`CameraError::PointBehindCamera`] for the first point with `Z ≤ MIN_DEPTH`. On error
/// the content of `out` is unspecified.
pub fn project_points(
    c_from_o: &Isometry3<f64>,
    points_in_object: &[Point3<f64>],
    out: &mut [ImagePoint],
) -> Result<(), CameraError> {
    if out.len() != points_in_object.len() {
        return Err(CameraError::LengthMismatch {
            points: points_in_object.len(),
            outputs: out.len(),
        });
    }
    if !is_finite_pose(c_from_o) {
        return Err(CameraError::NonFinite {
            what: "c_from_o".to_owned(),
        });
    }
    for (index, (p, o)) in points_in_object.iter().zip(out.iter_mut()).enumerate() {
        *o = project_indexed(index, &(c_from_o * p))?;
    }
    Ok(())
}

/// `true` when the translation and rotation of a pose are finite.
pub(crate) fn is_finite_pose(pose: &Isometry3<f64>) -> bool {
    all_finite(&pose.translation.vector) && all_finite(pose.rotation.as_vector())
}

/// An eye-in-hand camera: rigidly mounted on the end effector at `e_from_c` (ViSP `eMc`), with its twist transform
/// `c_v_e = twist_transform(e_from_c⁻¹)` (ViSP `cVe`, [\[M43\]](crate::theory#m43)) computed once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EyeInHand {
    e_from_c: Isometry3<f64>,
    c_v_e: TwistTransform,
}

impl EyeInHand {
    /// A camera mounted at `e_from_c`: the pose of the camera frame (z forward, x right, y down) in the end-effector
    /// frame.
    ///
    /// # Errors
    /// [`CameraError::NonFinite`] when the pose is not finite.
    pub fn new(e_from_c: Isometry3<f64>) -> Result<Self, CameraError> {
        if !is_finite_pose(&e_from_c) {
            return Err(CameraError::NonFinite {
                what: "e_from_c".to_owned(),
            });
        }
        Ok(Self {
            e_from_c,
            c_v_e: twist_transform(&e_from_c.inverse()),
        })
    }

    /// `e_from_c` (ViSP `eMc`).
    pub fn e_from_c(&self) -> &Isometry3<f64> {
        &self.e_from_c
    }

    /// `c_v_e` (ViSP `cVe`, [\[M43\]](crate::theory#m43)): maps an end-effector twist in `e` to the camera twist in `c`.
    pub fn c_v_e(&self) -> &TwistTransform {
        &self.c_v_e
    }

    /// The camera pose in the robot base frame: `base_from_camera = base_from_tip · e_from_c` (ViSP `fMc = fMe eMc`).
    pub fn base_from_camera(&self, base_from_tip: &Isometry3<f64>) -> Isometry3<f64> {
        base_from_tip * self.e_from_c
    }

    /// The camera Jacobian `cVe · eJe` ([\[M42\]](crate::theory#m42) without the interaction matrix): maps `q̇` to the camera twist
    /// `(v, ω)` in the camera frame.
    pub fn camera_jacobian<const N: usize>(
        &self,
        tip_jacobian: &KinematicJacobian<N>,
    ) -> KinematicJacobian<N> {
        self.c_v_e * tip_jacobian
    }
}
