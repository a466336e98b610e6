//! Loading a [`CalibratedCamera`] from the calibration files people have: the ROS `camera_info` YAML
//! (`camera_calibration_parsers`) and OpenCV's `FileStorage` YAML (`cv::calibrateCamera` samples and tutorials, the
//! ArUco samples' camera parameters).
//!
//! Fields read, under any of the keys listed (the tools' own spellings, exactly; a field written under two of its
//! keys is [`CalibrationError::DuplicateField`]):
//!
//! | field | keys | meaning |
//! |---|---|---|
//! | image width, height | `image_width`, `image_Width`; `image_height`, `image_Height` | image size (px), optional: see below |
//! | camera matrix | `camera_matrix`, `Camera_Matrix` | `{rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}`, pinhole intrinsics (px), row-major |
//! | distortion | `distortion_coefficients`, `Distortion_Coefficients` | a 1 × n or n × 1 matrix of 4, 5, 8, 12 or 14 coefficients in OpenCV's order ([`BrownConrady::from_coefficients`]) |
//! | distortion model (ROS) | `distortion_model` | optional; `plumb_bob` or `rational_polynomial` (the coefficients' count says which, as ROS's `image_geometry` reads them) |
//! | fisheye flag (OpenCV tutorial) | `fisheye_model` | optional; must be 0 (the fisheye model's coefficients are another model's) |
//!
//! The lower-case keys are written by ROS, OpenCV's `samples/cpp/calibration.cpp` and the calibration tutorial's
//! current `camera_calibration.cpp`; `image_Width`, `Camera_Matrix`, ... by the tutorial's older `out_camera_data.yml`;
//! the ArUco samples' camera parameters have no image size. Other fields (`camera_name`, `rectification_matrix`,
//! `projection_matrix`, `calibration_time`, `nr_of_frames`, `board_width`, `square_size`, `flags`,
//! `avg_reprojection_error`, `extrinsic_parameters`, `image_points`, a matrix's `dt`, ...) are ignored.
//!
//! **The image size.** A file without one loads only when the caller gives it, with
//! [`CalibrationOptions::with_image_size`] and [`CalibratedCamera::from_yaml_str_with`] (or
//! [`from_yaml_file_with`](CalibratedCamera::from_yaml_file_with)); otherwise it is
//! [`CalibrationError::MissingImageSize`]. A size given for a file that has another is
//! [`CalibrationError::ImageSizeConflict`]: intrinsics hold for the resolution they were calibrated at (a scaled or
//! cropped image has other `fx`, `cx`), so neither size can be picked silently.
//!
//! OpenCV writes a `%YAML:1.0` directive (not valid YAML: the directive needs a space; some files have `%YAML 1.0`)
//! and tags its matrices `!!opencv-matrix`. Before parsing, the directive line is dropped and the tag removed; the
//! rest is parsed by `yaml-rust2` as YAML 1.2.
//!
//! Bounds ([D17](crate::theory#d17)): a file is read through a reader that stops past [`MAX_CALIBRATION_BYTES`]
//! (calibration files are a few hundred bytes); before the document is built, its events are scanned once for YAML
//! aliases, which are refused (no calibration tool writes them, and a few kilobytes of nested aliases expand to
//! billions of nodes), and for collections nested deeper than [`MAX_CALIBRATION_DEPTH`] levels.

mod fields;

use super::{BrownConrady, CalibratedCamera, CameraError, CameraIntrinsics};
use crate::bounds::{read_text_file, ReadFailure};
use fields::{
    find, matrix, wrong_type, CAMERA_MATRIX, DISTORTION_COEFFICIENTS, DISTORTION_MODEL,
    FISHEYE_MODEL,
};
use std::path::Path;
use yaml_rust2::parser::{Event, Parser};
use yaml_rust2::{Yaml, YamlLoader};

