//! Planar target: the rectangle of four points and its plane seen from the camera ([theory §7.1](crate::theory#s7-1), [peer scene](crate::theory::peer_scene#scene)).

use crate::camera::{is_finite_pose, MIN_DEPTH};
use nalgebra::{Isometry3, Point3, Vector3};

/// The target plane in the camera frame, written as `1/Z = A x + B y + C` for the normalised image coordinates
/// `(x, y)` of any point of the plane ([theory §7.1](crate::theory#s7-1); ViSP's moment features use the same `A, B, C`). Units: 1/m.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TargetPlane {
    /// Coefficient `A` (1/m).
    pub a: f64,
    /// Coefficient `B` (1/m).
    pub b: f64,
    /// Coefficient `C` (1/m); `1/C` is the depth of the plane along the optical axis.
    pub c: f64,
}

impl TargetPlane {
    /// The inverse depth `1/Z` (1/m) of the plane point seen at normalised coordinates `(x, y)`.
    pub fn inverse_depth(&self, x: f64, y: f64) -> f64 {
        self.a * x + self.b * y + self.c
    }
}

impl TargetPlane {
    /// The plane `z = 0` of an object frame `o` seen from the camera at `c_from_o` (ViSP `cMo`).
    ///
    /// In the camera frame the plane is `n · X = d` with `n = cRo e_z` and `d = n · cto` (m); a point of the plane at
    /// normalised coordinates `(x, y)` has `X = Z (x, y, 1)`, hence `1/Z = (n / d) · (x, y, 1)`: `(A, B, C) = n / d`.
    ///
    /// # Errors
    /// [`TargetError::NonFinitePose`] for a non-finite pose; [`TargetError::PlaneThroughCentre`] when
    /// `|d| ≤ MIN_DEPTH` (the optical centre lies on the plane, which is then seen edge-on).
    pub fn from_object_pose(c_from_o: &Isometry3<f64>) -> Result<Self, TargetError> {
        if !is_finite_pose(c_from_o) {
            return Err(TargetError::NonFinitePose);
        }
        let normal = c_from_o.rotation * Vector3::z();
        let distance = normal.dot(&c_from_o.translation.vector);
        if distance.abs() <= MIN_DEPTH {
            return Err(TargetError::PlaneThroughCentre { distance });
        }
        let abc = normal / distance;
        Ok(Self {
            a: abc.x,
            b: abc.y,
            c: abc.z,
        })
    }
}

/// Errors of the target model.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TargetError {
    /// The rectangle's width or height is not a positive finite length.
    #[error("degenerate rectangle: width {width} m, height {height} m")]
    DegenerateRectangle {
        /// Width (m).
        width: f64,
        /// Height (m).
        height: f64,
    },
    /// The target plane passes through the optical centre (|distance| ≤ [`MIN_DEPTH`]): `(A, B, C)` is undefined.
    #[error("the target plane passes through the optical centre (distance {distance} m)")]
    PlaneThroughCentre {
        /// Signed distance `d` of the plane from the optical centre (m).
        distance: f64,
    },
    /// The pose given has a NaN or infinite entry.
    #[error("non-finite target pose")]
    NonFinitePose,
}

/// A planar rectangle target of four points in the plane `z = 0` of the object frame `o` ([peer scene](crate::theory::peer_scene#scene)), numbered
/// around the rectangle:
/// `P0 = (−w/2, −h/2, 0)`, `P1 = (w/2, −h/2, 0)`, `P2 = (w/2, h/2, 0)`, `P3 = (−w/2, h/2, 0)` (m).
/// The diagonal of [D8](crate::theory#d8) runs from `P0` to `P2`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RectangleTarget {
    width: f64,
    height: f64,
    points: [Point3<f64>; 4],
}

impl RectangleTarget {
    /// A rectangle of `width` (along x of `o`) by `height` (along y of `o`), in metres, centred on the origin of `o`.
    ///
    /// # Errors
    /// [`TargetError::DegenerateRectangle`] unless both sizes are `> 0` and within [`crate::bounds::LENGTH_M`].
    pub fn new(width: f64, height: f64) -> Result<Self, TargetError> {
        let valid = |v: f64| v > 0.0 && crate::bounds::LENGTH_M.contains(v);
        if !(valid(width) && valid(height)) {
            return Err(TargetError::DegenerateRectangle { width, height });
        }
        let (hw, hh) = (0.5 * width, 0.5 * height);
        Ok(Self {
            width,
            height,
            points: [
                Point3::new(-hw, -hh, 0.0),
                Point3::new(hw, -hh, 0.0),
                Point3::new(hw, hh, 0.0),
                Point3::new(-hw, hh, 0.0),
            ],
        })
    }

    /// Width (m), along x of the object frame.
    pub fn width(&self) -> f64 {
        self.width
    }

    /// Height (m), along y of the object frame.
    pub fn height(&self) -> f64 {
        self.height
    }

    /// The four corner points in the object frame (m), in the order above.
    pub fn points(&self) -> &[Point3<f64>; 4] {
        &self.points
    }

    /// The target's plane in the camera frame at `c_from_o`, see [`TargetPlane::from_object_pose`].
    ///
    /// # Errors
    /// Those of [`TargetPlane::from_object_pose`].
    pub fn plane_in_camera(&self, c_from_o: &Isometry3<f64>) -> Result<TargetPlane, TargetError> {
        TargetPlane::from_object_pose(c_from_o)
    }
}
