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
