//! Obstacle and visibility costs: gradients against central finite differences, exact zeros outside the influence
//! zone and inside the image margin, hand-computed values, bad input.

use crate::obstacle_fixture as fixture;

use approx::assert_relative_eq;
use nalgebra::{Isometry3, Point3, Vector1, Vector3};
use proptest::prelude::*;
use servostack::avoidance::{
    Collider, CompositeCost, Cost, CostError, Geometry, JointLimits, LinkColliders, Obstacle,
    ObstacleCost, ObstaclePair, VisibilityCost,
};
use servostack::camera::{CameraIntrinsics, EyeInHand};
use servostack::math::JointVector;
use servostack::robot::{builtin, SerialChain};

/// Max over joints of |central difference − analytic| / (1 + |analytic|).
fn gradient_error<const N: usize>(cost: &impl Cost<N>, q: &JointVector<N>, step: f64) -> f64 {
    let mut analytic = JointVector::<N>::zeros();
    cost.value_and_gradient(q, &mut analytic).unwrap();
    (0..N)
        .map(|i| {
            let (mut plus, mut minus) = (*q, *q);
            plus[i] += step;
            minus[i] -= step;
            let numeric = (cost.value(&plus).unwrap() - cost.value(&minus).unwrap()) / (2.0 * step);
            (numeric - analytic[i]).abs() / (1.0 + analytic[i].abs())
        })
        .fold(0.0, f64::max)
}

fn perturbed(s: &[f64]) -> JointVector<6> {
    let amplitude = [0.05, 0.05, 0.05, 0.2, 0.2, 0.2];
    fixture::reference_q() + JointVector::<6>::from_fn(|i, _| amplitude[i] * s[i])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// ∇h = Σ (δ/d_i) J_pᵀ n matches central differences wherever the shapes are apart and the cost is active, for
    /// the shapes on which parry's distance is exact (spheres, boxes, capsules). The cost is C¹ but not C² (the
    /// curvature of a box distance jumps across face and edge regions, and the cost is cut at the influence
    /// distance), so within a step of such a transition central differences are accurate to O(h), not O(h²): with
    /// h = 1e−6 the tolerance is 1e−5 (a wrong normal or Jacobian is off by O(1); 3.4e−6 was seen at h = 1e−5).
    #[test]
    fn obstacle_gradient_matches_finite_differences(s in proptest::collection::vec(-1.0..1.0f64, 6)) {
        let cost = fixture::obstacle_cost_of(0.15, false);
        let q = perturbed(&s);
        let closest = cost.closest_pair(&q).unwrap().unwrap();
        prop_assume!(closest.distance > 0.005 && closest.distance < 0.15);
        prop_assert!(cost.value(&q).unwrap() > 0.0);
        let error = gradient_error(&cost, &q, 1e-6);
        prop_assert!(error < 1e-5, "relative gradient error {error} at q = {q:?}");
    }

    /// With cylinders too, to the accuracy of parry's GJK normal on a cylinder's curved side: over ~800 random
    /// configurations the relative error was mostly below 3e−3 with one case at 1.75e−2, hence 5e−2. The gradient
    /// formula is the same as for exact shapes (tested above to 1e−5); this guards the cylinder path against sign or
    /// Jacobian errors, which are off by O(1). GJK's distance to the curved side is also noisy in its last digits:
    /// at one configuration (joint 2's central difference) it gave 0.17, −1.21 and −4.28 with steps 1e−3, 1e−5 and
    /// 1e−6 against an analytic −0.86, which 1e−7 reproduces to 1e−4. So the best of three steps is compared: noise
    /// spoils one step, a wrong gradient every step.
    #[test]
    fn obstacle_gradient_with_cylinders_matches_finite_differences(s in proptest::collection::vec(-1.0..1.0f64, 6)) {
        let cost = fixture::obstacle_cost(0.15);
        let q = perturbed(&s);
        let closest = cost.closest_pair(&q).unwrap().unwrap();
        prop_assume!(closest.distance > 0.005 && closest.distance < 0.15);
        let error = [1e-3, 1e-4, 1e-5]
            .map(|step| gradient_error(&cost, &q, step))
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        prop_assert!(error < 5e-2, "relative gradient error {error} at q = {q:?}");
    }

    /// D27: the facing term's gradient, `−δ R_bcᵀ (n − cos θ d̂)/‖d‖` through the linear rows of `cVe eJe`, matches
    /// central differences wherever the term is active (the image term off: no margin).
    #[test]
    fn facing_gradient_matches_finite_differences(s in proptest::collection::vec(-1.0..1.0f64, 6)) {
        let cost = afma6_visibility_facing(0.0, Some(2.0));
        let q = perturbed(&s);
        prop_assume!(cost.value(&q).unwrap() > 0.0);
        let error = gradient_error(&cost, &q, 1e-6);
        prop_assert!(error < 1e-6, "relative gradient error {error} at q = {q:?}");
    }

    /// ∇h through L_x cVe eJe matches central differences, with points in the active band.
    #[test]
    fn visibility_gradient_matches_finite_differences(s in proptest::collection::vec(-1.0..1.0f64, 6)) {
        let cost = afma6_visibility(170.0);
        let q = perturbed(&s);
        prop_assume!(cost.value(&q).unwrap() > 0.0);
        let error = gradient_error(&cost, &q, 1e-6);
        prop_assert!(error < 1e-6, "relative gradient error {error} at q = {q:?}");
    }
}

