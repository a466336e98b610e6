//! Fuzz cases of the file readers: mesh files (binary and ASCII STL, Wavefront OBJ, COLLADA) and calibration files
//! (ROS `camera_info`, OpenCV `FileStorage`), mutated from the fixtures of the test suite.
//!
//! A mesh case runs the bytes through the reader, the convex hull and a distance query; a calibration case loads the
//! text and undistorts a grid of pixels across the image, each accepted pixel checked to distort back to itself (a
//! wrong value inside `Ok` fails the case as surely as a non-finite one).

use super::mutate::{self, Syntax};
use super::{finite, Case, Verdict};
use crate::avoidance::mesh::{scaled_vertices, MeshFormat};
use crate::avoidance::{collision::signed_distance, Collider, Geometry};
use crate::camera::{CalibratedCamera, CalibrationError, CalibrationOptions};
use nalgebra::{Isometry3, Vector3};
use rand::rngs::StdRng;
use rand::RngExt;
use std::path::Path;

/// The mesh fixtures, by extension: a binary STL box, an ASCII STL cylinder, an OBJ capsule, a COLLADA tetrahedron
/// in centimetres.
pub const MESH_SEEDS: [(&str, &[u8]); 4] = [
    (
        "stl",
        include_bytes!("../../tests/data/robots/arm_fixtures_description/meshes/box.stl"),
    ),
    (
        "stl",
        include_bytes!("../../tests/data/robots/arm_fixtures_description/meshes/cylinder.stl"),
    ),
    (
        "obj",
        include_bytes!("../../tests/data/robots/arm_fixtures_description/meshes/capsule.obj"),
    ),
    (
        "dae",
        include_bytes!("../../tests/data/robots/arm_fixtures_description/meshes/tetra_cm.dae"),
    ),
];

/// The calibration fixtures: ROS `camera_info`; OpenCV files with five, four and eight coefficients; the shapes of
/// OpenCV's samples and tutorials (ArUco's without an image size, the tutorial's `Camera_Matrix`, `calibration.cpp`'s
/// with extrinsics and image points, twelve coefficients).
pub const CALIBRATION_SEEDS: [&str; 8] = [
    include_str!("../../tests/data/ros_camera_info.yaml"),
    include_str!("../../tests/data/opencv_calibration.yaml"),
    include_str!("../../tests/data/opencv_four_coefficients.yaml"),
    include_str!("../../tests/data/opencv_rational.yaml"),
    include_str!("../../tests/data/opencv_aruco_no_size.yml"),
    include_str!("../../tests/data/opencv_tutorial_out_camera_data.yml"),
    include_str!("../../tests/data/opencv_calibration_cpp.yml"),
    include_str!("../../tests/data/opencv_thin_prism.yml"),
];

/// Single-precision values that break naive mesh code, as little-endian bytes are written: NaN, infinities, the
/// largest and smallest floats, zero.
const F32_EXTREMES: [f32; 8] = [
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::MAX,
    -f32::MAX,
    f32::MIN_POSITIVE,
    1e-45,
    0.0,
];

/// A mutated mesh case from the fixtures: byte-level mutations of a binary file, structured ones of a text file.
pub fn mesh_case(rng: &mut StdRng) -> Case {
    let (extension, bytes) = MESH_SEEDS[rng.random_range(0..MESH_SEEDS.len())];
    let bytes = match std::str::from_utf8(bytes) {
        Ok(text) => {
            let syntax = if extension == "dae" {
                Syntax::Xml
            } else {
                Syntax::Lines
            };
            mutate::mutate(text, syntax, rng).into_bytes()
        }
        Err(_) => mutate_binary(bytes, rng),
    };
    Case::Mesh {
        extension: extension.to_owned(),
        bytes,
    }
}

/// One to three byte-level mutations of a binary STL: its triangle count replaced (by 0, by one more or fewer, by
/// `u32::MAX`, at random), a coordinate replaced by an extreme float, random bytes changed, the file cut or extended.
fn mutate_binary(bytes: &[u8], rng: &mut StdRng) -> Vec<u8> {
    let mut bytes = bytes.to_vec();
    for _ in 0..rng.random_range(1..=3) {
        match rng.random_range(0..5) {
            0 if bytes.len() >= 84 => {
                let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]);
                let new = match rng.random_range(0..4) {
                    0 => 0,
                    1 => count.wrapping_add(1),
                    2 => count.wrapping_sub(1),
                    _ => u32::MAX,
                };
                bytes[80..84].copy_from_slice(&new.to_le_bytes());
            }
            1 if bytes.len() >= 88 => {
                let at = 84 + 4 * rng.random_range(0..(bytes.len() - 84) / 4);
                let value = F32_EXTREMES[rng.random_range(0..F32_EXTREMES.len())];
                bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
            }
            2 if !bytes.is_empty() => {
                for _ in 0..rng.random_range(1..=8) {
                    let at = rng.random_range(0..bytes.len());
                    bytes[at] = rng.random();
                }
            }
            3 => {
                let at = rng.random_range(0..=bytes.len());
                bytes.truncate(at);
            }
            _ => {
                let extra = rng.random_range(1..=200);
                bytes.extend((0..extra).map(|_| rng.random::<u8>()));
            }
        }
    }
    bytes
}

