//! Kinematics of the built-in robots: Jacobians against finite differences of the forward kinematics, the Afma6
//! against the peer scene's closed forms (docs/peer_scene.md), the UR5e against its DH product, cVe against camera motion.

use approx::assert_relative_eq;
use nalgebra::{
    Isometry3, Matrix3, Point3, Rotation3, SMatrix, Translation3, UnitQuaternion, Vector3,
};
use proptest::prelude::*;
use servostack::math::{JointVector, KinematicJacobian};
use servostack::robot::builtin::{self, BuiltinRobot, AFMA6_WRIST_OFFSET};
use servostack::robot::{JointKind, KinematicsWorkspace, RobotError, SerialChain};
use std::f64::consts::{FRAC_PI_2, PI};

const H: f64 = 1e-6;
const FD_TOL: f64 = 1e-6;

/// A configuration from unit-interval samples, inside the limits (continuous joints in [−π, π]).
fn config<const N: usize>(chain: &SerialChain<N>, unit: &[f64]) -> JointVector<N> {
    JointVector::from_fn(|i, _| {
        let (lo, hi) = (chain.lower_limits()[i], chain.upper_limits()[i]);
        let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (-PI, PI) };
        lo + (hi - lo) * unit[i]
    })
}

fn fk<const N: usize>(chain: &SerialChain<N>, q: &JointVector<N>) -> Isometry3<f64> {
    let mut ws = KinematicsWorkspace::new();
    *chain.kinematics(&mut ws, q).unwrap().base_from_tip()
}

/// Central differences of a pose along a joint-space direction: (ṗ in base, ω in base, ω in the pose's own frame).
fn pose_rates(pose: impl Fn(f64) -> Isometry3<f64>) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    let (plus, minus) = (pose(H), pose(-H));
    let linear = (plus.translation.vector - minus.translation.vector) / (2.0 * H);
    let angular_base = (plus.rotation * minus.rotation.inverse()).scaled_axis() / (2.0 * H);
    let angular_own = (minus.rotation.inverse() * plus.rotation).scaled_axis() / (2.0 * H);
    (linear, angular_base, angular_own)
}

/// Both Jacobians against central differences of the forward kinematics, column by column.
fn check_jacobians<const N: usize>(chain: &SerialChain<N>, q: &JointVector<N>) {
    let mut ws = KinematicsWorkspace::new();
    let state = chain.kinematics(&mut ws, q).unwrap();
    let tip_from_base = state.base_from_tip().rotation.inverse();
    for j in 0..N {
        let (linear, angular_base, angular_tip) = pose_rates(|h| {
            let mut qh = *q;
            qh[j] += h;
            fk(chain, &qh)
        });
        let base_col = state.base_jacobian().column(j);
        let tip_col = state.tip_jacobian().column(j);
        assert_relative_eq!(
            base_col.fixed_rows::<3>(0).into_owned(),
            linear,
            epsilon = FD_TOL
        );
        assert_relative_eq!(
            base_col.fixed_rows::<3>(3).into_owned(),
            angular_base,
            epsilon = FD_TOL
        );
        assert_relative_eq!(
            tip_col.fixed_rows::<3>(0).into_owned(),
            tip_from_base * linear,
            epsilon = FD_TOL
        );
        assert_relative_eq!(
            tip_col.fixed_rows::<3>(3).into_owned(),
            angular_tip,
            epsilon = FD_TOL
        );
    }
}