/// The Afma6 camera looking at a 0.2 × 0.1 m rectangle 0.5 m ahead at the reference configuration, with a large
/// margin so that the points fall in the active band near it.
fn afma6_visibility(margin_px: f64) -> VisibilityCost<6> {
    afma6_visibility_facing(margin_px, None)
}

/// [`afma6_visibility`], with the facing term of D27 active beyond `facing_deg` when given: the rectangle's centre
/// 0.5 m ahead, its front normal back towards the camera of the reference configuration.
fn afma6_visibility_facing(margin_px: f64, facing_deg: Option<f64>) -> VisibilityCost<6> {
    let robot = builtin::afma6().unwrap();
    let mut workspace = servostack::robot::KinematicsWorkspace::new();
    let state = robot
        .chain
        .kinematics(&mut workspace, &fixture::reference_q())
        .unwrap();
    let base_from_camera = robot.mount.base_from_camera(state.base_from_tip());
    let points: Vec<Point3<f64>> = [(-0.1, -0.05), (0.1, -0.05), (0.1, 0.05), (-0.1, 0.05)]
        .iter()
        .map(|&(x, y)| base_from_camera * Point3::new(x, y, 0.5))
        .collect();
    let intrinsics = CameraIntrinsics::new(800.0, 800.0, 320.0, 240.0, 640.0, 480.0).unwrap();
    let cost =
        VisibilityCost::new(robot.chain, robot.mount, &intrinsics, &points, margin_px).unwrap();
    match facing_deg {
        None => cost,
        Some(activation) => cost
            .with_facing(
                base_from_camera * Point3::new(0.0, 0.0, 0.5),
                base_from_camera.rotation * Vector3::new(0.0, 0.0, -2.0),
                activation,
            )
            .unwrap(),
    }
}

