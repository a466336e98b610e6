//! Pseudo-inverses with an explicit rank policy, damped least squares, and projector helpers ([theory §2.1](crate::theory#s2-1), [D2](crate::theory#d2)).
//!
//! Every level of the task stack needs, for its limited Jacobian `J̃ = J P` (`m × N`, `m` may exceed `N`), the
//! least-squares velocity `J̃⁺ r` and the projector onto its row space `J̃⁺ J̃` ([\[M8\]](crate::theory#m8)). Both come from one
//! singular value decomposition `J̃ = U Σ Vᵀ`:
//!
//! ```text
//! J̃⁺ r   = Σ_{k kept} v_k (u_kᵀ r) / σ_k                (truncated, theory §2.1.1)
//! J̃^{#δ} r = Σ_k v_k σ_k (u_kᵀ r) / (σ_k² + δ²)         (damped least squares, theory §2.1.2)
//! J̃⁺ J̃   = Σ_{k kept} v_k v_kᵀ                          (always truncated and exact, D2)
//! ```
//!
//! The decomposition is a **one-sided Jacobi SVD** (Hestenes): plane rotations applied to the columns of a working
//! copy `W` of the matrix until its columns are mutually orthogonal. Then `W = A V = [σ_1 u_1, …, σ_N u_N]`. It runs on
//! the caller's storage plus fixed `N × N` matrices, allocates nothing, works for any row count (including `m > N`),
//! and is accurate to working precision for the small singular values that decide ranks (no normal equations, whose
//! squared condition number would blur them).
//!
//! It works on the **smaller side** (each level is solved on fixed-size storage of at most `N × N`): a matrix with fewer rows than columns (`m < N`, every level
//! of the paper's stack) is decomposed through the `m` columns of `Aᵀ` (`m(m−1)/2` pairs instead of `N(N−1)/2`): a
//! one-row level needs no rotation, a two-row level one rotation, the closed form of its `2 × 2` Gram matrix `AAᵀ`
//! (the singular values are still taken as column norms, never as square roots of Gram eigenvalues). A square matrix,
//! or a tall one of at most 8 rows (a four-point task), is rotated directly on a fixed-size, zero-padded copy; a taller
//! one on its `N × N` triangular factor. In a control loop the rotations start from the previous step's right singular
//! vectors ([`ColumnSvd::decompose_warm`]). Columns that are zero (or rounding noise) cost no rotation.
//!
//! **Rank policy** ([`RankPolicy`], [D2](crate::theory#d2)): a singular value is kept when `σ_k > max(relative · σ_max, absolute)`, with
//! `relative = 1e−6` by default (ViSP's `svThreshold`) and a tiny absolute floor so that a zero matrix has rank 0.
//! For a limited Jacobian `J̃_i = J_i P` the stack measures `σ_max` on the task's own scale, `max(σ_max(J̃_i), ‖J_i‖_F)`
//! ([`ColumnSvd::decompose_with_scale`]).

use crate::math::{first_non_finite_entry, JointMatrix, JointVector};
use nalgebra::{Const, Dim, Matrix, RawStorage, SMatrix, StorageMut, Vector, U1};

/// Errors of the linear-algebra helpers.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinalgError {
    /// A rank threshold is negative, not finite, or the relative threshold is not below 1.
    #[error("invalid rank policy: relative = {relative}, absolute = {absolute} (need 0 ≤ relative < 1, 0 ≤ absolute, both finite)")]
    InvalidRankPolicy {
        /// The relative threshold given.
        relative: f64,
        /// The absolute threshold given.
        absolute: f64,
    },
    /// The damping factor of damped least squares is negative or not finite.
    #[error("invalid damping δ = {damping} (need a finite δ ≥ 0)")]
    InvalidDamping {
        /// The damping given.
        damping: f64,
    },
    /// The matrix to decompose holds a NaN or an infinity (the first one, in column-major order).
    #[error("matrix entry ({row}, {column}) = {value} is not finite")]
    NonFiniteMatrix {
        /// Its row.
        row: usize,
        /// Its column.
        column: usize,
        /// The entry (NaN or ±∞).
        value: f64,
    },
    /// Two operands disagree on their number of rows.
    #[error("dimension mismatch: {what} has {found} rows, expected {expected}")]
    DimensionMismatch {
        /// Which operand.
        what: &'static str,
        /// The expected number of rows.
        expected: usize,
        /// The number found.
        found: usize,
    },
    /// The Jacobi sweeps did not converge (cannot happen for finite input of sane magnitude).
    #[error("one-sided Jacobi SVD did not converge in {sweeps} sweeps")]
    NoConvergence {
        /// The number of sweeps performed.
        sweeps: usize,
    },
}

/// Which singular values count as non-zero ([theory §2.1.1](crate::theory#s2-1-1), [D2](crate::theory#d2)): keep `σ_k > max(relative · σ_max, absolute)`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RankPolicy {
    relative: f64,
    absolute: f64,
}

impl RankPolicy {
    /// Default relative threshold, as ViSP's `vpServo` pseudo-inverse threshold.
    pub const DEFAULT_RELATIVE: f64 = 1e-6;
    /// Default absolute floor: below it a singular value is zero whatever `σ_max` (same unit as the matrix).
    pub const DEFAULT_ABSOLUTE: f64 = 1e-12;

