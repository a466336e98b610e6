//! Conversions between Python objects and the Rust API's values: errors, joint vectors, corners, poses, JSON-shaped
//! values (dicts), arrays of records and method names. Each checks shape and finiteness where the Rust API would not,
//! so that no input reaches a call that could panic.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::PyTypeInfo;
use servostack::nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};
use servostack::scenario::RunKind;
use servostack::servo::Corners;

/// The exception `X` carrying the Rust error's message.
pub fn raise<X: PyTypeInfo>(error: impl std::fmt::Display) -> PyErr {
    PyErr::new::<X, _>(error.to_string())
}

/// Fills `out` from a 1-D NumPy array or a sequence of exactly `out.len()` numbers (`name` in errors).
pub fn read_vector(value: &Bound<'_, PyAny>, out: &mut [f64], name: &str) -> PyResult<()> {
    let wrong_length = |found: usize| {
        PyValueError::new_err(format!("{name}: {found} values, expected {}", out.len()))
    };
    if let Ok(array) = value.extract::<PyReadonlyArray1<'_, f64>>() {
        let view = array.as_array();
        if view.len() != out.len() {
            return Err(wrong_length(view.len()));
        }
        for (o, v) in out.iter_mut().zip(view.iter()) {
            *o = *v;
        }
        return Ok(());
    }
    let values: Vec<f64> = value.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name}: expected a sequence of {} numbers",
            out.len()
        ))
    })?;
    if values.len() != out.len() {
        return Err(wrong_length(values.len()));
    }
    out.copy_from_slice(&values);
    Ok(())
}

/// A vector of any length from a 1-D array or a sequence of numbers.
pub fn vector(value: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<f64>> {
    if let Ok(array) = value.extract::<PyReadonlyArray1<'_, f64>>() {
        return Ok(array.as_array().to_vec());
    }
    value
        .extract()
        .map_err(|_| PyTypeError::new_err(format!("{name}: expected a sequence of numbers")))
}

/// The four corners (px or normalised): a `(4, 2)` array, or a sequence of four `(u, v)` pairs or `None` (a corner
/// the detector missed).
pub fn corners(value: &Bound<'_, PyAny>) -> PyResult<Corners> {
    let shape_error = || {
        PyValueError::new_err(
            "corners: expected a (4, 2) array or four (u, v) pairs (None for a missing corner)",
        )
    };
    let mut out: Corners = [None; 4];
    if let Ok(array) = value.extract::<PyReadonlyArray2<'_, f64>>() {
        let view = array.as_array();
        if view.shape() != [4, 2] {
            return Err(shape_error());
        }
        for (corner, row) in out.iter_mut().zip(view.rows()) {
            *corner = Some((row[0], row[1]));
        }
        return Ok(out);
    }
    let items: Vec<Bound<'_, PyAny>> = value.extract().map_err(|_| shape_error())?;
    if items.len() != 4 {
        return Err(shape_error());
    }
    for (corner, item) in out.iter_mut().zip(&items) {
        *corner = if item.is_none() {
            None
        } else if let Ok(pair) = item.extract::<(f64, f64)>() {
            Some(pair)
        } else {
            match item.extract::<Vec<f64>>().map_err(|_| shape_error())?[..] {
                [u, v] => Some((u, v)),
                _ => return Err(shape_error()),
            }
        };
    }
    Ok(out)
}

/// The corners as a list of four `(u, v)` tuples or `None`.
pub fn corners_to_py<'py>(py: Python<'py>, corners: &Corners) -> PyResult<Bound<'py, PyAny>> {
    corners.to_vec().into_pyobject(py).map(Bound::into_any)
}

/// A rigid transform from a 4 × 4 homogeneous matrix (rotation orthonormal within 1e−9, last row `0 0 0 1`).
pub fn pose(value: &Bound<'_, PyAny>, name: &str) -> PyResult<Isometry3<f64>> {
    let rows: Vec<Vec<f64>> = match value.extract::<PyReadonlyArray2<'_, f64>>() {
        Ok(array) => array
            .as_array()
            .rows()
            .into_iter()
            .map(|r| r.to_vec())
            .collect(),
        Err(_) => value.extract().map_err(|_| {
            PyTypeError::new_err(format!("{name}: expected a 4 × 4 homogeneous matrix"))
        })?,
    };
    if rows.len() != 4 || rows.iter().any(|r| r.len() != 4) {
        return Err(PyValueError::new_err(format!(
            "{name}: expected a 4 × 4 homogeneous matrix"
        )));
    }
    if rows.iter().flatten().any(|v| !v.is_finite()) || rows[3] != [0.0, 0.0, 0.0, 1.0] {
        return Err(PyValueError::new_err(format!(
            "{name}: the matrix must be finite with the last row [0, 0, 0, 1]"
        )));
    }
    let r = Matrix3::from_fn(|i, j| rows[i][j]);
    if (r.transpose() * r - Matrix3::identity()).amax() > 1e-9 || r.determinant() <= 0.0 {
        return Err(PyValueError::new_err(format!(
            "{name}: the upper-left 3 × 3 block is not a rotation (orthonormal within 1e-9, determinant +1)"
        )));
    }
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let translation = Translation3::new(rows[0][3], rows[1][3], rows[2][3]);
    Ok(Isometry3::from_parts(translation, rotation))
}

/// The 4 × 4 homogeneous matrix of a rigid transform.
pub fn pose_to_py<'py>(py: Python<'py>, pose: &Isometry3<f64>) -> Bound<'py, PyArray2<f64>> {
    let m = pose.to_homogeneous();
    Array2::from_shape_fn((4, 4), |(i, j)| m[(i, j)]).into_pyarray(py)
}

/// A 1-D array.
pub fn array1<'py>(py: Python<'py>, values: &[f64]) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, values)
}

/// A `rows × cols` array from its values, row after row.
pub fn array2<'py>(
    py: Python<'py>,
    rows: usize,
    cols: usize,
    values: Vec<f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let array = Array2::from_shape_vec((rows, cols), values)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(array.into_pyarray(py))
}

/// A Rust value as Python objects (dicts for structs, lists for sequences) in its serde form.
pub fn to_py<'py, T: serde::Serialize>(py: Python<'py>, value: &T) -> PyResult<Bound<'py, PyAny>> {
    pythonize::pythonize(py, value).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// A Rust value read from Python objects as its serde form (a dict for a struct): unknown keys and wrong types are
/// errors naming the key (`name` says what was read).
pub fn from_py<T: serde::de::DeserializeOwned>(
    value: &Bound<'_, PyAny>,
    name: &str,
) -> PyResult<T> {
    pythonize::depythonize(value).map_err(|e| PyValueError::new_err(format!("{name}: {e}")))
}

/// A method by name: `classical`, `stack`, `stack_gradient`, `full_method` (or its name in outputs,
/// `stack_controller`), `sns`, `hqp`.
pub fn run_kind(name: &str) -> PyResult<RunKind> {
    if name == "full_method" {
        return Ok(RunKind::FullMethod);
    }
    RunKind::from_name(name).ok_or_else(|| {
        PyValueError::new_err(format!(
            "unknown method {name:?}: expected classical, stack, stack_gradient, full_method, sns or hqp"
        ))
    })
}