/// D27 facing term: at the reference configuration the camera sees the rectangle head-on (θ = 0), so the term is zero
/// even when active from 0°. With joint 0 (prismatic) moved by 0.1 m, the optical centre is displaced in the base frame
/// and the value is ½ (cos θ_a − cos θ)², θ computed from that displacement and the head-on geometry; zero when active
/// only beyond θ. Bad arguments are refused.
#[test]
fn facing_term_value_and_bad_arguments() {
    let q = fixture::reference_q();
    let head_on = afma6_visibility_facing(0.0, Some(0.0));
    assert_eq!(head_on.value(&q).unwrap(), 0.0);
    // Moving joint 0 (prismatic) moves the optical centre by Δ in the base frame; the incidence is then the angle
    // between the normal (back along the optical axis) and the centre-to-camera vector d = −0.5 z_c + Δ.
    let robot = builtin::afma6().unwrap();
    let mut workspace = servostack::robot::KinematicsWorkspace::new();
    let camera_at =
        |q: &JointVector<6>, workspace: &mut servostack::robot::KinematicsWorkspace<6>| {
            let state = robot.chain.kinematics(workspace, q).unwrap();
            robot.mount.base_from_camera(state.base_from_tip())
        };
    let reference = camera_at(&q, &mut workspace);
    let mut moved = q;
    moved[0] += 0.1;
    let shifted = camera_at(&moved, &mut workspace);
    let centre = reference * Point3::new(0.0, 0.0, 0.5);
    let d = shifted.translation.vector - centre.coords;
    let normal = reference.rotation * Vector3::new(0.0, 0.0, -1.0);
    let cos = normal.dot(&d) / d.norm();
    assert!(cos < 0.99, "the move turns the view: cos θ = {cos}");
    // The image term stays zero: every point still inside the image.
    assert_eq!(afma6_visibility(0.0).value(&moved).unwrap(), 0.0);
    for activation_deg in [0.0, 10.0] {
        let expected = 0.5
            * (f64::to_radians(activation_deg).cos() - cos)
                .max(0.0)
                .powi(2);
        let cost = afma6_visibility_facing(0.0, Some(activation_deg));
        assert_relative_eq!(cost.value(&moved).unwrap(), expected, max_relative = 1e-12);
    }
    // Past the angle only: active from 89°, the same view costs nothing.
    assert_eq!(
        afma6_visibility_facing(0.0, Some(89.0))
            .value(&moved)
            .unwrap(),
        0.0
    );
    let base = afma6_visibility(0.0);
    let centre = Point3::new(0.0, 0.0, 0.0);
    let normal = Vector3::new(0.0, 0.0, 1.0);
    for (centre, normal, angle) in [
        (centre, normal, 180.0),
        (centre, normal, -1.0),
        (centre, normal, f64::NAN),
        (centre, Vector3::zeros(), 10.0),
        (centre, Vector3::new(f64::NAN, 0.0, 1.0), 10.0),
        (Point3::new(f64::INFINITY, 0.0, 0.0), normal, 10.0),
    ] {
        assert!(matches!(
            base.clone().with_facing(centre, normal, angle),
            Err(CostError::InvalidFacing { .. })
        ));
    }
}

#[test]
fn obstacle_cost_is_exactly_zero_beyond_the_influence_distance() {
    let q = fixture::reference_q();
    let near = fixture::obstacle_cost(0.15);
    let closest = near.closest_pair(&q).unwrap().unwrap().distance;
    assert!(closest > 0.0 && closest < 0.15, "closest {closest}");
    assert!(near.value(&q).unwrap() > 0.0);
    // With an influence distance just below the smallest distance, nothing is active: exact zeros.
    let far = fixture::obstacle_cost(closest * 0.999);
    let mut gradient = JointVector::<6>::repeat(1.0);
    assert_eq!(far.value_and_gradient(&q, &mut gradient).unwrap(), 0.0);
    assert_eq!(gradient, JointVector::<6>::zeros());
}

#[test]
fn visibility_cost_is_exactly_zero_inside_the_margin() {
    let cost = afma6_visibility(20.0);
    let mut gradient = JointVector::<6>::repeat(1.0);
    assert_eq!(
        cost.value_and_gradient(&fixture::reference_q(), &mut gradient)
            .unwrap(),
        0.0
    );
    assert_eq!(gradient, JointVector::<6>::zeros());
    // The corners are 160 px from the centre along u (480 px of 640) and 80 px along v (320 of 480): inside a 150 px
    // margin, within a 170 px one.
    assert_eq!(
        afma6_visibility(150.0)
            .value(&fixture::reference_q())
            .unwrap(),
        0.0
    );
    assert!(
        afma6_visibility(170.0)
            .value(&fixture::reference_q())
            .unwrap()
            > 0.0
    );
}

