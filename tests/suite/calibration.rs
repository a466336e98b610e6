//! Calibration files: the ROS `camera_info` and OpenCV YAML fixtures load with the values written in them, and every
//! malformed file gives a named error (never a panic).

use servostack::camera::{
    CalibratedCamera, CalibrationError, CalibrationFormat, CameraError, UNDISTORTION_TOLERANCE,
};
use std::path::Path;

const ROS: &str = include_str!("../data/ros_camera_info.yaml");
const OPENCV: &str = include_str!("../data/opencv_calibration.yaml");

fn data(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

#[test]
fn ros_camera_info_loads() {
    assert_eq!(
        CalibrationFormat::detect(ROS),
        CalibrationFormat::RosCameraInfo
    );
    let camera = CalibratedCamera::from_yaml_file(data("ros_camera_info.yaml")).unwrap();
    let k = camera.intrinsics;
    assert_eq!(
        (k.fx(), k.fy(), k.cx(), k.cy(), k.width(), k.height()),
        (612.5, 611.75, 318.25, 241.5, 640.0, 480.0)
    );
    assert_eq!(
        camera.distortion.coefficients(),
        [-0.2875, 0.0812, 0.00041, -0.00073, -0.0104]
    );
}

#[test]
fn opencv_file_storage_loads() {
    assert_eq!(CalibrationFormat::detect(OPENCV), CalibrationFormat::OpenCv);
    let camera = CalibratedCamera::from_yaml_file(data("opencv_calibration.yaml")).unwrap();
    let k = camera.intrinsics;
    assert_eq!(
        (k.fx(), k.fy(), k.cx(), k.cy(), k.width(), k.height()),
        (912.345, 910.987, 640.12, 360.45, 1280.0, 720.0)
    );
    assert_eq!(
        camera.distortion.coefficients(),
        [0.10123, -0.23456, 0.0012, -0.0009, 0.12345]
    );
    // Four coefficients: k3 = 0.
    let four = CalibratedCamera::from_yaml_file(data("opencv_four_coefficients.yaml")).unwrap();
    assert_eq!(
        four.distortion.coefficients(),
        [-0.1, 0.02, 0.001, 0.002, 0.0]
    );
}

/// Pixels measured by the loaded camera map back to the normalised points that produced them.
#[test]
fn loaded_camera_round_trips_pixels() {
    let camera = CalibratedCamera::from_yaml_str(ROS).unwrap();
    for (x, y) in [(0.0, 0.0), (0.4, -0.3), (-0.45, 0.35), (0.1, 0.38)] {
        let (u, v) = camera.pixel_of(x, y);
        let (xr, yr) = camera.normalized_of(u, v).unwrap();
        assert!(
            (xr - x).abs() < 10.0 * UNDISTORTION_TOLERANCE,
            "{xr} vs {x}"
        );
        assert!(
            (yr - y).abs() < 10.0 * UNDISTORTION_TOLERANCE,
            "{yr} vs {y}"
        );
    }
    assert!(matches!(
        camera.normalized_of(f64::NAN, 3.0),
        Err(CameraError::NonFiniteImagePoint { .. })
    ));
}

fn edited(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "fixture text not found: {from}");
    text.replacen(from, to, 1)
}

fn ros_error(from: &str, to: &str) -> CalibrationError {
    CalibratedCamera::from_yaml_str(&edited(ROS, from, to)).expect_err("should be rejected")
}

const K: &str = "data: [612.5, 0, 318.25, 0, 611.75, 241.5, 0, 0, 1]";
const D: &str = "data: [-0.2875, 0.0812, 0.00041, -0.00073, -0.0104]";

#[test]
fn missing_fields_are_named() {
    assert_eq!(
        ros_error("image_width: 640\n", ""),
        CalibrationError::MissingField {
            field: "image_width or image_Width".into()
        }
    );
    assert_eq!(
        ros_error(&format!("  {K}\n"), ""),
        CalibrationError::MissingField {
            field: "camera_matrix.data".into()
        }
    );
    let without_distortion = ROS.split("distortion_model").next().unwrap();
    assert_eq!(
        CalibratedCamera::from_yaml_str(without_distortion).unwrap_err(),
        CalibrationError::MissingField {
            field: "distortion_coefficients or Distortion_Coefficients".into()
        }
    );
}

