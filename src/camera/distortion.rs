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
//!
//! **The fold.** The radial map `r ↦ r D(r)`, `D(r) = 1 + k1 r² + k2 r⁴ + k3 r⁶`, is one-to-one only up to the
//! first radius `r_f` where its slope `d(r D(r))/dr = 1 + 3 k1 r² + 5 k2 r⁴ + 7 k3 r⁶` reaches 0 (∞ when it never
//! does): past it the lens folds the image back onto itself, and a pixel there has two or more preimages (or none).
//! [`BrownConrady::fold_radius`] computes `r_f` once, when the coefficients are set, and undistortion refuses a
//! preimage at or past it ([`CameraError::BeyondFold`]) — even where Newton's method converges there, as it does for
//! a lens whose slope turns positive again (`k1 = −1, k3 = 0.5`).

use super::CameraError;

/// Residual `‖d(x, y) − (x_d, y_d)‖∞` (normalised units, ≈ 1e−12 · f px) below which undistortion has converged.
pub const UNDISTORTION_TOLERANCE: f64 = 1e-12;

/// Newton steps allowed before undistortion reports [`CameraError::UndistortionFailed`] (from an undistorted start,
/// realistic lenses converge in 3–6 steps).
pub const UNDISTORTION_MAX_ITERATIONS: usize = 20;

/// Brown–Conrady distortion coefficients `(k1, k2, p1, p2, k3)` (dimensionless, OpenCV order): radial `k1, k2, k3`,
/// tangential `p1, p2`. The default is no distortion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BrownConrady {
    k1: f64,
    k2: f64,
    p1: f64,
    p2: f64,
    k3: f64,
    /// `r_f²`, the square of the fold radius (module docs), `∞` when the radial map never folds.
    fold_r2: f64,
}

impl Default for BrownConrady {
    /// No distortion (the pinhole model), which never folds.
    fn default() -> Self {
        Self {
            k1: 0.0,
            k2: 0.0,
            p1: 0.0,
            p2: 0.0,
            k3: 0.0,
            fold_r2: f64::INFINITY,
        }
    }
}

/// The smallest `s > 0` where `g(s) = 1 + 3 k1 s + 5 k2 s² + 7 k3 s³` (the radial map's slope at `r² = s`) reaches
/// 0, `∞` when it stays positive. `g` is monotone between the roots of `g'(s) = 3 k1 + 10 k2 s + 21 k3 s²`, so its
/// first sign change lies in the first of those intervals whose right end is non-positive, where bisection finds it.
fn first_fold(k1: f64, k2: f64, k3: f64) -> f64 {
    let g = |s: f64| 1.0 + s * (3.0 * k1 + s * (5.0 * k2 + s * 7.0 * k3));
    // The roots of g' in (0, ∞), in increasing order.
    let (a, b, c) = (21.0 * k3, 10.0 * k2, 3.0 * k1);
    let mut ends = [f64::INFINITY; 3];
    if a != 0.0 {
        let discriminant = b * b - 4.0 * a * c;
        if discriminant >= 0.0 {
            // The stable form: q = −(b + sign(b) √Δ)/2, roots q/a and c/q (no cancellation when |a c| ≪ b²).
            let q = -0.5 * (b + b.signum() * discriminant.sqrt());
            let (r1, r2) = (q / a, if q != 0.0 { c / q } else { q / a });
            ends[0] = r1.min(r2);
            ends[1] = r1.max(r2);
        }
    } else if b != 0.0 {
        ends[0] = -c / b;
    }
    let mut low = 0.0f64;
    for end in ends.into_iter().filter(|e| *e > 0.0) {
        let mut high = end;
        if high.is_infinite() {
            // g is monotone on (low, ∞): it falls to 0 only if it falls without bound; find a finite bracket.
            high = low.max(1.0);
            while g(high) > 0.0 {
                high *= 2.0;
                if !high.is_finite() || g(high) > g(high / 2.0) {
                    return f64::INFINITY;
                }
            }
        }
        if g(high) <= 0.0 {
            // To the resolution of f64: a bracket as wide as 1e308 needs about 1 100 halvings (a lens with a tiny k2
            // has its slope's critical point there, found by the fuzz harness); the cap only guards the loop.
            for _ in 0..2_200 {
                let middle = 0.5 * (low + high);
                if middle <= low || middle >= high {
                    break;
                }
                if g(middle) > 0.0 {
                    low = middle;
                } else {
                    high = middle;
                }
            }
            return high;
        }
        low = end;
    }
    f64::INFINITY
}

impl BrownConrady {
    /// Coefficients in OpenCV's order.
    ///
    /// # Errors
    /// [`CameraError::InvalidDistortion`] when a coefficient is outside
    /// [`DISTORTION_COEFFICIENT`](crate::bounds::DISTORTION_COEFFICIENT) (NaN and infinities never pass).
    pub fn new(k1: f64, k2: f64, p1: f64, p2: f64, k3: f64) -> Result<Self, CameraError> {
        let named = [("k1", k1), ("k2", k2), ("p1", p1), ("p2", p2), ("k3", k3)];
        let range = crate::bounds::DISTORTION_COEFFICIENT;
        if let Some(&(name, value)) = named.iter().find(|(_, v)| !range.contains(*v)) {
            return Err(CameraError::InvalidDistortion { name, value });
        }
        Ok(Self {
            k1,
            k2,
            p1,
            p2,
            k3,
            fold_r2: first_fold(k1, k2, k3),
        })
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

    /// The fold radius `r_f` (normalised units, module docs): the first radius where the radial map's slope reaches
    /// 0, `∞` when it never does. Undistortion refuses preimages at or past it.
    pub fn fold_radius(&self) -> f64 {
        self.fold_r2.sqrt()
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

    #[test]
    fn fold_radius_is_where_the_radial_slope_first_vanishes() {
        let slope = |d: &BrownConrady, r: f64| {
            let s = r * r;
            1.0 + 3.0 * d.k1 * s + 5.0 * d.k2 * s * s + 7.0 * d.k3 * s * s * s
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