/// The largest calibration file read (bytes): 1 MiB. A calibration file is a few hundred bytes; to parse a larger
/// text, read it yourself and pass it to [`CalibratedCamera::from_yaml_str`].
pub const MAX_CALIBRATION_BYTES: usize = 1 << 20;

/// The deepest nesting of YAML collections accepted in a calibration text: 16 levels (the formats nest 2).
pub const MAX_CALIBRATION_DEPTH: usize = 16;

/// Errors of calibration-file loading. Each names the field at fault.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrationError {
    /// The file could not be read.
    #[error("cannot read calibration file {path}: {message}")]
    Io {
        /// The path.
        path: String,
        /// The system's message.
        message: String,
    },
    /// The file is larger than [`MAX_CALIBRATION_BYTES`], checked before it is read.
    #[error("calibration file {path} has {bytes} bytes, above the limit of {limit} (to parse a larger text, read it and pass it to CalibratedCamera::from_yaml_str)")]
    TooLarge {
        /// The path.
        path: String,
        /// Its size (bytes; `limit + 1` when the size is known only by reading, as for a pipe).
        bytes: u64,
        /// The limit (bytes).
        limit: usize,
    },
    /// The text uses a YAML alias (`*name`), or nests collections deeper than [`MAX_CALIBRATION_DEPTH`].
    #[error("calibration text refused at line {line}: {reason}")]
    Refused {
        /// The line (from 1).
        line: usize,
        /// Why.
        reason: &'static str,
    },
    /// The text is not YAML (or is empty).
    #[error("calibration file is not valid YAML: {message}")]
    Yaml {
        /// The parser's message.
        message: String,
    },
    /// A required field is absent.
    #[error("calibration field `{field}` is missing")]
    MissingField {
        /// The field, by the keys accepted for it (`"camera_matrix or Camera_Matrix"`, `"camera_matrix.data"`, ...).
        field: String,
    },
    /// A field is written twice, under two of its accepted keys.
    #[error("calibration field written twice, as `{first}` and `{second}`")]
    DuplicateField {
        /// The first key.
        first: &'static str,
        /// The second.
        second: &'static str,
    },
    /// The file has no image size and the caller gave none.
    #[error("the calibration file has no image size (image_width, image_height): give it with CalibrationOptions::default().with_image_size(width, height) and CalibratedCamera::from_yaml_str_with or from_yaml_file_with")]
    MissingImageSize,
    /// The caller gave an image size and the file has another.
    #[error("the calibration file is for {file_width} × {file_height} px images, but {given_width} × {given_height} px was given: intrinsics hold only at the size they were calibrated at")]
    ImageSizeConflict {
        /// Width in the file (px).
        file_width: u64,
        /// Height in the file (px).
        file_height: u64,
        /// Width given (px).
        given_width: u32,
        /// Height given (px).
        given_height: u32,
    },
    /// A field has the wrong type.
    #[error("calibration field `{field}` must be {expected}")]
    WrongType {
        /// The field.
        field: String,
        /// What it must be.
        expected: &'static str,
    },
    /// A matrix's `rows × cols` is not the expected shape.
    #[error("calibration matrix `{field}` is {rows} × {cols}, expected {expected}")]
    MatrixShape {
        /// The field.
        field: &'static str,
        /// Its rows.
        rows: usize,
        /// Its columns.
        cols: usize,
        /// The expected shape.
        expected: &'static str,
    },
    /// A matrix's `data` does not have `rows · cols` entries.
    #[error("calibration matrix `{field}` is {rows} × {cols} but its data has {found} entries")]
    DataLength {
        /// The field.
        field: &'static str,
        /// Its rows.
        rows: usize,
        /// Its columns.
        cols: usize,
        /// Entries in `data`.
        found: usize,
    },
    /// An entry of a matrix is NaN or infinite.
    #[error("calibration matrix `{field}`: entry {index} = {value} is not finite")]
    NonFiniteEntry {
        /// The field.
        field: &'static str,
        /// The entry's index in `data` (row-major).
        index: usize,
        /// Its value.
        value: f64,
    },
    /// The camera matrix has a non-zero skew `K[0][1]`, which the pinhole model here does not have.
    #[error("camera_matrix has skew {skew}: only zero skew is supported")]
    Skew {
        /// `K[0][1]`.
        skew: f64,
    },
    /// The camera matrix's other fixed entries (`K[1][0]` and the last row) are not `0` and `(0, 0, 1)`.
    #[error("camera_matrix is not of the form [fx 0 cx; 0 fy cy; 0 0 1]: K[1][0] = {k10}, last row {last_row:?}")]
    NotACameraMatrix {
        /// `K[1][0]`.
        k10: f64,
        /// `K[2][·]`.
        last_row: [f64; 3],
    },
    /// `distortion_model` names another model than `plumb_bob` or `rational_polynomial`, or `fisheye_model` is set.
    #[error("distortion model `{model}` is not supported: only `plumb_bob` and `rational_polynomial` (OpenCV's k1, k2, p1, p2[, k3[, k4, k5, k6[, s1 … s4]]]) are")]
    UnsupportedDistortionModel {
        /// The model named in the file.
        model: String,
    },
    /// The intrinsics or the distortion coefficients are invalid (negative focal length, 7 coefficients, a tilt, ...).
    #[error(transparent)]
    Camera(#[from] CameraError),
}

