//! Pseudo-inverses with an explicit rank policy, damped least squares, and projector helpers ([theory §2.1](crate::theory#s2-1), [D2](crate::theory#d2)).
//!
//! Every level of the task stack needs, for its limited Jacobian `J̃ = J P` (`m × N`, `m` may exceed `N`), the
//! least-squares velocity `J̃⁺ r` and the projector onto its row space `J̃⁺ J̃` ([\[M8\]](crate::theory#m8)). Both come from one
//! singular value decomposition `J̃ = U Σ Vᵀ`:
//!
//! ```text
//! J̃⁺ r   = Σ_{k kept} v_k (u_kᵀ r) / σ_k                (truncated, theory §2.1.1)
//! J̃^{#δ} r = Σ_k v_k σ_k (u_kᵀ r) / (σ_k² + δ²)         (damped least squares, theory §2.1.2)
//! J̃^{#ε} r = Σ_{k kept} v_k σ_k (u_kᵀ r) / max(σ_k², ε²)  (filtered: gains capped at 1/ε, D30)
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
//! **Certified fast path** ([`solve_full_column_rank`], [D15](crate::theory#d15)): a matrix of `N` to 16 rows that a
//! Cholesky-based bound certifies to have full column rank and `σ_max/σ_min ≤ 10³` is solved by the normal equations,
//! refined once, without the SVD; the result is the SVD's to `10⁻¹² ‖r‖/σ_min`. Any doubt leaves the decision to the
//! SVD.
//!
//! **Rank policy** ([`RankPolicy`], [D2](crate::theory#d2)): a singular value is kept when `σ_k > max(relative · σ_max, absolute)`, with
//! `relative = 1e−6` by default (ViSP's `svThreshold`) and a tiny absolute floor so that a zero matrix has rank 0.
//! For a limited Jacobian `J̃_i = J_i P` the stack measures `σ_max` on the task's own scale, `max(σ_max(J̃_i), ‖J_i‖_F)`
//! ([`ColumnSvd::decompose_with_scale`]).

mod certified;
mod jacobi;
mod projector;
mod pseudo_inverse;
mod svd;
#[cfg(test)]
mod tests;

pub(crate) use certified::rank_test_threshold;
pub use certified::{
    solve_full_column_rank, solve_small_full_row_rank, solve_small_stack_level,
    FAST_PATH_CONDITION_BOUND, SMALL_PATH_CONDITION_BOUND,
};
pub use projector::{null_space_projector, symmetrize};
pub use pseudo_inverse::pseudo_inverse;
pub use svd::ColumnSvd;

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
    /// The floor of the filtered inverse is outside `[0, 1)`.
    #[error("invalid singular-value floor {floor} (need 0 ≤ floor < 1)")]
    InvalidFilterFloor {
        /// The floor given.
        floor: f64,
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
    /// The truncated pseudo-inverse with every kept singular value's inverse capped at `1/ε`,
    /// `ε = floor · max(σ_max(J̃), reference)` (the rank policy's reference, `‖J_i‖_F` for a stack level):
    /// `Σ_k v_k σ_k (u_kᵀ r) / max(σ_k², ε²)`, numerical filtering (damping only the singular values below `ε`, with
    /// `δ_k² = ε² − σ_k²`; [D30](crate::theory#d30)). Equal to [`Self::Truncated`] when every kept `σ_k ≥ ε`,
    /// continuous in `σ_k`, and no direction's gain exceeds `1/ε`.
    Filtered {
        /// `ε` relative to the level's scale (`0 ≤ floor < 1`; 0 is the truncated pseudo-inverse).
        floor: f64,
    },
}

impl VelocityInverse {
    /// Checks the damping factor or the filter's floor.
    pub fn validate(&self) -> Result<(), LinalgError> {
        match *self {
            Self::Truncated => Ok(()),
            Self::Damped { damping } if damping.is_finite() && damping >= 0.0 => Ok(()),
            Self::Damped { damping } => Err(LinalgError::InvalidDamping { damping }),
            Self::Filtered { floor } if (0.0..1.0).contains(&floor) => Ok(()),
            Self::Filtered { floor } => Err(LinalgError::InvalidFilterFloor { floor }),
        }
    }

