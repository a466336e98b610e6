//! Lens distortion on normalised image coordinates: the Brown–Conrady "plumb bob" model of OpenCV, ROS and ViSP,
//! with OpenCV's rational and thin-prism extensions.
//!
//! For undistorted normalised coordinates `(x, y)` (camera frame, `x = X/Z`, `y = Y/Z`) and `r² = x² + y²`, the
//! distorted normalised coordinates are (OpenCV's `projectPoints`, without its tilt)
//!
//! ```text
//! radial = (1 + k1 r² + k2 r⁴ + k3 r⁶) / (1 + k4 r² + k5 r⁴ + k6 r⁶)
//! x_d = x · radial + 2 p1 x y + p2 (r² + 2 x²) + s1 r² + s2 r⁴
//! y_d = y · radial + p1 (r² + 2 y²) + 2 p2 x y + s3 r² + s4 r⁴
//! ```
//!
//! and the measured pixel is `u = cx + fx x_d`, `v = cy + fy y_d` ([`super::CalibratedCamera`]). The coefficients are
//! dimensionless and are kept in OpenCV's order `(k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4)`. Three models, as
//! OpenCV's coefficient lists name them: the plumb bob `(k1, k2, p1, p2[, k3])` (4 or 5 coefficients, the others 0),
//! the rational model (8: `k4, k5, k6` added) and the thin-prism model (12: `s1 … s4` added). OpenCV's 14-coefficient
//! tilted model is accepted only with zero tilt `τx = τy = 0`, where it is the thin-prism model
//! ([`CameraError::TiltedDistortion`] otherwise).
//!
//! Undistortion inverts the map by Newton's method on `d(x, y) − (x_d, y_d) = 0` with the exact 2 × 2 Jacobian of
//! `d`, starting from `(x_d, y_d)`; it stops when the residual is below [`UNDISTORTION_TOLERANCE`] (normalised units)
//! and gives up after [`UNDISTORTION_MAX_ITERATIONS`] steps with [`CameraError::UndistortionFailed`].
//!
//! **The fold.** The radial map `r ↦ r R(r²)`, `R(s) = N(s)/M(s)` with `N(s) = 1 + k1 s + k2 s² + k3 s³` and
//! `M(s) = 1 + k4 s + k5 s² + k6 s³`, is one-to-one only up to the first radius `r_f` where its slope
//! `d(r R)/dr = P(s)/M(s)²`, `P(s) = N M + 2 s (N′ M − N M′)`, reaches 0, or where the denominator `M` does (the map
//! has a pole there); `r_f = ∞` when neither does. For the plumb bob (`M = 1`), `P(s) = 1 + 3 k1 s + 5 k2 s² + 7 k3 s³`.
//! Past `r_f` the lens folds the image back onto itself, and a pixel there has two or more preimages (or none).
//! [`BrownConrady::fold_radius`] computes `r_f` once, when the coefficients are set, and undistortion refuses a
//! preimage at or past it ([`CameraError::BeyondFold`]) — even where Newton's method converges there, as it does for
//! a lens whose slope turns positive again (`k1 = −1, k3 = 0.5`). Past the pole, [`BrownConrady::distort`] is not
//! finite.

mod fold;

use super::CameraError;
use fold::fold_r2;

/// Residual `‖d(x, y) − (x_d, y_d)‖∞` (normalised units, ≈ 1e−12 · f px) below which undistortion has converged.
pub const UNDISTORTION_TOLERANCE: f64 = 1e-12;

/// Newton steps allowed before undistortion reports [`CameraError::UndistortionFailed`] (from an undistorted start,
/// realistic lenses converge in 3–6 steps).
pub const UNDISTORTION_MAX_ITERATIONS: usize = 20;

/// The names of OpenCV's distortion coefficients, in its order (the 14-coefficient tilted model's list).
const COEFFICIENT_NAMES: [&str; 14] = [
    "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "tau_x", "tau_y",
];

/// Lens distortion coefficients (dimensionless, OpenCV order, module docs): radial `k1, k2, k3` over
/// `1 + k4 r² + k5 r⁴ + k6 r⁶` (rational model), tangential `p1, p2`, thin prism `s1 … s4`. The default is no
/// distortion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BrownConrady {
    /// `(k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4)`; those past `count` are 0.
    all: [f64; 12],
    /// The model's number of coefficients: 5 (plumb bob), 8 (rational) or 12 (thin prism).
    count: usize,
    /// `r_f²`, the square of the fold radius (module docs), `∞` when the radial map never folds.
    fold_r2: f64,
}