/// The calibration file formats understood by [`CalibratedCamera::from_yaml_str`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CalibrationFormat {
    /// ROS `camera_info` YAML (`camera_calibration_parsers`).
    RosCameraInfo,
    /// OpenCV `FileStorage` YAML (`%YAML:1.0`, `!!opencv-matrix`).
    OpenCv,
}

impl CalibrationFormat {
    /// The format of a calibration text: OpenCV when it starts with the `%YAML:` directive or tags a matrix
    /// `!!opencv-matrix`, ROS otherwise.
    pub fn detect(text: &str) -> Self {
        if text.trim_start().starts_with("%YAML:") || text.contains("!!opencv-matrix") {
            Self::OpenCv
        } else {
            Self::RosCameraInfo
        }
    }
}

/// The YAML text with OpenCV's directive line (`%YAML:1.0` or `%YAML 1.0`) dropped and `!!opencv-matrix` tags
/// removed.
fn normalized_yaml(text: &str) -> String {
    let trimmed = text.trim_start();
    let without_directive = match trimmed.strip_prefix("%YAML") {
        Some(rest) if rest.starts_with([':', ' ']) => {
            rest.split_once('\n').map_or("", |(_, body)| body)
        }
        _ => text,
    };
    without_directive.replace("!!opencv-matrix", "")
}

/// What the caller tells the reader beyond the file ([`CalibratedCamera::from_yaml_str_with`]). The default adds
/// nothing.
#[non_exhaustive]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CalibrationOptions {
    /// The image size `(width, height)` (px) for a file without one (the ArUco samples' camera parameters); for a
    /// file with one, it must be the same (module docs).
    pub image_size: Option<(u32, u32)>,
}

impl CalibrationOptions {
    /// These options with the image size `width × height` (px).
    pub fn with_image_size(self, width: u32, height: u32) -> Self {
        Self {
            image_size: Some((width, height)),
        }
    }
}

impl CalibratedCamera {
    /// A calibrated camera from the text of a ROS `camera_info` or OpenCV YAML calibration file (format detected by
    /// [`CalibrationFormat::detect`]; fields and their accepted keys in the module docs). The file must give the
    /// image size; for one without, see [`Self::from_yaml_str_with`].
    ///
    /// # Errors
    /// A [`CalibrationError`] naming the field at fault: invalid YAML, a missing or duplicated field, a wrong type, a
    /// matrix of the wrong size, a non-finite entry, a skewed camera matrix, an unsupported distortion model, a count
    /// of distortion coefficients other than 4, 5, 8, 12 or 14 (tilt zero), a non-positive focal length or image size;
    /// [`CalibrationError::MissingImageSize`] when the file has no image size.
    pub fn from_yaml_str(text: &str) -> Result<Self, CalibrationError> {
        Self::from_yaml_str_with(text, CalibrationOptions::default())
    }