/// A mutated calibration case from the fixtures.
pub fn calibration_case(rng: &mut StdRng) -> Case {
    let text = CALIBRATION_SEEDS[rng.random_range(0..CALIBRATION_SEEDS.len())];
    Case::Calibration {
        text: mutate::mutate(text, Syntax::Yaml, rng),
    }
}

/// Reads the mesh bytes as a file of this extension, then takes their convex hull and its distance to a ball.
pub(super) fn check_mesh(extension: &str, bytes: &[u8]) -> Verdict {
    let Some(format) = MeshFormat::of_path(Path::new(&format!("mesh.{extension}"))) else {
        return Verdict::Rejected(format!("extension {extension:?}"));
    };
    let vertices = match scaled_vertices("fuzz", "fuzz", format, bytes, Vector3::repeat(1.0)) {
        Ok(vertices) => vertices,
        Err(error) => return Verdict::Rejected(error.to_string()),
    };
    let coordinates: Vec<f64> = vertices.iter().flat_map(|v| v.iter().copied()).collect();
    if let Err(what) = finite("vertices", &coordinates) {
        return Verdict::NonFinite(what);
    }
    let hull = Geometry::ConvexHull {
        points_m: vertices.iter().map(|v| [v.x, v.y, v.z]).collect(),
    };
    let ball = Geometry::Sphere { radius_m: 0.1 };
    let colliders = Collider::new("fuzz", hull, Isometry3::identity())
        .and_then(|hull| Ok((hull, Collider::new("ball", ball, Isometry3::identity())?)));
    let (hull, ball) = match colliders {
        Ok(pair) => pair,
        Err(error) => return Verdict::Rejected(error.to_string()),
    };
    let away = Isometry3::translation(5.0, -3.0, 2.0);
    match signed_distance(&hull, &Isometry3::identity(), &ball, &away) {
        Ok(distance) => match finite("signed distance", &[distance]) {
            Ok(()) => Verdict::Accepted,
            Err(what) => Verdict::NonFinite(what),
        },
        Err(error) => Verdict::Rejected(error.to_string()),
    }
}

/// Loads the calibration text, then undistorts a 9 × 9 grid of pixels over the image (its corners included): each
/// pixel accepted must be finite, lie inside the lens's fold and distort back to itself within the undistortion
/// tolerance.
pub(super) fn check_calibration(text: &str) -> Verdict {
    // A file without an image size loads with one given, as a caller would.
    let camera = match CalibratedCamera::from_yaml_str(text) {
        Err(CalibrationError::MissingImageSize) => CalibratedCamera::from_yaml_str_with(
            text,
            CalibrationOptions::default().with_image_size(640, 480),
        ),
        loaded => loaded,
    };
    let camera = match camera {
        Ok(camera) => camera,
        Err(error) => return Verdict::Rejected(error.to_string()),
    };
    let intrinsics = camera.intrinsics;
    let focal = intrinsics.fx().max(intrinsics.fy());
    for i in 0..9 {
        for j in 0..9 {
            let u = intrinsics.width() * f64::from(i) / 8.0;
            let v = intrinsics.height() * f64::from(j) / 8.0;
            let Ok((x, y)) = camera.normalized_of(u, v) else {
                continue;
            };
            if let Err(what) = finite("undistorted pixel", &[x, y]) {
                return Verdict::NonFinite(what);
            }
            // Inside the lens's fold: the radial map's slope numerator N M + 2 s (N′ M − N M′) and its denominator M
            // stay positive from the centre to the preimage (a preimage past the fold distorts back to the pixel too,
            // but is not the one).
            let mut c = [0.0; 12];
            c[..camera.distortion.coefficients().len()]
                .copy_from_slice(camera.distortion.coefficients());
            let [k1, k2, _, _, k3, k4, k5, k6, ..] = c;
            let inside = |s: f64| {
                let (n, m) = (
                    1.0 + s * (k1 + s * (k2 + s * k3)),
                    1.0 + s * (k4 + s * (k5 + s * k6)),
                );
                let (n_, m_) = (
                    k1 + s * (2.0 * k2 + s * 3.0 * k3),
                    k4 + s * (2.0 * k5 + s * 3.0 * k6),
                );
                m > 0.0 && n * m + 2.0 * s * (n_ * m - n * m_) > 0.0
            };
            let reach = x * x + y * y;
            let folded = (0..=64)
                .map(|i| reach * f64::from(i) / 64.0)
                .find(|&s| !inside(s));
            if let Some(s) = folded {
                return Verdict::Wrong(format!(
                    "pixel ({u}, {v}) undistorted to ({x}, {y}), past the fold at r² ≤ {s}"
                ));
            }
            let (u_back, v_back) = camera.pixel_of(x, y);
            // Newton stops at a residual of 1e−12 in normalised units: 1e−12 f px; rounding of u itself adds a few ulps.
            let tolerance = 1e-9 * focal + 1e-9 * u.abs().max(v.abs()).max(1.0);
            if !((u_back - u).abs() <= tolerance && (v_back - v).abs() <= tolerance) {
                return Verdict::Wrong(format!(
                    "pixel ({u}, {v}) undistorted to ({x}, {y}), which distorts to ({u_back}, {v_back})"
                ));
            }
        }
    }
    Verdict::Accepted
}
