//! One-sided Jacobi (Hestenes) rotations: the sweeps, their round-robin schedule and the rotation of a column pair.

use super::*;

/// Maximum number of Jacobi sweeps; quadratic convergence makes 6–10 typical for `N ≤ 12`.
const MAX_SWEEPS: usize = 60;

/// One-sided Jacobi (Hestenes) on the first `columns ≤ N` columns of `a`: plane rotations of column pairs, accumulated in
/// the columns of `acc`, until every pair is orthogonal to working precision. `scale` is `‖a‖_F²`: columns below
/// `(16 ε)² · scale` are rounding noise (`σ ≤ 16 ε ‖A‖_F`) and are left alone, since rotations among them cannot reach
/// relative orthogonality and do not affect any singular value a rank policy keeps; zero columns cost nothing.
///
/// The squared column norms are computed at the start of each sweep and updated in closed form after each rotation
/// (`α' = α − tγ`, `β' = β + tγ`), so a pair costs one dot product and the rotation.
pub(super) fn jacobi<const L: usize, const N: usize>(
    a: &mut SMatrix<f64, L, N>,
    columns: usize,
    acc: &mut JointMatrix<N>,
    scale: f64,
) -> Result<(), LinalgError> {
    let negligible = (16.0 * f64::EPSILON).powi(2) * scale;
    // An L-term dot product carries a rounding error of about L ε √(αβ): asking for less never converges.
    let tolerance = (L.max(1) as f64) * f64::EPSILON;
    let columns = columns.min(N);
    if columns < 2 {
        return Ok(()); // no pair to rotate (a one-row level of the stack, decomposed on its smaller side)
    }
    let mut norms = [0.0; N];
    // Round-robin ("circle") order: each round rotates disjoint pairs, whose dependency chains (a division and a
    // square root or two per rotation) the processor then overlaps. Every pair is visited once per sweep. The schedule
    // of a sweep is computed once: round r rotates the pairs `schedule[r][..counts[r]]` (at most `N` rounds of at most
    // `N` pairs, since `players ≤ N + 1`), without the pairs of the dummy player an odd count adds. Column indices are
    // stored as bytes: the schedule is initialised at every call, and a 6-joint one then fills 72 bytes, not 576.
    const { assert!(N <= u8::MAX as usize, "at most 255 joints") };
    let players = columns + columns % 2;
    let mut schedule = [[(0u8, 0u8); N]; N];
    let mut counts = [0; N];
    for ((round, pairs), count) in schedule.iter_mut().enumerate().zip(counts.iter_mut()) {
        if round + 1 >= players {
            break;
        }
        for k in 0..players / 2 {
            let (p, q) = round_robin_pair(players, round, k);
            if q < columns {
                pairs[*count] = (p as u8, q as u8);
                *count += 1;
            }
        }
    }
    for _ in 0..MAX_SWEEPS {
        for (norm, column) in norms
            .iter_mut()
            .zip(a.as_slice().chunks_exact(L))
            .take(columns)
        {
            *norm = column.iter().map(|x| x * x).sum();
        }
        let mut rotated = false;
        for (pairs, &count) in schedule.iter().zip(counts.iter()) {
            for &(p, q) in &pairs[..count] {
                let (p, q) = (usize::from(p), usize::from(q));
                let (alpha, beta) = (norms[p], norms[q]);
                if alpha <= negligible || beta <= negligible {
                    continue;
                }
                // The rotation's reciprocal does not depend on the dot product: asked for first, it can overlap with it.
                let rotation = RotationNorms::new(alpha, beta);
                let (x, y) = column_pair(a, p, q);
                let gamma = dot(x, y);
                if gamma.abs() <= tolerance * (alpha * beta).sqrt() {
                    continue;
                }
                let (c, s, t) = rotation.rotation(gamma);
                rotate(x, y, c, s);
                let (x, y) = column_pair(acc, p, q);
                rotate(x, y, c, s);
                norms[p] = alpha - t * gamma;
                norms[q] = beta + t * gamma;
                rotated = true;
            }
        }
        if !rotated {
            return Ok(());
        }
    }
    Err(LinalgError::NoConvergence { sweeps: MAX_SWEEPS })
}

/// Pair `k` of round `round` of the circle method for `players` (even) columns: player 0 stays, the others turn.
/// Returns `(p, q)` with `p < q`.
#[inline(always)]
pub(super) fn round_robin_pair(players: usize, round: usize, k: usize) -> (usize, usize) {
    let turning = players - 1;
    let seat = |i: usize| {
        if i == 0 {
            return 0;
        }
        // (i − 1 + round) mod turning, without a division: both terms are below `turning`.
        let turned = i - 1 + round;
        1 + if turned >= turning {
            turned - turning
        } else {
            turned
        }
    };
    let (a, b) = (seat(k), seat(players - 1 - k));
    (a.min(b), a.max(b))
}