    /// A policy from a relative threshold (`0 ≤ relative < 1`) and an absolute floor (`absolute ≥ 0`).
    pub fn new(relative: f64, absolute: f64) -> Result<Self, LinalgError> {
        let valid = relative.is_finite()
            && absolute.is_finite()
            && (0.0..1.0).contains(&relative)
            && absolute >= 0.0;
        if valid {
            Ok(Self { relative, absolute })
        } else {
            Err(LinalgError::InvalidRankPolicy { relative, absolute })
        }
    }

    /// The relative threshold.
    pub fn relative(&self) -> f64 {
        self.relative
    }

    /// The absolute floor.
    pub fn absolute(&self) -> f64 {
        self.absolute
    }

    /// The cut-off below which (inclusive) a singular value is treated as zero, for a matrix whose largest singular
    /// value is `sigma_max`.
    pub fn threshold(&self, sigma_max: f64) -> f64 {
        (self.relative * sigma_max).max(self.absolute)
    }
}

impl Default for RankPolicy {
    fn default() -> Self {
        Self {
            relative: Self::DEFAULT_RELATIVE,
            absolute: Self::DEFAULT_ABSOLUTE,
        }
    }
}

/// The inverse used for the **velocity** term of each stack level ([theory §2.1.2](crate::theory#s2-1-2), [D2](crate::theory#d2)). The projector update always
/// uses the truncated, exact `J̃⁺J̃`.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum VelocityInverse {
    /// Truncated pseudo-inverse with the rank policy (the paper's and ViSP's choice).
    #[default]
    Truncated,
    /// Damped least squares `Jᵀ(JJᵀ + δ²I)⁻¹` (Nakamura, Chiaverini), robust near singularities.
    Damped {
        /// The damping `δ` (same unit as the singular values of `J̃`).
        damping: f64,
    },
}

impl VelocityInverse {
    /// Checks the damping factor.
    pub fn validate(&self) -> Result<(), LinalgError> {
        match *self {
            Self::Truncated => Ok(()),
            Self::Damped { damping } if damping.is_finite() && damping >= 0.0 => Ok(()),
            Self::Damped { damping } => Err(LinalgError::InvalidDamping { damping }),
        }
    }
}

/// The right half of a singular value decomposition `A = U Σ Vᵀ` of an `m × N` matrix `A`, computed by
/// [`ColumnSvd::decompose`]. Together with the rotated working matrix `W = A V` (whose column k is `σ_k u_k`) it gives
/// pseudo-inverses and projectors without forming `U`.
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnSvd<const N: usize> {
    /// Right singular vectors, one per column (orthonormal).
    v: JointMatrix<N>,
    /// Singular values `σ_k = ‖W e_k‖`, unordered, one per column of `v`.
    sigma: JointVector<N>,
    /// The cut-off chosen by the rank policy at the last decomposition.
    threshold: f64,
    /// `Some(k)` when `v` is a full orthogonal basis that has been through `k` warm starts since the last cold one.
    basis_age: Option<u32>,
}

/// A warm-started decomposition ([`ColumnSvd::decompose_warm`]) starts cold after this many warm starts in a row, which
/// bounds the loss of orthogonality that rotating the same `V` accumulates (about `ε √(rotations)`).
const WARM_RESTART: u32 = 64;

/// Matrices with `N < m ≤ TALL_ROWS` rows are rotated directly, zero-padded to `TALL_ROWS` rows (cheaper than a
/// triangular factor followed by `W = A V` at the sizes of a point task, 8 rows); taller ones on their triangular factor.
const TALL_ROWS: usize = 8;

/// Maximum number of Jacobi sweeps; quadratic convergence makes 6–10 typical for `N ≤ 12`.
const MAX_SWEEPS: usize = 60;

impl<const N: usize> Default for ColumnSvd<N> {
    fn default() -> Self {
        Self {
            v: JointMatrix::identity(),
            sigma: JointVector::zeros(),
            threshold: 0.0,
            basis_age: None,
        }
    }
}

impl<const N: usize> ColumnSvd<N> {
    /// Decomposes `work` (an `m × N` matrix `A`, overwritten with `W = A V`) by one-sided Jacobi rotations, and fixes
    /// the rank with `policy`. Allocates nothing.
    ///
    /// # Errors
    /// [`LinalgError::NonFiniteMatrix`] if `A` holds a NaN or an infinity; [`LinalgError::NoConvergence`] if the
    /// sweeps do not converge.
    pub fn decompose<R, S>(
        &mut self,
        work: &mut Matrix<f64, R, Const<N>, S>,
        policy: &RankPolicy,
    ) -> Result<(), LinalgError>
    where
        R: Dim,
        S: StorageMut<f64, R, Const<N>, RStride = U1>,
    {
        self.decompose_with_scale(work, policy, 0.0)
    }

    /// As [`Self::decompose`], with the relative threshold taken against `max(σ_max, reference_scale)` instead of
    /// `σ_max` alone.
    ///
    /// The stack uses this for the limited Jacobian `J̃_i = J_i P^A_{i−1}` with `reference_scale = ‖J_i‖_F`: a
    /// direction of `J̃_i` that is tiny compared with the task itself is an algorithmic singularity (the task conflicts
    /// with higher levels) or rounding noise left by a full higher stack, and must be truncated even when it is all
    /// that is left of `J̃_i`.
    ///
    /// # Errors
    /// As [`Self::decompose`].
    pub fn decompose_with_scale<R, S>(
        &mut self,
        work: &mut Matrix<f64, R, Const<N>, S>,
        policy: &RankPolicy,
        reference_scale: f64,
    ) -> Result<(), LinalgError>
    where
        R: Dim,
        S: StorageMut<f64, R, Const<N>, RStride = U1>,
    {
        self.decompose_from(work, policy, reference_scale, false)
    }