/// The camera twist `cVe · eJe · q̇` against central differences of the camera pose `base_from_tip · e_from_c`.
fn check_camera_twist<const N: usize>(
    robot: &BuiltinRobot<N>,
    q: &JointVector<N>,
    qdot: &JointVector<N>,
) {
    let mut ws = KinematicsWorkspace::new();
    let state = robot.chain.kinematics(&mut ws, q).unwrap();
    let twist = robot.mount.camera_jacobian(state.tip_jacobian()) * qdot;
    let base_from_camera = robot.mount.base_from_camera(state.base_from_tip());
    let (linear, _, angular_camera) = pose_rates(|h| {
        robot
            .mount
            .base_from_camera(&fk(&robot.chain, &(q + qdot * h)))
    });
    let camera_from_base = base_from_camera.rotation.inverse();
    assert_relative_eq!(
        twist.fixed_rows::<3>(0).into_owned(),
        camera_from_base * linear,
        epsilon = FD_TOL
    );
    assert_relative_eq!(
        twist.fixed_rows::<3>(3).into_owned(),
        angular_camera,
        epsilon = FD_TOL
    );
}

/// The point Jacobian of a point fixed on each link against central differences of the point's position.
fn check_point_jacobians<const N: usize>(
    chain: &SerialChain<N>,
    q: &JointVector<N>,
    local: &Point3<f64>,
) {
    let mut ws = KinematicsWorkspace::new();
    let state = chain.kinematics(&mut ws, q).unwrap().clone();
    for link in chain.links() {
        let point = state.base_from_link(link).unwrap() * local;
        let mut jac = SMatrix::<f64, 3, N>::from_element(f64::NAN);
        state.point_jacobian(link, &point, &mut jac).unwrap();
        for j in 0..N {
            let moved = |h: f64| {
                let mut qh = *q;
                qh[j] += h;
                let mut ws = KinematicsWorkspace::new();
                let s = chain.kinematics(&mut ws, &qh).unwrap();
                s.base_from_link(link).unwrap() * local
            };
            let fd = (moved(H) - moved(-H)) / (2.0 * H);
            assert_relative_eq!(jac.column(j).into_owned(), fd, epsilon = FD_TOL);
        }
    }
}

fn unit_samples(n: usize) -> impl Strategy<Value = Vec<f64>> {
    proptest::collection::vec(0.0..1.0f64, n)
}

