//! The certified fast path for a well-conditioned level of full column rank ([D15](crate::theory#d15)).

use super::*;

/// The largest bound on the condition number `σ_max/σ_min` for which [`solve_full_column_rank`] answers
/// ([D15](crate::theory#d15)): below it the normal equations, refined once, agree with the SVD's pseudo-inverse within
/// `10⁻¹² · ‖r‖/σ_min`, and the rank is `N` with a margin of three orders of magnitude over the default relative
/// threshold `10⁻⁶`. The four-point task of the peer scene has `κ ≈ 130–145` (`‖A‖_F/σ_min ≈ 200`).
pub const FAST_PATH_CONDITION_BOUND: f64 = 1e3;

/// The least-squares solution `x = A⁺ r` of an `m × N` matrix `A` (`N ≤ m ≤ 16`) **certified** to have full column
/// rank `N` under `policy`, or `None` when the certificate fails or `m` is out of that range (the caller then takes the
/// SVD).
///
/// ```text
/// G = AᵀA = L Lᵀ = L₁ D L₁ᵀ         (Cholesky of the normal equations, N × N, L = L₁ D^{1/2})
/// x₀ = L⁻ᵀ L⁻¹ Aᵀ r,   x = x₀ + L⁻ᵀ L⁻¹ Aᵀ (r − A x₀)      (one step of refinement on A itself)
/// ```
///
/// The factor is computed without its square roots, as `L₁ D L₁ᵀ` (`L₁` unit lower triangular, `D` the pivots), and
/// `L⁻¹ = D^{−1/2} L₁⁻¹` is used through `L₁⁻¹` and `D⁻¹`: the same factorisation, with one division per pivot on
/// its dependency chain instead of a square root and a division.
///
/// **Certificate.** `‖G⁻¹‖₂ ≤ ‖L⁻¹‖_F²` bounds the smallest eigenvalue of the factored matrix from below, and the
/// rounding of forming and factoring `G` is at most `2 (m + N + 1) ε ‖A‖_F²` in the 2-norm (the classical bounds
/// `γ_m |A|ᵀ|A|` and `γ_{N+1} |L||Lᵀ|`, with `‖L‖_F² = trace G = ‖A‖_F²`). Hence
///
/// ```text
/// σ_min(A)² ≥ s² := 1/‖L⁻¹‖_F² − 2 (m + N + 1) ε ‖A‖_F²
/// ```
///
/// The fast path answers only when `s ≥ ‖A‖_F / FAST_PATH_CONDITION_BOUND` (so `σ_max/σ_min ≤ 1000`) **and**
/// `s > (1 + 10⁻⁹) · policy.threshold(max(‖A‖_F, reference_scale)) + 10³ N ε ‖A‖_F` (with `‖A‖_F ≥ σ_max`, a
/// threshold at least the SVD's; the relative term covers the rounding of `‖L⁻¹‖_F`, the absolute one that of the
/// SVD's own singular values, `|σ̂_i − σ_i| ≤ c ε ‖A‖` for its backward-stable sweeps, with `c` far below `10³ N`): then
/// every singular value is kept by the rank policy, as the SVD would decide, so the truncated pseudo-inverse is the
/// plain least-squares solution and the row-space projector `A⁺A` is the identity. A failed pivot, a non-finite entry
/// or a bound missed by any margin gives `None`: the fast path never decides a rank, it only confirms a full one.
///
/// **Accuracy.** The normal equations alone lose `κ² ε`; the refinement step, whose residual is computed from `A`,
/// contracts that error by a factor `O(κ² ε) ≤ 10⁻¹⁰`, which leaves the `O(κ ε) ≤ 10⁻¹³` of a backward-stable solve:
/// the result agrees with the SVD's `Σ v_k (u_kᵀ r)/σ_k` within `10⁻¹² · ‖r‖/σ_min(A)` (tested against the SVD on
/// random well- and ill-conditioned matrices).
///
/// **Square matrices** (`m = N`): `A⁺ r = A⁻¹ r` does not change when a row of `A` and its entry of `r` are scaled
/// together, so each row is first scaled by a power of two `d_i` (exact) that brings its norm into `[1, 2)`, and the
/// above is applied to `D A` and `D r`. The condition bound then applies to `D A` (row equilibration, which is within
/// `√N` of the best diagonal scaling, van der Sluis), the solution keeps the accuracy `κ(DA) ε` and
/// `σ_min(A) ≥ s/max d_i` replaces `s` in the rank test, which is still the SVD's of `A` itself. That bound is loose
/// when a short row carries `σ_min(A)`; when it misses the threshold, `σ_min(A) ≥ 1/‖A⁻¹‖_F` is tried, with the
/// columns `A⁻¹ e_i = d_i G⁻¹ (DA)ᵀ e_i` from the same factor and `4 · 2 (m + N + 1) ε ‖DA‖_F² / s²` of relative
/// rounding taken off. A least-squares solution (`m > N`) depends on the rows' weights, so taller matrices are solved
/// as they are.
///
/// Returns the certified lower bound `s ≤ σ_min(A)` (for a square matrix, one of the two bounds above). Allocates
/// nothing; `out` is written only on success.
pub fn solve_full_column_rank<const N: usize, R, S, SR>(
    a: &Matrix<f64, R, Const<N>, S>,
    r: &Vector<f64, R, SR>,
    policy: &RankPolicy,
    reference_scale: f64,
    out: &mut JointVector<N>,
) -> Option<f64>
where
    R: Dim,
    S: RawStorage<f64, R, Const<N>>,
    SR: RawStorage<f64, R>,
{
    let rows = a.nrows();
    if r.nrows() != rows {
        return None;
    }
    // On zero-padded fixed-size copies (zero rows change no product), so that every loop has a known length.
    if (N..=PADDED_ROWS).contains(&rows) {
        solve_padded::<PADDED_ROWS, N, R, S, SR>(a, r, policy, reference_scale, out)
    } else if (N..=2 * PADDED_ROWS).contains(&rows) {
        solve_padded::<{ 2 * PADDED_ROWS }, N, R, S, SR>(a, r, policy, reference_scale, out)
    } else {
        None
    }
}