impl Default for BrownConrady {
    /// No distortion (the pinhole model), which never folds.
    fn default() -> Self {
        Self {
            all: [0.0; 12],
            count: 5,
            fold_r2: f64::INFINITY,
        }
    }
}

impl BrownConrady {
    /// The plumb-bob model: coefficients `(k1, k2, p1, p2, k3)` in OpenCV's order.
    ///
    /// # Errors
    /// [`CameraError::InvalidDistortion`] when a coefficient is outside
    /// [`DISTORTION_COEFFICIENT`](crate::bounds::DISTORTION_COEFFICIENT) (NaN and infinities never pass).
    pub fn new(k1: f64, k2: f64, p1: f64, p2: f64, k3: f64) -> Result<Self, CameraError> {
        Self::from_coefficients(&[k1, k2, p1, p2, k3])
    }

    /// Coefficients from a list as OpenCV and calibration files write it: `(k1, k2, p1, p2)` (`k3 = 0`),
    /// `(k1, k2, p1, p2, k3)`, the rational `(…, k3, k4, k5, k6)`, the thin-prism `(…, k6, s1, s2, s3, s4)`, or the
    /// tilted `(…, s4, τx, τy)` with `τx = τy = 0` (loaded as the thin-prism model).
    ///
    /// # Errors
    /// [`CameraError::InvalidDistortion`] for a coefficient outside
    /// [`DISTORTION_COEFFICIENT`](crate::bounds::DISTORTION_COEFFICIENT); [`CameraError::TiltedDistortion`] for 14
    /// coefficients with a non-zero tilt; [`CameraError::DistortionCoefficientCount`] for another count than 4, 5, 8,
    /// 12 or 14.
    pub fn from_coefficients(coefficients: &[f64]) -> Result<Self, CameraError> {
        let count = match coefficients.len() {
            4 | 5 => 5,
            count @ (8 | 12) => count,
            14 => 12,
            count => return Err(CameraError::DistortionCoefficientCount { count }),
        };
        let range = crate::bounds::DISTORTION_COEFFICIENT;
        if let Some((&name, &value)) = COEFFICIENT_NAMES
            .iter()
            .zip(coefficients)
            .find(|(_, v)| !range.contains(**v))
        {
            return Err(CameraError::InvalidDistortion { name, value });
        }
        if let Some(&[tau_x, tau_y]) = coefficients.get(12..14) {
            if tau_x != 0.0 || tau_y != 0.0 {
                return Err(CameraError::TiltedDistortion { tau_x, tau_y });
            }
        }
        let mut all = [0.0; 12];
        for (slot, &c) in all.iter_mut().zip(coefficients) {
            *slot = c;
        }
        Ok(Self {
            all,
            count,
            fold_r2: fold_r2(&all),
        })
    }

    /// The coefficients in OpenCV's order, as many as the model has: `[k1, k2, p1, p2, k3]` (plumb bob, also for a
    /// list of 4), `[…, k4, k5, k6]` (rational) or `[…, s1, s2, s3, s4]` (thin prism, also for a list of 14).
    pub fn coefficients(&self) -> &[f64] {
        &self.all[..self.count]
    }

    /// The fold radius `r_f` (normalised units, module docs): the first radius where the radial map's slope or its
    /// denominator reaches 0, `∞` when neither does. Undistortion refuses preimages at or past it.
    pub fn fold_radius(&self) -> f64 {
        self.fold_r2.sqrt()
    }

    /// `true` when every coefficient is zero (the pinhole model).
    pub fn is_identity(&self) -> bool {
        self.all.iter().all(|&c| c == 0.0)
    }