    /// The rank policy under which a certified fast path ([D15](crate::theory#d15)) may answer for this inverse: the
    /// policy itself, or for [`Self::Filtered`] one whose relative threshold is at least the floor, so that a level
    /// certified has every `σ_k > ε` and its truncated pseudo-inverse is the filtered one; `None` for
    /// [`Self::Damped`], which always takes the SVD.
    pub fn certifiable_policy(&self, policy: &RankPolicy) -> Option<RankPolicy> {
        match *self {
            Self::Truncated => Some(*policy),
            Self::Filtered { floor } => Some(RankPolicy {
                relative: policy.relative.max(floor),
                absolute: policy.absolute,
            }),
            Self::Damped { .. } => None,
        }
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

/// `out = a · b` for a matrix `a` with a run-time number of rows and a small fixed-size `b` (`K × N`), row by row:
/// `out_ij = a_iᵀ b_j` with the row `a_i` copied to a fixed-size array and `b_j` a column of `b`, contiguous (summed in
/// the order of `k`). Allocation-free and without the packing of a general matrix product (nalgebra's dynamic `gemm`
/// hands sizes like `8 × 6 · 6 × 6` to a blocked kernel that allocates its packing buffers), nor its generic
/// row-times-matrix product.
pub(crate) fn mul_rows_to<const K: usize, const N: usize, R, SA, SO>(
    a: &Matrix<f64, R, Const<K>, SA>,
    b: &nalgebra::SMatrix<f64, K, N>,
    out: &mut Matrix<f64, R, Const<N>, SO>,
) where
    R: Dim,
    SA: RawStorage<f64, R, Const<K>>,
    SO: StorageMut<f64, R, Const<N>>,
{
    for i in 0..a.nrows().min(out.nrows()) {
        mul_row_to(&row_array(a, i), b, out, i);
    }
}

/// [`mul_rows_to`] and, from the same copies of the rows, `a · v` for a vector `v` of `K` entries: `out = a · b`,
/// `av_i = a_iᵀ v` (the product a stack level needs for its limited Jacobian `J P` and its residual `J q̇`).
pub(crate) fn mul_rows_and_vector_to<const K: usize, const N: usize, R, SA, SO, SV>(
    a: &Matrix<f64, R, Const<K>, SA>,
    b: &nalgebra::SMatrix<f64, K, N>,
    v: &nalgebra::SVector<f64, K>,
    out: &mut Matrix<f64, R, Const<N>, SO>,
    av: &mut Vector<f64, R, SV>,
) where
    R: Dim,
    SA: RawStorage<f64, R, Const<K>>,
    SO: StorageMut<f64, R, Const<N>>,
    SV: StorageMut<f64, R>,
{
    for i in 0..a.nrows().min(out.nrows()).min(av.nrows()) {
        let row = row_array(a, i);
        mul_row_to(&row, b, out, i);
        av[i] = dot_array(&row, v.as_slice());
    }
}

/// Row `i` of `a`, copied to a fixed-size array.
#[inline(always)]
fn row_array<const K: usize, R: Dim, SA: RawStorage<f64, R, Const<K>>>(
    a: &Matrix<f64, R, Const<K>, SA>,
    i: usize,
) -> [f64; K] {
    std::array::from_fn(|k| a[(i, k)])
}

/// `out_ij = rowᵀ b_j` for every column `j` of `b`.
#[inline(always)]
fn mul_row_to<const K: usize, const N: usize, R, SO>(
    row: &[f64; K],
    b: &nalgebra::SMatrix<f64, K, N>,
    out: &mut Matrix<f64, R, Const<N>, SO>,
    i: usize,
) where
    R: Dim,
    SO: StorageMut<f64, R, Const<N>>,
{
    for (j, column) in b.as_slice().chunks_exact(K).enumerate() {
        out[(i, j)] = dot_array(row, column);
    }
}

/// `Σ_k row_k c_k`, summed in the order of `k`, from `−0`: the identity of floating-point addition (`−0 + p = p` for
/// every `p`), so the compiler drops the first addition, which a start at `+0` keeps (`+0 + (−0) = +0`); the sum
/// differs only in the sign of a zero.
#[inline(always)]
fn dot_array<const K: usize>(row: &[f64; K], column: &[f64]) -> f64 {
    row.iter()
        .zip(column.iter())
        .fold(-0.0, |sum, (a, b)| sum + a * b)
}