#[test]
fn wrong_sizes_are_named() {
    assert_eq!(
        ros_error(K, "data: [612.5, 0, 318.25, 0, 611.75, 241.5, 0, 0]"),
        CalibrationError::DataLength {
            field: "camera_matrix",
            rows: 3,
            cols: 3,
            found: 8
        }
    );
    assert_eq!(
        ros_error(
            "  rows: 3\n  cols: 3\n  data: [612.5",
            "  rows: 1\n  cols: 9\n  data: [612.5"
        ),
        CalibrationError::MatrixShape {
            field: "camera_matrix",
            rows: 1,
            cols: 9,
            expected: "3 × 3"
        }
    );
    assert_eq!(
        ros_error("  rows: 1\n  cols: 5\n", "  rows: 5\n  cols: 5\n"),
        CalibrationError::DataLength {
            field: "distortion_coefficients",
            rows: 5,
            cols: 5,
            found: 5
        }
    );
    assert!(matches!(
        ros_error("  rows: 3\n  cols: 3\n  data: [612.5", "  rows: -3\n  cols: 3\n  data: [612.5"),
        CalibrationError::WrongType { field, .. } if field == "camera_matrix.rows"
    ));
}

#[test]
fn non_finite_and_negative_values_are_named() {
    assert_eq!(
        ros_error(K, "data: [612.5, 0, .nan, 0, 611.75, 241.5, 0, 0, 1]").to_string(),
        CalibrationError::NonFiniteEntry {
            field: "camera_matrix",
            index: 2,
            value: f64::NAN
        }
        .to_string()
    );
    assert!(matches!(
        ros_error(D, "data: [-0.2875, .inf, 0.00041, -0.00073, -0.0104]"),
        CalibrationError::NonFiniteEntry {
            field: "distortion_coefficients",
            index: 1,
            ..
        }
    ));
    assert_eq!(
        ros_error(K, "data: [-612.5, 0, 318.25, 0, 611.75, 241.5, 0, 0, 1]"),
        CalibrationError::Camera(CameraError::InvalidIntrinsic {
            name: "fx",
            value: -612.5,
            expected: servostack::bounds::FOCAL_LENGTH_PX.text,
        })
    );
    assert!(matches!(
        ros_error("image_height: 480", "image_height: 0"),
        CalibrationError::WrongType { field, .. } if field == "image_height"
    ));
    assert!(matches!(
        ros_error(K, "data: [612.5, 0, \"abc\", 0, 611.75, 241.5, 0, 0, 1]"),
        CalibrationError::WrongType { field, .. } if field == "camera_matrix.data"
    ));
}

#[test]
fn unsupported_distortion_is_named() {
    assert_eq!(
        ros_error(
            &format!("  cols: 5\n  {D}"),
            "  cols: 3\n  data: [-0.2875, 0.0812, 0.00041]"
        ),
        CalibrationError::Camera(CameraError::DistortionCoefficientCount { count: 3 })
    );
    assert_eq!(
        ros_error("plumb_bob", "equidistant"),
        CalibrationError::UnsupportedDistortionModel {
            model: "equidistant".into()
        }
    );
}

#[test]
fn malformed_camera_matrices_are_named() {
    assert_eq!(
        ros_error(K, "data: [612.5, 0.5, 318.25, 0, 611.75, 241.5, 0, 0, 1]"),
        CalibrationError::Skew { skew: 0.5 }
    );
    assert_eq!(
        ros_error(K, "data: [612.5, 0, 318.25, 0, 611.75, 241.5, 0, 0, 2]"),
        CalibrationError::NotACameraMatrix {
            k10: 0.0,
            last_row: [0.0, 0.0, 2.0]
        }
    );
}

#[test]
fn unreadable_files_are_named() {
    assert!(matches!(
        CalibratedCamera::from_yaml_str("camera_matrix: [unclosed"),
        Err(CalibrationError::Yaml { .. })
    ));
    assert!(matches!(
        CalibratedCamera::from_yaml_str(""),
        Err(CalibrationError::Yaml { .. })
    ));
    assert!(matches!(
        CalibratedCamera::from_yaml_str("- 1\n- 2\n"),
        Err(CalibrationError::WrongType { .. })
    ));
    assert!(matches!(
        CalibratedCamera::from_yaml_file(Path::new("/nonexistent/calibration.yaml")),
        Err(CalibrationError::Io { .. })
    ));
}