fn direction(n: usize) -> impl Strategy<Value = Vec<f64>> {
    proptest::collection::vec(-1.0..1.0f64, n)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn afma6_jacobians_match_finite_differences(u in unit_samples(6), d in direction(6)) {
        let robot = builtin::afma6().unwrap();
        let q = config(&robot.chain, &u);
        check_jacobians(&robot.chain, &q);
        check_camera_twist(&robot, &q, &JointVector::from_column_slice(&d));
    }

    #[test]
    fn ur5e_jacobians_match_finite_differences(u in unit_samples(6), d in direction(6)) {
        let robot = builtin::ur5e().unwrap();
        let q = config(&robot.chain, &u);
        check_jacobians(&robot.chain, &q);
        check_camera_twist(&robot, &q, &JointVector::from_column_slice(&d));
    }

    #[test]
    fn rail7_jacobians_match_finite_differences(u in unit_samples(7), d in direction(7)) {
        let robot = builtin::rail7().unwrap();
        let q = config(&robot.chain, &u);
        check_jacobians(&robot.chain, &q);
        check_camera_twist(&robot, &q, &JointVector::from_column_slice(&d));
    }

    #[test]
    fn point_jacobians_match_finite_differences(
        u in unit_samples(7),
        p in proptest::collection::vec(-0.3..0.3f64, 3),
    ) {
        let local = Point3::new(p[0], p[1], p[2]);
        let rail7 = builtin::rail7().unwrap().chain;
        check_point_jacobians(&rail7, &config(&rail7, &u), &local);
        let afma6 = builtin::afma6().unwrap().chain;
        check_point_jacobians(&afma6, &config(&afma6, &u[..6]), &local);
    }

    /// The peer scene's closed forms with g = 0, for the URDF file and the built-in constructor.
    #[test]
    fn afma6_matches_the_closed_form(u in unit_samples(6)) {
        let from_file = SerialChain::<6>::from_urdf_file(
            concat!(env!("CARGO_MANIFEST_DIR"), "/assets/urdf/afma6.urdf"),
            "afma6_base",
            "afma6_end_effector",
        ).unwrap();
        let builtin = builtin::afma6().unwrap().chain;
        let q = config(&builtin, &u);
        let (f_from_e, e_j_e) = afma6_closed_form(&q, 0.0);
        for chain in [&from_file, &builtin] {
            let mut ws = KinematicsWorkspace::new();
            let state = chain.kinematics(&mut ws, &q).unwrap();
            assert_relative_eq!(state.base_from_tip().to_homogeneous(), f_from_e.to_homogeneous(), epsilon = 1e-12);
            assert_relative_eq!(*state.tip_jacobian(), e_j_e, epsilon = 1e-12);
        }
    }

    /// The Afma6 with ViSP's coupling (a mimic joint) against the peer scene's closed forms with g = 0.009091, at
    /// random configurations: `fMe`, `eJe` and the camera twist.
    #[test]
    fn afma6_coupled_matches_the_coupled_closed_form(u in unit_samples(6), d in direction(6)) {
        let robot = builtin::afma6_coupled().unwrap();
        let q = config(&robot.chain, &u);
        let (f_from_e, e_j_e) = afma6_closed_form(&q, 0.009091);
        let mut ws = KinematicsWorkspace::new();
        let state = robot.chain.kinematics(&mut ws, &q).unwrap();
        assert_relative_eq!(state.base_from_tip().to_homogeneous(), f_from_e.to_homogeneous(), epsilon = 1e-12);
        assert_relative_eq!(*state.tip_jacobian(), e_j_e, epsilon = 1e-12);
        check_jacobians(&robot.chain, &q);
        check_camera_twist(&robot, &q, &JointVector::from_column_slice(&d));
    }

    /// Point Jacobians of links beyond a mimic joint (the coupled Afma6's end effector and camera) against finite
    /// differences.
    #[test]
    fn point_jacobians_beyond_a_mimic_joint_match_finite_differences(
        u in unit_samples(6),
        p in proptest::collection::vec(-0.3..0.3f64, 3),
    ) {
        let chain = builtin::afma6_coupled().unwrap().chain;
        assert!(!chain.link("afma6_end_effector").unwrap().mimics().is_empty());
        check_point_jacobians(&chain, &config(&chain, &u), &Point3::new(p[0], p[1], p[2]));
    }

    /// The UR5e against the product of its standard DH transforms.
    #[test]
    fn ur5e_matches_the_dh_product(u in unit_samples(6)) {
        let chain = builtin::ur5e().unwrap().chain;
        let q = config(&chain, &u);
        let d = [0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996];
        let a = [0.0, -0.425, -0.3922, 0.0, 0.0, 0.0];
        let alpha = [FRAC_PI_2, 0.0, 0.0, FRAC_PI_2, -FRAC_PI_2, 0.0];
        let mut expected = nalgebra::Matrix4::identity();
        for i in 0..6 {
            let (ct, st) = (q[i].cos(), q[i].sin());
            let (ca, sa) = (alpha[i].cos(), alpha[i].sin());
            #[rustfmt::skip]
            let link = nalgebra::Matrix4::new(
                ct, -st * ca,  st * sa, a[i] * ct,
                st,  ct * ca, -ct * sa, a[i] * st,
                0.0,     sa,       ca,      d[i],
                0.0,    0.0,      0.0,       1.0,
            );
            expected *= link;
        }
        assert_relative_eq!(fk(&chain, &q).to_homogeneous(), expected, epsilon = 1e-12);
    }
}