    /// `(R, dR/ds)` of the radial factor `R(s) = N(s)/M(s)` at `s = r²` (module docs).
    fn radial(&self, r2: f64) -> (f64, f64) {
        let [k1, k2, _, _, k3, k4, k5, k6, ..] = self.all;
        let numerator = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        let denominator = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6));
        let numerator_slope = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);
        let denominator_slope = k4 + r2 * (2.0 * k5 + 3.0 * k6 * r2);
        (
            numerator / denominator,
            (numerator_slope * denominator - numerator * denominator_slope)
                / (denominator * denominator),
        )
    }

    /// Distorted normalised coordinates `(x_d, y_d)` of undistorted ones `(x, y)` (module equation).
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let [_, _, p1, p2, _, _, _, _, s1, s2, s3, s4] = self.all;
        let (xy, r2) = (x * y, x * x + y * y);
        let (radial, _) = self.radial(r2);
        (
            x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x) + r2 * (s1 + s2 * r2),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy + r2 * (s3 + s4 * r2),
        )
    }

    /// The Jacobian `∂(x_d, y_d)/∂(x, y)` of [`Self::distort`] as `[[∂x_d/∂x, ∂x_d/∂y], [∂y_d/∂x, ∂y_d/∂y]]`:
    /// with `R = radial`, `R' = dR/d(r²)`, `S_x = s1 + 2 s2 r²` and `S_y = s3 + 2 s4 r²`,
    /// `∂x_d/∂x = R + 2x² R' + 2 p1 y + 6 p2 x + 2x S_x`, `∂x_d/∂y = 2xy R' + 2 p1 x + 2 p2 y + 2y S_x`,
    /// `∂y_d/∂x = 2xy R' + 2 p1 x + 2 p2 y + 2x S_y`, `∂y_d/∂y = R + 2y² R' + 6 p1 y + 2 p2 x + 2y S_y`.
    pub fn jacobian(&self, x: f64, y: f64) -> [[f64; 2]; 2] {
        let [_, _, p1, p2, _, _, _, _, s1, s2, s3, s4] = self.all;
        let r2 = x * x + y * y;
        let (radial, slope) = self.radial(r2);
        let (prism_x, prism_y) = (s1 + 2.0 * s2 * r2, s3 + 2.0 * s4 * r2);
        let cross = 2.0 * x * y * slope + 2.0 * p1 * x + 2.0 * p2 * y;
        [
            [
                radial + 2.0 * x * x * slope + 2.0 * p1 * y + 6.0 * p2 * x + 2.0 * x * prism_x,
                cross + 2.0 * y * prism_x,
            ],
            [
                cross + 2.0 * x * prism_y,
                radial + 2.0 * y * y * slope + 6.0 * p1 * y + 2.0 * p2 * x + 2.0 * y * prism_y,
            ],
        ]
    }

    /// Undistorted normalised coordinates `(x, y)` with `distort(x, y) = (x_d, y_d)`, by Newton's method (module
    /// docs). Allocates nothing.
    ///
    /// # Errors
    /// [`CameraError::NonFiniteImagePoint`] for a non-finite input; [`CameraError::UndistortionFailed`] when the
    /// residual is still above [`UNDISTORTION_TOLERANCE`] after [`UNDISTORTION_MAX_ITERATIONS`] steps, or the
    /// Jacobian is singular (the point lies beyond the radius where the lens model folds back);
    /// [`CameraError::BeyondFold`] when the preimage found lies at or past the [fold radius](Self::fold_radius).
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
                let r2 = x * x + y * y;
                if r2 >= self.fold_r2 {
                    return Err(CameraError::BeyondFold {
                        x_distorted: x_d,
                        y_distorted: y_d,
                        radius: r2.sqrt(),
                        fold_radius: self.fold_radius(),
                    });
                }
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

    /// The coefficients of a plumb-bob lens.
    fn plumb_bob(d: &BrownConrady) -> [f64; 5] {
        d.coefficients().try_into().expect("a plumb-bob lens")
    }

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

    /// The Jacobian at `(x, y)` against central differences of `distort` (step 10⁻⁶, agreement to 10⁻⁸).
    fn assert_jacobian_matches_finite_differences(d: &BrownConrady, x: f64, y: f64) {
        let h = 1e-6;
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
    fn jacobian_matches_finite_differences() {
        let d = BrownConrady::new(-0.3, 0.12, 0.004, -0.003, -0.02).unwrap();
        assert_jacobian_matches_finite_differences(&d, 0.41, -0.27);
    }

    #[test]
    fn coefficient_lists_of_opencv_models_are_accepted_others_named() {
        let four = BrownConrady::from_coefficients(&[0.1, -0.2, 0.01, 0.02]).unwrap();
        assert_eq!(four.coefficients(), [0.1, -0.2, 0.01, 0.02, 0.0]);
        let five = BrownConrady::from_coefficients(&[0.1, -0.2, 0.01, 0.02, 0.3]).unwrap();
        assert_eq!(five.coefficients(), [0.1, -0.2, 0.01, 0.02, 0.3]);
        let rational: Vec<f64> = (1..=8).map(|i| f64::from(i) / 100.0).collect();
        assert_eq!(
            BrownConrady::from_coefficients(&rational)
                .unwrap()
                .coefficients(),
            rational
        );
        let prism: Vec<f64> = (1..=12).map(|i| f64::from(i) / 100.0).collect();
        assert_eq!(
            BrownConrady::from_coefficients(&prism)
                .unwrap()
                .coefficients(),
            prism
        );
        // Fourteen with zero tilt: the thin-prism model; with a tilt, refused by name.
        let untilted = [&prism[..], &[0.0, 0.0]].concat();
        assert_eq!(
            BrownConrady::from_coefficients(&untilted)
                .unwrap()
                .coefficients(),
            prism
        );
        let tilted = [&prism[..], &[0.0, 0.003]].concat();
        assert_eq!(
            BrownConrady::from_coefficients(&tilted),
            Err(CameraError::TiltedDistortion {
                tau_x: 0.0,
                tau_y: 0.003
            })
        );
        for count in [0, 1, 3, 6, 7, 9, 10, 11, 13, 15, 64] {
            assert_eq!(
                BrownConrady::from_coefficients(&vec![0.0; count]),
                Err(CameraError::DistortionCoefficientCount { count })
            );
        }
        assert!(matches!(
            BrownConrady::from_coefficients(&[&prism[..11], &[f64::INFINITY]].concat()),
            Err(CameraError::InvalidDistortion { name: "s4", .. })
        ));
        assert!(matches!(
            BrownConrady::from_coefficients(&[&prism[..], &[0.0, f64::NAN]].concat()),
            Err(CameraError::InvalidDistortion { name: "tau_y", .. })
        ));
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

    #[test]
    fn fold_radius_is_where_the_radial_slope_first_vanishes() {
        let slope = |d: &BrownConrady, r: f64| {
            let (s, [k1, k2, _, _, k3]) = (r * r, plumb_bob(d));
            1.0 + 3.0 * k1 * s + 5.0 * k2 * s * s + 7.0 * k3 * s * s * s
        };
        // Barrel k1 = −0.2: slope 1 − 0.6 r², zero at r² = 1/0.6 (hand-computed).
        let barrel = BrownConrady::new(-0.2, 0.0, 0.0, 0.0, 0.0).unwrap();
        assert!((barrel.fold_radius() - (1.0f64 / 0.6).sqrt()).abs() < 1e-12);
        // A pincushion lens and the pinhole never fold.
        assert_eq!(
            BrownConrady::new(0.2, 0.05, 0.0, 0.0, 0.0)
                .unwrap()
                .fold_radius(),
            f64::INFINITY
        );
        assert_eq!(BrownConrady::default().fold_radius(), f64::INFINITY);
        // k1 = −1, k3 = 0.5: the slope 1 − 3 s + 3.5 s³ dips below 0 between two roots and turns positive again.
        let dip = BrownConrady::new(-1.0, 0.0, 0.0, 0.0, 0.5).unwrap();
        let r_f = dip.fold_radius();
        assert!(
            slope(&dip, r_f).abs() < 1e-9,
            "slope {} at {r_f}",
            slope(&dip, r_f)
        );
        assert!((0..1000).all(|i| slope(&dip, r_f * f64::from(i) / 1000.0) > 0.0));
        // A negligible k2 puts the slope's critical point near 3e298: the bisection must still reach r² = 1/0.3.
        let tiny = BrownConrady::new(-0.1, 1e-300, 0.001, 0.002, 0.0).unwrap();
        assert!(
            (tiny.fold_radius().powi(2) - 1.0 / 0.3).abs() < 1e-12,
            "{}",
            tiny.fold_radius()
        );
        // A lens whose slope falls only through its cubic term: 1 − 7e−6 s³ vanishes at s = (1/7e−6)^(1/3).
        let far = BrownConrady::new(0.0, 0.0, 0.0, 0.0, -1e-6).unwrap();
        assert!((far.fold_radius().powi(2) - (1.0f64 / 7e-6).cbrt()).abs() < 1e-9);
    }

    /// A coefficient of a real lens's size, or of any magnitude down to 1e−300 (the fold's critical points then lie
    /// far out, and its bracket is wide).
    fn coefficient() -> impl Strategy<Value = f64> {
        prop_oneof![
            -2.0..2.0f64,
            (-2.0..2.0f64, -300..0i32).prop_map(|(m, e)| m * 10f64.powi(e)),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]
        /// Over any coefficients, the slope is positive on a fine grid inside the fold radius and reaches 0 at it.
        #[test]
        fn fold_radius_is_the_first_zero_of_the_slope(
            k1 in coefficient(), k2 in coefficient(), k3 in coefficient(),
        ) {
            let d = BrownConrady::new(k1, k2, 0.0, 0.0, k3).unwrap();
            // Horner's form: the fold of a lens with a tiny coefficient can lie where s³ overflows.
            let slope = |s: f64| 1.0 + s * (3.0 * k1 + s * (5.0 * k2 + s * 7.0 * k3));
            let r_f = d.fold_radius();
            let reach = if r_f.is_finite() { r_f * r_f } else { 100.0 };
            for i in 0..2000 {
                let s = reach * f64::from(i) / 2000.0;
                prop_assert!(slope(s) > 0.0, "slope {} at s = {s} below s_f = {reach}", slope(s));
            }
            if r_f.is_finite() {
                // Zero to the rounding of its terms (the root is found to the resolution of f64).
                let s = r_f * r_f;
                let scale = 1.0 + (3.0 * k1 * s).abs() + (5.0 * k2 * s * s).abs() + (7.0 * k3 * s * s).abs() * s;
                prop_assert!(slope(s).abs() <= 1e-12 * scale, "slope {} at s = {s}", slope(s));
            }
        }
    }

    #[test]
    fn a_non_monotonic_lens_refuses_every_pixel_past_its_fold() {
        // k1 = −1, k3 = 0.5: Newton converges past the fold for many pixels, where the slope is positive again.
        let d = BrownConrady::new(-1.0, 0.0, 0.0, 0.0, 0.5).unwrap();
        let r_f = d.fold_radius();
        let (mut refused, mut inside) = (0, 0);
        for i in -40..=40 {
            for j in -40..=40 {
                let (xd, yd) = (f64::from(i) / 25.0, f64::from(j) / 25.0);
                match d.undistort(xd, yd) {
                    Ok((x, y)) => {
                        assert!(
                            x.hypot(y) < r_f,
                            "({xd}, {yd}) undistorted past the fold to ({x}, {y})"
                        );
                        inside += 1;
                    }
                    Err(
                        CameraError::BeyondFold { .. } | CameraError::UndistortionFailed { .. },
                    ) => refused += 1,
                    Err(other) => panic!("{other}"),
                }
            }
        }
        // Both answers occur on this grid (the distorted radius reaches 0.40 at the fold).
        assert!(
            inside > 100 && refused > 100,
            "{inside} inside, {refused} refused"
        );
        // A pixel whose only preimages lie past the fold is refused by name.
        let (xd, _) = d.distort(1.3, 0.0);
        assert!(
            matches!(d.undistort(xd, 0.0), Err(CameraError::BeyondFold { .. })),
            "{:?}",
            d.undistort(xd, 0.0)
        );
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
            let [k1, k2, _, _, k3] = plumb_bob(d);
            let radial = |r: f64| r * (1.0 + k1 * r * r + k2 * r.powi(4) + k3 * r.powi(6));
            let slope =
                |r: f64| 1.0 + 3.0 * k1 * r * r + 5.0 * k2 * r.powi(4) + 7.0 * k3 * r.powi(6);
            (0..=80).all(|i| slope(f64::from(i) / 100.0) > 0.0) && radial(0.8) > 0.6
        })
    }

    /// `undistort(distort(x, y)) = (x, y)` within 10⁻¹¹ (normalised; ≈ 6·10⁻⁹ px at f = 600 px).
    fn assert_undistort_inverts_distort(
        d: &BrownConrady,
        x: f64,
        y: f64,
    ) -> Result<(), proptest::test_runner::TestCaseError> {
        let (xd, yd) = d.distort(x, y);
        let (xu, yu) = d.undistort(xd, yd).unwrap();
        prop_assert!(
            (xu - x).abs() < 1e-11 && (yu - y).abs() < 1e-11,
            "{xu} {yu} vs {x} {y}"
        );
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// Undistorting a distorted point over a 640 × 480 image at f = 600 px (|x| ≤ 0.54, |y| ≤ 0.4) gives it back.
        #[test]
        fn undistort_inverts_distort(d in lens(), x in -0.54..0.54f64, y in -0.4..0.4f64) {
            assert_undistort_inverts_distort(&d, x, y)?;
        }

        /// And the other way: a measured (distorted) point, undistorted then distorted, is unchanged.
        #[test]
        fn distort_inverts_undistort(d in invertible_lens(), xd in -0.45..0.45f64, yd in -0.33..0.33f64) {
            let (x, y) = d.undistort(xd, yd).unwrap();
            let (xr, yr) = d.distort(x, y);
            prop_assert!((xr - xd).abs() <= 1e-12 && (yr - yd).abs() <= 1e-12);
        }
    }

    /// Rational (8) and thin-prism (12) lenses against OpenCV: the expected values are `cv2.projectPoints` (OpenCV
    /// 5.0.0, opencv-python-headless) of the points `(0.3, −0.2, 1)` and `(−0.45, 0.35, 1)` with `K = I`, no rotation
    /// or translation, and these coefficients.
    #[test]
    fn rational_and_thin_prism_distortion_match_opencv() {
        let rational = [0.1, 0.01, 0.001, 0.002, 0.001, 0.05, -0.02, 0.003];
        let prism = [&rational[..], &[0.004, -0.001, -0.003, 0.0005]].concat();
        let cases = [
            (
                &rational[..],
                [
                    (0.302_587_902_384_144_3, -0.201_421_934_922_762_86),
                    (-0.457_440_283_590_671_96, 0.356_617_442_792_744_9),
                ],
            ),
            (
                &prism[..],
                [
                    (0.303_091_002_384_144_3, -0.201_803_484_922_762_87),
                    (-0.456_245_908_590_671_93, 0.355_695_255_292_744_87),
                ],
            ),
        ];
        for (coefficients, expected) in cases {
            let d = BrownConrady::from_coefficients(coefficients).unwrap();
            for ((x, y), (u, v)) in [(0.3, -0.2), (-0.45, 0.35)].into_iter().zip(expected) {
                let (xd, yd) = d.distort(x, y);
                assert_relative_eq!(xd, u, epsilon = 1e-15);
                assert_relative_eq!(yd, v, epsilon = 1e-15);
                let (xu, yu) = d.undistort(xd, yd).unwrap();
                assert!((xu - x).abs() < 1e-12 && (yu - y).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn thin_prism_jacobian_matches_finite_differences() {
        let d = BrownConrady::from_coefficients(&[
            -0.3, 0.12, 0.004, -0.003, -0.02, 0.2, -0.05, 0.01, 0.006, -0.002, -0.004, 0.001,
        ])
        .unwrap();
        for (x, y) in [(0.41, -0.27), (-0.2, 0.33), (0.0, 0.1)] {
            assert_jacobian_matches_finite_differences(&d, x, y);
        }
    }

    #[test]
    fn rational_fold_is_at_the_slope_zero_or_the_pole() {
        let rational = |k4: f64, k5: f64, k6: f64| {
            BrownConrady::from_coefficients(&[0.0, 0.0, 0.0, 0.0, 0.0, k4, k5, k6]).unwrap()
        };
        // k4 = −1: r R = r / (1 − r²) rises without a fold up to its pole at r² = 1 (hand-computed).
        assert!((rational(-1.0, 0.0, 0.0).fold_radius() - 1.0).abs() < 1e-15);
        // k4 = 0.5: r / (1 + 0.5 r²) has the slope (1 − 0.5 r²)/(1 + 0.5 r²)², zero at r² = 2 (hand-computed).
        assert!((rational(0.5, 0.0, 0.0).fold_radius() - 2f64.sqrt()).abs() < 1e-15);
        // k6 = 0.01: the denominator stays positive and r R = r / (1 + 0.01 r⁶) peaks where 1 − 0.05 r⁶ = 0.
        let far = rational(0.0, 0.0, 0.01).fold_radius();
        assert!((far.powi(6) - 20.0).abs() < 1e-12, "{far}");
        // k1 = −0.1, k4 = 0.01 and a subnormal k2 (found by the fuzz harness: its slope's critical points lie past
        // the largest f64, and were taken for the sign at ∞): the slope's numerator is 1 − 0.31 s − 0.001 s² (+ terms
        // in k2, below 1e−300 here), zero at s = (−0.31 + √(0.31² + 0.004))/0.002 (hand-computed).
        let subnormal =
            BrownConrady::from_coefficients(&[-0.1, 1e-320, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0])
                .unwrap();
        let s = (-0.31 + (0.31f64 * 0.31 + 0.004).sqrt()) / 0.002;
        assert!(
            (subnormal.fold_radius().powi(2) - s).abs() < 1e-12,
            "{}",
            subnormal.fold_radius()
        );
        // k1 = 0.1 over k4 = 0.1: R = 1, no fold.
        let cancelled = BrownConrady::from_coefficients(&[0.1, 0.0, 0.0, 0.0, 0.0, 0.1, 0.0, 0.0]);
        assert_eq!(cancelled.unwrap().fold_radius(), f64::INFINITY);
        // A pixel whose preimage lies past the pole is refused, not undistorted onto the other branch.
        assert!(rational(-1.0, 0.0, 0.0).undistort(-3.0, 0.0).is_err());
    }

    /// A rational thin-prism lens with coefficients of real calibrations' sizes.
    fn thin_prism_lens() -> impl Strategy<Value = BrownConrady> {
        (
            prop::array::uniform8(-0.1..0.1f64),
            prop::array::uniform4(-0.005..0.005f64),
        )
            .prop_map(|(radial, prism)| {
                let [k1, k2, k3, k4, k5, k6, p1, p2] = radial;
                let [s1, s2, s3, s4] = prism;
                BrownConrady::from_coefficients(&[
                    k1,
                    k2,
                    p1 / 10.0,
                    p2 / 10.0,
                    k3,
                    k4,
                    k5,
                    k6,
                    s1,
                    s2,
                    s3,
                    s4,
                ])
                .unwrap()
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// Undistortion inverts the rational thin-prism model over a 640 × 480 image at f = 600 px.
        #[test]
        fn undistort_inverts_thin_prism_distort(d in thin_prism_lens(), x in -0.54..0.54f64, y in -0.4..0.4f64) {
            assert_undistort_inverts_distort(&d, x, y)?;
        }

        /// Over any rational coefficients, the radial slope's numerator `N M + 2 s (N′ M − N M′)` and the denominator
        /// `M`, evaluated term by term, stay positive on a grid inside the fold, and one of them reaches 0 at it.
        #[test]
        fn rational_fold_radius_is_the_first_zero(
            k1 in coefficient(), k2 in coefficient(), k3 in coefficient(),
            k4 in coefficient(), k5 in coefficient(), k6 in coefficient(),
        ) {
            let d = BrownConrady::from_coefficients(&[k1, k2, 0.0, 0.0, k3, k4, k5, k6]).unwrap();
            let n = |s: f64| 1.0 + k1 * s + k2 * s * s + k3 * s * s * s;
            let m = |s: f64| 1.0 + k4 * s + k5 * s * s + k6 * s * s * s;
            let n_ = |s: f64| k1 + 2.0 * k2 * s + 3.0 * k3 * s * s;
            let m_ = |s: f64| k4 + 2.0 * k5 * s + 3.0 * k6 * s * s;
            let slope = |s: f64| n(s) * m(s) + 2.0 * s * (n_(s) * m(s) - n(s) * m_(s));
            // Checked up to s = 1e6 (r = 1000, far past any image), where these products stay finite.
            let r_f = d.fold_radius();
            let reach = (r_f * r_f).min(1e6);
            for i in 0..2000 {
                let s = reach * f64::from(i) / 2000.0;
                prop_assert!(slope(s) > 0.0 && m(s) > 0.0, "slope {}, M {} at s = {s} below {reach}", slope(s), m(s));
            }
            if reach < 1e6 {
                let s = reach;
                let scale = |c: [f64; 3]| 1.0 + (c[0] * s).abs() + (c[1] * s * s).abs() + (c[2] * s * s * s).abs();
                let tolerance = 1e-10 * scale([k1, k2, k3]) * scale([k4, k5, k6]);
                prop_assert!(slope(s).abs() <= tolerance || m(s).abs() <= tolerance,
                    "slope {}, M {} at s = {s}", slope(s), m(s));
            }
        }
    }
}