/// One prismatic joint along x carrying a ball of radius 0.1 and a camera looking along z.
const SLIDER: &str = r#"<robot name="slider">
  <link name="base"/>
  <link name="cart"><collision><geometry><sphere radius="0.1"/></geometry></collision></link>
  <link name="mast"/>
  <joint name="slide" type="prismatic">
    <parent link="base"/><child link="cart"/><axis xyz="1 0 0"/>
    <limit lower="-2" upper="2" effort="0" velocity="1"/>
  </joint>
  <joint name="mount" type="fixed"><parent link="cart"/><child link="mast"/><origin xyz="0 0 0.2"/></joint>
</robot>"#;

fn slider() -> SerialChain<1> {
    SerialChain::from_urdf_str(SLIDER, "base", "cart").unwrap()
}

/// d = 1 − q − 0.2 between the cart ball and a ball of radius 0.1 at x = 1; with d_i = 0.2 at q = 0.65:
/// δ = 0.05, h = ½ δ²/d_i = 0.00625, ∂h/∂q = −(δ/d_i) ∂d/∂q = 0.25.
#[test]
fn hand_computed_obstacle_cost() {
    let chain = slider();
    let links = LinkColliders::from_urdf_str(SLIDER, &chain).unwrap();
    let ball = Obstacle::new(
        "ball",
        Geometry::Sphere { radius_m: 0.1 },
        Isometry3::translation(1.0, 0.0, 0.0),
    )
    .unwrap();
    let pair = ObstaclePair {
        link: "cart".into(),
        obstacle: "ball".into(),
        influence_distance: 0.2,
    };
    let cost = ObstacleCost::new(chain, &links, vec![ball], &[pair]).unwrap();
    let mut gradient = Vector1::zeros();
    let h = cost
        .value_and_gradient(&Vector1::new(0.65), &mut gradient)
        .unwrap();
    assert_relative_eq!(h, 0.00625, epsilon = 1e-12);
    assert_relative_eq!(gradient[0], 0.25, epsilon = 1e-9);
    let closest = cost.closest_pair(&Vector1::new(0.65)).unwrap().unwrap();
    assert_eq!((closest.link, closest.obstacle), ("cart", "ball"));
    assert_relative_eq!(closest.distance, 0.15, epsilon = 1e-12);
    // Penetrating by 0.05: the signed distance is negative and the cost keeps growing.
    let inside = Vector1::new(0.85);
    assert_relative_eq!(
        cost.closest_pair(&inside).unwrap().unwrap().distance,
        -0.05,
        epsilon = 1e-9
    );
    assert_relative_eq!(
        cost.value(&inside).unwrap(),
        0.5 * 0.25 * 0.25 / 0.2,
        epsilon = 1e-9
    );
    assert_eq!(cost.value(&Vector1::new(0.4)).unwrap(), 0.0); // d = 0.4 > d_i
}