/// ViSP's Afma6 `fMe` and `eJe` (docs/peer_scene.md), coded from the closed forms, with coupling `g`.
fn afma6_closed_form(q: &JointVector<6>, g: f64) -> (Isometry3<f64>, KinematicJacobian<6>) {
    let l = AFMA6_WRIST_OFFSET;
    let (s1, c1) = q[3].sin_cos();
    let (s2, c2) = q[4].sin_cos();
    let (s3, c3) = (q[5] - g * q[4]).sin_cos();
    #[rustfmt::skip]
    let r = Matrix3::new(
        s1 * s2 * c3 + c1 * s3,  -s1 * s2 * s3 + c1 * c3, -s1 * c2,
        -c1 * s2 * c3 + s1 * s3,  c1 * s2 * s3 + s1 * c3,  c1 * c2,
        c2 * c3,                 -c2 * s3,                 s2,
    );
    let t = Vector3::new(q[0] + l * c1, q[1] + l * s1, q[2]);
    let pose = Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r)),
    );
    #[rustfmt::skip]
    let jac = KinematicJacobian::<6>::from_row_slice(&[
        s1 * s2 * c3 + c1 * s3,  -c1 * s2 * c3 + s1 * s3,  c2 * c3, -l * s2 * c3, 0.0, 0.0,
        -s1 * s2 * s3 + c1 * c3,  c1 * s2 * s3 + s1 * c3, -c2 * s3,  l * s2 * s3, 0.0, 0.0,
        -s1 * c2,                 c1 * c2,                 s2,       l * c2,      0.0, 0.0,
        0.0,                      0.0,                     0.0,      c2 * c3,     s3,  0.0,
        0.0,                      0.0,                     0.0,     -c2 * s3,     c3,  0.0,
        0.0,                      0.0,                     0.0,      s2,          -g,  1.0,
    ]);
    (pose, jac)
}

#[test]
fn afma6_limits_names_and_camera_mount_are_those_of_peer_scene() {
    let robot = builtin::afma6().unwrap();
    let lower = JointVector::<6>::from_column_slice(&[
        -0.6501, -0.6001, -0.5001, -2.7301, -0.1001, -1.5901,
    ]);
    let upper =
        JointVector::<6>::from_column_slice(&[0.7001, 0.5201, 0.4601, 2.7301, 2.4801, 1.5901]);
    assert_eq!(robot.chain.lower_limits(), &lower);
    assert_eq!(robot.chain.upper_limits(), &upper);
    let kinds: Vec<_> = robot.chain.joints().iter().map(|j| j.kind()).collect();
    use JointKind::{Prismatic as P, Revolute as R};
    assert_eq!(kinds, [P, P, P, R, R, R]);
    #[rustfmt::skip]
    let e_from_c = nalgebra::Matrix4::new(
        0.0018317693203412728, 0.006010201265265396, 0.9999802608561371, 0.0117,
        0.9997410569356338, -0.02269242709552799, -0.0016949423990506207, 0.0033,
        0.02268179222149358, 0.9997244276465715, -0.00605021225708998, 0.2272,
        0.0, 0.0, 0.0, 1.0,
    );
    assert_relative_eq!(
        robot.mount.e_from_c().to_homogeneous(),
        e_from_c,
        epsilon = 1e-12
    );
    // cVe is the twist transform of cMe = eMc⁻¹, [M43], written out here from its blocks.
    let c_from_e = e_from_c.try_inverse().unwrap();
    let rot = c_from_e.fixed_view::<3, 3>(0, 0).into_owned();
    let t = c_from_e.fixed_view::<3, 1>(0, 3).into_owned();
    let c_v_e = robot.mount.c_v_e();
    assert_relative_eq!(
        c_v_e.fixed_view::<3, 3>(0, 0).into_owned(),
        rot,
        epsilon = 1e-12
    );
    assert_relative_eq!(
        c_v_e.fixed_view::<3, 3>(0, 3).into_owned(),
        t.cross_matrix() * rot,
        epsilon = 1e-12
    );
    assert_relative_eq!(
        c_v_e.fixed_view::<3, 3>(3, 3).into_owned(),
        rot,
        epsilon = 1e-12
    );
    assert_eq!(
        c_v_e.fixed_view::<3, 3>(3, 0).into_owned(),
        Matrix3::zeros()
    );
}

