//! Bring your own robot: seven-joint arms shaped like the URDFs users have (tests/data/robots: a Gen3-like arm with
//! continuous joints, a Panda-like arm with a mimic finger gripper, link shapes as STL, OBJ and COLLADA meshes), run from
//! scenario files (tests/data/scenarios) with the camera given as a URDF link; mesh errors name the link and the file.

use approx::assert_relative_eq;
use nalgebra::{Isometry3, Vector3};
use servostack::avoidance::{Collider, CostError, Geometry, LinkColliders, MeshPaths};
use servostack::robot::{JointKind, RobotError, SerialChain};
use servostack::scenario::{with_joint_count, ForJointCount, RunKind, Scenario, ScenarioError};
use servostack::sim::Outcome;
use std::path::{Path, PathBuf};

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data")
}

fn package() -> PathBuf {
    data().join("robots/arm_fixtures_description")
}

fn scenario(name: &str) -> Scenario {
    Scenario::from_file(data().join(format!("scenarios/{name}.toml"))).unwrap()
}

/// The four runs of a scenario on its 7-joint arm: each converges, and none stops at a joint limit.
fn four_runs_converge(scenario: &Scenario) -> Vec<servostack::sim::Run<7>> {
    assert_eq!(scenario.joint_count().unwrap(), 7);
    let experiment = scenario.experiment::<7>().unwrap();
    RunKind::ALL
        .iter()
        .map(|&kind| {
            let run = experiment.run(&scenario.settings(), kind).unwrap();
            assert_eq!(run.outcome, Outcome::Converged, "{}", kind.name());
            assert!(run
                .final_error_norm()
                .is_some_and(|e| e < 4.0 * scenario.simulation.convergence_error));
            run
        })
        .collect()
}

#[test]
fn gen3_like_arm_with_continuous_joints_runs_the_four_methods() {
    let scenario = scenario("gen3_like");
    let experiment = scenario.experiment::<7>().unwrap();
    let chain = experiment.scene.chain();
    // Joints 1, 3, 5, 7 continuous: unlimited in the chain and in the joint-limit cost.
    for (i, joint) in chain.joints().iter().enumerate() {
        let continuous = i % 2 == 0;
        assert_eq!(
            joint.kind() == JointKind::Continuous,
            continuous,
            "joint {i}"
        );
        assert_eq!(experiment.scene.limits().is_unlimited(i), continuous);
        assert_eq!(chain.upper_limits()[i].is_infinite(), continuous);
    }
    for run in four_runs_converge(&scenario) {
        // Never at a limit: no continuous joint counts in the closest normalised margin, which stays that of the
        // limited joints.
        for record in &run.records {
            let normalized = run.limits.normalized(&record.q);
            for i in [0, 2, 4, 6] {
                assert_eq!(normalized[i], 0.5);
            }
        }
        // The first joint starts at 3.4 rad and ends near its desired 3.3 rad, past π: never wrapped into (−π, π].
        let q_end = run.records.last().unwrap().q;
        assert!((q_end[0] - 3.3).abs() < 0.1, "q0 = {}", q_end[0]);
        assert!(run.records.iter().all(|r| r.q[0] > 3.0));
    }
}

#[test]
fn panda_like_arm_with_a_mimic_gripper_runs_the_four_methods() {
    let scenario = scenario("panda_like");
    four_runs_converge(&scenario);
}

