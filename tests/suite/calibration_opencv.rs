//! Calibration files in the shapes OpenCV's own samples and tutorials write them (issue 47): the ArUco samples' camera
//! parameters (no image size), the calibration tutorial's `out_camera_data.yml` (`Camera_Matrix`, `image_Width`),
//! `samples/cpp/calibration.cpp`'s output with its extra fields, and the rational (8) and thin-prism (12) models.
//! The fixtures under `tests/data/` were written for these tests, in those shapes, with their own numbers.
//!
//! Each file is checked against what OpenCV reads: the intrinsics, size and coefficients expected are the numbers
//! written in the file, and the reference pixels are `cv2.projectPoints` (OpenCV 5.0.0, opencv-python-headless) of
//! the camera-frame points `(0.12, −0.08, 0.5)` and `(−0.2, 0.15, 0.6)` (m) with the file's camera matrix and
//! coefficients as `cv2.FileStorage` read them, no rotation or translation.

use servostack::camera::{
    CalibratedCamera, CalibrationError, CalibrationOptions, CameraError, UNDISTORTION_TOLERANCE,
};
use std::path::{Path, PathBuf};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn text(name: &str) -> String {
    std::fs::read_to_string(data(name)).unwrap()
}

/// `text` with the first `from` replaced by `to`, which must be there.
fn edited(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "fixture text not found: {from}");
    text.replacen(from, to, 1)
}

/// What a file should load as: intrinsics `(fx, fy, cx, cy, width, height)` (px), coefficients, and the pixels
/// OpenCV projects the two points of the module docs to.
struct Expected<'a> {
    intrinsics: [f64; 6],
    coefficients: &'a [f64],
    pixels: [(f64, f64); 2],
}

const POINTS: [(f64, f64, f64); 2] = [(0.12, -0.08, 0.5), (-0.2, 0.15, 0.6)];

fn assert_loads_as(camera: &CalibratedCamera, expected: &Expected) {
    let k = camera.intrinsics;
    assert_eq!(
        [k.fx(), k.fy(), k.cx(), k.cy(), k.width(), k.height()],
        expected.intrinsics
    );
    assert_eq!(camera.distortion.coefficients(), expected.coefficients);
    for ((x, y, z), (u, v)) in POINTS.into_iter().zip(expected.pixels) {
        let (u_, v_) = camera.pixel_of(x / z, y / z);
        // OpenCV computes in double too: a few ulps of a thousand-pixel coordinate.
        assert!(
            (u_ - u).abs() < 1e-9 && (v_ - v).abs() < 1e-9,
            "({u_}, {v_}) vs OpenCV's ({u}, {v})"
        );
        let (xr, yr) = camera.normalized_of(u, v).unwrap();
        assert!((xr - x / z).abs() < 1e-9 && (yr - y / z).abs() < 1e-9);
    }
}

#[test]
fn aruco_sample_without_image_size_loads_with_the_size_given() {
    let error = CalibratedCamera::from_yaml_file(data("opencv_aruco_no_size.yml")).unwrap_err();
    assert_eq!(error, CalibrationError::MissingImageSize);
    // The message says how to give the size.
    let message = error.to_string();
    assert!(
        message.contains("with_image_size") && message.contains("from_yaml_file_with"),
        "{message}"
    );

    let options = CalibrationOptions::default().with_image_size(640, 480);
    let camera =
        CalibratedCamera::from_yaml_file_with(data("opencv_aruco_no_size.yml"), options).unwrap();
    assert_loads_as(
        &camera,
        &Expected {
            intrinsics: [628.71534, 626.93217, 324.156, 238.987, 640.0, 480.0],
            coefficients: &[-0.41287, 0.23109, -0.00076, 0.00118, -0.08543],
            pixels: [
                (470.282_272_022_647_6, 141.847_172_997_149_67),
                (128.613_345_659_275_15, 385.241_645_735_415_66),
            ],
        },
    );
}