    /// As [`Self::from_yaml_str`], with what the file leaves out given in `options`:
    ///
    /// ```
    /// # use servostack::camera::{CalibratedCamera, CalibrationOptions};
    /// let aruco_sample = "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n  \
    ///     data: [600., 0., 320., 0., 600., 240., 0., 0., 1.]\ndistortion_coefficients: !!opencv-matrix\n  \
    ///     rows: 1\n  cols: 5\n  dt: d\n  data: [0.1, -0.2, 0., 0., 0.]\n";
    /// let options = CalibrationOptions::default().with_image_size(640, 480);
    /// let camera = CalibratedCamera::from_yaml_str_with(aruco_sample, options)?;
    /// assert_eq!(camera.intrinsics.width(), 640.0);
    /// # Ok::<(), servostack::camera::CalibrationError>(())
    /// ```
    ///
    /// # Errors
    /// Those of [`Self::from_yaml_str`]; [`CalibrationError::ImageSizeConflict`] when the file's image size differs
    /// from the one given; [`CameraError::InvalidIntrinsic`] (in [`CalibrationError::Camera`]) for a given size of 0
    /// or above [`IMAGE_SIZE_PX`](crate::bounds::IMAGE_SIZE_PX).
    pub fn from_yaml_str_with(
        text: &str,
        options: CalibrationOptions,
    ) -> Result<Self, CalibrationError> {
        let text = normalized_yaml(text);
        check_structure(&text)?;
        let documents = YamlLoader::load_from_str(&text).map_err(|e| CalibrationError::Yaml {
            message: e.to_string(),
        })?;
        let root = match documents.first() {
            Some(root @ Yaml::Hash(_)) => root,
            Some(_) => {
                return Err(CalibrationError::WrongType {
                    field: "(document)".into(),
                    expected: "a mapping of calibration fields",
                })
            }
            None => {
                return Err(CalibrationError::Yaml {
                    message: "empty document".into(),
                })
            }
        };
        check_distortion_model(root)?;
        let (width, height) = match (fields::image_size(root)?, options.image_size) {
            (Some((width, height)), None) => (width as f64, height as f64),
            (None, Some((width, height))) => (f64::from(width), f64::from(height)),
            (Some(file), Some(given)) if file == (u64::from(given.0), u64::from(given.1)) => {
                (f64::from(given.0), f64::from(given.1))
            }
            (Some((file_width, file_height)), Some((given_width, given_height))) => {
                return Err(CalibrationError::ImageSizeConflict {
                    file_width,
                    file_height,
                    given_width,
                    given_height,
                })
            }
            (None, None) => return Err(CalibrationError::MissingImageSize),
        };
        let camera_matrix = matrix(root, &CAMERA_MATRIX)?;
        let k = &camera_matrix.data;
        if (camera_matrix.rows, camera_matrix.cols) != (3, 3) {
            return Err(CalibrationError::MatrixShape {
                field: camera_matrix.key,
                rows: camera_matrix.rows,
                cols: camera_matrix.cols,
                expected: "3 × 3",
            });
        }
        if k[1] != 0.0 {
            return Err(CalibrationError::Skew { skew: k[1] });
        }
        if k[3] != 0.0 || k[6..9] != [0.0, 0.0, 1.0] {
            return Err(CalibrationError::NotACameraMatrix {
                k10: k[3],
                last_row: [k[6], k[7], k[8]],
            });
        }
        let intrinsics = CameraIntrinsics::new(k[0], k[4], k[2], k[5], width, height)?;
        let coefficients = matrix(root, &DISTORTION_COEFFICIENTS)?;
        if coefficients.rows != 1 && coefficients.cols != 1 {
            return Err(CalibrationError::MatrixShape {
                field: coefficients.key,
                rows: coefficients.rows,
                cols: coefficients.cols,
                expected: "1 × n or n × 1",
            });
        }
        let distortion = BrownConrady::from_coefficients(&coefficients.data)?;
        Ok(Self {
            intrinsics,
            distortion,
        })
    }