/// The ignored coupling matters: with ViSP's g the closed form differs from the model (so the test above is not
/// vacuous about which g it checks).
#[test]
fn afma6_model_differs_from_the_coupled_closed_form() {
    let chain = builtin::afma6().unwrap().chain;
    let q = JointVector::<6>::new(0.1, -0.1, 0.2, 0.4, 1.2, -0.3);
    let (coupled, _) = afma6_closed_form(&q, builtin::AFMA6_COUPLING);
    let diff = (fk(&chain, &q).to_homogeneous() - coupled.to_homogeneous())
        .abs()
        .max();
    assert!(diff > 1e-3, "{diff}");
}

/// A hand-computed chain: base –fixed (0,0,1)→ revolute z at (1,0,0) → prismatic x → fixed (0.5,0,0) → tip.
#[test]
fn fixed_joints_fold_into_a_hand_computed_pose() {
    let xml = r#"<robot name="hand">
      <link name="base"/><link name="riser"/><link name="arm"/><link name="slide"/><link name="tip"/>
      <joint name="riser_joint" type="fixed"><parent link="base"/><child link="riser"/><origin xyz="0 0 1"/></joint>
      <joint name="turn" type="revolute"><parent link="riser"/><child link="arm"/><origin xyz="1 0 0"/>
        <axis xyz="0 0 3"/><limit lower="-3" upper="3" effort="0" velocity="1"/></joint>
      <joint name="push" type="prismatic"><parent link="arm"/><child link="slide"/>
        <axis xyz="1 0 0"/><limit lower="0" upper="1" effort="0" velocity="1"/></joint>
      <joint name="tip_joint" type="fixed"><parent link="slide"/><child link="tip"/><origin xyz="0.5 0 0"/></joint>
    </robot>"#;
    let chain = SerialChain::<2>::from_urdf_str(xml, "base", "tip").unwrap();
    let pose = fk(&chain, &JointVector::<2>::new(FRAC_PI_2, 0.2));
    assert_relative_eq!(
        pose.translation.vector,
        Vector3::new(1.0, 0.7, 1.0),
        epsilon = 1e-15
    );
    assert_relative_eq!(
        pose.rotation,
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), FRAC_PI_2),
        epsilon = 1e-15
    );
    let names: Vec<_> = chain
        .links()
        .iter()
        .map(|l| (l.name(), l.moved_by()))
        .collect();
    assert_eq!(
        names,
        [
            ("base", None),
            ("riser", None),
            ("arm", Some(0)),
            ("slide", Some(1)),
            ("tip", Some(1))
        ]
    );
    assert_eq!(chain.joints()[0].child_link(), "arm");
    // Hand Jacobian at that pose: turning moves the tip (at 0.7 from the axis, along y) towards −x.
    let mut ws = KinematicsWorkspace::new();
    let state = chain
        .kinematics(&mut ws, &JointVector::<2>::new(FRAC_PI_2, 0.2))
        .unwrap();
    #[rustfmt::skip]
    let expected = KinematicJacobian::<2>::from_row_slice(&[
        -0.7, 0.0,
        0.0, 1.0,
        0.0, 0.0,
        0.0, 0.0,
        0.0, 0.0,
        1.0, 0.0,
    ]);
    assert_relative_eq!(*state.base_jacobian(), expected, epsilon = 1e-15);
}

