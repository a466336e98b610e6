//! One test per class of hostile input of the second round (issue 46): the mesh and calibration readers, the knobs
//! added with the camera model, `package://` paths and unbounded runs. Each input once aborted the process, panicked,
//! read outside its folder, gave a wrong value without an error or grew without bound; each is now a named error or a
//! bounded, correct result.

use crate::hostile_input::on_2_mib_thread;
use servostack::avoidance::{CostError, Geometry, LinkColliders, MeshPaths, MAX_COLLADA_DEPTH};
use servostack::bounds::{FOCAL_LENGTH_PX, PIXEL_NOISE_PX};
use servostack::camera::{
    BrownConrady, CalibratedCamera, CalibrationError, CameraError, MAX_CALIBRATION_BYTES,
};
use servostack::measurement::MeasurementError;
use servostack::robot::SerialChain;
use servostack::scenario::{RunKind, Scenario, ScenarioError, DEFAULT_RECORD_CAPACITY};
use servostack::sim::SimError;
use servostack::study::{
    standard_families, Study, StudyError, MAX_DRAWS_PER_FAMILY, MAX_SLICE_POINTS,
};
use std::path::{Path, PathBuf};

const ROS_CALIBRATION: &str = include_str!("../data/ros_camera_info.yaml");
const PAPER: &str = include_str!("../../assets/scenarios/paper_afma6.toml");
const TETRA: &str = include_str!("../data/robots/arm_fixtures_description/meshes/tetra_cm.dae");

/// A fresh directory for one test's files.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("servostack-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The collision geometry of a one-link URDF whose link's mesh is `filename`, read with `meshes`.
fn mesh_geometry(filename: &str, meshes: &MeshPaths) -> Result<Geometry, CostError> {
    let urdf = format!(
        r#"<robot name="m"><link name="a"/><link name="b"><collision><geometry>
        <mesh filename="{filename}"/></geometry></collision></link>
        <joint name="j" type="prismatic"><parent link="a"/><child link="b"/><axis xyz="1 0 0"/>
        <limit lower="-1" upper="1" effort="0" velocity="1"/></joint></robot>"#
    );
    let chain = SerialChain::<1>::from_urdf_str(&urdf, "a", "b").unwrap();
    let robot = urdf_rs::read_from_string(&urdf).unwrap();
    let links = LinkColliders::from_urdf_robot_with_meshes(&robot, &chain, meshes)?;
    let (_, collider) = links.of_link("b").next().unwrap();
    Ok(collider.geometry().clone())
}

/// The tetrahedron fixture with its scene node wrapped in `levels` more `<node>` elements.
fn nested_tetra(levels: usize) -> String {
    let node = "<node id=\"tetra\" name=\"tetra\" type=\"NODE\">";
    assert!(TETRA.contains(node));
    let open = "<node type=\"NODE\">".repeat(levels);
    let close = "</node>".repeat(levels);
    TETRA.replacen(node, &format!("{open}{node}"), 1).replacen(
        "</visual_scene>",
        &format!("{close}</visual_scene>"),
        1,
    )
}

