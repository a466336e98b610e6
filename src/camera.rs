//! Pinhole camera: intrinsics, pixel ↔ normalised coordinates, projection of 3-D points (MATH §7.1, §8).
//!
//! Frames: the camera frame `c` has z forward along the optical axis, x right, y down. Projection gives normalised
//! image coordinates `x = X/Z`, `y = Y/Z` (metric, not pixels) and the depth `Z` (m) of each point.

/// A point seen by the camera: normalised image coordinates `x = X/Z`, `y = Y/Z` (dimensionless) and its depth `Z`
/// (m, along the optical axis, strictly positive for a visible point), all in the camera frame `c`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
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
