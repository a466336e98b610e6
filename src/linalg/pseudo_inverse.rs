//! The Moore–Penrose pseudo-inverse as a matrix, for analysis and tests.

use super::*;

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