/// A camera on the slider looking along z at a point (0.5, 0, 1): x = 0.5 − q. With f = 100 px, c = 50 px, a 100 px
/// image and a 10 px margin, x̃_max = 0.4 and Δx = 1: at q = 0, δ = 0.1, h = ½ δ²/Δx = 0.005, ∂h/∂q = −0.1.
#[test]
fn hand_computed_visibility_cost() {
    let intrinsics = CameraIntrinsics::new(100.0, 100.0, 50.0, 50.0, 100.0, 100.0).unwrap();
    let camera = EyeInHand::new(Isometry3::identity()).unwrap();
    let cost = VisibilityCost::new(
        slider(),
        camera,
        &intrinsics,
        &[Point3::new(0.5, 0.0, 1.0)],
        10.0,
    )
    .unwrap();
    let mut gradient = Vector1::zeros();
    let h = cost
        .value_and_gradient(&Vector1::new(0.0), &mut gradient)
        .unwrap();
    assert_relative_eq!(h, 0.005, epsilon = 1e-12);
    assert_relative_eq!(gradient[0], -0.1, epsilon = 1e-12);
    assert_eq!(cost.value(&Vector1::new(0.15)).unwrap(), 0.0); // x = 0.35 < 0.4
                                                               // The camera moved past the point's plane side: the point is behind it.
    let behind = VisibilityCost::new(
        slider(),
        camera,
        &intrinsics,
        &[Point3::new(0.0, 0.0, -1.0)],
        10.0,
    )
    .unwrap();
    assert!(matches!(
        behind.value(&Vector1::new(0.0)),
        Err(CostError::PointBehindCamera { point: 0, .. })
    ));
}

/// The sum's gradient is the sum of the gradients, and its dominant term is named.
#[test]
fn composite_of_limits_obstacles_and_visibility() {
    let robot = builtin::afma6().unwrap();
    let limits = JointLimits::new(
        *robot.chain.lower_limits(),
        *robot.chain.upper_limits(),
        0.1,
    )
    .unwrap();
    let obstacles = fixture::obstacle_cost(0.15);
    let visibility = afma6_visibility(170.0);
    let sum = CompositeCost::new()
        .with(&limits)
        .with(&obstacles)
        .with(&visibility);
    assert_eq!(
        sum.term_names().collect::<Vec<_>>(),
        ["joint_limits", "obstacles", "visibility"]
    );
    let q = fixture::reference_q();
    assert_eq!(
        sum.term_values(&q, &mut [0.0; 2]),
        Err(CostError::LengthMismatch {
            what: "term values",
            expected: 3,
            found: 2
        })
    );
    let mut values = [0.0; 3];
    sum.term_values(&q, &mut values).unwrap();
    assert_relative_eq!(
        sum.value(&q).unwrap(),
        values.iter().sum::<f64>(),
        epsilon = 1e-15
    );
    let dominant = ["joint_limits", "obstacles", "visibility"][values
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap()
        .0];
    assert_eq!(sum.dominant_term(&q).unwrap(), dominant);
    let (mut total, mut part) = (JointVector::<6>::zeros(), JointVector::<6>::zeros());
    sum.value_and_gradient(&q, &mut total).unwrap();
    let mut expected = JointVector::<6>::zeros();
    for term in [&limits as &dyn Cost<6>, &obstacles, &visibility] {
        term.value_and_gradient(&q, &mut part).unwrap();
        expected += part;
    }
    assert_relative_eq!(total, expected, epsilon = 1e-15);
}