#[test]
fn calibration_tutorial_output_loads() {
    let path = data("opencv_tutorial_out_camera_data.yml");
    let expected = Expected {
        intrinsics: [
            712.3456000000001,
            712.3456000000001,
            399.5,
            299.5,
            800.0,
            600.0,
        ],
        coefficients: &[-0.20512, 0.11734, 0.0, 0.0, -0.03105],
        pixels: [
            (567.681_101_480_445_2, 187.379_265_679_703_1),
            (169.706_063_071_617_73, 471.845_452_696_286_66),
        ],
    };
    assert_loads_as(&CalibratedCamera::from_yaml_file(&path).unwrap(), &expected);
    // The same size given again is no conflict; another one is.
    let same = CalibrationOptions::default().with_image_size(800, 600);
    assert_loads_as(
        &CalibratedCamera::from_yaml_file_with(&path, same).unwrap(),
        &expected,
    );
    let other = CalibrationOptions::default().with_image_size(1600, 1200);
    assert_eq!(
        CalibratedCamera::from_yaml_file_with(&path, other).unwrap_err(),
        CalibrationError::ImageSizeConflict {
            file_width: 800,
            file_height: 600,
            given_width: 1600,
            given_height: 1200
        }
    );
}

#[test]
fn calibration_sample_output_with_extrinsics_and_image_points_loads() {
    let camera = CalibratedCamera::from_yaml_file(data("opencv_calibration_cpp.yml")).unwrap();
    assert_loads_as(
        &camera,
        &Expected {
            intrinsics: [1402.7250000000001, 1401.1375, 963.4, 541.7, 1920.0, 1080.0],
            coefficients: &[0.08765, -0.19875, 0.0, 0.0, 0.09123],
            pixels: [
                (1_302.063_564_122_041_5, 316.179_806_768_945_35),
                (491.287_692_911_187_2, 895.383_504_076_165),
            ],
        },
    );
}

#[test]
fn rational_model_loads() {
    let camera = CalibratedCamera::from_yaml_file(data("opencv_rational.yaml")).unwrap();
    assert_loads_as(
        &camera,
        &Expected {
            intrinsics: [600.0, 600.0, 320.0, 240.0, 640.0, 480.0],
            coefficients: &[-0.1, 0.02, 0.001, 0.002, 0.0, 0.01, 0.0, 0.0],
            pixels: [
                (462.895_127_049_494_8, 144.853_061_967_003_44),
                (124.067_470_633_545_18, 387.209_813_691_507_8),
            ],
        },
    );
}

const THIN_PRISM: [f64; 12] = [
    0.32145,
    -0.12345,
    0.00042,
    -0.00031,
    0.018760000000000002,
    0.65432,
    -0.08765,
    0.04567,
    0.00123,
    -0.000456,
    -0.000987,
    0.000234,
];

fn thin_prism_expected() -> Expected<'static> {
    Expected {
        intrinsics: [1050.321, 1049.7654, 642.87, 478.13, 1280.0, 960.0],
        coefficients: &THIN_PRISM,
        pixels: [
            (888.265_315_012_660_3, 314.623_201_091_895_2),
            (311.362_818_049_411_26, 726.647_865_337_893_3),
        ],
    }
}

#[test]
fn thin_prism_model_loads_and_a_tilt_is_refused() {
    let file = text("opencv_thin_prism.yml");
    assert_loads_as(
        &CalibratedCamera::from_yaml_str(&file).unwrap(),
        &thin_prism_expected(),
    );
    // The tilted model's 14 coefficients with zero tilt: the same lens.
    let last = "2.3400000000000000e-04 ]";
    let with_tilt = |tau: &str| {
        edited(
            &edited(&file, "cols: 12", "cols: 14"),
            last,
            &format!("2.3400000000000000e-04, {tau} ]"),
        )
    };
    assert_loads_as(
        &CalibratedCamera::from_yaml_str(&with_tilt("0., 0.")).unwrap(),
        &thin_prism_expected(),
    );
    assert_eq!(
        CalibratedCamera::from_yaml_str(&with_tilt("0.0015, 0.")).unwrap_err(),
        CalibrationError::Camera(CameraError::TiltedDistortion {
            tau_x: 0.0015,
            tau_y: 0.0
        })
    );
    // The tutorial's fisheye flag: its coefficients are another model's.
    assert_eq!(
        CalibratedCamera::from_yaml_str(&edited(&file, "fisheye_model: 0", "fisheye_model: 1"))
            .unwrap_err(),
        CalibrationError::UnsupportedDistortionModel {
            model: "fisheye (fisheye_model set)".into()
        }
    );
}