#[test]
fn deeply_nested_collada_is_refused_before_parsing() {
    let dir = scratch("nested-collada");
    for (levels, name) in [(2_000, "deep.dae"), (MAX_COLLADA_DEPTH - 8, "at_limit.dae")] {
        std::fs::write(dir.join(name), nested_tetra(levels)).unwrap();
    }
    let meshes = MeshPaths::new(&dir).with_ros_package_path(None);
    // 2 000 levels overflowed the stack inside the COLLADA reader and aborted the process.
    let deep = {
        let meshes = meshes.clone();
        on_2_mib_thread(move || mesh_geometry("deep.dae", &meshes))
    };
    match deep {
        Err(CostError::MalformedMesh { message, .. }) => {
            assert!(message.contains("nested deeper than 256"), "{message}")
        }
        other => panic!("expected MalformedMesh, got {other:?}"),
    }
    // Just inside the limit, the same file is read on the same stack: the limit is safe.
    let inside = on_2_mib_thread(move || mesh_geometry("at_limit.dae", &meshes));
    assert!(
        matches!(&inside, Ok(Geometry::ConvexHull { points_m }) if points_m.len() == 4),
        "{inside:?}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn oversized_mesh_and_calibration_files_are_refused_before_reading() {
    let dir = scratch("oversized");
    // Sparse files: announced sizes above the limits, no byte written.
    let mesh = dir.join("huge.stl");
    std::fs::File::create(&mesh)
        .unwrap()
        .set_len(servostack::avoidance::MAX_MESH_BYTES as u64 + 1)
        .unwrap();
    let meshes = MeshPaths::new(&dir).with_ros_package_path(None);
    match mesh_geometry("huge.stl", &meshes) {
        Err(error @ CostError::MeshTooLarge { .. }) => {
            assert!(error.to_string().contains("with_max_file_bytes"), "{error}")
        }
        other => panic!("expected MeshTooLarge, got {other:?}"),
    }
    // A lower limit refuses a small real file; the default reads it.
    let small = dir.join("box.stl");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/robots/arm_fixtures_description/meshes/box.stl"),
        &small,
    )
    .unwrap();
    assert!(mesh_geometry("box.stl", &meshes).is_ok());
    assert!(matches!(
        mesh_geometry("box.stl", &meshes.clone().with_max_file_bytes(100)),
        Err(CostError::MeshTooLarge {
            bytes: 684,
            limit: 100,
            ..
        })
    ));
    let calibration = dir.join("huge.yaml");
    std::fs::File::create(&calibration)
        .unwrap()
        .set_len(MAX_CALIBRATION_BYTES as u64 + 1)
        .unwrap();
    assert!(matches!(
        CalibratedCamera::from_yaml_file(&calibration),
        Err(CalibrationError::TooLarge { bytes, .. }) if bytes == MAX_CALIBRATION_BYTES as u64 + 1
    ));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A file whose size is not known before reading (a device that never ends) is read only up to the limit.
#[cfg(target_os = "linux")]
#[test]
fn an_endless_file_is_read_only_up_to_the_limit() {
    assert!(matches!(
        CalibratedCamera::from_yaml_file(Path::new("/dev/zero")),
        Err(CalibrationError::TooLarge { bytes, .. }) if bytes == MAX_CALIBRATION_BYTES as u64 + 1
    ));
}

#[test]
fn yaml_alias_bombs_and_deep_nesting_are_refused() {
    // 1.3 KB whose aliases expand to 10¹⁰ nodes exhausted memory.
    let mut bomb = String::from("a0: &a0 [x, x, x, x, x, x, x, x, x, x]\n");
    for level in 1..10 {
        let aliases = vec![format!("*a{}", level - 1); 10].join(", ");
        bomb.push_str(&format!("a{level}: &a{level} [{aliases}]\n"));
    }
    let text = format!("{bomb}{ROS_CALIBRATION}");
    match CalibratedCamera::from_yaml_str(&text) {
        Err(CalibrationError::Refused { line: 2, reason }) => assert!(reason.contains("alias")),
        other => panic!("expected Refused at line 2, got {other:?}"),
    }
    // One alias is enough to refuse: no calibration tool writes them.
    let one = ROS_CALIBRATION.replace("image_height: 480", "w: &w 480\nimage_height: *w");
    assert!(matches!(
        CalibratedCamera::from_yaml_str(&one),
        Err(CalibrationError::Refused { .. })
    ));
    // Collections nested thousands deep are refused before a document is built (and dropped recursively): block
    // mappings by the depth check, flow sequences by it or by the YAML reader's own recursion limit.
    let block: String = (0..3_000)
        .map(|level| format!("{}a:\n", " ".repeat(level)))
        .collect();
    let flow = format!("deep: {}1{}\n", "[".repeat(100_000), "]".repeat(100_000));
    for (deep, reader_may_refuse) in [(block, false), (flow, true)] {
        let text = format!("{ROS_CALIBRATION}{deep}");
        let refused = on_2_mib_thread(move || CalibratedCamera::from_yaml_str(&text));
        assert!(
            matches!(&refused, Err(CalibrationError::Refused { reason, .. }) if reason.contains("nested"))
                || (reader_may_refuse
                    && matches!(&refused, Err(CalibrationError::Yaml { message }) if message.contains("recursion"))),
            "{refused:?}"
        );
    }
    // The fixture itself still loads.
    assert!(CalibratedCamera::from_yaml_str(ROS_CALIBRATION).is_ok());
}

#[test]
fn extreme_pixel_noise_is_a_named_error() {
    // 1e308 passed validation and panicked on an unwrap of a non-finite noise range.
    for value in ["1e308", "1001.0"] {
        let text = format!("{PAPER}\n[measurement]\npixel_noise_uniform_px = {value}\n");
        let scenario = Scenario::from_toml_str(&text, None).unwrap();
        match scenario.run::<6>(RunKind::FullMethod) {
            Err(error) => {
                let message = error.to_string();
                assert!(
                    message.contains("pixel_noise_uniform_px")
                        && message.contains(PIXEL_NOISE_PX.text),
                    "{message}"
                );
            }
            Ok(run) => panic!("accepted: {:?}", run.outcome),
        }
    }
    let mut parameters = servostack::measurement::MeasurementParameters {
        pixel_noise_sigma_px: 1e300,
        ..Default::default()
    };
    assert!(matches!(
        parameters.validate(0.01),
        Err(MeasurementError::InvalidParameter {
            name: "pixel_noise_sigma_px",
            ..
        })
    ));
    parameters.pixel_noise_sigma_px = PIXEL_NOISE_PX.high;
    assert!(parameters.validate(0.01).is_ok());
}

#[test]
fn a_tiny_focal_length_is_refused_from_files_and_the_api() {
    // fx = 1e−300 was accepted, and a step at the desired image reported an error norm of 1.31.
    let text = ROS_CALIBRATION.replace("data: [612.5,", "data: [1e-300,");
    assert_ne!(text, ROS_CALIBRATION);
    assert!(matches!(
        CalibratedCamera::from_yaml_str(&text),
        Err(CalibrationError::Camera(CameraError::InvalidIntrinsic { name: "fx", expected, .. }))
            if expected == FOCAL_LENGTH_PX.text
    ));
    let scenario = PAPER.replacen("fx = ", "fx = 1e-300 # ", 1);
    assert_ne!(scenario, PAPER);
    let refused = Scenario::from_toml_str(&scenario, None)
        .and_then(|s| s.run::<6>(RunKind::Classical).map(|_| ()));
    assert!(
        matches!(&refused, Err(e) if e.to_string().contains("fx")),
        "{refused:?}"
    );
}

#[test]
fn a_non_monotonic_lens_file_undistorts_nothing_past_its_fold() {
    // k1 = −1, k3 = 0.5: 884 of 3 185 grid pixels undistorted to points past the fold, without an error.
    let text = ROS_CALIBRATION.replace(
        "data: [-0.2875, 0.0812, 0.00041, -0.00073, -0.0104]",
        "data: [-1.0, 0.0, 0.0, 0.0, 0.5]",
    );
    assert_ne!(text, ROS_CALIBRATION);
    let camera = CalibratedCamera::from_yaml_str(&text).unwrap();
    let fold = camera.distortion.fold_radius();
    assert!(fold.is_finite());
    let (mut accepted, mut refused) = (0, 0);
    for i in 0..=64 {
        for j in 0..=48 {
            let (u, v) = (10.0 * f64::from(i), 10.0 * f64::from(j));
            match camera.normalized_of(u, v) {
                Ok((x, y)) => {
                    assert!(
                        x.hypot(y) < fold,
                        "pixel ({u}, {v}) undistorted past the fold"
                    );
                    let (u_back, v_back) = camera.pixel_of(x, y);
                    assert!((u_back - u).abs() < 1e-6 && (v_back - v).abs() < 1e-6);
                    accepted += 1;
                }
                Err(CameraError::BeyondFold { .. } | CameraError::UndistortionFailed { .. }) => {
                    refused += 1
                }
                Err(other) => panic!("{other}"),
            }
        }
    }
    assert!(
        accepted > 100 && refused > 100,
        "{accepted} accepted, {refused} refused"
    );
    // A lens that never folds refuses nothing over its image.
    let monotonic = BrownConrady::new(-0.2875, 0.0812, 0.00041, -0.00073, -0.0104).unwrap();
    assert!(monotonic.fold_radius() > 1.0);
}

#[test]
fn package_uris_stay_inside_their_package() {
    let dir = scratch("package-escape");
    let package = dir.join("pkg");
    std::fs::create_dir_all(package.join("meshes")).unwrap();
    let source = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/robots/arm_fixtures_description/meshes/box.stl");
    std::fs::copy(&source, dir.join("outside.stl")).unwrap();
    std::fs::copy(&source, package.join("meshes/inside.stl")).unwrap();
    let meshes = MeshPaths::new(&dir)
        .with_ros_package_path(None)
        .with_package("pkg", &package);
    assert!(mesh_geometry("package://pkg/meshes/inside.stl", &meshes).is_ok());
    assert!(mesh_geometry("package://pkg/./meshes/inside.stl", &meshes).is_ok());
    for escaping in [
        "package://pkg/../outside.stl",
        "package://pkg/meshes/../../outside.stl",
        "package://pkg//etc/passwd.stl",
    ] {
        match mesh_geometry(escaping, &meshes) {
            Err(CostError::PathOutsidePackage { filename, .. }) => assert_eq!(filename, escaping),
            other => panic!("{escaping}: expected PathOutsidePackage, got {other:?}"),
        }
    }
    // Allowed on request; relative paths from the URDF's folder keep their documented meaning.
    let allowed = meshes.clone().allowing_paths_outside_packages();
    assert!(mesh_geometry("package://pkg/../outside.stl", &allowed).is_ok());
    assert!(mesh_geometry("pkg/../outside.stl", &meshes).is_ok());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn runs_and_studies_are_bounded() {
    // A budget of 1e18 that never converged kept every record until memory ran out.
    let huge = PAPER.replace(
        "max_iterations = 10000",
        "max_iterations = 1000000000000000000",
    );
    assert_ne!(huge, PAPER);
    let refused = Scenario::from_toml_str(&huge, None)
        .and_then(|s| s.run::<6>(RunKind::Classical).map(|_| ()));
    assert!(
        matches!(
            &refused,
            Err(ScenarioError::Simulation(SimError::InvalidParameter {
                name: "max_iterations",
                ..
            }))
        ),
        "{refused:?}"
    );
    // A run longer than the default log's capacity keeps at most that many records, evenly spaced, and its summary
    // still counts every iteration.
    // Started at the goal with an unreachable threshold, the classical law runs its whole budget.
    let endless = PAPER
        .replace("max_iterations = 10000", "max_iterations = 70000")
        .replace("convergence_error = 1e-4", "convergence_error = 1e-300")
        .replace(
            "joints = [-0.3405, 0.3942, -0.4766, -1.1201, 0.4517, 0.2271]",
            "joints = [-0.037, 0.229, -0.450, -0.876, 0.746, -0.397]",
        );
    let run = Scenario::from_toml_str(&endless, None)
        .unwrap()
        .run::<6>(RunKind::Classical)
        .unwrap();
    assert_eq!(run.iterations(), 70_000, "{:?}", run.outcome);
    assert!(
        run.records.len() <= DEFAULT_RECORD_CAPACITY
            && run.records.len() >= DEFAULT_RECORD_CAPACITY / 2,
        "{} records",
        run.records.len()
    );
    assert_eq!(run.records[1].iteration - run.records[0].iteration, 2);
    // A study of 1e12 draws would run for centuries: refused by name.
    let scenario = Scenario::from_toml_str(PAPER, None).unwrap();
    for draws in [MAX_DRAWS_PER_FAMILY + 1, 1_000_000_000_000] {
        assert!(matches!(
            Study::new(&scenario, standard_families(), draws, 1),
            Err(StudyError::InvalidParameter { name: "draws", .. })
        ));
    }
    let study = Study::new(&scenario, standard_families(), MAX_DRAWS_PER_FAMILY, 1).unwrap();
    // A slice of a million cells likewise.
    assert!(matches!(
        study.slice((0, 1), (0.1, 0.1), MAX_SLICE_POINTS + 1),
        Err(StudyError::InvalidParameter {
            name: "slice points",
            ..
        })
    ));
}

#[test]
fn depths_target_sizes_and_hand_eye_errors_beyond_their_ranges_are_named() {
    use servostack::bounds::DEPTH_M;
    use servostack::target::{RectangleTarget, TargetError};
    // A target of 1e−300 m and an a-priori depth of 1e−300 m were accepted and run.
    for (from, to, named) in [
        ("width_m = 0.2", "width_m = 1e-300", "degenerate rectangle"),
        ("height_m = 0.1", "height_m = 2e3", "degenerate rectangle"),
        (
            "interaction = \"exact\"",
            "interaction = \"exact\"\na_priori_depth_m = 1e-300",
            "Z_g",
        ),
        (
            "interaction = \"exact\"",
            "interaction = \"exact\"\narea_depth_m = 1e308",
            "Z*",
        ),
        (
            "[simulation]",
            "[measurement]\nhand_eye_translation_m = 1e308\n\n[simulation]",
            "hand_eye_translation_m",
        ),
    ] {
        let text = PAPER.replacen(from, to, 1);
        assert_ne!(text, PAPER, "{from}");
        let refused = Scenario::from_toml_str(&text, None)
            .and_then(|s| s.run::<6>(RunKind::FullMethod).map(|_| ()));
        match refused {
            Err(error) => assert!(error.to_string().contains(named), "{to}: {error}"),
            Ok(()) => panic!("{to}: accepted"),
        }
    }
    assert!(matches!(
        RectangleTarget::new(1e-300, 0.1),
        Err(TargetError::DegenerateRectangle { .. })
    ));
    assert!(RectangleTarget::new(DEPTH_M.low, DEPTH_M.high).is_ok());
}
