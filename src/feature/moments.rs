//! Centroid and centred moments of a point set with their exact interaction rows, [\[M30\]](crate::theory#m30), [\[M34\]](crate::theory#m34)–[\[M35\]](crate::theory#m35) [(F33)](crate::theory#f33).

use super::{point_interaction, FeatureError, InteractionRow, RELATIVE_TOLERANCE};
use crate::camera::ImagePoint;

/// Highest moment order computed.
const MAX_ORDER: usize = 3;

/// Number of moments `μ_ij` with `i + j ≤ MAX_ORDER`.
const MOMENT_COUNT: usize = (MAX_ORDER + 1) * (MAX_ORDER + 2) / 2;

/// Number of moments `μ_ij` with `i + j < MAX_ORDER`: those whose point sums enter the rows of the next order.
const LOWER_COUNT: usize = MAX_ORDER * (MAX_ORDER + 1) / 2;

/// Where `μ_ij` (`i + j ≤ MAX_ORDER`) is stored: by order `i + j`, then by `j` (`μ00, μ10, μ01, μ20, μ11, μ02, …`).
/// The triangular storage keeps [`Moments`] small: it is moved into its observation's cache at every step.
const fn packed(i: usize, j: usize) -> usize {
    let order = i + j;
    order * (order + 1) / 2 + j
}

/// The centroid and the centred moments `μ_ij` (`i + j ≤ 3`) of a set of N image points, with their exact
/// interaction rows, computed once per point set by [`super::Observation::new`] and shared by every feature.
///
/// Definitions ([\[M30\]](crate::theory#m30), [\[M34\]](crate::theory#m34), [(F30)](crate::theory#f30), [(F33)](crate::theory#f33)), **without** a `1/N` factor on the moments:
///
/// ```text
/// x_g = (1/N) Σ x_k,   y_g = (1/N) Σ y_k,   μ_ij = Σ_k (x_k − x_g)^i (y_k − y_g)^j   (μ_00 = N, μ_10 = μ_01 = 0)
/// ```
///
/// Interaction rows by the chain rule \[M29\] over the point rows \[M28\]: `L_{x_g} = (1/N) Σ L_{x_k}` (exact \[M31\]) and
/// \[M35\], summed as
/// `L_{μ_ij} = i (Σ_k Δx^{i−1} Δy^j L_{x_k} − μ_{i−1,j} L_{x_g}) + j (Σ_k Δx^i Δy^{j−1} L_{y_k} − μ_{i,j−1} L_{y_g})`
/// with `Δx = x_k − x_g`, `Δy = y_k − y_g`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Moments {
    n: usize,
    xg: f64,
    yg: f64,
    l_xg: InteractionRow,
    l_yg: InteractionRow,
    /// `μ_ij` at [`packed`]`(i, j)`.
    mu: [f64; MOMENT_COUNT],
    /// `L_{μ_ij}` at [`packed`]`(i, j)`.
    l_mu: [InteractionRow; MOMENT_COUNT],
    /// `Σ (x_k² + y_k²)`, scale of the relative test on `a`.
    scale: f64,
    /// Whether every moment and row above is finite (false only on overflow of extreme coordinates), decided once
    /// when they are computed.
    finite: bool,
}

