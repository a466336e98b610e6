use super::jacobi::{round_robin_pair, RotationNorms};
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
        prop_assert!((p - p.transpose()).norm() < 1e-14);
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
    assert!((c * c + s * s - 1.0).abs() < 1e-14);
}

/// A long warm-started sequence (a slowly moving 8 × 6 matrix, as in a control loop) keeps V orthogonal to
/// 1e−13: the periodic cold start bounds the drift of rotating the same basis.
#[test]
fn warm_started_basis_stays_orthogonal() {
    let a = OMatrix::<f64, Dyn, Const<6>>::from_fn(8, |i, j| ((i * 6 + j) as f64 * 0.37).sin());
    let d = OMatrix::<f64, Dyn, Const<6>>::from_fn(8, |i, j| ((i * 7 + 3 * j) as f64 * 0.91).cos());
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

/// An `m × 6` matrix `U diag(σ) Vᵀ` with random orthonormal `U`, `V` (QR of random matrices) and singular values
/// spread log-uniformly from `scale` down to `scale/condition`.
fn conditioned_matrix(
    rows: usize,
    left: &[f64],
    right: &[f64],
    condition: f64,
    scale: f64,
) -> OMatrix<f64, Dyn, Const<6>> {
    let u = OMatrix::<f64, Dyn, Const<6>>::from_row_slice_generic(
        Dyn(rows),
        Const::<6>,
        &left[..rows * 6],
    )
    .qr()
    .q();
    let v = SMatrix::<f64, 6, 6>::from_row_slice(&right[..36]).qr().q();
    let sigma = JointVector::<6>::from_fn(|k, _| scale * condition.powf(-(k as f64) / 5.0));
    u * JointMatrix::<6>::from_diagonal(&sigma) * v.transpose()
}

/// The SVD path's least-squares solution and rank, the reference of the fast path.
fn svd_solution<const N: usize>(
    a: &OMatrix<f64, Dyn, Const<N>>,
    r: &DVector<f64>,
    policy: &RankPolicy,
    scale: f64,
) -> (JointVector<N>, usize) {
    let mut work = a.clone();
    let mut svd = ColumnSvd::<N>::default();
    svd.decompose_with_scale(&mut work, policy, scale).unwrap();
    let mut x = JointVector::<N>::zeros();
    svd.solve(&work, r, VelocityInverse::Truncated, &mut x)
        .unwrap();
    (x, svd.rank())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// D15: on random matrices of 7 to 10 rows with condition numbers from 1 to 10⁹ and magnitudes from 10⁻⁴ to 10⁴,
    /// the fast path answers only when the SVD finds full rank, its solution equals the SVD's within
    /// `10⁻¹² ‖r‖/σ_min`, its bound is a true lower bound of `σ_min` within `√N`, it always answers when
    /// `N κ ≤ 1000` (the certificate is not vacuous) and never when `κ > 1000` (ill-conditioned or rank-deficient: the
    /// SVD decides). Square matrices, whose rows are equilibrated first, have their own tests below.
    #[test]
    fn fast_path_agrees_with_the_svd(
        rows in 7usize..=10,
        left in proptest::collection::vec(-1.0..1.0f64, 60),
        right in proptest::collection::vec(-1.0..1.0f64, 36),
        residual in proptest::collection::vec(-1.0..1.0f64, 10),
        log_condition in 0.0..9.0f64,
        log_scale in -4.0..4.0f64,
    ) {
        let (condition, scale) = (10f64.powf(log_condition), 10f64.powf(log_scale));
        let a = conditioned_matrix(rows, &left, &right, condition, scale);
        let r = DVector::from_column_slice(&residual[..rows]) * scale;
        let policy = RankPolicy::default();
        let sigma_min = scale / condition;
        let mut fast = JointVector::<6>::repeat(f64::NAN);
        let answer = solve_full_column_rank(&a, &r, &policy, 0.0, &mut fast);
        let (reference, rank) = svd_solution(&a, &r, &policy, 0.0);
        if condition * 6.0 <= FAST_PATH_CONDITION_BOUND {
            prop_assert!(answer.is_some(), "κ = {condition:.3e}: the certificate must hold");
        }
        if condition > FAST_PATH_CONDITION_BOUND {
            prop_assert!(answer.is_none(), "κ = {condition:.3e}: the SVD must decide");
        }
        if let Some(lower) = answer {
            prop_assert_eq!(rank, 6);
            prop_assert!(lower <= sigma_min * (1.0 + 1e-12) && lower >= sigma_min / 6f64.sqrt() * (1.0 - 1e-6),
                "bound {lower:.6e}, σ_min {sigma_min:.6e}");
            let tolerance = 1e-12 * r.norm() / sigma_min;
            prop_assert!((fast - reference).norm() <= tolerance,
                "κ = {condition:.3e}: |Δx| = {:.3e} > {tolerance:.3e}", (fast - reference).norm());
        } else {
            prop_assert!(fast.iter().all(|x| x.is_nan()), "out written without a certificate");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// D15, square matrices (the rows equilibrated by powers of two): on random 6 × 6 matrices with condition numbers
    /// from 1 to 10⁹, magnitudes from 10⁻⁴ to 10⁴, the fast path answers only when the SVD finds full rank, its solution
    /// equals the SVD's within `10⁻¹² ‖r‖/σ_min`, and its bound is a true lower bound of `σ_min`.
    #[test]
    fn square_fast_path_agrees_with_the_svd(
        left in proptest::collection::vec(-1.0..1.0f64, 36),
        right in proptest::collection::vec(-1.0..1.0f64, 36),
        residual in proptest::collection::vec(-1.0..1.0f64, 6),
        log_condition in 0.0..9.0f64,
        log_scale in -4.0..4.0f64,
    ) {
        let (condition, scale) = (10f64.powf(log_condition), 10f64.powf(log_scale));
        let a = conditioned_matrix(6, &left, &right, condition, scale);
        let r = DVector::from_column_slice(&residual) * scale;
        let sigma_min = scale / condition;
        check_square_fast_path(&a, &r, sigma_min, false)?;
    }

    /// D15, square matrices whose rows have very different scales, `A = S B` with `κ(B) ≤ 3` and the row scales `S`
    /// log-uniform over three decades (`κ(A)` up to about 3·10³, often beyond the bound for rows left as they are, as
    /// with the third-order rows of a moment task): the fast path always answers, and agrees with the SVD. (Equilibrated,
    /// `σ_min(DA) ≥ 1/3`, `‖DA‖_F < 5` and `max d_i < 6·10³`, so both conditions of the certificate hold with margin.)
    #[test]
    fn square_fast_path_answers_for_rows_of_different_scales(
        left in proptest::collection::vec(-1.0..1.0f64, 36),
        right in proptest::collection::vec(-1.0..1.0f64, 36),
        residual in proptest::collection::vec(-1.0..1.0f64, 6),
        log_condition in 0.0..0.47f64,
        log_row_scales in proptest::collection::vec(-3.0..0.0f64, 6),
    ) {
        let b = conditioned_matrix(6, &left, &right, 10f64.powf(log_condition), 1.0);
        let scales = JointVector::<6>::from_fn(|i, _| 10f64.powf(log_row_scales[i]));
        let a = JointMatrix::<6>::from_diagonal(&scales) * b;
        let a = OMatrix::<f64, Dyn, Const<6>>::from_fn(6, |i, j| a[(i, j)]);
        let r = DVector::from_column_slice(&residual);
        let sigma_min = *a.singular_values().as_slice().last().unwrap();
        check_square_fast_path(&a, &r, sigma_min, true)?;
    }
}

/// The claims shared by the square tests: an answer only where the SVD finds rank 6 (always one when `must_answer`),
/// the SVD's solution within `10⁻¹² ‖r‖/σ_min`, a bound at most `σ_min`; nothing written without an answer.
fn check_square_fast_path(
    a: &OMatrix<f64, Dyn, Const<6>>,
    r: &DVector<f64>,
    sigma_min: f64,
    must_answer: bool,
) -> Result<(), TestCaseError> {
    let policy = RankPolicy::default();
    let mut fast = JointVector::<6>::repeat(f64::NAN);
    let answer = solve_full_column_rank(a, r, &policy, 0.0, &mut fast);
    let (reference, rank) = svd_solution(a, r, &policy, 0.0);
    if must_answer {
        prop_assert!(
            answer.is_some(),
            "σ_min = {sigma_min:.3e}: the certificate must hold"
        );
    }
    if let Some(lower) = answer {
        prop_assert_eq!(rank, 6);
        prop_assert!(
            lower <= sigma_min * (1.0 + 1e-12),
            "bound {lower:.6e}, σ_min {sigma_min:.6e}"
        );
        let tolerance = 1e-12 * r.norm() / sigma_min;
        prop_assert!(
            (fast - reference).norm() <= tolerance,
            "|Δx| = {:.3e} > {tolerance:.3e}",
            (fast - reference).norm()
        );
    } else {
        prop_assert!(
            fast.iter().all(|x| x.is_nan()),
            "out written without a certificate"
        );
    }
    Ok(())
}

/// The moment task of the peer scene's variant B, as measured: one row (`P_y`) 2000 times shorter than the others,
/// `κ(A) ≈ 5·10³`. Left as they are, the rows fail the certificate's condition bound; equilibrated, the fast path
/// answers with the SVD's solution. Fails if the rows are not equilibrated or if the bound is not mapped back to `A`.
#[test]
fn square_fast_path_equilibrates_a_short_row() {
    let left: Vec<f64> = (0..36).map(|k| ((k * 7 + 3) as f64 * 0.37).sin()).collect();
    let right: Vec<f64> = (0..36).map(|k| ((k * 5 + 1) as f64 * 0.53).cos()).collect();
    let mut a = conditioned_matrix(6, &left, &right, 3.0, 1.0);
    a.row_mut(5).scale_mut(6.5e-4);
    let sigma_min = *a.singular_values().as_slice().last().unwrap();
    let condition = a.norm() / sigma_min;
    assert!(condition > FAST_PATH_CONDITION_BOUND, "κ = {condition:.3e}");
    let r = DVector::from_fn(6, |k, _| ((k + 1) as f64).sin());
    let mut fast = JointVector::<6>::zeros();
    let lower = solve_full_column_rank(&a, &r, &RankPolicy::default(), 0.0, &mut fast)
        .expect("equilibrated, the rows are well conditioned");
    assert!(lower <= sigma_min);
    let (reference, _) = svd_solution(&a, &r, &RankPolicy::default(), 0.0);
    assert!((fast - reference).norm() <= 1e-12 * r.norm() / sigma_min);
    // A threshold of σ_min(A)/3 keeps every singular value, but the bound through max d_i alone (about 10 times
    // below σ_min here) would miss it: the bound on ‖A⁻¹‖_F answers, and stays below σ_min.
    let close = RankPolicy::new(sigma_min / (3.0 * a.norm()), 0.0).unwrap();
    assert_eq!(svd_solution(&a, &r, &close, 0.0).1, 6);
    let lower = solve_full_column_rank(&a, &r, &close, 0.0, &mut fast)
        .expect("σ_min(A) is three times the threshold");
    assert!(lower <= sigma_min && lower > 2.0 * sigma_min / 3.0);
    // A policy whose threshold lies above σ_min(A) truncates: the certificate, mapped back to A, defers to the SVD.
    let coarse = RankPolicy::new(2.0 * sigma_min / a.norm(), 0.0).unwrap();
    assert!(svd_solution(&a, &r, &coarse, 0.0).1 < 6);
    assert!(solve_full_column_rank(&a, &r, &coarse, 0.0, &mut fast).is_none());
    // At the edge: a certificate threshold (relative to ‖A‖_F ≥ σ_max, at least the SVD's) 10⁻⁴ below σ_min(A), and
    // the bound on ‖A⁻¹‖_F (within 10⁻⁶ of σ_min here, a short row carrying it) confirms full rank, as the SVD
    // decides; 10⁻⁴ above σ_min, no bound below σ_min can pass it, and the fast path defers.
    let below = RankPolicy::new(sigma_min * (1.0 - 1e-4) / a.norm(), 0.0).unwrap();
    assert_eq!(svd_solution(&a, &r, &below, 0.0).1, 6);
    assert!(solve_full_column_rank(&a, &r, &below, 0.0, &mut fast).is_some());
    let above = RankPolicy::new(sigma_min * (1.0 + 1e-4) / a.norm(), 0.0).unwrap();
    assert!(solve_full_column_rank(&a, &r, &above, 0.0, &mut fast).is_none());
}

/// The rank decision of the fast path: it never certifies full rank where the SVD's rank policy would truncate,
/// whatever the policy. Each case would fail if the certificate ignored the policy's threshold (a relative threshold
/// above `1/FAST_PATH_CONDITION_BOUND`, the task's own scale of a limited Jacobian, the absolute floor) or if it
/// trusted a nearly singular matrix.
#[test]
fn fast_path_defers_the_rank_decision_to_the_svd() {
    let left: Vec<f64> = (0..60).map(|k| ((k * 7 + 3) as f64 * 0.37).sin()).collect();
    let right: Vec<f64> = (0..36).map(|k| ((k * 5 + 1) as f64 * 0.53).cos()).collect();
    let r = DVector::from_fn(8, |k, _| ((k + 1) as f64).sin());
    let mut out = JointVector::<6>::zeros();
    // Nearly rank-deficient under the default policy (σ_min/σ_max = 10⁻⁷): the SVD truncates, the fast path defers.
    let a = conditioned_matrix(8, &left, &right, 1e7, 1.0);
    assert_eq!(svd_solution(&a, &r, &RankPolicy::default(), 0.0).1, 5);
    assert!(solve_full_column_rank(&a, &r, &RankPolicy::default(), 0.0, &mut out).is_none());
    // Well conditioned (κ = 4), but a policy with relative threshold 0.3 truncates σ_min = 0.25 σ_max.
    let a = conditioned_matrix(8, &left, &right, 4.0, 1.0);
    let coarse = RankPolicy::new(0.3, 0.0).unwrap();
    assert!(svd_solution(&a, &r, &coarse, 0.0).1 < 6);
    assert!(solve_full_column_rank(&a, &r, &coarse, 0.0, &mut out).is_none());
    assert!(solve_full_column_rank(&a, &r, &RankPolicy::default(), 0.0, &mut out).is_some());
    // The same matrix as the limited Jacobian of a task a million times larger: its directions are conflicts, dropped.
    assert_eq!(svd_solution(&a, &r, &RankPolicy::default(), 1e7).1, 0);
    assert!(solve_full_column_rank(&a, &r, &RankPolicy::default(), 1e7, &mut out).is_none());
    // A well-conditioned matrix below the absolute floor has rank 0.
    let tiny = conditioned_matrix(8, &left, &right, 2.0, 1e-13);
    assert_eq!(
        svd_solution(&tiny, &(&r * 1e-13), &RankPolicy::default(), 0.0).1,
        0
    );
    assert!(
        solve_full_column_rank(&tiny, &(&r * 1e-13), &RankPolicy::default(), 0.0, &mut out)
            .is_none()
    );
    // Too few rows, or a non-finite entry: no answer.
    let wide = a.rows(0, 5).into_owned();
    assert!(solve_full_column_rank(
        &wide,
        &r.rows(0, 5).into_owned(),
        &RankPolicy::default(),
        0.0,
        &mut out
    )
    .is_none());
    let mut broken = conditioned_matrix(8, &left, &right, 2.0, 1.0);
    broken[(3, 2)] = f64::NAN;
    assert!(solve_full_column_rank(&broken, &r, &RankPolicy::default(), 0.0, &mut out).is_none());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// The closed form for one- and two-row matrices against the SVD: where it answers, `A⁺e` and `‖A⁺A g‖` agree with
    /// the SVD's to `1e−11` (relative to `‖e‖/σ_min` and `‖g‖`); it answers for every well-conditioned matrix and for
    /// none whose second row is (nearly) a multiple of the first.
    #[test]
    fn small_full_row_rank_matches_the_svd(
        rows in 1usize..3,
        data in matrix_strategy::<6>(2),
        e in proptest::collection::vec(-1.0..1.0f64, 2),
        g in proptest::collection::vec(-1.0..1.0f64, 6),
        scale_exponent in -3.0..3.0f64,
        dependence in prop_oneof![Just(0.0), 1e-9..1e-3f64],
    ) {
        let mut a = data.rows(0, rows).into_owned() * 10f64.powf(scale_exponent);
        if rows == 2 && dependence > 0.0 {
            // Second row = first + a small perturbation: σ_min/σ_max ≈ dependence.
            let first = a.row(0).into_owned();
            let perturbation = a.row(1).into_owned() * dependence;
            a.set_row(1, &(first + perturbation));
        }
        let e = DVector::from_column_slice(&e[..rows]);
        let g = JointVector::<6>::from_column_slice(&g);
        let policy = RankPolicy::default();
        let mut fast = JointVector::<6>::zeros();
        let answer = solve_small_full_row_rank(&a, &e, &g, &policy, &mut fast);

        let mut svd = ColumnSvd::<6>::default();
        let mut work = a.clone();
        svd.decompose(&mut work, &policy).unwrap();
        let mut reference = JointVector::<6>::zeros();
        svd.solve(&work, &e, VelocityInverse::Truncated, &mut reference).unwrap();
        let component = svd.row_space_component_norm(&g);
        let singular = a.clone().svd(false, false).singular_values;
        let (sigma_max, sigma_min) = (singular.max(), singular.min());
        let well_conditioned = sigma_min * SMALL_PATH_CONDITION_BOUND > 1.01 * sigma_max;
        match answer {
            Some(fast_component) => {
                prop_assert!(sigma_min * SMALL_PATH_CONDITION_BOUND >= 0.99 * sigma_max);
                let tolerance = 1e-11 * (e.norm() / sigma_min + 1.0);
                prop_assert!((fast - reference).norm() <= tolerance, "{fast} vs {reference}");
                prop_assert!((fast_component - component).abs() <= 1e-11 * (g.norm() + 1.0));
            }
            None => prop_assert!(!well_conditioned, "σ = {sigma_min} .. {sigma_max}: no answer"),
        }
        if rows == 2 && dependence > 0.0 && dependence < 1e-3 / 2.0 {
            prop_assert!(answer.is_none());
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// A stack level of one or two rows in closed form against the SVD, on `J̃ = J P` with `P` the kernel projector of
    /// up to three random higher rows: where it answers, the step `J̃⁺r` and the updated projector `P − J̃⁺J̃` agree with
    /// the SVD's within `1e−12` (relative to `‖r‖/σ_min` and to 1); it answers for every `J̃` well conditioned and
    /// clear of the stack's rank threshold (taken against `‖J‖_F`), and for none that nearly repeats a higher row.
    #[test]
    fn small_stack_level_matches_the_svd(
        rows in 1usize..3,
        higher in 0usize..4,
        data in matrix_strategy::<6>(5),
        r in proptest::collection::vec(-1.0..1.0f64, 2),
        scale_exponent in -3.0..3.0f64,
        repeat in prop_oneof![Just(0.0), 1e-9..1e-2f64],
    ) {
        small_stack_level_case(rows, higher, &data, &r, scale_exponent, repeat)?;
    }
}

/// A case the property test drew (CI, 2026-11-24): a two-row level with `σ_max/σ_min` near the closed form's bound of
/// 100, where `J̃ᵀ G⁻¹ r` differed from the SVD's step by 1.5e−12 relative to `‖r‖/σ_min` (the Gram matrix's
/// `κ² ε`). Such a level is now solved on its orthonormalised rows.
#[test]
fn small_stack_level_near_its_condition_bound() {
    #[rustfmt::skip]
    let data = [
        -0.05400316187491307, 0.0, 0.0, -0.39391713018247715, -0.3063496069323168,
        0.6776333728847183, 0.0, 0.0, -0.5521455180567124, 0.67267562425311,
        0.5116143114569465, 0.0, 0.0, 0.9732363089450511, 0.5858384270152098,
        -0.03180147527318344, 0.0, 0.0, 0.11701828835453477, -0.037429620306119946,
        -0.9539495414044997, 0.0, 0.0, 0.6481908445055161, -0.24860501751427339,
        -0.5516326052398346, 0.0, 0.0, -0.7996199839652245, 0.0059766528860344635,
    ];
    // Column-major storage of a 5 × 6 matrix, as the strategy's `VecStorage`.
    let data = OMatrix::<f64, Dyn, Const<6>>::from_column_slice_generic(Dyn(5), Const::<6>, &data);
    let result = small_stack_level_case(
        2,
        1,
        &data,
        &[-0.7789892592286352, 0.0],
        -0.5641262746195611,
        0.004473792960606814,
    );
    assert!(result.is_ok(), "{result:?}");
}

/// The body of [`small_stack_level_matches_the_svd`], shared with its recorded failures.
fn small_stack_level_case(
    rows: usize,
    higher: usize,
    data: &OMatrix<f64, Dyn, Const<6>>,
    r: &[f64],
    scale_exponent: f64,
    repeat: f64,
) -> Result<(), TestCaseError> {
    let upper = data.rows(0, higher).into_owned();
    let mut work = upper.clone();
    let policy = RankPolicy::default();
    let projector = null_space_projector(&upper, &mut work, &policy).unwrap();
    let mut jacobian = data.rows(3, rows).into_owned() * 10f64.powf(scale_exponent);
    if higher > 0 && repeat > 0.0 {
        // The first row nearly repeats a higher one: J̃'s first row is then of size `repeat`.
        let nearly = upper.row(0) * 10f64.powf(scale_exponent) + jacobian.row(0) * repeat;
        jacobian.set_row(0, &nearly);
    }
    let limited = &jacobian * projector;
    let reference_scale = jacobian.norm();
    let r = DVector::from_column_slice(&r[..rows]);

    let mut step = JointVector::<6>::zeros();
    let mut updated = projector;
    let answer = solve_small_stack_level(
        &limited,
        &r,
        &policy,
        reference_scale,
        &mut step,
        Some(&mut updated),
    );

    let mut svd = ColumnSvd::<6>::default();
    let mut w = limited.clone();
    svd.decompose_with_scale(&mut w, &policy, reference_scale)
        .unwrap();
    let mut reference_step = JointVector::<6>::zeros();
    svd.solve(&w, &r, VelocityInverse::Truncated, &mut reference_step)
        .unwrap();
    let mut reference_projector = projector;
    svd.subtract_row_space_projector(&mut reference_projector);
    let singular = limited
        .clone()
        .transpose()
        .svd(false, false)
        .singular_values;
    let (sigma_max, sigma_min) = (singular.max(), singular.min());
    let clear = sigma_min * SMALL_PATH_CONDITION_BOUND > 1.01 * sigma_max
        && sigma_min > 2.01 * policy.threshold(sigma_max.max(reference_scale));
    match answer {
        Some(answered_sigma_min) => {
            prop_assert_eq!(svd.rank(), rows);
            prop_assert!((answered_sigma_min - sigma_min).abs() <= 1e-9 * sigma_min);
            let tolerance = 1e-12 * (r.norm() / sigma_min + 1.0);
            prop_assert!(
                (step - reference_step).norm() <= tolerance,
                "{step} vs {reference_step}"
            );
            let difference = (updated - reference_projector).amax();
            prop_assert!(difference <= 1e-12, "|P − P_svd| = {difference:e}");
            prop_assert_eq!(updated, updated.transpose());
        }
        None => {
            prop_assert!(!clear, "σ = {sigma_min} .. {sigma_max}: no answer");
            prop_assert_eq!(step, JointVector::<6>::zeros());
            prop_assert_eq!(updated, projector);
        }
    }
    if higher > 0 && repeat > 0.0 && repeat < 1e-7 {
        prop_assert!(answer.is_none());
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The row-by-row products of a stack level, `J P` and `J v`, are nalgebra's general products (summed in another
    /// order: equal to rounding), for any row count, including more rows than the output holds (only the common
    /// rows are written).
    #[test]
    fn row_products_match_the_general_products(
        rows in 1usize..10,
        a in matrix_strategy::<6>(10),
        b in matrix_strategy::<6>(6),
        v in proptest::collection::vec(-1.0..1.0f64, 6),
    ) {
        let a = a.rows(0, rows).into_owned();
        let b = SMatrix::<f64, 6, 6>::from_iterator(b.iter().copied());
        let v = nalgebra::SVector::<f64, 6>::from_column_slice(&v);
        let (expected, expected_v) = (&a * b, &a * v);
        let mut out = OMatrix::<f64, Dyn, Const<6>>::from_element(rows, f64::NAN);
        mul_rows_to(&a, &b, &mut out);
        prop_assert!((&out - &expected).amax() < 1e-14);
        let mut out = OMatrix::<f64, Dyn, Const<6>>::from_element(rows, f64::NAN);
        let mut out_v = DVector::from_element(rows, f64::NAN);
        mul_rows_and_vector_to(&a, &b, &v, &mut out, &mut out_v);
        prop_assert!((&out - &expected).amax() < 1e-14);
        prop_assert!((&out_v - &expected_v).amax() < 1e-14);
        // A shorter output: only its rows are written, from the first rows of `a`.
        let mut short = OMatrix::<f64, Dyn, Const<6>>::zeros(rows.div_ceil(2));
        let mut short_v = DVector::zeros(rows.div_ceil(2));
        mul_rows_and_vector_to(&a, &b, &v, &mut short, &mut short_v);
        prop_assert!((&short - expected.rows(0, short.nrows())).amax() < 1e-14);
        prop_assert!((&short_v - expected_v.rows(0, short.nrows())).amax() < 1e-14);
    }
}
