//! Projector helpers: re-symmetrisation and the null-space projector of a matrix.

use super::*;

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