impl Moments {
    /// Moments of validated, non-empty `points`, with `inverse_depth(p)` the (positive, finite) `1/Z` of each.
    pub(super) fn compute(
        points: &[ImagePoint],
        inverse_depth: impl Fn(&ImagePoint) -> f64,
    ) -> Self {
        let n = points.len();
        let inv_n = 1.0 / n as f64;
        let zero = InteractionRow::zeros();
        let (mut sx, mut sy, mut scale) = (0.0, 0.0, 0.0);
        for p in points {
            sx += p.x;
            sy += p.y;
            scale += p.x * p.x + p.y * p.y;
        }
        let (xg, yg) = (sx * inv_n, sy * inv_n);

        // Per point, the weights Δx^i Δy^j of every moment in packed order (μ00, μ10, μ01, μ20, μ11, μ02, μ30, …);
        // sum_x[packed(i, j)] = Σ_k Δx^i Δy^j L_{x_k} and sum_y likewise with L_{y_k}, for i + j ≤ 2
        // (sum_x[0] = Σ_k L_{x_k}). Fixed-size packed arrays: the loops unroll and the sums stay in registers.
        let mut mu = [0.0; MOMENT_COUNT];
        let mut sum_x = [zero; LOWER_COUNT];
        let mut sum_y = [zero; LOWER_COUNT];
        for p in points {
            let (lx, ly) = point_interaction(p.x, p.y, inverse_depth(p));
            let (dx, dy) = (p.x - xg, p.y - yg);
            let (dx2, dy2) = (dx * dx, dy * dy);
            let weights = [
                1.0,
                dx,
                dy,
                dx2,
                dx * dy,
                dy2,
                dx2 * dx,
                dx2 * dy,
                dx * dy2,
                dy2 * dy,
            ];
            for (m, w) in mu.iter_mut().zip(weights) {
                *m += w;
            }
            for ((sx, sy), w) in sum_x.iter_mut().zip(sum_y.iter_mut()).zip(weights) {
                *sx += lx * w;
                *sy += ly * w;
            }
        }
        let l_xg = sum_x[0] * inv_n;
        let l_yg = sum_y[0] * inv_n;
        // Exact by definition; the sums above only carry rounding noise.
        mu[packed(0, 0)] = n as f64;
        mu[packed(1, 0)] = 0.0;
        mu[packed(0, 1)] = 0.0;

        let mut l_mu = [zero; MOMENT_COUNT];
        for i in 0..=MAX_ORDER {
            for j in 0..=MAX_ORDER - i {
                if i + j < 2 {
                    continue; // μ_00, μ_10, μ_01 are constants.
                }
                let mut row = zero;
                if i > 0 {
                    let lower = packed(i - 1, j);
                    row += (sum_x[lower] - l_xg * mu[lower]) * i as f64;
                }
                if j > 0 {
                    let lower = packed(i, j - 1);
                    row += (sum_y[lower] - l_yg * mu[lower]) * j as f64;
                }
                l_mu[packed(i, j)] = row;
            }
        }
        let finite = [xg, yg, scale]
            .iter()
            .chain(mu.iter())
            .all(|v| v.is_finite())
            && [&l_xg, &l_yg]
                .into_iter()
                .chain(l_mu.iter())
                .all(crate::math::all_finite);
        Self {
            n,
            xg,
            yg,
            l_xg,
            l_yg,
            mu,
            l_mu,
            scale,
            finite,
        }
    }

    /// `true` when every moment and row is finite (false only on overflow of extreme coordinates).
    pub(super) fn is_finite(&self) -> bool {
        self.finite
    }

    /// Number of points N.
    pub fn count(&self) -> usize {
        self.n
    }

    /// Centroid abscissa `x_g` \[M30\].
    pub fn xg(&self) -> f64 {
        self.xg
    }

    /// Centroid ordinate `y_g` \[M30\].
    pub fn yg(&self) -> f64 {
        self.yg
    }

    /// Exact interaction row of `x_g`, `(1/N) Σ L_{x_k}` (\[M29\], equal to \[M31\] with the plane model).
    pub fn interaction_xg(&self) -> &InteractionRow {
        &self.l_xg
    }

    /// Exact interaction row of `y_g`, `(1/N) Σ L_{y_k}` (\[M29\], equal to \[M31\] with the plane model).
    pub fn interaction_yg(&self) -> &InteractionRow {
        &self.l_yg
    }

    /// Centred moment `μ_ij` \[M34\], or `None` when `i + j > 3`.
    pub fn mu(&self, i: usize, j: usize) -> Option<f64> {
        (i + j <= MAX_ORDER).then(|| self.mu[packed(i, j)])
    }

    /// Exact interaction row of `μ_ij` \[M35\], or `None` when `i + j > 3`.
    pub fn interaction_mu(&self, i: usize, j: usize) -> Option<&InteractionRow> {
        (i + j <= MAX_ORDER).then(|| &self.l_mu[packed(i, j)])
    }

    /// The second-order size `a = μ20 + μ02` \[M37\] (`= I3` of \[M40\]) and its row `L_{μ20} + L_{μ02}`.
    ///
    /// # Errors
    /// [`FeatureError::DegenerateArea`] when `a ≤ RELATIVE_TOLERANCE · Σ (x_k² + y_k²)` (the points coincide).
    pub fn size(&self) -> Result<(f64, InteractionRow), FeatureError> {
        let a = self.mu[packed(2, 0)] + self.mu[packed(0, 2)];
        if a <= RELATIVE_TOLERANCE * self.scale {
            return Err(FeatureError::DegenerateArea {
                a,
                scale: self.scale,
            });
        }
        Ok((a, self.l_mu[packed(2, 0)] + self.l_mu[packed(0, 2)]))
    }

    /// The anisotropy `I1 / I3² = ((μ20 − μ02)² + 4 μ11²) / (μ20 + μ02)²` \[M40\] (dimensionless, in `[0, 1]`): 0 when
    /// the second-order moments are isotropic (a square or any regular polygon seen head-on, D9), 1 for points on a
    /// line. For a `w × h` rectangle seen head-on it is `((w² − h²)/(w² + h²))²`.
    ///
    /// # Errors
    /// [`FeatureError::DegenerateArea`] as [`Moments::size`].
    pub fn anisotropy(&self) -> Result<f64, FeatureError> {
        let o = self.second_order_terms()?;
        Ok(o.i1 / (o.i3 * o.i3))
    }