/// The camera link's fixed joints give the mount; an extra `camera_mount` is composed after them.
#[test]
fn camera_given_as_a_urdf_link() {
    let scenario = scenario("gen3_like");
    let (_, camera) = scenario.robot_model::<7>().unwrap();
    // camera_joint: (0, 0.056, −0.02) m from end_effector_link, axes parallel.
    assert_relative_eq!(
        camera.e_from_c().to_homogeneous(),
        Isometry3::translation(0.0, 0.056, -0.02).to_homogeneous(),
        epsilon = 1e-12
    );
    let text = std::fs::read_to_string(data().join("scenarios/gen3_like.toml")).unwrap();
    let with_offset = text.replace(
        "camera_link = \"camera_link\"",
        "camera_link = \"camera_link\"\ncamera_mount = { translation_m = [0.0, 0.0, 0.01], rpy_deg = [0.0, 0.0, 90.0] }",
    );
    let base_dir = data().join("scenarios");
    let offset = Scenario::from_toml_str(&with_offset, Some(&base_dir)).unwrap();
    let (_, camera) = offset.robot_model::<7>().unwrap();
    let expected = Isometry3::translation(0.0, 0.056, -0.02)
        * Isometry3::new(
            Vector3::new(0.0, 0.0, 0.01),
            Vector3::z() * 90f64.to_radians(),
        );
    assert_relative_eq!(
        camera.e_from_c().to_homogeneous(),
        expected.to_homogeneous(),
        epsilon = 1e-12
    );
    // A link not attached to the tip by fixed joints, and no camera at all, are named.
    let field_of = |text: &str| match Scenario::from_toml_str(text, Some(&base_dir))
        .unwrap()
        .robot_model::<7>()
    {
        Err(ScenarioError::Invalid { field, reason }) => (field, reason),
        other => panic!("expected an invalid field, got {other:?}"),
    };
    let (field, reason) = field_of(&text.replace(
        "camera_link = \"camera_link\"",
        "camera_link = \"left_finger_link\"",
    ));
    assert_eq!(field, "robot.camera_link");
    assert!(reason.contains("left_finger_link"), "{reason}");
    let (field, _) = field_of(&text.replace("camera_link = \"camera_link\"", ""));
    assert_eq!(field, "robot.camera_mount");
}

/// Continuous joints load without `<limit>` ranges; the mimic finger joints of the Panda-like gripper are off the
/// chain to the hand, and a chain ending at the mimic finger is refused by name (its leader is off that path).
#[test]
fn the_fixture_urdfs_load_as_real_ones_do() {
    let gen3 = SerialChain::<7>::from_urdf_file(
        package().join("urdf/gen3_like.urdf"),
        "base_link",
        "end_effector_link",
    )
    .unwrap();
    assert_eq!(gen3.joints()[6].name(), "joint_7");
    let panda_urdf = package().join("urdf/panda_like.urdf");
    let panda = SerialChain::<7>::from_urdf_file(&panda_urdf, "panda_link0", "panda_hand").unwrap();
    assert!(panda.mimic_joints().is_empty());
    assert_eq!(
        SerialChain::<7>::from_urdf_file(&panda_urdf, "panda_link0", "panda_rightfinger")
            .unwrap_err(),
        RobotError::MimicLeaderNotOnPath {
            joint: "panda_finger_joint2".into(),
            leader: "panda_finger_joint1".into()
        }
    );
    // To the left finger: eight independent joints (the arm's and the finger's).
    assert!(
        SerialChain::<8>::from_urdf_file(&panda_urdf, "panda_link0", "panda_leftfinger").is_ok()
    );
}

/// `with_joint_count` reaches the chain's joint count at run time, for any count of the documented range, and names
/// the robot field beyond it.
#[test]
fn runners_dispatch_the_joint_count_at_run_time() {
    struct Count;
    impl ForJointCount for Count {
        type Output = usize;
        fn call<const N: usize>(self) -> usize {
            N
        }
    }
    for n in 1..=servostack::scenario::MAX_JOINTS {
        assert_eq!(with_joint_count(n, Count).unwrap(), n);
    }
    for n in [0, servostack::scenario::MAX_JOINTS + 1] {
        match with_joint_count(n, Count) {
            Err(ScenarioError::Invalid { field, .. }) => assert_eq!(field, "robot"),
            other => panic!("{n} joints: {other:?}"),
        }
    }
    // An eight-joint chain (the Panda-like arm to its left finger) is counted.
    let text = std::fs::read_to_string(data().join("scenarios/panda_like.toml"))
        .unwrap()
        .replace(
            "tip_link = \"panda_hand\"",
            "tip_link = \"panda_leftfinger\"",
        )
        .replace(
            "camera_link = \"panda_camera\"",
            "camera_mount = { translation_m = [0.0, 0.0, 0.0] }",
        );
    let eight = Scenario::from_toml_str(&text, Some(&data().join("scenarios"))).unwrap();
    assert_eq!(eight.joint_count().unwrap(), 8);
}

fn meshes() -> MeshPaths {
    MeshPaths::new(package().join("urdf"))
        .with_ros_package_path(None)
        .with_package("arm_fixtures_description", package())
}