    /// As [`Self::decompose_with_scale`], warm-started: for a matrix with at least `N` rows, the rotations start from
    /// the right singular vectors of this object's previous decomposition (`W = A V_prev`) instead of the identity.
    /// When the matrix changed little since that call, as in a control loop, the columns of `A V_prev` are nearly
    /// orthogonal and the sweeps converge in a few rotations of small angle; the result is the same decomposition, to
    /// rounding (any orthogonal start converges to the same singular values and subspaces, with the same stopping test).
    /// Every 64th call in a row starts cold, to bound the loss of orthogonality accumulated by rotating the same `V`.
    /// Matrices with fewer rows than `N` are decomposed on their smaller side, as by [`Self::decompose_with_scale`].
    ///
    /// # Errors
    /// As [`Self::decompose`].
    pub fn decompose_warm<R, S>(
        &mut self,
        work: &mut Matrix<f64, R, Const<N>, S>,
        policy: &RankPolicy,
        reference_scale: f64,
    ) -> Result<(), LinalgError>
    where
        R: Dim,
        S: StorageMut<f64, R, Const<N>, RStride = U1>,
    {
        self.decompose_from(work, policy, reference_scale, true)
    }

    fn decompose_from<R, S>(
        &mut self,
        work: &mut Matrix<f64, R, Const<N>, S>,
        policy: &RankPolicy,
        reference_scale: f64,
        warm: bool,
    ) -> Result<(), LinalgError>
    where
        R: Dim,
        S: StorageMut<f64, R, Const<N>, RStride = U1>,
    {
        // ‖A‖_F² in one pass; a NaN or an infinity makes it non-finite (so does an overflow: then the entries decide).
        let scale = work.norm_squared();
        if !scale.is_finite() {
            if let Some((row, column, value)) = first_non_finite_entry(work) {
                return Err(LinalgError::NonFiniteMatrix { row, column, value });
            }
        }
        let rows = work.nrows();
        let age = match self.basis_age {
            Some(age) if warm && rows >= N && age < WARM_RESTART => Some(age),
            _ => None,
        };
        self.basis_age = None; // until this decomposition succeeds with a full basis
        if rows < N {
            self.v = JointMatrix::identity();
            self.decompose_wide(work, scale)?;
        } else {
            if age.is_none() {
                self.v = JointMatrix::identity();
            }
            let warm = age.is_some();
            if rows == N {
                self.rotate_padded::<N, R, S>(work, warm, scale)?;
            } else if rows <= TALL_ROWS {
                self.rotate_padded::<TALL_ROWS, R, S>(work, warm, scale)?;
            } else {
                // A taller matrix is rotated on its triangular factor R (same σ and V); W = A V is then formed from A.
                let mut square = triangular_factor(work);
                if warm {
                    square *= self.v;
                }
                jacobi(&mut square, N, &mut self.v, scale)?;
                for mut row in work.row_iter_mut() {
                    let rotated = &row * self.v;
                    row.copy_from(&rotated);
                }
                for (sigma, column) in self.sigma.iter_mut().zip(work.column_iter()) {
                    *sigma = column.norm();
                }
            }
            self.basis_age = Some(age.map_or(0, |age| age + 1));
        }
        self.threshold = policy.threshold(self.sigma_max().max(reference_scale));
        Ok(())
    }

    /// One-sided Jacobi directly on the columns of `A V` (`V` the previous right singular vectors when `warm`, else
    /// the identity), copied into fixed-size `L × N` storage (`rows ≤ L`, zero rows below: they change no dot product
    /// and no rotation touches them), so that the column loops unroll. Leaves `W = A V` in `work`: no triangular factor
    /// and no final product `A V`.
    fn rotate_padded<const L: usize, R, S>(
        &mut self,
        work: &mut Matrix<f64, R, Const<N>, S>,
        warm: bool,
        scale: f64,
    ) -> Result<(), LinalgError>
    where
        R: Dim,
        S: StorageMut<f64, R, Const<N>, RStride = U1>,
    {
        let rows = work.nrows();
        let mut padded = SMatrix::<f64, L, N>::zeros();
        for (k, to) in padded.as_mut_slice().chunks_exact_mut(L).enumerate() {
            to[..rows].copy_from_slice(work.column(k).as_slice());
        }
        if warm {
            padded *= self.v;
        }
        jacobi(&mut padded, N, &mut self.v, scale)?;
        for ((k, from), sigma) in padded
            .as_slice()
            .chunks_exact(L)
            .enumerate()
            .zip(self.sigma.iter_mut())
        {
            work.column_mut(k)
                .as_mut_slice()
                .copy_from_slice(&from[..rows]);
            *sigma = from.iter().map(|x| x * x).sum::<f64>().sqrt();
        }
        Ok(())
    }

