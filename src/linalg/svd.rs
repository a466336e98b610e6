//! The allocation-free SVD of a level: [`ColumnSvd`], its pseudo-inverse products and projectors.

use super::jacobi::jacobi;
use super::*;

/// The right half of a singular value decomposition `A = U Σ Vᵀ` of an `m × N` matrix `A`, computed by
/// [`ColumnSvd::decompose`]. Together with the rotated working matrix `W = A V` (whose column k is `σ_k u_k`) it gives
/// pseudo-inverses and projectors without forming `U`.
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnSvd<const N: usize> {
    /// Right singular vectors, one per column (orthonormal).
    pub(super) v: JointMatrix<N>,
    /// Singular values `σ_k = ‖W e_k‖`, unordered, one per column of `v`.
    pub(super) sigma: JointVector<N>,
    /// The cut-off chosen by the rank policy at the last decomposition.
    threshold: f64,
    /// The scale the relative thresholds were taken against at the last decomposition, `max(σ_max, reference_scale)`.
    reference: f64,
    /// `Some(k)` when `v` is a full orthogonal basis that has been through `k` warm starts since the last cold one.
    basis_age: Option<u32>,
}

/// A warm-started decomposition ([`ColumnSvd::decompose_warm`]) starts cold after this many warm starts in a row, which
/// bounds the loss of orthogonality that rotating the same `V` accumulates (about `ε √(rotations)`).
const WARM_RESTART: u32 = 64;

/// Matrices with `N < m ≤ TALL_ROWS` rows are rotated directly, zero-padded to `TALL_ROWS` rows (cheaper than a
/// triangular factor followed by `W = A V` at the sizes of a point task, 8 rows); taller ones on their triangular factor.
const TALL_ROWS: usize = 8;

impl<const N: usize> Default for ColumnSvd<N> {
    fn default() -> Self {
        Self {
            v: JointMatrix::identity(),
            sigma: JointVector::zeros(),
            threshold: 0.0,
            reference: 0.0,
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
        self.reference = self.sigma_max().max(reference_scale);
        self.threshold = policy.threshold(self.reference);
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
        self.v.fill(0.0);
        self.sigma.fill(0.0);
        if rows == 1 {
            // No rotation: σ = ‖a‖, v = a/σ, u = 1, w = [σ].
            let sigma = work.row(0).norm();
            self.sigma[0] = sigma;
            if sigma > 0.0 {
                self.v.set_column(0, &(work.row(0).transpose() / sigma));
            }
            work.fill(0.0);
            work[(0, 0)] = sigma;
            return Ok(());
        }
        let mut transposed = JointMatrix::<N>::zeros();
        for (mut column, row) in transposed.column_iter_mut().zip(work.row_iter()) {
            column.tr_copy_from(&row);
        }
        let mut left = JointMatrix::<N>::identity();
        // Rotating whole columns of U (N entries) is harmless: rows m.. of its first m columns stay zero.
        jacobi(&mut transposed, rows, &mut left, scale)?;
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
    /// truncated pseudo-inverse, damped least squares ([theory §2.1.2](crate::theory#s2-1-2)) or the filtered inverse
    /// ([D30](crate::theory#d30)).
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
                VelocityInverse::Filtered { floor } if self.is_kept(k) => {
                    let epsilon = floor * self.reference;
                    1.0 / sigma_sq.max(epsilon * epsilon)
                }
                VelocityInverse::Truncated | VelocityInverse::Filtered { .. } => continue,
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