/// Every link of both arms gets its mesh shapes, through `package://` (Gen3-like) and relative paths (Panda-like).
#[test]
fn mesh_collision_geometry_loads_through_packages_and_relative_paths() {
    let gen3_urdf = std::fs::read_to_string(package().join("urdf/gen3_like.urdf")).unwrap();
    let gen3 =
        SerialChain::<7>::from_urdf_str(&gen3_urdf, "base_link", "end_effector_link").unwrap();
    let robot = urdf_rs::read_from_string(&gen3_urdf).unwrap();
    let links = LinkColliders::from_urdf_robot_with_meshes(&robot, &gen3, &meshes()).unwrap();
    assert_eq!(links.of_link("camera_link").count(), 1);
    assert_eq!(links.of_link("half_arm_2_link").count(), 1);
    // The same through ROS_PACKAGE_PATH instead of the map.
    let ros = MeshPaths::new(package().join("urdf"))
        .with_ros_package_path(Some(data().join("robots").to_str().unwrap()));
    assert!(LinkColliders::from_urdf_robot_with_meshes(&robot, &gen3, &ros).is_ok());
    // Without either: the unknown package is named, with the link.
    let none = MeshPaths::new(package().join("urdf")).with_ros_package_path(None);
    match LinkColliders::from_urdf_robot_with_meshes(&robot, &gen3, &none) {
        Err(CostError::UnknownPackage { link, package, .. }) => {
            assert_eq!(link, "base_link");
            assert_eq!(package, "arm_fixtures_description");
        }
        other => panic!("expected UnknownPackage, got {other:?}"),
    }
    let panda_urdf = std::fs::read_to_string(package().join("urdf/panda_like.urdf")).unwrap();
    let panda = SerialChain::<7>::from_urdf_str(&panda_urdf, "panda_link0", "panda_hand").unwrap();
    let robot = urdf_rs::read_from_string(&panda_urdf).unwrap();
    let links = LinkColliders::from_urdf_robot_with_meshes(&robot, &panda, &meshes()).unwrap();
    assert_eq!(links.of_link("panda_hand").count(), 1);
}

/// The collider of one `<collision>` mesh element, read with the fixture's mesh paths.
fn mesh_collider(filename: &str, scale: &str) -> Result<Geometry, CostError> {
    let urdf = format!(
        r#"<robot name="m"><link name="a"/><link name="b"><collision><geometry>
        <mesh filename="{filename}" scale="{scale}"/></geometry></collision></link>
        <joint name="j" type="prismatic"><parent link="a"/><child link="b"/><axis xyz="1 0 0"/>
        <limit lower="-1" upper="1" effort="0" velocity="1"/></joint></robot>"#
    );
    let chain = SerialChain::<1>::from_urdf_str(&urdf, "a", "b").unwrap();
    let robot = urdf_rs::read_from_string(&urdf).unwrap();
    let links = LinkColliders::from_urdf_robot_with_meshes(&robot, &chain, &meshes())?;
    let (_, collider) = links.of_link("b").next().unwrap();
    Ok(collider.geometry().clone())
}