    /// The decomposition of a matrix with fewer rows than columns (`m < N`), on its smaller side: one-sided Jacobi on
    /// the `m` columns of `Aᵀ` (`N × m`), `Aᵀ U = [σ_1 v_1, …, σ_m v_m]` with `U` (`m × m`) orthogonal. A one-row level
    /// needs no rotation at all, a two-row level one (the closed form of the `2 × 2` Gram matrix `A Aᵀ`, with `σ_k`
    /// taken as column norms, not square roots of its eigenvalues). Then `W = A V` has columns `σ_k u_k` (`k < m`) and
    /// zeros; `v_k` and `σ_k` of the `N − m` remaining columns are zero.
    fn decompose_wide<R, S>(
        &mut self,
        work: &mut Matrix<f64, R, Const<N>, S>,
        scale: f64,
    ) -> Result<(), LinalgError>
    where
        R: Dim,
        S: StorageMut<f64, R, Const<N>, RStride = U1>,
    {
        let rows = work.nrows();
        let mut transposed = JointMatrix::<N>::zeros();
        for (mut column, row) in transposed.column_iter_mut().zip(work.row_iter()) {
            column.tr_copy_from(&row);
        }
        let mut left = JointMatrix::<N>::identity();
        // Rotating whole columns of U (N entries) is harmless: rows m.. of its first m columns stay zero.
        jacobi(&mut transposed, rows, &mut left, scale)?;
        self.v.fill(0.0);
        self.sigma.fill(0.0);
        work.fill(0.0);
        for k in 0..rows {
            let sigma = transposed.column(k).norm();
            self.sigma[k] = sigma;
            if sigma > 0.0 {
                self.v.set_column(k, &(transposed.column(k) / sigma));
            }
            // w_k = A v_k = σ_k u_k (the first m entries of column k of U).
            for (w, u) in work.column_mut(k).iter_mut().zip(left.column(k).iter()) {
                *w = sigma * u;
            }
        }
        Ok(())
    }

    /// The largest singular value.
    pub fn sigma_max(&self) -> f64 {
        self.sigma.max()
    }

    /// The singular values (unordered; column k of [`Self::right_vectors`] belongs to entry k).
    pub fn singular_values(&self) -> &JointVector<N> {
        &self.sigma
    }

    /// The right singular vectors, one per column. For a matrix with `m < N` rows only the first `m` columns are
    /// singular vectors; the others, whose singular value is zero, are zero.
    pub fn right_vectors(&self) -> &JointMatrix<N> {
        &self.v
    }

    /// `true` when singular value `k` is kept by the rank policy (`false` for `k ≥ N`).
    pub fn is_kept(&self, k: usize) -> bool {
        self.sigma
            .get(k)
            .is_some_and(|&sigma| sigma > self.threshold)
    }

    /// The numerical rank under the rank policy used at decomposition.
    pub fn rank(&self) -> usize {
        (0..N).filter(|&k| self.is_kept(k)).count()
    }

    /// The smallest kept singular value, `None` at rank 0.
    pub fn smallest_kept(&self) -> Option<f64> {
        (0..N)
            .filter(|&k| self.is_kept(k))
            .map(|k| self.sigma[k])
            .reduce(f64::min)
    }

    /// Writes `A^{inv} r` into `out`, where `work` is the `W = A V` left by [`Self::decompose`] and the inverse is the
    /// truncated pseudo-inverse or damped least squares ([theory §2.1.2](crate::theory#s2-1-2)).
    ///
    /// # Errors
    /// [`LinalgError::DimensionMismatch`] when `r` and `work` have different row counts.
    pub fn solve<R, S, SR>(
        &self,
        work: &Matrix<f64, R, Const<N>, S>,
        r: &Vector<f64, R, SR>,
        inverse: VelocityInverse,
        out: &mut JointVector<N>,
    ) -> Result<(), LinalgError>
    where
        R: Dim,
        S: RawStorage<f64, R, Const<N>>,
        SR: RawStorage<f64, R>,
    {
        check_rows("right-hand side", work.nrows(), r.nrows())?;
        out.fill(0.0);
        for k in 0..N {
            let sigma_sq = self.sigma[k] * self.sigma[k];
            let weight = match inverse {
                VelocityInverse::Truncated if self.is_kept(k) => 1.0 / sigma_sq,
                VelocityInverse::Truncated => continue,
                VelocityInverse::Damped { damping } if sigma_sq + damping * damping > 0.0 => {
                    1.0 / (sigma_sq + damping * damping)
                }
                VelocityInverse::Damped { .. } => continue,
            };
            // v_k (u_kᵀ r)/σ_k  =  v_k (w_kᵀ r)/σ_k²   since w_k = σ_k u_k.
            let coefficient = work.column(k).dot(r) * weight;
            out.axpy(coefficient, &self.v.column(k), 1.0);
        }
        Ok(())
    }

    /// Subtracts the projector onto the row space of `A`, `A⁺A = Σ_{k kept} v_k v_kᵀ`, from `projector`
    /// ([\[M8\]](crate::theory#m8)), then re-symmetrises it ([theory §2.1.3](crate::theory#s2-1-3)).
    pub fn subtract_row_space_projector(&self, projector: &mut JointMatrix<N>) {
        for k in (0..N).filter(|&k| self.is_kept(k)) {
            let v = self.v.column(k);
            projector.ger(-1.0, &v, &v, 1.0);
        }
        symmetrize(projector);
    }