/// Rows of the smaller padded copy of [`solve_full_column_rank`] (a four-point task); up to twice as many are solved
/// on a copy twice as tall, taller matrices by the SVD.
const PADDED_ROWS: usize = 8;

fn solve_padded<const L: usize, const N: usize, R, S, SR>(
    a: &Matrix<f64, R, Const<N>, S>,
    r: &Vector<f64, R, SR>,
    policy: &RankPolicy,
    reference_scale: f64,
    out: &mut JointVector<N>,
) -> Option<f64>
where
    R: Dim,
    S: RawStorage<f64, R, Const<N>>,
    SR: RawStorage<f64, R>,
{
    let rows = a.nrows();
    let mut padded = [[0.0; L]; N];
    for (to, column) in padded.iter_mut().zip(a.column_iter()) {
        to.iter_mut()
            .zip(column.iter())
            .for_each(|(to, a)| *to = *a);
    }
    let mut rhs = [0.0; L];
    rhs.iter_mut().zip(r.iter()).for_each(|(to, r)| *to = *r);
    // A square matrix (m = N) is solved as D A x = D r, its rows equilibrated by powers of two: the same x = A⁻¹ r,
    // scaled exactly, but the certificate and the solve see the condition of D A (variant B's moment task: κ(A) ≈ 5·10³,
    // κ(DA) ≈ 12). ‖D‖₂ = max d_i turns the bound on σ_min(DA) into one on σ_min(A).
    let (row_scales, square_norm) = if rows == N {
        let (scales, norm) = equilibrate_rows(&mut padded, &mut rhs);
        (scales, Some(norm))
    } else {
        ([1.0; N], None)
    };
    let dot = |x: &[f64; L], y: &[f64; L]| x.iter().zip(y.iter()).map(|(x, y)| x * y).sum::<f64>();
    // G = AᵀA (lower triangle, row i holds G_ij for j ≤ i), its trace ‖A‖_F², and Aᵀ r (of D A and D r when scaled).
    let mut g = [[0.0; N]; N];
    let mut frobenius_sq = 0.0;
    for i in 0..N {
        for j in 0..=i {
            g[i][j] = dot(&padded[i], &padded[j]);
        }
        frobenius_sq += g[i][i];
    }
    let b: [f64; N] = std::array::from_fn(|j| dot(&padded[j], &rhs));
    let inverse = FactorInverse::factor(&g)?;
    let inverse_frobenius_sq = inverse.frobenius_sq();
    let rounding = 2.0 * (rows + N + 1) as f64 * f64::EPSILON * frobenius_sq;
    let lower_sq = 1.0 / inverse_frobenius_sq - rounding;
    let conditioned = frobenius_sq / (FAST_PATH_CONDITION_BOUND * FAST_PATH_CONDITION_BOUND);
    if !(lower_sq >= conditioned && lower_sq > 0.0) {
        return None;
    }
    // Finite and positive here, as is the threshold: σ_min(A) ≥ σ_min(DA)/max d_i.
    let largest_row_scale = row_scales.iter().fold(1.0, |m: f64, &d| m.max(d));
    let mut lower = lower_sq.sqrt() / largest_row_scale;
    let frobenius_a = square_norm.unwrap_or_else(|| frobenius_sq.sqrt());
    let threshold = rank_test_threshold::<N>(policy, frobenius_a, reference_scale);
    if lower <= threshold && square_norm.is_some() {
        // The bound through ‖D‖₂ is loose when one short row carries σ_min(A): bound ‖A⁻¹‖_F itself,
        // A⁻¹ e_i = d_i G⁻¹ (DA)ᵀ e_i. The computed columns of G⁻¹ carry at most ‖G⁻¹‖ ‖δG‖ ≤ rounding/s² of
        // relative error (first order); four times that is taken off.
        let inverse_sq: f64 = row_scales
            .iter()
            .enumerate()
            .map(|(i, d)| {
                let column = inverse.solve(&std::array::from_fn(|j| padded[j][i]));
                d * d * column.iter().map(|c| c * c).sum::<f64>()
            })
            .sum();
        lower = (1.0 - 4.0 * rounding / lower_sq) / inverse_sq.sqrt();
    }
    if lower.is_nan() || lower <= threshold {
        return None;
    }
    // x₀ = L⁻ᵀ (L⁻¹ b), then x = x₀ + L⁻ᵀ L⁻¹ Aᵀ (r − A x₀), the residual formed from A.
    let mut x = inverse.solve(&b);
    let mut residual = rhs;
    for (column, &xj) in padded.iter().zip(x.iter()) {
        residual
            .iter_mut()
            .zip(column.iter())
            .for_each(|(res, a)| *res -= a * xj);
    }
    let correction = inverse.solve(&std::array::from_fn(|j| dot(&padded[j], &residual)));
    x.iter_mut()
        .zip(correction.iter())
        .for_each(|(x, c)| *x += c);
    if !x.iter().all(|x| x.is_finite()) {
        return None;
    }
    out.iter_mut().zip(x.iter()).for_each(|(out, x)| *out = *x);
    Some(lower)
}

