//! Planar target: the rectangle of four points and its plane seen from the camera (MATH §7.1, PEER_SCENE.md).

/// The target plane in the camera frame, written as `1/Z = A x + B y + C` for the normalised image coordinates
/// `(x, y)` of any point of the plane (MATH §7.1; ViSP's moment features use the same `A, B, C`). Units: 1/m.
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
