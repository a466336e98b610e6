//! Brown–Conrady lens distortion on normalised image coordinates (the "plumb bob" model of OpenCV, ROS and ViSP).
//!
//! For undistorted normalised coordinates `(x, y)` (camera frame, `x = X/Z`, `y = Y/Z`) and `r² = x² + y²`, the
//! distorted normalised coordinates are
//!
//! ```text
//! radial = 1 + k1 r² + k2 r⁴ + k3 r⁶
//! x_d = x · radial + 2 p1 x y + p2 (r² + 2 x²)
//! y_d = y · radial + p1 (r² + 2 y²) + 2 p2 x y
//! ```
//!
//! and the measured pixel is `u = cx + fx x_d`, `v = cy + fy y_d` ([`super::CalibratedCamera`]). The coefficients are
//! dimensionless and are stored in OpenCV's order `(k1, k2, p1, p2, k3)`.
//!
//! Undistortion inverts the map by Newton's method on `d(x, y) − (x_d, y_d) = 0` with the exact 2 × 2 Jacobian of
//! `d`, starting from `(x_d, y_d)`; it stops when the residual is below [`UNDISTORTION_TOLERANCE`] (normalised units)
//! and gives up after [`UNDISTORTION_MAX_ITERATIONS`] steps with [`CameraError::UndistortionFailed`].

use super::CameraError;

/// Residual `‖d(x, y) − (x_d, y_d)‖∞` (normalised units, ≈ 1e−12 · f px) below which undistortion has converged.
pub const UNDISTORTION_TOLERANCE: f64 = 1e-12;

/// Newton steps allowed before undistortion reports [`CameraError::UndistortionFailed`] (from an undistorted start,
/// realistic lenses converge in 3–6 steps).
pub const UNDISTORTION_MAX_ITERATIONS: usize = 20;

/// Brown–Conrady distortion coefficients `(k1, k2, p1, p2, k3)` (dimensionless, OpenCV order): radial `k1, k2, k3`,
/// tangential `p1, p2`. The default is no distortion.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BrownConrady {
    k1: f64,
    k2: f64,
    p1: f64,
    p2: f64,
    k3: f64,
}

impl BrownConrady {
    /// Coefficients in OpenCV's order.
    ///
    /// # Errors
    /// [`CameraError::InvalidDistortion`] when a coefficient is not finite.
    pub fn new(k1: f64, k2: f64, p1: f64, p2: f64, k3: f64) -> Result<Self, CameraError> {
        let named = [("k1", k1), ("k2", k2), ("p1", p1), ("p2", p2), ("k3", k3)];
        if let Some(&(name, value)) = named.iter().find(|(_, v)| !v.is_finite()) {
            return Err(CameraError::InvalidDistortion { name, value });
        }
        Ok(Self { k1, k2, p1, p2, k3 })
    }

    /// Coefficients from a list as calibration files write it: `(k1, k2, p1, p2)` (`k3 = 0`) or
    /// `(k1, k2, p1, p2, k3)`.
    ///
    /// # Errors
    /// [`CameraError::RationalDistortion`] for 8, 12 or 14 coefficients (OpenCV's rational / thin-prism models, not
    /// supported); [`CameraError::DistortionCoefficientCount`] for any other count but 4 or 5;
    /// [`CameraError::InvalidDistortion`] for a non-finite coefficient.
    pub fn from_coefficients(coefficients: &[f64]) -> Result<Self, CameraError> {
        match *coefficients {
            [k1, k2, p1, p2] => Self::new(k1, k2, p1, p2, 0.0),
            [k1, k2, p1, p2, k3] => Self::new(k1, k2, p1, p2, k3),
            _ if matches!(coefficients.len(), 8 | 12 | 14) => {
                Err(CameraError::RationalDistortion {
                    count: coefficients.len(),
                })
            }
            _ => Err(CameraError::DistortionCoefficientCount {
                count: coefficients.len(),
            }),
        }
    }

    /// The coefficients `[k1, k2, p1, p2, k3]`.
    pub fn coefficients(&self) -> [f64; 5] {
        [self.k1, self.k2, self.p1, self.p2, self.k3]
    }

    /// `true` when every coefficient is zero (the pinhole model).
    pub fn is_identity(&self) -> bool {
        self.coefficients().iter().all(|&c| c == 0.0)
    }