/// What a certified lower bound on `σ_min(A)` must exceed for the SVD to keep every singular value of `A`: its
/// threshold, at least, with the margins of [`solve_full_column_rank`] (`(1 + 10⁻⁹)` relative, `10³ N ε ‖A‖_F`
/// absolute).
pub(crate) fn rank_test_threshold<const N: usize>(
    policy: &RankPolicy,
    frobenius: f64,
    reference_scale: f64,
) -> f64 {
    (1.0 + 1e-9) * policy.threshold(frobenius.max(reference_scale))
        + 1e3 * N as f64 * f64::EPSILON * frobenius
}

/// Scales each row of the square, column-major `padded` (and its entry of `rhs`) by the power of two
/// `d_i = 2^{−⌊log₂ ‖a_i‖⌋`, which brings its norm into `[1, 2)` without rounding; rows whose norm is zero, subnormal
/// or not finite, or whose scale would not be a normal number, keep `d_i = 1`. Returns the scales `d_i` and `‖A‖_F`
/// (before the scaling).
fn equilibrate_rows<const L: usize, const N: usize>(
    padded: &mut [[f64; L]; N],
    rhs: &mut [f64; L],
) -> ([f64; N], f64) {
    let mut scales = [1.0; N];
    let mut frobenius_sq = 0.0;
    for ((i, rhs), d) in rhs.iter_mut().enumerate().zip(scales.iter_mut()) {
        let norm_sq = padded
            .iter()
            .map(|column| column[i] * column[i])
            .sum::<f64>();
        frobenius_sq += norm_sq;
        let Some(scale) = power_of_two_reciprocal(norm_sq.sqrt()) else {
            continue;
        };
        padded.iter_mut().for_each(|column| column[i] *= scale);
        *rhs *= scale;
        *d = scale;
    }
    (scales, frobenius_sq.sqrt())
}