    /// As [`Self::from_yaml_str`], reading the file at `path`.
    ///
    /// # Errors
    /// [`CalibrationError::Io`] when the file cannot be read, [`CalibrationError::TooLarge`], then those of
    /// [`Self::from_yaml_str`].
    pub fn from_yaml_file(path: impl AsRef<Path>) -> Result<Self, CalibrationError> {
        Self::from_yaml_file_with(path, CalibrationOptions::default())
    }

    /// As [`Self::from_yaml_str_with`], reading the file at `path`.
    ///
    /// # Errors
    /// [`CalibrationError::Io`] when the file cannot be read, [`CalibrationError::TooLarge`], then those of
    /// [`Self::from_yaml_str_with`].
    pub fn from_yaml_file_with(
        path: impl AsRef<Path>,
        options: CalibrationOptions,
    ) -> Result<Self, CalibrationError> {
        let path = path.as_ref();
        let text =
            read_text_file(path, MAX_CALIBRATION_BYTES).map_err(|failure| match failure {
                ReadFailure::Io(e) => CalibrationError::Io {
                    path: path.display().to_string(),
                    message: e.to_string(),
                },
                ReadFailure::TooLarge(bytes) => CalibrationError::TooLarge {
                    path: path.display().to_string(),
                    bytes,
                    limit: MAX_CALIBRATION_BYTES,
                },
            })?;
        Self::from_yaml_str_with(&text, options)
    }
}

/// Refuses a distortion model the coefficients do not describe: a ROS `distortion_model` other than `plumb_bob` or
/// `rational_polynomial` (`equidistant` is the fisheye model), or the OpenCV tutorial's `fisheye_model` flag set.
fn check_distortion_model(root: &Yaml) -> Result<(), CalibrationError> {
    if let Some((key, model)) = find(root, &DISTORTION_MODEL)? {
        match model.as_str() {
            Some("plumb_bob" | "rational_polynomial") => {}
            Some(other) => {
                return Err(CalibrationError::UnsupportedDistortionModel {
                    model: other.to_owned(),
                })
            }
            None => return Err(wrong_type(key, "a string")),
        }
    }
    if let Some((key, fisheye)) = find(root, &FISHEYE_MODEL)? {
        match fisheye {
            Yaml::Integer(0) | Yaml::Boolean(false) => {}
            Yaml::Integer(_) | Yaml::Boolean(true) => {
                return Err(CalibrationError::UnsupportedDistortionModel {
                    model: "fisheye (fisheye_model set)".to_owned(),
                })
            }
            _ => return Err(wrong_type(key, "0 or 1")),
        }
    }
    Ok(())
}

/// Scans the YAML events of `text` once, without building the document: refuses aliases and collections nested
/// deeper than [`MAX_CALIBRATION_DEPTH`] (module docs). Syntax errors are left to the loader, which names them.
fn check_structure(text: &str) -> Result<(), CalibrationError> {
    let mut parser = Parser::new_from_str(text);
    let mut depth = 0usize;
    loop {
        let Ok((event, mark)) = parser.next_token() else {
            return Ok(());
        };
        let refused = |reason| {
            Err(CalibrationError::Refused {
                line: mark.line(),
                reason,
            })
        };
        match event {
            Event::StreamEnd => return Ok(()),
            Event::Alias(_) => return refused("YAML aliases are not accepted"),
            Event::SequenceStart(..) | Event::MappingStart(..) => {
                depth += 1;
                if depth > MAX_CALIBRATION_DEPTH {
                    return refused("collections nested deeper than 16 levels");
                }
            }
            Event::SequenceEnd | Event::MappingEnd => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
}