#[test]
fn rail7_is_generic_in_n_with_a_continuous_joint() {
    let robot = builtin::rail7().unwrap();
    let names: Vec<_> = robot.chain.joints().iter().map(|j| j.name()).collect();
    assert_eq!(
        names,
        [
            "rail7_rail",
            "rail7_turret_joint",
            "rail7_shoulder_joint",
            "rail7_slide_joint",
            "rail7_roll_joint",
            "rail7_pitch_joint",
            "rail7_wrist_joint"
        ]
    );
    assert_eq!(robot.chain.joints()[4].kind(), JointKind::Continuous);
    assert_eq!(robot.chain.lower_limits()[4], f64::NEG_INFINITY);
    assert_eq!(robot.chain.upper_limits()[4], f64::INFINITY);
    let s = 0.5f64.sqrt();
    assert_relative_eq!(
        robot.chain.joints()[2].axis().into_inner(),
        Vector3::new(0.0, s, s),
        epsilon = 1e-15
    );
    // Every URDF link from base to tip, each tagged with the joint that carries it.
    assert_eq!(robot.chain.links().len(), 11);
    assert_eq!(robot.chain.link("rail7_cover").unwrap().moved_by(), Some(4));
    assert_eq!(robot.chain.link("rail7_mount").unwrap().moved_by(), Some(0));
    // The tip link's pose is the chain's tip pose.
    let q = JointVector::<7>::from_column_slice(&[0.3, -1.0, 0.5, 0.1, 2.0, -0.4, 1.1]);
    let mut ws = KinematicsWorkspace::new();
    let state = robot.chain.kinematics(&mut ws, &q).unwrap();
    let tip = robot.chain.link("rail7_tool").unwrap();
    assert_eq!(&state.base_from_link(tip).unwrap(), state.base_from_tip());
}

#[test]
fn by_name_finds_each_builtin_and_checks_the_joint_count() {
    assert_eq!(
        builtin::by_name::<6>("afma6").unwrap(),
        builtin::afma6().unwrap()
    );
    assert_eq!(
        builtin::by_name::<6>("ur5e").unwrap().chain.tip_link(),
        "tool0"
    );
    assert_eq!(builtin::by_name::<7>("rail7").unwrap().name, "rail7");
    assert_eq!(
        builtin::by_name::<7>("afma6").unwrap_err(),
        RobotError::JointCount {
            expected: 7,
            found: 6
        }
    );
    assert!(
        matches!(builtin::by_name::<6>("puma560"), Err(RobotError::UnknownRobot { name, .. }) if name == "puma560")
    );
}

#[test]
fn non_finite_joint_positions_are_rejected() {
    let chain = builtin::afma6().unwrap().chain;
    let mut ws = KinematicsWorkspace::new();
    let q = JointVector::<6>::new(0.0, 0.0, f64::NAN, 0.0, 0.0, 0.0);
    assert!(
        matches!(chain.kinematics(&mut ws, &q), Err(RobotError::NonFiniteJoint { index: 2, value }) if value.is_nan())
    );
    let q = JointVector::<6>::new(0.0, 0.0, 0.0, 0.0, f64::INFINITY, 0.0);
    assert_eq!(
        chain.kinematics(&mut ws, &q).unwrap_err(),
        RobotError::NonFiniteJoint {
            index: 4,
            value: f64::INFINITY
        }
    );
    // The pose-only pass checks its input the same way.
    assert_eq!(
        chain.tip_pose(&mut ws, &q).unwrap_err(),
        RobotError::NonFiniteJoint {
            index: 4,
            value: f64::INFINITY
        }
    );
}

#[test]
fn a_link_of_a_longer_chain_is_rejected_by_link_queries() {
    let afma6 = builtin::afma6().unwrap().chain;
    let rail7 = builtin::rail7().unwrap().chain;
    let mut ws = KinematicsWorkspace::new();
    let state = afma6.kinematics(&mut ws, &JointVector::zeros()).unwrap();
    let last = rail7.links().last().unwrap();
    let err = RobotError::JointIndexOutOfRange {
        index: 6,
        joints: 6,
    };
    assert_eq!(state.base_from_link(last).unwrap_err(), err);
    let mut out = SMatrix::<f64, 3, 6>::zeros();
    assert_eq!(
        state
            .point_jacobian(last, &Point3::origin(), &mut out)
            .unwrap_err(),
        err
    );
}