/// `2^{−e}` with `e = ⌊log₂ x⌋`, for a positive normal `x` whose result is normal too; `None` otherwise.
fn power_of_two_reciprocal(x: f64) -> Option<f64> {
    if !(x.is_normal() && x > 0.0) {
        return None;
    }
    // The biased exponent of x is e + 1023; 2^{−e} has the biased exponent 1023 − e = 2046 − biased.
    let biased = (x.to_bits() >> 52) & 0x7ff;
    let scaled = 2046u64
        .checked_sub(biased)
        .filter(|&b| (1..=2046).contains(&b))?;
    Some(f64::from_bits(scaled << 52))
}

/// The inverse of the Cholesky factor `L = L₁ D^{1/2}` of a symmetric positive definite `G = L₁ D L₁ᵀ`, kept as its
/// square-root-free parts: `L⁻¹ = D^{−1/2} M` with `M = L₁⁻¹` (unit lower triangular, by rows) and `D⁻¹`. The
/// factorisation is the `L Lᵀ` one without its square roots (one division per pivot on the dependency chain instead
/// of a square root and a division); its rounding obeys the Cholesky bound `γ_{N+1} |L||Lᵀ|` with `L = L₁ D^{1/2}`.
struct FactorInverse<const N: usize> {
    /// `M = L₁⁻¹`, unit lower triangular, by rows.
    unit: [[f64; N]; N],
    /// `1/d_i`, the reciprocal pivots.
    reciprocal_pivots: [f64; N],
}

impl<const N: usize> FactorInverse<N> {
    /// `L₁ D L₁ᵀ` of the symmetric matrix whose lower triangle is `g` (by rows) and the inverse of its factor, or `None`
    /// when a pivot is not strictly positive and finite (not numerically positive definite).
    fn factor(g: &[[f64; N]; N]) -> Option<Self> {
        // `l[i][k]` = (L₁)_ik, `w[i][k]` = (L₁)_ik d_k, for k < i.
        let mut l = [[0.0; N]; N];
        let mut w = [[0.0; N]; N];
        let mut reciprocal_pivots = [0.0; N];
        for j in 0..N {
            let pivot = g[j][j]
                - w[j][..j]
                    .iter()
                    .zip(l[j][..j].iter())
                    .map(|(w, l)| w * l)
                    .sum::<f64>();
            if !(pivot > 0.0 && pivot.is_finite()) {
                return None;
            }
            let reciprocal = 1.0 / pivot;
            reciprocal_pivots[j] = reciprocal;
            for i in (j + 1)..N {
                let product: f64 = w[i][..j]
                    .iter()
                    .zip(l[j][..j].iter())
                    .map(|(w, l)| w * l)
                    .sum();
                let scaled = g[i][j] - product;
                w[i][j] = scaled;
                l[i][j] = scaled * reciprocal;
            }
        }
        // Forward substitution, row by row: L₁ M = I, M_ij = −Σ_{j≤k<i} (L₁)_ik M_kj.
        let mut unit = [[0.0; N]; N];
        for (i, l_row) in l.iter().enumerate() {
            let (done, rest) = unit.split_at_mut(i);
            let Some(row) = rest.first_mut() else { break };
            for (j, entry) in row[..i].iter_mut().enumerate() {
                *entry = -(j..i).map(|k| l_row[k] * done[k][j]).sum::<f64>();
            }
            row[i] = 1.0;
        }
        Some(Self {
            unit,
            reciprocal_pivots,
        })
    }

    /// `‖L⁻¹‖_F² = Σ_i ‖M_i‖² / d_i`.
    fn frobenius_sq(&self) -> f64 {
        self.unit
            .iter()
            .zip(self.reciprocal_pivots.iter())
            .map(|(row, r)| r * row.iter().map(|x| x * x).sum::<f64>())
            .sum()
    }

    /// `G⁻¹ b = Mᵀ D⁻¹ (M b)`.
    fn solve(&self, b: &[f64; N]) -> [f64; N] {
        let mut y = [0.0; N];
        for (i, row) in self.unit.iter().enumerate() {
            y[i] = self.reciprocal_pivots[i]
                * row[..=i]
                    .iter()
                    .zip(b.iter())
                    .map(|(m, b)| m * b)
                    .sum::<f64>();
        }
        let mut x = [0.0; N];
        for (i, row) in self.unit.iter().enumerate() {
            for (x, m) in x[..=i].iter_mut().zip(row.iter()) {
                *x += m * y[i];
            }
        }
        x
    }
}