    /// Second-order terms of \[M40\]: `c1 = μ20 − μ02`, `s1 = 2 μ11`, `I1 = c1² + s1²`, `I3 = a` and their rows.
    ///
    /// # Errors
    /// [`FeatureError::DegenerateArea`] as [`Moments::size`].
    pub(super) fn second_order_terms(&self) -> Result<Orientation, FeatureError> {
        let (i3, l_i3) = self.size()?;
        let c1 = self.mu[packed(2, 0)] - self.mu[packed(0, 2)];
        let s1 = 2.0 * self.mu[packed(1, 1)];
        let l_c1 = self.l_mu[packed(2, 0)] - self.l_mu[packed(0, 2)];
        let l_s1 = self.l_mu[packed(1, 1)] * 2.0;
        Ok(Orientation {
            c1,
            s1,
            i1: c1 * c1 + s1 * s1,
            i3,
            l_c1,
            l_s1,
            l_i1: l_c1 * (2.0 * c1) + l_s1 * (2.0 * s1),
            l_i3,
        })
    }

    /// As [`Moments::second_order_terms`], for the features that divide by `I1` (orientation, paper's `P_x, P_y`).
    ///
    /// # Errors
    /// [`FeatureError::DegenerateArea`]; [`FeatureError::IsotropicMoments`] when `I1 ≤ RELATIVE_TOLERANCE · I3²`
    /// (D9: a square seen head-on).
    pub(super) fn orientation_terms(&self) -> Result<Orientation, FeatureError> {
        self.second_order_terms()?.anisotropic()
    }

    /// Third-order terms of \[M40\]: `c2 = μ03 − 3 μ21`, `s2 = μ30 − 3 μ12` and their rows.
    pub(super) fn third_order_terms(&self) -> (f64, f64, InteractionRow, InteractionRow) {
        let m = |i, j| self.mu[packed(i, j)];
        let l = |i, j| self.l_mu[packed(i, j)];
        (
            m(0, 3) - 3.0 * m(2, 1),
            m(3, 0) - 3.0 * m(1, 2),
            l(0, 3) - l(2, 1) * 3.0,
            l(3, 0) - l(1, 2) * 3.0,
        )
    }
}

/// Second-order terms shared by the orientation and the invariants (\[M40\]–\[M41\]).
#[derive(Debug, Clone, Copy)]
pub(super) struct Orientation {
    pub c1: f64,
    pub s1: f64,
    pub i1: f64,
    pub i3: f64,
    pub l_c1: InteractionRow,
    pub l_s1: InteractionRow,
    pub l_i1: InteractionRow,
    pub l_i3: InteractionRow,
}

impl Orientation {
    /// The terms themselves, for the features that divide by `I1` (see [`Moments::orientation_terms`]).
    ///
    /// # Errors
    /// [`FeatureError::IsotropicMoments`] when `I1 ≤ RELATIVE_TOLERANCE · I3²` (D9).
    pub(super) fn anisotropic(self) -> Result<Self, FeatureError> {
        if self.i1 <= RELATIVE_TOLERANCE * self.i3 * self.i3 {
            return Err(FeatureError::IsotropicMoments {
                i1: self.i1,
                i3: self.i3,
            });
        }
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every stored moment is the one asked for: `μ_ij` against its definition `Σ Δx^i Δy^j` on an irregular point
    /// set, for every `i + j ≤ 3` (a wrong slot of the packed storage would return another moment), and `None` beyond.
    #[test]
    fn every_moment_is_stored_in_its_own_slot() {
        let points = [
            (0.11, -0.03),
            (-0.07, 0.05),
            (0.02, 0.19),
            (-0.13, -0.08),
            (0.05, 0.01),
        ]
        .map(|(x, y)| ImagePoint { x, y, depth: 1.0 });
        let moments = Moments::compute(&points, |p| 1.0 / p.depth);
        let n = points.len() as f64;
        let xg = points.iter().map(|p| p.x).sum::<f64>() / n;
        let yg = points.iter().map(|p| p.y).sum::<f64>() / n;
        for i in 0..=MAX_ORDER {
            for j in 0..=MAX_ORDER - i {
                let direct: f64 = points
                    .iter()
                    .map(|p| (p.x - xg).powi(i as i32) * (p.y - yg).powi(j as i32))
                    .sum();
                let stored = moments.mu(i, j).unwrap();
                assert!(
                    (stored - direct).abs() < 1e-15,
                    "μ_{i}{j}: {stored} vs {direct}"
                );
            }
        }
        assert_eq!(moments.mu(2, 2), None);
        assert!(moments.interaction_mu(0, 4).is_none());
    }
}
