//! The fields of a calibration file, the keys each is written under, and their reading from the YAML document: the
//! table of the module docs, as code.

use super::CalibrationError;
use yaml_rust2::Yaml;

/// A field of a calibration file and the keys the tools write it under (the first is the usual one).
pub(super) struct Field {
    pub keys: &'static [&'static str],
}

/// The image width (px): ROS, OpenCV's `calibration.cpp` and the calibration tutorial write `image_width`; the
/// tutorial's older `out_camera_data.yml` writes `image_Width`.
pub(super) const IMAGE_WIDTH: Field = Field {
    keys: &["image_width", "image_Width"],
};
/// The image height (px), as [`IMAGE_WIDTH`].
pub(super) const IMAGE_HEIGHT: Field = Field {
    keys: &["image_height", "image_Height"],
};
/// The 3 × 3 camera matrix.
pub(super) const CAMERA_MATRIX: Field = Field {
    keys: &["camera_matrix", "Camera_Matrix"],
};
/// The distortion coefficients, a 1 × n or n × 1 matrix.
pub(super) const DISTORTION_COEFFICIENTS: Field = Field {
    keys: &["distortion_coefficients", "Distortion_Coefficients"],
};
/// ROS's name of the distortion model.
pub(super) const DISTORTION_MODEL: Field = Field {
    keys: &["distortion_model"],
};
/// The OpenCV calibration tutorial's flag for the fisheye model (`cv::fisheye`, another set of coefficients).
pub(super) const FISHEYE_MODEL: Field = Field {
    keys: &["fisheye_model"],
};

impl Field {
    /// The accepted keys, as an error names them: `image_width or image_Width`.
    pub fn spellings(&self) -> String {
        self.keys.join(" or ")
    }
}

/// The field's `(key, node)` in `parent`, `None` when no key of the field is present (or its value is null).
///
/// # Errors
/// [`CalibrationError::DuplicateField`] when the field is written under two of its keys.
pub(super) fn find<'a>(
    parent: &'a Yaml,
    field: &Field,
) -> Result<Option<(&'static str, &'a Yaml)>, CalibrationError> {
    let mut present = field
        .keys
        .iter()
        .filter_map(|&key| optional(parent, key).map(|node| (key, node)));
    let first = present.next();
    if let (Some((first, _)), Some((second, _))) = (first, present.next()) {
        return Err(CalibrationError::DuplicateField { first, second });
    }
    Ok(first)
}

/// As [`find`], the field being required: [`CalibrationError::MissingField`] naming its keys when absent.
pub(super) fn require<'a>(
    parent: &'a Yaml,
    field: &Field,
) -> Result<(&'static str, &'a Yaml), CalibrationError> {
    find(parent, field)?.ok_or_else(|| CalibrationError::MissingField {
        field: field.spellings(),
    })
}

pub(super) fn wrong_type(field: &str, expected: &'static str) -> CalibrationError {
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

/// A YAML number (integer or real, including `.nan` and `.inf`) as `f64`.
fn number(node: &Yaml) -> Option<f64> {
    match node {
        Yaml::Integer(i) => Some(*i as f64),
        Yaml::Real(_) => node.as_f64(),
        _ => None,
    }
}

/// The image size `(width, height)` written in the file (px, positive integers), `None` when it has neither.
///
/// # Errors
/// [`CalibrationError::MissingField`] when it has only one of them, [`CalibrationError::WrongType`] for a size that
/// is not a positive integer, [`CalibrationError::DuplicateField`].
pub(super) fn image_size(root: &Yaml) -> Result<Option<(u64, u64)>, CalibrationError> {
    let size = |(key, node): (&str, &Yaml)| match node {
        Yaml::Integer(i) if *i > 0 => Ok(i.unsigned_abs()),
        _ => Err(wrong_type(key, "a positive integer (px)")),
    };
    match (find(root, &IMAGE_WIDTH)?, find(root, &IMAGE_HEIGHT)?) {
        (None, None) => Ok(None),
        (Some(width), Some(height)) => Ok(Some((size(width)?, size(height)?))),
        (None, Some(_)) => Err(CalibrationError::MissingField {
            field: IMAGE_WIDTH.spellings(),
        }),
        (Some(_), None) => Err(CalibrationError::MissingField {
            field: IMAGE_HEIGHT.spellings(),
        }),
    }
}

/// Largest `rows` or `cols` accepted (calibration matrices are at most 3 × 4 or 1 × 14).
const MAX_MATRIX_SIDE: i64 = 64;

/// A matrix read from a calibration file: its key as written, `rows × cols` and the entries, row-major.
pub(super) struct Matrix {
    pub key: &'static str,
    pub rows: usize,
    pub cols: usize,
    pub data: Vec<f64>,
}

/// The matrix `field`, with `data.len() == rows · cols` and every entry finite.
pub(super) fn matrix(root: &Yaml, field: &Field) -> Result<Matrix, CalibrationError> {
    let (key, node) = require(root, field)?;
    if !matches!(node, Yaml::Hash(_)) {
        return Err(wrong_type(key, "a mapping with rows, cols and data"));
    }
    let entry = |name: &str| {
        let path = format!("{key}.{name}");
        match optional(node, name) {
            Some(value) => Ok((path, value)),
            None => Err(CalibrationError::MissingField { field: path }),
        }
    };
    let dimension = |name: &str| -> Result<usize, CalibrationError> {
        match entry(name)? {
            (_, Yaml::Integer(i)) if (1..=MAX_MATRIX_SIDE).contains(i) => {
                Ok(i.unsigned_abs() as usize)
            }
            (path, _) => Err(wrong_type(&path, "an integer from 1 to 64")),
        }
    };
    let (rows, cols) = (dimension("rows")?, dimension("cols")?);
    let (data_path, Yaml::Array(entries)) = entry("data")? else {
        return Err(wrong_type(&format!("{key}.data"), "a list of numbers"));
    };
    if entries.len() != rows * cols {
        return Err(CalibrationError::DataLength {
            field: key,
            rows,
            cols,
            found: entries.len(),
        });
    }
    let data = entries
        .iter()
        .map(|e| number(e).ok_or_else(|| wrong_type(&data_path, "a list of numbers")))
        .collect::<Result<Vec<f64>, _>>()?;
    if let Some((index, &value)) = data.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(CalibrationError::NonFiniteEntry {
            field: key,
            index,
            value,
        });
    }
    Ok(Matrix {
        key,
        rows,
        cols,
        data,
    })
}