/// The largest condition number `σ_max/σ_min` for which [`solve_small_full_row_rank`] and
/// [`solve_small_stack_level`] answer: the Gram matrix then has `κ(G) ≤ 10⁴`. Computed through `G⁻¹` up to
/// `κ(G) ≈ 1100` and on the orthonormalised rows beyond, the step and the projector agree with the SVD's within
/// `10⁻¹²` (relative to `‖e‖/σ_min` for the step).
pub const SMALL_PATH_CONDITION_BOUND: f64 = 1e2;

/// The rows of a `1 × N` or `2 × N` matrix `A` certified to have full row rank, well conditioned, with its Gram matrix
/// `G = A Aᵀ = [p b; b c]` (for one row, `G = p`, with `b = 0`, `c = 1`):
///
/// ```text
/// λ± = (p + c)/2 ± √(((p − c)/2)² + b²)        the eigenvalues of G, the squared singular values of A
/// ```
///
/// Certified when `σ_min = √λ₋` is finite, `σ_max/σ_min ≤ SMALL_PATH_CONDITION_BOUND`, and
/// `σ_min > 2 · policy.threshold(max(σ_max, reference_scale))`: the SVD's rank decision (the threshold it takes, with
/// a factor 2 of margin), so every singular value is kept and `A⁺ = Aᵀ G⁻¹`.
struct SmallFullRowRank<const N: usize> {
    rows: [JointVector<N>; 2],
    count: usize,
    /// `G = [p b; b c]`.
    p: f64,
    b: f64,
    c: f64,
    /// `1/det G = 1/(p c − b²)` (for one row, `1/p`). Formed from the entries, not as `λ₊ λ₋`: no square root on the
    /// level's dependency chain, and its relative error, about `κ(G) ε`, is that of `λ₋` (both are only used up to
    /// `κ(G) ≈ 1100`, [`GRAM_ACCURATE_CONDITION`]).
    inverse_det: f64,
    sigma_min: f64,
    /// When `κ(G) = λ₊/λ₋ = κ(A)²` exceeds [`GRAM_ACCURATE_CONDITION`] (the products through `G⁻¹` would lose more
    /// than `10⁻¹²`): the rows' orthonormal basis and triangular factor ([`Self::orthonormal_rows`]), computed once
    /// for the products below.
    orthonormal: Option<OrthonormalRows<N>>,
}

/// `A = R Qᵀ`: the orthonormal rows `[q0, q1]` and the lower-triangular `R = [ρ00 0; ρ01 ρ11]` as `[ρ00, ρ01, ρ11]`.
type OrthonormalRows<const N: usize> = ([JointVector<N>; 2], [f64; 3]);

impl<const N: usize> SmallFullRowRank<N> {
    fn certify<R, S>(
        a: &Matrix<f64, R, Const<N>, S>,
        policy: &RankPolicy,
        reference_scale: f64,
    ) -> Option<Self>
    where
        R: Dim,
        S: RawStorage<f64, R, Const<N>>,
    {
        let row = |i: usize| JointVector::<N>::from_fn(|k, _| a[(i, k)]);
        let (rows, p, b, c, largest, smallest) = match a.nrows() {
            1 => {
                let r0 = row(0);
                let p = r0.norm_squared();
                ([r0, JointVector::zeros()], p, 0.0, 1.0, p, p)
            }
            2 => {
                let (r0, r1) = (row(0), row(1));
                let (p, b, c) = (r0.norm_squared(), r0.dot(&r1), r1.norm_squared());
                // √(x² + b²) without `hypot`: a square that overflows makes λ₋ = −∞ or NaN, which the certificate
                // refuses (the SVD then answers).
                let half_gap = (0.25 * (p - c) * (p - c) + b * b).sqrt();
                let mean = 0.5 * (p + c);
                ([r0, r1], p, b, c, mean + half_gap, mean - half_gap)
            }
            _ => return None,
        };
        let (sigma_min, sigma_max) = (smallest.max(0.0).sqrt(), largest.sqrt());
        let certified = smallest > 0.0
            && sigma_min.is_finite()
            && sigma_min * SMALL_PATH_CONDITION_BOUND >= sigma_max
            && sigma_min > 2.0 * policy.threshold(sigma_max.max(reference_scale));
        certified.then(|| Self {
            orthonormal: (largest / smallest > GRAM_ACCURATE_CONDITION)
                .then(|| Self::orthonormal_rows(&rows)),
            rows,
            count: a.nrows(),
            p,
            b,
            c,
            inverse_det: 1.0 / if a.nrows() == 1 { p } else { p * c - b * b },
            sigma_min,
        })
    }