    /// Distorted normalised coordinates `(x_d, y_d)` of undistorted ones `(x, y)` (module equation).
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let (xy, r2) = (x * y, x * x + y * y);
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        (
            x * radial + 2.0 * self.p1 * xy + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * xy,
        )
    }

    /// The Jacobian `∂(x_d, y_d)/∂(x, y)` of [`Self::distort`] as `[[∂x_d/∂x, ∂x_d/∂y], [∂y_d/∂x, ∂y_d/∂y]]`:
    /// with `R = radial` and `R' = dR/d(r²) = k1 + 2 k2 r² + 3 k3 r⁴`,
    /// `∂x_d/∂x = R + 2x² R' + 2 p1 y + 6 p2 x`, `∂x_d/∂y = 2xy R' + 2 p1 x + 2 p2 y`,
    /// `∂y_d/∂x = 2xy R' + 2 p1 x + 2 p2 y`, `∂y_d/∂y = R + 2y² R' + 6 p1 y + 2 p2 x`.
    pub fn jacobian(&self, x: f64, y: f64) -> [[f64; 2]; 2] {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let slope = self.k1 + r2 * (2.0 * self.k2 + 3.0 * self.k3 * r2);
        let cross = 2.0 * x * y * slope + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
        [
            [
                radial + 2.0 * x * x * slope + 2.0 * self.p1 * y + 6.0 * self.p2 * x,
                cross,
            ],
            [
                cross,
                radial + 2.0 * y * y * slope + 6.0 * self.p1 * y + 2.0 * self.p2 * x,
            ],
        ]
    }

    /// Undistorted normalised coordinates `(x, y)` with `distort(x, y) = (x_d, y_d)`, by Newton's method (module
    /// docs). Allocates nothing.
    ///
    /// # Errors
    /// [`CameraError::NonFiniteImagePoint`] for a non-finite input; [`CameraError::UndistortionFailed`] when the
    /// residual is still above [`UNDISTORTION_TOLERANCE`] after [`UNDISTORTION_MAX_ITERATIONS`] steps, or the
    /// Jacobian is singular (the point lies beyond the radius where the lens model folds back).
    pub fn undistort(&self, x_d: f64, y_d: f64) -> Result<(f64, f64), CameraError> {
        if !(x_d.is_finite() && y_d.is_finite()) {
            return Err(CameraError::NonFiniteImagePoint { x: x_d, y: y_d });
        }
        let failed = |residual: f64, iterations: usize| CameraError::UndistortionFailed {
            x_distorted: x_d,
            y_distorted: y_d,
            residual,
            iterations,
        };
        let (mut x, mut y) = (x_d, y_d);
        for iteration in 0..=UNDISTORTION_MAX_ITERATIONS {
            let (fx, fy) = self.distort(x, y);
            let (rx, ry) = (fx - x_d, fy - y_d);
            let residual = rx.abs().max(ry.abs());
            if !residual.is_finite() {
                return Err(failed(residual, iteration));
            }
            if residual <= UNDISTORTION_TOLERANCE {
                return Ok((x, y));
            }
            if iteration == UNDISTORTION_MAX_ITERATIONS {
                return Err(failed(residual, iteration));
            }
            let [[a, b], [c, d]] = self.jacobian(x, y);
            let det = a * d - b * c;
            // The model folds back (det ≤ 0) beyond its invertible radius: no unique undistorted point there.
            if det.is_nan() || det <= f64::EPSILON {
                return Err(failed(residual, iteration));
            }
            x -= (d * rx - b * ry) / det;
            y -= (a * ry - c * rx) / det;
        }
        Err(failed(f64::NAN, UNDISTORTION_MAX_ITERATIONS))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    /// Hand-computed: k1 = 0.1, k2 = 0.01, p1 = 0.001, p2 = 0.002, k3 = 0.001 at (x, y) = (0.3, −0.2):
    /// r² = 0.13, radial = 1 + 0.013 + 0.000169 + 0.000002197 = 1.013171197,
    /// x_d = 0.3039513591 + 2·0.001·(−0.06) + 0.002·(0.13 + 0.18) = 0.3039513591 − 0.00012 + 0.00062 = 0.3044513591,
    /// y_d = −0.2026342394 + 0.001·(0.13 + 0.08) + 2·0.002·(−0.06) = −0.2026342394 + 0.00021 − 0.00024
    ///     = −0.2026642394.
    #[test]
    fn distortion_matches_hand_computed_values() {
        let d = BrownConrady::new(0.1, 0.01, 0.001, 0.002, 0.001).unwrap();
        let (xd, yd) = d.distort(0.3, -0.2);
        assert_relative_eq!(xd, 0.304_451_359_1, epsilon = 1e-10);
        assert_relative_eq!(yd, -0.202_664_239_4, epsilon = 1e-10);
        // The identity model leaves every point unchanged.
        assert_eq!(BrownConrady::default().distort(0.3, -0.2), (0.3, -0.2));
        // Pure barrel k1 = −0.2 at r = 0.5: the radius shrinks to 0.5 (1 − 0.05) = 0.475.
        let barrel = BrownConrady::new(-0.2, 0.0, 0.0, 0.0, 0.0).unwrap();
        let (xd, yd) = barrel.distort(0.3, 0.4);
        assert_relative_eq!(xd.hypot(yd), 0.475, epsilon = 1e-15);
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let d = BrownConrady::new(-0.3, 0.12, 0.004, -0.003, -0.02).unwrap();
        let (x, y, h) = (0.41, -0.27, 1e-6);
        let j = d.jacobian(x, y);
        let (xp, yp) = d.distort(x + h, y);
        let (xm, ym) = d.distort(x - h, y);
        assert_relative_eq!(j[0][0], (xp - xm) / (2.0 * h), epsilon = 1e-8);
        assert_relative_eq!(j[1][0], (yp - ym) / (2.0 * h), epsilon = 1e-8);
        let (xp, yp) = d.distort(x, y + h);
        let (xm, ym) = d.distort(x, y - h);
        assert_relative_eq!(j[0][1], (xp - xm) / (2.0 * h), epsilon = 1e-8);
        assert_relative_eq!(j[1][1], (yp - ym) / (2.0 * h), epsilon = 1e-8);
    }

    #[test]
    fn coefficient_lists_of_four_and_five_are_accepted_others_named() {
        let four = BrownConrady::from_coefficients(&[0.1, -0.2, 0.01, 0.02]).unwrap();
        assert_eq!(four.coefficients(), [0.1, -0.2, 0.01, 0.02, 0.0]);
        let five = BrownConrady::from_coefficients(&[0.1, -0.2, 0.01, 0.02, 0.3]).unwrap();
        assert_eq!(five.coefficients(), [0.1, -0.2, 0.01, 0.02, 0.3]);
        assert_eq!(
            BrownConrady::from_coefficients(&[0.0; 8]),
            Err(CameraError::RationalDistortion { count: 8 })
        );
        assert_eq!(
            BrownConrady::from_coefficients(&[0.0; 3]),
            Err(CameraError::DistortionCoefficientCount { count: 3 })
        );
        assert!(matches!(
            BrownConrady::new(0.0, f64::NAN, 0.0, 0.0, 0.0),
            Err(CameraError::InvalidDistortion { name: "k2", .. })
        ));
    }

    #[test]
    fn bad_undistortion_inputs_are_named_errors() {
        let d = BrownConrady::new(-0.2, 0.0, 0.0, 0.0, 0.0).unwrap();
        assert!(matches!(
            d.undistort(f64::NAN, 0.1),
            Err(CameraError::NonFiniteImagePoint { .. })
        ));
        assert!(matches!(
            d.undistort(0.1, f64::INFINITY),
            Err(CameraError::NonFiniteImagePoint { .. })
        ));
        // Barrel k1 = −0.2: r_d(r) = r − 0.2 r³ peaks at r = 1.29 with r_d = 0.861; a distorted radius of 1.0 has no
        // undistorted preimage.
        assert!(matches!(
            d.undistort(1.0, 0.0),
            Err(CameraError::UndistortionFailed { .. })
        ));
    }

    /// Coefficients in the ranges of real calibrations (|k1| ≤ 0.5, |k2| ≤ 0.2, |k3| ≤ 0.05, |p| ≤ 0.01).
    fn lens() -> impl Strategy<Value = BrownConrady> {
        (
            -0.5..0.5f64,
            -0.2..0.2f64,
            -0.01..0.01f64,
            -0.01..0.01f64,
            -0.05..0.05f64,
        )
            .prop_map(|(k1, k2, p1, p2, k3)| BrownConrady::new(k1, k2, p1, p2, k3).unwrap())
    }

    /// As [`lens`], restricted to lenses whose radial map `r ↦ r (1 + k1 r² + k2 r⁴ + k3 r⁶)` is invertible over the
    /// image — increasing up to `r = 0.8` and reaching beyond `r_d = 0.6` there — as a calibration is on its own image.
    /// Strong barrel lenses of [`lens`] (say `k1 = −0.47, k2 = −0.18`) peak below the image corner's distorted radius:
    /// a measured point there has no undistorted preimage (a named error, `bad_undistortion_inputs_are_named_errors`).
    fn invertible_lens() -> impl Strategy<Value = BrownConrady> {
        lens().prop_filter("radial map invertible over the image", |d| {
            let radial = |r: f64| r * (1.0 + d.k1 * r * r + d.k2 * r.powi(4) + d.k3 * r.powi(6));
            let slope =
                |r: f64| 1.0 + 3.0 * d.k1 * r * r + 5.0 * d.k2 * r.powi(4) + 7.0 * d.k3 * r.powi(6);
            (0..=80).all(|i| slope(f64::from(i) / 100.0) > 0.0) && radial(0.8) > 0.6
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// Undistorting a distorted point over a 640 × 480 image at f = 600 px (|x| ≤ 0.54, |y| ≤ 0.4) gives it back.
        #[test]
        fn undistort_inverts_distort(d in lens(), x in -0.54..0.54f64, y in -0.4..0.4f64) {
            let (xd, yd) = d.distort(x, y);
            let (xu, yu) = d.undistort(xd, yd).unwrap();
            // 1e−11 normalised ≈ 6e−9 px at f = 600 px.
            prop_assert!((xu - x).abs() < 1e-11 && (yu - y).abs() < 1e-11, "{xu} {yu} vs {x} {y}");
        }

        /// And the other way: a measured (distorted) point, undistorted then distorted, is unchanged.
        #[test]
        fn distort_inverts_undistort(d in invertible_lens(), xd in -0.45..0.45f64, yd in -0.33..0.33f64) {
            let (x, y) = d.undistort(xd, yd).unwrap();
            let (xr, yr) = d.distort(x, y);
            prop_assert!((xr - xd).abs() <= 1e-12 && (yr - yd).abs() <= 1e-12);
        }
    }
}