    /// Writes `V_1ᵀ g`'s norm, with `V_1` the kept right singular vectors: the norm of the part of `g` in the row
    /// space of `A` ([\[M26\]](crate::theory#m26)–[\[M27\]](crate::theory#m27), criterion C2').
    pub fn row_space_component_norm(&self, g: &JointVector<N>) -> f64 {
        (0..N)
            .filter(|&k| self.is_kept(k))
            .map(|k| self.v.column(k).dot(g).powi(2))
            .sum::<f64>()
            .sqrt()
    }
}

fn check_rows(what: &'static str, expected: usize, found: usize) -> Result<(), LinalgError> {
    if expected == found {
        Ok(())
    } else {
        Err(LinalgError::DimensionMismatch {
            what,
            expected,
            found,
        })
    }
}

/// One-sided Jacobi (Hestenes) on the first `columns ≤ N` columns of `a`: plane rotations of column pairs, accumulated in
/// the columns of `acc`, until every pair is orthogonal to working precision. `scale` is `‖a‖_F²`: columns below
/// `(16 ε)² · scale` are rounding noise (`σ ≤ 16 ε ‖A‖_F`) and are left alone, since rotations among them cannot reach
/// relative orthogonality and do not affect any singular value a rank policy keeps; zero columns cost nothing.
///
/// The squared column norms are computed at the start of each sweep and updated in closed form after each rotation
/// (`α' = α − tγ`, `β' = β + tγ`), so a pair costs one dot product and the rotation.
fn jacobi<const L: usize, const N: usize>(
    a: &mut SMatrix<f64, L, N>,
    columns: usize,
    acc: &mut JointMatrix<N>,
    scale: f64,
) -> Result<(), LinalgError> {
    let negligible = (16.0 * f64::EPSILON).powi(2) * scale;
    // An L-term dot product carries a rounding error of about L ε √(αβ): asking for less never converges.
    let tolerance = (L.max(1) as f64) * f64::EPSILON;
    let columns = columns.min(N);
    let mut norms = [0.0; N];
    // Round-robin ("circle") order: each round rotates disjoint pairs, whose dependency chains (a division and a
    // square root or two per rotation) the processor then overlaps. Every pair is visited once per sweep. The schedule
    // of a sweep is computed once: round r rotates the pairs `schedule[r][..counts[r]]` (at most `N` rounds of at most
    // `N` pairs, since `players ≤ N + 1`), without the pairs of the dummy player an odd count adds.
    let players = columns + columns % 2;
    let mut schedule = [[(0, 0); N]; N];
    let mut counts = [0; N];
    for ((round, pairs), count) in schedule.iter_mut().enumerate().zip(counts.iter_mut()) {
        if round + 1 >= players {
            break;
        }
        for k in 0..players / 2 {
            let (p, q) = round_robin_pair(players, round, k);
            if q < columns {
                pairs[*count] = (p, q);
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
fn round_robin_pair(players: usize, round: usize, k: usize) -> (usize, usize) {
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
struct RotationNorms {
    difference: f64,
    reciprocal: f64,
}

impl RotationNorms {
    #[inline(always)]
    fn new(alpha: f64, beta: f64) -> Self {
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
    fn rotation(self, gamma: f64) -> (f64, f64, f64) {
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

/// `xᵀ y` with two accumulators (half the dependency chain of a sequential sum).
#[inline(always)]
fn dot<const N: usize>(x: &[f64; N], y: &[f64; N]) -> f64 {
    let (mut even, mut odd) = (0.0, 0.0);
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

/// The triangular factor `R` (`N × N`, `Rᵀ R = Aᵀ A`) of a matrix with at least `N` rows, by Givens rotations of each
/// row of `A` into `R` in turn: `A` is only read, and `R` has the singular values and right singular vectors of `A`
/// (`[R; 0] = Qᵀ A` with `Q` orthogonal, backward stable as Householder's QR).
fn triangular_factor<const N: usize, R, S>(a: &Matrix<f64, R, Const<N>, S>) -> JointMatrix<N>
where
    R: Dim,
    S: RawStorage<f64, R, Const<N>>,
{
    let mut r = JointMatrix::<N>::zeros();
    for row in a.row_iter() {
        let mut x = [0.0; N];
        x.iter_mut().zip(row.iter()).for_each(|(x, a)| *x = *a);
        for j in 0..N {
            let (diagonal, entry) = (r[(j, j)], x[j]);
            if entry == 0.0 {
                continue;
            }
            // √(a² + b²) directly when no square can overflow or underflow (the usual case), `hypot` otherwise.
            let squares = diagonal * diagonal + entry * entry;
            let norm = if (1e-290..1e290).contains(&squares) {
                squares.sqrt()
            } else {
                diagonal.hypot(entry)
            };
            let inverse = 1.0 / norm;
            let (c, s) = (diagonal * inverse, entry * inverse);
            for k in j..N {
                let (rk, xk) = (r[(j, k)], x[k]);
                r[(j, k)] = c * rk + s * xk;
                x[k] = c * xk - s * rk;
            }
        }
    }
    r
}

/// `out = a · b` for a matrix `a` with a run-time number of rows and a small fixed-size `b` (`K × N`), row by row on
/// fixed-size rows: allocation-free and without the packing of a general matrix product (nalgebra's dynamic `gemm`
/// hands sizes like `8 × 6 · 6 × 6` to a blocked kernel that allocates its packing buffers).
pub(crate) fn mul_rows_to<const K: usize, const N: usize, R, SA, SO>(
    a: &Matrix<f64, R, Const<K>, SA>,
    b: &nalgebra::SMatrix<f64, K, N>,
    out: &mut Matrix<f64, R, Const<N>, SO>,
) where
    R: Dim,
    SA: RawStorage<f64, R, Const<K>>,
    SO: StorageMut<f64, R, Const<N>>,
{
    for (row, mut out_row) in a.row_iter().zip(out.row_iter_mut()) {
        out_row.copy_from(&(row * b));
    }
}

/// Replaces `p` by `(p + pᵀ)/2`, removing the asymmetry that repeated projector updates accumulate ([theory §2.1.3](crate::theory#s2-1-3)).
pub fn symmetrize<const N: usize>(p: &mut JointMatrix<N>) {
    for i in 0..N {
        for j in (i + 1)..N {
            let mean = 0.5 * (p[(i, j)] + p[(j, i)]);
            p[(i, j)] = mean;
            p[(j, i)] = mean;
        }
    }
}

/// The orthogonal projector `I − A⁺A` onto the kernel of `a` (`m × N`), with the rank decided by `policy`
/// ([theory §0](crate::theory#s0), `P_i`). Copies `a` into `work` (same shape), which it overwrites.
///
/// # Errors
/// As [`ColumnSvd::decompose`]; [`LinalgError::DimensionMismatch`] when `work` and `a` differ in rows.
pub fn null_space_projector<const N: usize, R, S, SW>(
    a: &Matrix<f64, R, Const<N>, S>,
    work: &mut Matrix<f64, R, Const<N>, SW>,
    policy: &RankPolicy,
) -> Result<JointMatrix<N>, LinalgError>
where
    R: Dim,
    S: RawStorage<f64, R, Const<N>>,
    SW: StorageMut<f64, R, Const<N>, RStride = U1>,
{
    check_rows("work", a.nrows(), work.nrows())?;
    work.copy_from(a);
    let mut svd = ColumnSvd::default();
    svd.decompose(work, policy)?;
    let mut projector = JointMatrix::identity();
    svd.subtract_row_space_projector(&mut projector);
    Ok(projector)
}

/// The Moore–Penrose pseudo-inverse `A⁺` (`N × m`) of an `m × N` matrix with the rank decided by `policy`. A
/// convenience for analysis and tests; it allocates when `m` is dynamic. The control loop uses [`ColumnSvd`] directly.
///
/// # Errors
/// As [`ColumnSvd::decompose`].
pub fn pseudo_inverse<const N: usize, R, S>(
    a: &Matrix<f64, R, Const<N>, S>,
    policy: &RankPolicy,
) -> Result<nalgebra::OMatrix<f64, Const<N>, R>, LinalgError>
where
    R: Dim,
    S: nalgebra::Storage<f64, R, Const<N>>,
    nalgebra::DefaultAllocator:
        nalgebra::allocator::Allocator<R, Const<N>> + nalgebra::allocator::Allocator<Const<N>, R>,
{
    let mut work = nalgebra::OMatrix::<f64, nalgebra::Dyn, Const<N>>::from_iterator_generic(
        nalgebra::Dyn(a.nrows()),
        Const::<N>,
        a.iter().copied(),
    );
    let mut svd = ColumnSvd::default();
    svd.decompose(&mut work, policy)?;
    let (rows, cols) = (Const::<N>, R::from_usize(a.nrows()));
    let mut out = nalgebra::OMatrix::<f64, Const<N>, R>::zeros_generic(rows, cols);
    for k in (0..N).filter(|&k| svd.is_kept(k)) {
        let sigma_sq = svd.sigma[k] * svd.sigma[k];
        // v_k u_kᵀ / σ_k = v_k w_kᵀ / σ_k²
        let (v, w) = (svd.v.column(k), work.column(k));
        for (mut column, w) in out.column_iter_mut().zip(w.iter()) {
            column.axpy(w / sigma_sq, &v, 1.0);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{DVector, Dyn, OMatrix, SMatrix};
    use proptest::prelude::*;

    fn matrix_strategy<const N: usize>(
        rows: usize,
    ) -> impl Strategy<Value = OMatrix<f64, Dyn, Const<N>>> {
        proptest::collection::vec(-1.0..1.0f64, rows * N).prop_map(move |data| {
            OMatrix::<f64, Dyn, Const<N>>::from_row_slice_generic(Dyn(rows), Const::<N>, &data)
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// The four Moore–Penrose conditions, which define `A⁺` uniquely, for wide, square and tall matrices:
        /// `A X A = A`, `X A X = X`, `(A X)ᵀ = A X`, `(X A)ᵀ = X A`. (An oracle independent of any SVD; nalgebra's own
        /// `pseudo_inverse` leaves residuals of 1e−12 where this one leaves 1e−16.) Tolerances scale as ε‖A‖‖X‖.
        #[test]
        fn pseudo_inverse_satisfies_penrose_conditions(rows in 1usize..10, seed in matrix_strategy::<6>(10)) {
            let a = seed.rows(0, rows).into_owned();
            let x = pseudo_inverse(&a, &RankPolicy::default()).unwrap();
            let scale = 1.0 + a.norm() * x.norm();
            let tolerance = 1e-13 * scale * scale;
            let ax = &a * &x;
            let xa = &x * &a;
            prop_assert!((&ax * &a - &a).amax() < tolerance * a.norm());
            prop_assert!((&ax - ax.transpose()).amax() < tolerance);
            prop_assert!((xa - xa.transpose()).amax() < tolerance); // xa: 6 × 6, Copy
            prop_assert!((xa * &x - &x).amax() < tolerance * x.norm());
        }

        /// A rank-deficient matrix (rank 2 built as a product) is detected and its kernel projector is exact.
        #[test]
        fn rank_and_projector_of_deficient_matrix(left in matrix_strategy::<2>(5), right in matrix_strategy::<7>(2)) {
            let a = &left * &right; // 5 × 7, rank 2
            let mut work = a.clone();
            let mut svd = ColumnSvd::<7>::default();
            svd.decompose(&mut work, &RankPolicy::default()).unwrap();
            prop_assert_eq!(svd.rank(), 2);
            let mut work2 = a.clone();
            let p = null_space_projector(&a, &mut work2, &RankPolicy::default()).unwrap();
            prop_assert!((&a * p).norm() < 1e-12);
            prop_assert!((p * p - p).norm() < 1e-12);
            prop_assert!((p - p.transpose()).norm() < 1e-15);
            prop_assert!((p.trace() - 5.0).abs() < 1e-10);
        }
    }

    /// Every pair of columns is visited exactly once per sweep by the round-robin order.
    #[test]
    fn round_robin_visits_every_pair_once() {
        for players in (2..=16).step_by(2) {
            let mut seen = vec![0usize; players * players];
            for round in 0..players - 1 {
                for k in 0..players / 2 {
                    let (p, q) = round_robin_pair(players, round, k);
                    assert!(p < q && q < players);
                    seen[p * players + q] += 1;
                }
            }
            for p in 0..players {
                for q in (p + 1)..players {
                    assert_eq!(
                        seen[p * players + q],
                        1,
                        "players {players}, pair ({p}, {q})"
                    );
                }
            }
        }
    }

    /// Rutishauser's rotation computed the textbook way (ζ, then t, then c and s), as a reference.
    fn textbook_rotation(alpha: f64, beta: f64, gamma: f64) -> (f64, f64, f64) {
        let zeta = (beta - alpha) / (2.0 * gamma);
        let t = zeta.signum() / (zeta.abs() + (1.0 + zeta * zeta).sqrt());
        let c = 1.0 / (1.0 + t * t).sqrt();
        (c, c * t, t)
    }

    /// Both branches of the rotation (the series below |γ/(β − α)| = 2⁻¹⁴, the closed form above it) agree with the
    /// textbook formulas to a few ulps, for both signs and across scales, and give `c² + s² = 1`; and the rotation
    /// orthogonalises (a 2 × 2 check against the closed form).
    #[test]
    fn rotation_matches_the_textbook_formulas() {
        let close = |a: f64, b: f64| (a - b).abs() <= 4.0 * f64::EPSILON * b.abs();
        let norms = [
            (1.0, 3.0),
            (3.0, 1.0),
            (2.5e-7, 1e-9),
            (1e5, 7e5),
            (4.0, 4.0 + 1e-6),
        ];
        let mut checked = 0;
        for (alpha, beta) in norms {
            for x in [
                1e-30, 1e-12, 3e-8, 1e-5, 6.0e-5, 6.2e-5, 1e-3, 0.3, 2.0, 1e3,
            ] {
                for sign in [1.0, -1.0] {
                    let gamma = sign * x * (beta - alpha);
                    if gamma * gamma >= alpha * beta {
                        continue; // not the product of two columns with these norms
                    }
                    let (c, s, t) = RotationNorms::new(alpha, beta).rotation(gamma);
                    let (c0, s0, t0) = textbook_rotation(alpha, beta, gamma);
                    assert!(
                        close(c, c0) && close(s, s0) && close(t, t0),
                        "x = {x}: {:?} vs {:?}",
                        (c, s, t),
                        (c0, s0, t0)
                    );
                    assert!((c * c + s * s - 1.0).abs() <= 2.0 * f64::EPSILON);
                    checked += 1;
                }
            }
        }
        assert!(checked > 60);
        // Columns x = (1, 0), y = (0.3, 0.2): α = 1, β = 0.13, γ = 0.3; the rotated pair is orthogonal.
        let (c, s, _) = RotationNorms::new(1.0, 0.13).rotation(0.3);
        let (x0, y0) = ([1.0, 0.0], [0.3, 0.2]);
        let x1 = [c * x0[0] - s * y0[0], c * x0[1] - s * y0[1]];
        let y1 = [s * x0[0] + c * y0[0], s * x0[1] + c * y0[1]];
        assert!((x1[0] * y1[0] + x1[1] * y1[1]).abs() < 1e-16);
        assert!((c * c + s * s - 1.0).abs() < 1e-15);
    }

    /// A long warm-started sequence (a slowly moving 8 × 6 matrix, as in a control loop) keeps V orthogonal to
    /// 1e−13: the periodic cold start bounds the drift of rotating the same basis.
    #[test]
    fn warm_started_basis_stays_orthogonal() {
        let a = OMatrix::<f64, Dyn, Const<6>>::from_fn(8, |i, j| ((i * 6 + j) as f64 * 0.37).sin());
        let d =
            OMatrix::<f64, Dyn, Const<6>>::from_fn(8, |i, j| ((i * 7 + 3 * j) as f64 * 0.91).cos());
        let mut svd = ColumnSvd::<6>::default();
        for k in 0..3000 {
            let mut w = &a + &d * (1e-3 * k as f64);
            svd.decompose_warm(&mut w, &RankPolicy::default(), 0.0)
                .unwrap();
            let v = svd.right_vectors();
            let drift = (v.transpose() * v - JointMatrix::<6>::identity()).norm();
            assert!(drift < 1e-13, "step {k}: ‖VᵀV − I‖ = {drift}");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// A warm start from the decomposition of a nearby matrix gives the same pseudo-inverse and projector as a cold
        /// start, for square and tall matrices.
        #[test]
        fn warm_start_matches_cold_start(rows in 6usize..10, seed in matrix_strategy::<6>(10), step in matrix_strategy::<6>(10)) {
            let a = seed.rows(0, rows).into_owned();
            let nearby = &a + step.rows(0, rows) * 1e-3;
            let r = DVector::from_fn(rows, |i, _| (i as f64 * 0.7).sin());
            let policy = RankPolicy::default();
            let mut warm = ColumnSvd::<6>::default();
            warm.decompose_warm(&mut a.clone(), &policy, 0.0).unwrap();
            let mut w_warm = nearby.clone();
            warm.decompose_warm(&mut w_warm, &policy, 0.0).unwrap();
            let mut cold = ColumnSvd::<6>::default();
            let mut w_cold = nearby.clone();
            cold.decompose(&mut w_cold, &policy).unwrap();
            prop_assert_eq!(warm.rank(), cold.rank());
            let (mut x_warm, mut x_cold) = (JointVector::<6>::zeros(), JointVector::<6>::zeros());
            warm.solve(&w_warm, &r, VelocityInverse::Truncated, &mut x_warm).unwrap();
            cold.solve(&w_cold, &r, VelocityInverse::Truncated, &mut x_cold).unwrap();
            let scale = 1.0 + x_cold.norm();
            prop_assert!((x_warm - x_cold).norm() < 1e-11 * scale * scale);
            let (mut p_warm, mut p_cold) = (JointMatrix::<6>::identity(), JointMatrix::<6>::identity());
            warm.subtract_row_space_projector(&mut p_warm);
            cold.subtract_row_space_projector(&mut p_cold);
            prop_assert!((p_warm - p_cold).norm() < 1e-12);
        }
    }

    #[test]
    fn damped_inverse_matches_its_formula() {
        let a = SMatrix::<f64, 3, 6>::from_fn(|i, j| ((i * 6 + j) as f64 * 0.37).sin());
        let r = nalgebra::Vector3::new(0.3, -0.2, 0.5);
        let delta = 0.2;
        let mut work = a;
        let mut svd = ColumnSvd::<6>::default();
        svd.decompose(&mut work, &RankPolicy::default()).unwrap();
        let mut out = JointVector::<6>::zeros();
        svd.solve(
            &work,
            &r,
            VelocityInverse::Damped { damping: delta },
            &mut out,
        )
        .unwrap();
        let expected = a.transpose()
            * (a * a.transpose() + nalgebra::Matrix3::identity() * delta * delta)
                .try_inverse()
                .unwrap()
            * r;
        assert_relative_eq!(out, expected, epsilon = 1e-13);
    }

    #[test]
    fn zero_matrix_has_rank_zero_and_identity_projector() {
        let a = SMatrix::<f64, 2, 6>::zeros();
        let mut work = a;
        let p = null_space_projector(&a, &mut work, &RankPolicy::default()).unwrap();
        assert_eq!(p, JointMatrix::<6>::identity());
    }

    #[test]
    fn relative_threshold_drops_tiny_singular_values() {
        // diag(1, 1e-8): rank 1 under the default relative 1e-6, rank 2 under 1e-9.
        let a = SMatrix::<f64, 2, 2>::new(1.0, 0.0, 0.0, 1e-8);
        let mut svd = ColumnSvd::<2>::default();
        svd.decompose(&mut a.clone(), &RankPolicy::default())
            .unwrap();
        assert_eq!(svd.rank(), 1);
        svd.decompose(&mut a.clone(), &RankPolicy::new(1e-9, 0.0).unwrap())
            .unwrap();
        assert_eq!(svd.rank(), 2);
        assert_relative_eq!(svd.smallest_kept().unwrap(), 1e-8, max_relative = 1e-12);
    }

    #[test]
    fn bad_inputs_are_errors() {
        assert!(matches!(
            RankPolicy::new(-1e-6, 0.0),
            Err(LinalgError::InvalidRankPolicy { .. })
        ));
        assert!(RankPolicy::new(1.0, 0.0).is_err());
        assert!(RankPolicy::new(1e-6, f64::NAN).is_err());
        assert_eq!(
            VelocityInverse::Damped { damping: -0.1 }.validate(),
            Err(LinalgError::InvalidDamping { damping: -0.1 })
        );
        let mut a = SMatrix::<f64, 2, 3>::zeros();
        a[(1, 2)] = f64::NAN;
        let mut svd = ColumnSvd::<3>::default();
        assert!(matches!(
            svd.decompose(&mut a, &RankPolicy::default()),
            Err(LinalgError::NonFiniteMatrix { row: 1, column: 2, value }) if value.is_nan()
        ));
    }
}