#[test]
fn unsupported_coefficient_counts_are_named() {
    let file = text("opencv_thin_prism.yml");
    let first_eleven = edited(
        &edited(&file, "cols: 12", "cols: 11"),
        ",\n       -9.8700000000000003e-04",
        "",
    );
    assert_eq!(
        CalibratedCamera::from_yaml_str(&first_eleven).unwrap_err(),
        CalibrationError::Camera(CameraError::DistortionCoefficientCount { count: 11 })
    );
}

#[test]
fn directive_spellings_and_duplicated_fields() {
    let file = text("opencv_tutorial_out_camera_data.yml");
    // `%YAML 1.0` (with a space) as well as OpenCV's `%YAML:1.0`.
    let spaced = edited(&file, "%YAML:1.0", "%YAML 1.0");
    assert!(CalibratedCamera::from_yaml_str(&spaced).is_ok());
    // A field under two of its keys.
    let twice = edited(
        &file,
        "image_Width: 800",
        "image_Width: 800\nimage_width: 800",
    );
    assert_eq!(
        CalibratedCamera::from_yaml_str(&twice).unwrap_err(),
        CalibrationError::DuplicateField {
            first: "image_width",
            second: "image_Width"
        }
    );
    // One of the two sizes: the other is named with its accepted keys.
    let no_height = edited(&file, "image_Height: 600\n", "");
    assert_eq!(
        CalibratedCamera::from_yaml_str(&no_height).unwrap_err(),
        CalibrationError::MissingField {
            field: "image_height or image_Height".into()
        }
    );
    // Errors inside a matrix name its key as written.
    let short = edited(&file, "0., 0., 1. ]", "0., 0. ]");
    assert_eq!(
        CalibratedCamera::from_yaml_str(&short).unwrap_err(),
        CalibrationError::DataLength {
            field: "Camera_Matrix",
            rows: 3,
            cols: 3,
            found: 8
        }
    );
}

#[test]
fn given_image_sizes_are_checked() {
    let file = text("opencv_aruco_no_size.yml");
    for (width, height, name) in [
        (0, 480, "width"),
        (640, 0, "height"),
        (2_000_000, 480, "width"),
    ] {
        let options = CalibrationOptions::default().with_image_size(width, height);
        assert!(
            matches!(
                CalibratedCamera::from_yaml_str_with(&file, options),
                Err(CalibrationError::Camera(CameraError::InvalidIntrinsic { name: n, .. })) if n == name
            ),
            "{width} × {height}"
        );
    }
}

#[test]
fn ros_rational_polynomial_loads() {
    let ros = text("ros_camera_info.yaml");
    let rational = edited(&ros, "plumb_bob", "rational_polynomial");
    let rational = edited(&rational, "cols: 5", "cols: 8");
    let rational = edited(&rational, "-0.0104]", "-0.0104, 0.0021, -0.0003, 0.00005]");
    let camera = CalibratedCamera::from_yaml_str(&rational).unwrap();
    assert_eq!(
        camera.distortion.coefficients(),
        [-0.2875, 0.0812, 0.00041, -0.00073, -0.0104, 0.0021, -0.0003, 0.00005]
    );
    let (u, v) = camera.pixel_of(0.3, -0.2);
    let (x, y) = camera.normalized_of(u, v).unwrap();
    assert!((x - 0.3).abs() < 10.0 * UNDISTORTION_TOLERANCE);
    assert!((y + 0.2).abs() < 10.0 * UNDISTORTION_TOLERANCE);
}