    /// `G⁻¹ (u, v)` (`v` ignored for one row).
    fn inverse_gram(&self, u: f64, v: f64) -> (f64, f64) {
        match self.count {
            1 => (u * self.inverse_det, 0.0),
            _ => (
                (self.c * u - self.b * v) * self.inverse_det,
                (self.p * v - self.b * u) * self.inverse_det,
            ),
        }
    }

    /// The rows' orthonormal basis and triangular factor, `A = R Qᵀ` with `Q = [q0 q1]` (`N × 2`) and
    /// `R = [ρ00 0; ρ01 ρ11]`, by Gram–Schmidt applied twice (the second pass restores the orthogonality the first
    /// loses to cancellation when the rows are nearly dependent): the products below are then accurate to `κ(A) ε`,
    /// as the SVD's, instead of `κ(A)² ε`. Two rows only (one row never needs it: `κ(G) = 1`).
    fn orthonormal_rows(rows: &[JointVector<N>; 2]) -> OrthonormalRows<N> {
        let [r0, r1] = rows;
        let rho00 = r0.norm();
        let q0 = r0 / rho00;
        let first = q0.dot(r1);
        let mut w = r1 - q0 * first;
        let second = q0.dot(&w);
        w -= q0 * second;
        let rho11 = w.norm();
        ([q0, w / rho11], [rho00, first + second, rho11])
    }

    /// `A⁺ e = Aᵀ G⁻¹ e` (`= Q R⁻¹ e` when the Gram matrix is not accurate enough), `None` when not finite.
    fn pseudo_inverse_times<R, SE>(&self, e: &Vector<f64, R, SE>) -> Option<JointVector<N>>
    where
        R: Dim,
        SE: RawStorage<f64, R>,
    {
        if let Some(([q0, q1], [rho00, rho01, rho11])) = &self.orthonormal {
            // R z = e, forward: row 0 of A is ρ00 q0ᵀ, row 1 is ρ01 q0ᵀ + ρ11 q1ᵀ.
            let z0 = e[0] / rho00;
            let z1 = (e[1] - rho01 * z0) / rho11;
            let x = q0 * z0 + q1 * z1;
            return x.iter().all(|v| v.is_finite()).then_some(x);
        }
        let (y0, y1) = self.inverse_gram(e[0], if self.count == 2 { e[1] } else { 0.0 });
        (y0.is_finite() && y1.is_finite()).then(|| self.rows[0] * y0 + self.rows[1] * y1)
    }

    /// `‖A⁺A g‖ = √((A g)ᵀ G⁻¹ (A g))`, the norm of the component of `g` in the row space of `A`.
    fn row_space_component_norm(&self, g: &JointVector<N>) -> f64 {
        if let Some(([q0, q1], _)) = &self.orthonormal {
            return q0.dot(g).hypot(q1.dot(g));
        }
        let (w0, w1) = (self.rows[0].dot(g), self.rows[1].dot(g));
        let (z0, z1) = self.inverse_gram(w0, w1);
        (w0 * z0 + w1 * z1).max(0.0).sqrt()
    }

    /// `P ← P − A⁺A = P − Aᵀ G⁻¹ A` on the upper triangle, mirrored to the lower one: symmetric by construction, as
    /// the SVD path's re-symmetrised update.
    fn subtract_row_space_projector(&self, projector: &mut JointMatrix<N>) {
        // Aᵀ G⁻¹ A = α r0 r0ᵀ + β (r0 r1ᵀ + r1 r0ᵀ) + γ r1 r1ᵀ, or q0 q0ᵀ + q1 q1ᵀ on the orthonormal rows.
        let ([r0, r1], (alpha, beta, gamma)) = if let Some((q, _)) = &self.orthonormal {
            (*q, (1.0, 0.0, 1.0))
        } else {
            let d = self.inverse_det;
            let coefficients = match self.count {
                1 => (d, 0.0, 0.0),
                _ => (self.c * d, -self.b * d, self.p * d),
            };
            (self.rows, coefficients)
        };
        for j in 0..N {
            let (a0, a1) = (alpha * r0[j] + beta * r1[j], beta * r0[j] + gamma * r1[j]);
            for i in 0..=j {
                let entry = projector[(i, j)] - (r0[i] * a0 + r1[i] * a1);
                projector[(i, j)] = entry;
                projector[(j, i)] = entry;
            }
        }
    }
}