/// The formats read as the shapes they describe: the binary STL box is the scaled box (distances equal a box
/// primitive's), the ASCII STL cylinder a 12-gon prism of the scaled radius, the OBJ capsule envelope its 18 vertices,
/// the COLLADA tetrahedron its corners in metres.
#[test]
fn stl_obj_and_collada_meshes_become_their_convex_hulls() {
    let ball = Collider::new(
        "ball",
        Geometry::Sphere { radius_m: 0.01 },
        Isometry3::identity(),
    )
    .unwrap();
    let box_mesh = mesh_collider(
        "package://arm_fixtures_description/meshes/box.stl",
        "0.1 0.2 0.3",
    )
    .unwrap();
    let hull = Collider::new("b", box_mesh, Isometry3::identity()).unwrap();
    let cube = Collider::new(
        "c",
        Geometry::Box {
            size_m: [0.1, 0.2, 0.3],
        },
        Isometry3::identity(),
    )
    .unwrap();
    for centre in [[0.3, 0.0, 0.0], [0.1, -0.3, 0.2], [0.0, 0.0, -0.5]] {
        let at = Isometry3::translation(centre[0], centre[1], centre[2]);
        assert_relative_eq!(
            servostack::avoidance::collision::signed_distance(
                &hull,
                &Isometry3::identity(),
                &ball,
                &at
            )
            .unwrap(),
            servostack::avoidance::collision::signed_distance(
                &cube,
                &Isometry3::identity(),
                &ball,
                &at
            )
            .unwrap(),
            epsilon = 1e-9
        );
    }
    let Geometry::ConvexHull { points_m } =
        mesh_collider("../meshes/cylinder.stl", "0.05 0.05 0.4").unwrap()
    else {
        panic!("a mesh is a convex hull")
    };
    assert_eq!(points_m.len(), 24);
    for p in &points_m {
        assert_relative_eq!(p[0].hypot(p[1]), 0.05, epsilon = 1e-6);
        assert_relative_eq!(p[2].abs(), 0.2, epsilon = 1e-6);
    }
    let Geometry::ConvexHull { points_m } = mesh_collider(
        "package://arm_fixtures_description/meshes/capsule.obj",
        "1 1 1",
    )
    .unwrap() else {
        panic!("a mesh is a convex hull")
    };
    assert_eq!(points_m.len(), 18);
    // COLLADA, its unit (1 cm) applied: the tetrahedron's corners 0.1 m along each axis.
    let Geometry::ConvexHull { points_m } = mesh_collider(
        "package://arm_fixtures_description/meshes/tetra_cm.dae",
        "1 1 1",
    )
    .unwrap() else {
        panic!("a mesh is a convex hull")
    };
    assert_eq!(points_m.len(), 4);
    let farthest = points_m
        .iter()
        .map(|p| Vector3::from(*p).norm())
        .fold(0.0, f64::max);
    assert_relative_eq!(farthest, 0.1, epsilon = 1e-6);
}

/// A binary STL whose 80-byte header starts with `solid`, as many exporters write, is read as binary.
#[test]
fn binary_stl_with_a_solid_header_is_read_as_binary() {
    let mut bytes = std::fs::read(package().join("meshes/box.stl")).unwrap();
    bytes[..12].copy_from_slice(b"solid box   ");
    let path = std::env::temp_dir().join(format!("servostack-solid-{}.stl", std::process::id()));
    std::fs::write(&path, &bytes).unwrap();
    let result = mesh_collider(path.to_str().unwrap(), "1 1 1");
    std::fs::remove_file(&path).unwrap();
    let Geometry::ConvexHull { points_m } = result.unwrap() else {
        panic!("a mesh is a convex hull")
    };
    assert_eq!(points_m.len(), 8);
}

#[test]
fn missing_mesh_file_names_link_and_file() {
    let err = mesh_collider(
        "package://arm_fixtures_description/meshes/nowhere.stl",
        "1 1 1",
    )
    .unwrap_err();
    match &err {
        CostError::MeshFile { link, file, .. } => {
            assert_eq!(link, "b");
            assert!(file.ends_with("meshes/nowhere.stl"), "{file}");
        }
        other => panic!("expected MeshFile, got {other:?}"),
    }
    assert!(err.to_string().contains("nowhere.stl"), "{err}");
}

#[test]
fn malformed_stl_names_link_and_file() {
    let err = mesh_collider(
        "package://arm_fixtures_description/meshes/malformed.stl",
        "1 1 1",
    )
    .unwrap_err();
    match &err {
        CostError::MalformedMesh { link, file, .. } => {
            assert_eq!(link, "b");
            assert!(file.ends_with("malformed.stl"), "{file}");
        }
        other => panic!("expected MalformedMesh, got {other:?}"),
    }
    // A binary STL cut short is malformed too.
    let cut = std::env::temp_dir().join(format!("servostack-cut-{}.stl", std::process::id()));
    let bytes = std::fs::read(package().join("meshes/box.stl")).unwrap();
    std::fs::write(&cut, &bytes[..200]).unwrap();
    let result = mesh_collider(cut.to_str().unwrap(), "1 1 1");
    std::fs::remove_file(&cut).unwrap();
    assert!(
        matches!(result, Err(CostError::MalformedMesh { .. })),
        "{result:?}"
    );
}

#[test]
fn unknown_package_names_link_and_package() {
    let err = mesh_collider("package://other_description/meshes/box.stl", "1 1 1").unwrap_err();
    assert_eq!(
        err,
        CostError::UnknownPackage {
            link: "b".into(),
            filename: "package://other_description/meshes/box.stl".into(),
            package: "other_description".into()
        }
    );
}
