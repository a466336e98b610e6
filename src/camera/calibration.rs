//! Loading a [`CalibratedCamera`] from the calibration files people have: the ROS `camera_info` YAML
//! (`camera_calibration_parsers`) and OpenCV's `FileStorage` YAML (`cv::calibrateCamera` samples).
//!
//! Fields read (both formats):
//!
//! | field | meaning |
//! |---|---|
//! | `image_width`, `image_height` | image size (px) |
//! | `camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}` | pinhole intrinsics (px), row-major |
//! | `distortion_coefficients: {rows, cols, data}` | `(k1, k2, p1, p2)` or `(k1, k2, p1, p2, k3)`, a 1 × n or n × 1 matrix |
//! | `distortion_model` (ROS only, optional) | must be `plumb_bob` (Brown–Conrady) when present |
//!
//! Other fields (`camera_name`, `rectification_matrix`, `projection_matrix`, `calibration_time`, `dt`, ...) are
//! ignored.
//!
//! OpenCV writes a `%YAML:1.0` directive (not valid YAML: the directive needs a space) and tags its matrices
//! `!!opencv-matrix`. Before parsing, the directive line is dropped and the tag removed; the rest is parsed by
//! `yaml-rust2` as YAML 1.2.
//!
//! Bounds ([D17](crate::theory#d17)): a file is read through a reader that stops past [`MAX_CALIBRATION_BYTES`]
//! (calibration files are a few hundred bytes); before the document is built, its events are scanned once for YAML
//! aliases, which are refused (no calibration tool writes them, and a few kilobytes of nested aliases expand to
//! billions of nodes), and for collections nested deeper than [`MAX_CALIBRATION_DEPTH`] levels.

use super::{BrownConrady, CalibratedCamera, CameraError, CameraIntrinsics};
use crate::bounds::{read_text_file, ReadFailure};
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
        /// The field (`"camera_matrix.data"`, ...).
        field: String,
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
    /// `distortion_model` names another model than `plumb_bob`.
    #[error("distortion_model `{model}` is not supported: only `plumb_bob` (Brown–Conrady k1, k2, p1, p2, k3) is")]
    UnsupportedDistortionModel {
        /// The model named in the file.
        model: String,
    },
    /// The intrinsics or the distortion coefficients are invalid (negative focal length, 8 coefficients, ...).
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

/// The YAML text with OpenCV's non-standard `%YAML:1.0` directive line dropped and `!!opencv-matrix` tags removed.
fn normalized_yaml(text: &str) -> String {
    let without_directive = match text.trim_start().strip_prefix("%YAML:") {
        Some(rest) => rest.split_once('\n').map_or("", |(_, body)| body),
        None => text,
    };
    without_directive.replace("!!opencv-matrix", "")
}

impl CalibratedCamera {
    /// A calibrated camera from the text of a ROS `camera_info` or OpenCV YAML calibration file (format detected by
    /// [`CalibrationFormat::detect`]; fields in the module docs).
    ///
    /// # Errors
    /// A [`CalibrationError`] naming the field at fault: invalid YAML, a missing field, a wrong type, a matrix of the
    /// wrong size, a non-finite entry, a skewed camera matrix, a distortion model other than `plumb_bob`, 8 (rational)
    /// or another count than 4/5 distortion coefficients, a non-positive focal length or image size.
    pub fn from_yaml_str(text: &str) -> Result<Self, CalibrationError> {
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
        if let Some(model) = optional(root, "distortion_model") {
            match model.as_str() {
                Some("plumb_bob") => {}
                Some(other) => {
                    return Err(CalibrationError::UnsupportedDistortionModel {
                        model: other.to_owned(),
                    })
                }
                None => return Err(wrong_type("distortion_model", "a string")),
            }
        }
        let width = size(root, "image_width")?;
        let height = size(root, "image_height")?;
        let (rows, cols, k) = matrix(root, "camera_matrix")?;
        if (rows, cols) != (3, 3) {
            return Err(CalibrationError::MatrixShape {
                field: "camera_matrix",
                rows,
                cols,
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
        let (rows, cols, coefficients) = matrix(root, "distortion_coefficients")?;
        if rows != 1 && cols != 1 {
            return Err(CalibrationError::MatrixShape {
                field: "distortion_coefficients",
                rows,
                cols,
                expected: "1 × n or n × 1",
            });
        }
        let distortion = BrownConrady::from_coefficients(&coefficients)?;
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
        Self::from_yaml_str(&text)
    }
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

fn wrong_type(field: &str, expected: &'static str) -> CalibrationError {
    CalibrationError::WrongType {
        field: field.to_owned(),
        expected,
    }
}

/// The node `parent[key]`, `None` when absent or null.
fn optional<'a>(parent: &'a Yaml, key: &str) -> Option<&'a Yaml> {
    let node = &parent[key];
    (!node.is_badvalue() && !node.is_null()).then_some(node)
}

/// The node `parent[key]` of the field named `field`.
fn required<'a>(parent: &'a Yaml, key: &str, field: &str) -> Result<&'a Yaml, CalibrationError> {
    optional(parent, key).ok_or_else(|| CalibrationError::MissingField {
        field: field.to_owned(),
    })
}

/// A YAML number (integer or real, including `.nan` and `.inf`) as `f64`.
fn number(node: &Yaml) -> Option<f64> {
    match node {
        Yaml::Integer(i) => Some(*i as f64),
        Yaml::Real(_) => node.as_f64(),
        _ => None,
    }
}

/// An image size: a positive integer (px).
fn size(root: &Yaml, field: &str) -> Result<f64, CalibrationError> {
    match required(root, field, field)? {
        Yaml::Integer(i) if *i > 0 => Ok(*i as f64),
        _ => Err(wrong_type(field, "a positive integer (px)")),
    }
}

/// Largest `rows` or `cols` accepted (calibration matrices are at most 3 × 4 or 1 × 14).
const MAX_MATRIX_SIDE: i64 = 64;

/// `(rows, cols, data)` of the matrix `field`, with `data.len() == rows · cols` and every entry finite.
fn matrix(root: &Yaml, field: &'static str) -> Result<(usize, usize, Vec<f64>), CalibrationError> {
    let node = required(root, field, field)?;
    if !matches!(node, Yaml::Hash(_)) {
        return Err(wrong_type(field, "a mapping with rows, cols and data"));
    }
    let dimension = |key: &str| -> Result<usize, CalibrationError> {
        let name = format!("{field}.{key}");
        match required(node, key, &name)? {
            Yaml::Integer(i) if (1..=MAX_MATRIX_SIDE).contains(i) => Ok(*i as usize),
            _ => Err(wrong_type(&name, "an integer from 1 to 64")),
        }
    };
    let (rows, cols) = (dimension("rows")?, dimension("cols")?);
    let data_field = format!("{field}.data");
    let Yaml::Array(entries) = required(node, "data", &data_field)? else {
        return Err(wrong_type(&data_field, "a list of numbers"));
    };
    if entries.len() != rows * cols {
        return Err(CalibrationError::DataLength {
            field,
            rows,
            cols,
            found: entries.len(),
        });
    }
    let data = entries
        .iter()
        .map(|e| number(e).ok_or_else(|| wrong_type(&data_field, "a list of numbers")))
        .collect::<Result<Vec<f64>, _>>()?;
    if let Some((index, &value)) = data.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(CalibrationError::NonFiniteEntry {
            field,
            index,
            value,
        });
    }
    Ok((rows, cols, data))
}