/// `κ(G)` up to which [`SmallFullRowRank`] computes through `G⁻¹` (about 1100, `κ(A) ≈ 34`): there its error, about
/// `κ(G) ε`, is under `10⁻¹²` with a factor 4 of margin; above, on the orthonormalised rows.
const GRAM_ACCURATE_CONDITION: f64 = 1e-12 / (4.0 * f64::EPSILON);

/// For a matrix `A` of **one or two rows** (`1 × N` or `2 × N`) certified to have full row rank under `policy`, well
/// conditioned: `x = A⁺ e` into `out`, and `‖A⁺A g‖`, the norm of the component of `g` in the row space of `A`; `None`
/// otherwise (another number of rows, rank deficiency, `σ_max/σ_min > SMALL_PATH_CONDITION_BOUND`, a singular value
/// within a factor 2 of the rank threshold, non-finite data): the caller then takes the SVD.
///
/// ```text
/// G = A Aᵀ (1 × 1 or 2 × 2),   x = Aᵀ G⁻¹ e,   ‖A⁺A g‖² = (A g)ᵀ G⁻¹ (A g)
/// ```
///
/// The eigenvalues of the symmetric `G` are the squared singular values of `A`, in closed form; the rank decision is
/// the SVD's (`σ > policy.threshold(σ_max)`) with a factor 2 of margin, so the truncated pseudo-inverse is the plain
/// `Aᵀ G⁻¹`. Used for the removal criteria of the one- and two-row visual tasks, where it replaces one SVD per task
/// and period. Allocates nothing; `out` is written only on success.
pub fn solve_small_full_row_rank<const N: usize, R, S, SE>(
    a: &Matrix<f64, R, Const<N>, S>,
    e: &Vector<f64, R, SE>,
    g: &JointVector<N>,
    policy: &RankPolicy,
    out: &mut JointVector<N>,
) -> Option<f64>
where
    R: Dim,
    S: RawStorage<f64, R, Const<N>>,
    SE: RawStorage<f64, R>,
{
    if e.nrows() != a.nrows() {
        return None;
    }
    let certified = SmallFullRowRank::certify(a, policy, 0.0)?;
    *out = certified.pseudo_inverse_times(e)?;
    Some(certified.row_space_component_norm(g))
}

/// One level of the stack ([\[M8\]](crate::theory#m8)) of **one or two rows** in closed form, when the limited
/// Jacobian `J̃ = A` is certified to have full row rank, well conditioned (as [`solve_small_full_row_rank`], with the
/// stack's rank threshold taken against `max(σ_max, reference_scale)`, `reference_scale = ‖J_i‖_F`):
///
/// ```text
/// step = J̃ᵀ G⁻¹ r,    P ← P − J̃ᵀ G⁻¹ J̃    (G = J̃ J̃ᵀ)
/// ```
///
/// the SVD's truncated pseudo-inverse and row-space projector, since every singular value is kept. `projector` is
/// `None` when the caller has no use for the update (a level that uses up the last free directions, after which the
/// projector is zero). Returns `σ_min(J̃)` (from the closed-form eigenvalue of `G`); `None`, with `step` and
/// `projector` untouched, when the certificate fails or `r` is not finite: the caller then takes the SVD. Allocates
/// nothing.
pub fn solve_small_stack_level<const N: usize, R, S, SR>(
    a: &Matrix<f64, R, Const<N>, S>,
    r: &Vector<f64, R, SR>,
    policy: &RankPolicy,
    reference_scale: f64,
    step: &mut JointVector<N>,
    projector: Option<&mut JointMatrix<N>>,
) -> Option<f64>
where
    R: Dim,
    S: RawStorage<f64, R, Const<N>>,
    SR: RawStorage<f64, R>,
{
    if r.nrows() != a.nrows() {
        return None;
    }
    let certified = SmallFullRowRank::certify(a, policy, reference_scale)?;
    *step = certified.pseudo_inverse_times(r)?;
    if let Some(projector) = projector {
        certified.subtract_row_space_projector(projector);
    }
    Some(certified.sigma_min)
}