/// Mimic joints of both kinds after the independent ones, one mimicking the other: the multipliers and offsets
/// compose (θ_m2 = 3 (0.5 q1 + 0.01) + 0.2 = 1.5 q1 + 0.23), and the Jacobians, tip and point, match finite
/// differences of the forward kinematics.
#[test]
fn chained_mimic_joints_of_both_kinds_match_finite_differences() {
    let xml = r#"<robot name="fingers">
      <link name="base"/><link name="l1"/><link name="l2"/><link name="f1"/><link name="f2"/><link name="tip"/>
      <joint name="j0" type="revolute"><parent link="base"/><child link="l1"/>
        <origin xyz="0 0 0.3" rpy="0.1 0 0"/><axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="0" velocity="1"/></joint>
      <joint name="j1" type="prismatic"><parent link="l1"/><child link="l2"/>
        <origin xyz="0.2 0 0" rpy="0 0.3 0"/><axis xyz="1 0 0"/><limit lower="-0.1" upper="0.1" effort="0" velocity="1"/></joint>
      <joint name="m1" type="prismatic"><parent link="l2"/><child link="f1"/>
        <origin xyz="0 0.05 0" rpy="0 0 0.4"/><axis xyz="0 1 0"/><limit lower="0" upper="0.04" effort="0" velocity="1"/>
        <mimic joint="j1" multiplier="0.5" offset="0.01"/></joint>
      <joint name="m2" type="revolute"><parent link="f1"/><child link="f2"/>
        <origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="1 1 0"/><limit lower="-1" upper="1" effort="0" velocity="1"/>
        <mimic joint="m1" multiplier="3" offset="0.2"/></joint>
      <joint name="tool" type="fixed"><parent link="f2"/><child link="tip"/><origin xyz="0.03 0 0.02" rpy="0 0 0"/></joint>
    </robot>"#;
    let chain = SerialChain::<2>::from_urdf_str(xml, "base", "tip").unwrap();
    let mimics = chain.mimic_joints();
    assert_eq!(
        (
            mimics[0].leader(),
            mimics[0].multiplier(),
            mimics[0].offset()
        ),
        (1, 0.5, 0.01)
    );
    assert_eq!(mimics[1].leader(), 1);
    assert_relative_eq!(mimics[1].multiplier(), 1.5, epsilon = 1e-15);
    assert_relative_eq!(mimics[1].offset(), 0.23, epsilon = 1e-15);
    // The tip pose by hand at q = (0, 0.02): j1 slides 0.02 along its x axis, m1 0.02 along its y axis, m2 turns
    // 0.26 rad about (1,1,0)/√2.
    let q = JointVector::<2>::new(0.0, 0.02);
    let base_from_l2 = Isometry3::new(Vector3::new(0.0, 0.0, 0.3), Vector3::new(0.1, 0.0, 0.0))
        * Isometry3::new(Vector3::new(0.2, 0.0, 0.0), Vector3::new(0.0, 0.3, 0.0))
        * Translation3::new(0.02, 0.0, 0.0);
    let l2_from_f1 = Isometry3::from_parts(
        Translation3::new(0.0, 0.05, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, 0.4),
    ) * Translation3::new(0.0, 0.02, 0.0);
    let f1_from_f2 = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, 0.1),
        UnitQuaternion::from_axis_angle(
            &nalgebra::Unit::new_normalize(Vector3::new(1.0, 1.0, 0.0)),
            0.26,
        ),
    );
    let expected = base_from_l2 * l2_from_f1 * f1_from_f2 * Translation3::new(0.03, 0.0, 0.02);
    assert_relative_eq!(
        fk(&chain, &q).to_homogeneous(),
        expected.to_homogeneous(),
        epsilon = 1e-12
    );
    for q in [
        JointVector::<2>::new(0.7, -0.05),
        JointVector::<2>::new(-1.3, 0.08),
    ] {
        check_jacobians(&chain, &q);
        check_point_jacobians(&chain, &q, &Point3::new(0.01, -0.02, 0.03));
    }
}