#[test]
fn bad_input_is_a_clear_error() {
    let chain = slider();
    // A mesh format without a reader (PLY) names the link and the file (refused before the file is read).
    let mesh_urdf = SLIDER.replace(
        r#"<sphere radius="0.1"/>"#,
        r#"<mesh filename="cart.ply"/>"#,
    );
    let err = LinkColliders::from_urdf_str(&mesh_urdf, &chain).unwrap_err();
    assert!(
        matches!(&err, CostError::UnsupportedGeometry { link, geometry } if link == "cart" && geometry.contains("cart.ply")),
        "{err:?}"
    );
    let links = LinkColliders::from_urdf_str(SLIDER, &chain).unwrap();
    let ball = || {
        vec![Obstacle::new(
            "ball",
            Geometry::Sphere { radius_m: 0.1 },
            Isometry3::identity(),
        )
        .unwrap()]
    };
    let pair = |link: &str, obstacle: &str, influence| ObstaclePair {
        link: link.into(),
        obstacle: obstacle.into(),
        influence_distance: influence,
    };
    let build = |p: ObstaclePair| ObstacleCost::new(chain.clone(), &links, ball(), &[p]);
    assert_eq!(
        build(pair("wheel", "ball", 0.1)),
        Err(CostError::UnknownLink {
            link: "wheel".into()
        })
    );
    assert_eq!(
        build(pair("base", "ball", 0.1)),
        Err(CostError::NoCollisionGeometry {
            link: "base".into()
        })
    );
    assert_eq!(
        build(pair("cart", "wall", 0.1)),
        Err(CostError::UnknownObstacle {
            obstacle: "wall".into()
        })
    );
    assert_eq!(
        build(pair("cart", "ball", -0.1)),
        Err(CostError::InvalidInfluenceDistance {
            link: "cart".into(),
            obstacle: "ball".into(),
            value: -0.1
        })
    );
    assert!(matches!(
        build(pair("cart", "ball", f64::NAN)),
        Err(CostError::InvalidInfluenceDistance { .. })
    ));
    assert!(matches!(
        Obstacle::new(
            "wall",
            Geometry::Box {
                size_m: [1.0, 0.0, 1.0]
            },
            Isometry3::identity()
        ),
        Err(CostError::InvalidGeometry {
            field: "size_m[1]",
            ..
        })
    ));
    assert!(matches!(
        LinkColliders::new(
            &chain,
            [(
                "wheel".to_owned(),
                Collider::new(
                    "wheel",
                    Geometry::Sphere { radius_m: 0.1 },
                    Isometry3::identity()
                )
                .unwrap()
            )]
        ),
        Err(CostError::UnknownLink { .. })
    ));
    let cost = build(pair("cart", "ball", 0.1)).unwrap();
    assert!(matches!(
        cost.value(&Vector1::new(f64::NAN)),
        Err(CostError::NonFiniteConfiguration { joint: 0, value }) if value.is_nan()
    ));
    let intrinsics = CameraIntrinsics::new(100.0, 100.0, 50.0, 50.0, 100.0, 100.0).unwrap();
    let camera = EyeInHand::new(Isometry3::identity()).unwrap();
    let point = [Point3::new(0.0, 0.0, 1.0)];
    for margin in [-1.0, 50.0, f64::INFINITY] {
        assert!(matches!(
            VisibilityCost::new(slider(), camera, &intrinsics, &point, margin),
            Err(CostError::InvalidMargin { .. })
        ));
    }
    assert_eq!(
        VisibilityCost::new(slider(), camera, &intrinsics, &[], 10.0),
        Err(CostError::InvalidTargetPoints)
    );
}

/// A link hanging from the chain by fixed joints (a camera beyond the tip) is carried by its chain link.
#[test]
fn links_fixed_beyond_the_chain_are_carried_by_it() {
    let urdf = SLIDER.replace(
        r#"<link name="mast"/>"#,
        r#"<link name="mast"><collision><geometry><sphere radius="0.05"/></geometry></collision></link>"#,
    );
    let chain = slider();
    let links = LinkColliders::from_urdf_str(&urdf, &chain).unwrap();
    let ball = Obstacle::new(
        "ball",
        Geometry::Sphere { radius_m: 0.05 },
        Isometry3::translation(0.0, 0.0, 0.5),
    )
    .unwrap();
    let pair = ObstaclePair {
        link: "mast".into(),
        obstacle: "ball".into(),
        influence_distance: 1.0,
    };
    let cost = ObstacleCost::new(chain, &links, vec![ball], &[pair]).unwrap();
    // The mast ball is at (q, 0, 0.2): at q = 0, 0.3 − 0.1 = 0.2 m from the obstacle.
    let closest = cost.closest_pair(&Vector1::new(0.0)).unwrap().unwrap();
    assert_eq!(closest.link, "mast");
    assert_relative_eq!(closest.distance, 0.2, epsilon = 1e-12);
}