/// The squared norms `α`, `β` of a column pair, with `d = β − α` and its reciprocal, ready for the pair's product `γ`.
#[derive(Clone, Copy)]
pub(super) struct RotationNorms {
    difference: f64,
    reciprocal: f64,
}

impl RotationNorms {
    #[inline(always)]
    pub(super) fn new(alpha: f64, beta: f64) -> Self {
        let difference = beta - alpha;
        Self {
            difference,
            reciprocal: 1.0 / difference,
        }
    }

    /// The rotation `(c, s)` and `t = s/c` that makes the columns orthogonal when their product is `γ ≠ 0`
    /// (Rutishauser's `t = sign ζ / (|ζ| + √(1 + ζ²))`, `ζ = (β − α)/(2γ)`, `c = 1/√(1 + t²)`, `s = c t`).
    ///
    /// For a small angle, `|x| ≤ 2⁻¹⁴` with `x = γ/(β − α)` (the common case of a warm-started decomposition), the
    /// series `t = x(1 − x²)`, `c = 1 − x²/2`, `s = x(1 − 3x²/2)`, whose truncation errors (`2x⁴`, `11x⁴/8` and
    /// `31x⁴/8`, relative) stay below half an ulp; `x` is a product with the reciprocal computed beforehand, so the
    /// rotation adds a few multiplications to the dependency chain instead of two square roots and a division.
    /// Otherwise [`general_rotation`].
    #[inline(always)]
    pub(super) fn rotation(self, gamma: f64) -> (f64, f64, f64) {
        if self.difference.abs() >= SERIES_RATIO * gamma.abs() {
            let x = gamma * self.reciprocal;
            let y = x * x;
            return (1.0 - 0.5 * y, x * (1.0 - 1.5 * y), x * (1.0 - y));
        }
        general_rotation(self.difference, gamma)
    }
}

/// Rutishauser's rotation in closed form without forming `ζ` or `t` first: with `d = β − α`, `r = √(d² + 4γ²)` and
/// `u = |d| + r`, `t = 2γ sign d / u`, and since `1 + t² = 2r/u`, `c = u/k` and `s = 2γ sign d / k` with
/// `k = √(2 r u)`. Two square roots and one division on the dependency chain (`c`, `s` and `t` are divided in
/// parallel).
#[inline(always)]
fn general_rotation(difference: f64, gamma: f64) -> (f64, f64, f64) {
    let root = (difference * difference + 4.0 * gamma * gamma).sqrt();
    let sum = difference.abs() + root;
    let scale = (2.0 * root * sum).sqrt();
    let numerator = 2.0 * gamma * difference.signum();
    (sum / scale, numerator / scale, numerator / sum)
}

/// Below `|γ/(β − α)| = 2⁻¹⁴` the series of [`RotationNorms::rotation`] is exact to rounding.
const SERIES_RATIO: f64 = 16_384.0;

/// Columns `p < q < N` of a fixed-size matrix as two fixed-length mutable arrays (so that the loops over them unroll).
#[inline(always)]
fn column_pair<const L: usize, const N: usize>(
    m: &mut SMatrix<f64, L, N>,
    p: usize,
    q: usize,
) -> (&mut [f64; L], &mut [f64; L]) {
    let (head, tail) = m.as_mut_slice().split_at_mut(q * L);
    let x = head[p * L..].first_chunk_mut::<L>();
    let y = tail.first_chunk_mut::<L>();
    match (x, y) {
        (Some(x), Some(y)) => (x, y),
        // Unreachable for p < q < N (the slices hold N·N entries); kept total rather than panicking.
        _ => unreachable_pair(),
    }
}

#[cold]
fn unreachable_pair<'a, const N: usize>() -> (&'a mut [f64; N], &'a mut [f64; N]) {
    unreachable!("column pair out of range")
}

/// `xᵀ y` with two accumulators (half the dependency chain of a sequential sum). They start at `−0`, the identity of
/// floating-point addition (`−0 + p = p` for every `p`, where `+0 + (−0) = +0`), so the compiler drops the first
/// addition of each chain, which a start at `+0` keeps: one addition less on the dependency chain of every rotation.
/// The value differs only in the sign of a zero product, and `γ = ±0` is always left alone by the stopping test.
#[inline(always)]
fn dot<const N: usize>(x: &[f64; N], y: &[f64; N]) -> f64 {
    let (mut even, mut odd) = (-0.0, -0.0);
    for (k, (a, b)) in x.iter().zip(y.iter()).enumerate() {
        if k % 2 == 0 {
            even += a * b;
        } else {
            odd += a * b;
        }
    }
    even + odd
}

/// Replaces `(x, y)` by `(c·x − s·y, s·x + c·y)`, entry by entry.
#[inline(always)]
fn rotate<const N: usize>(x: &mut [f64; N], y: &mut [f64; N], c: f64, s: f64) {
    for (a, b) in x.iter_mut().zip(y.iter_mut()) {
        let (u, v) = (*a, *b);
        *a = c * u - s * v;
        *b = s * u + c * v;
    }
}
