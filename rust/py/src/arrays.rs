//! Zero-copy views of numpy arrays, with argument-naming errors.

use numpy::{
    PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArrayDyn,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// Shape and contiguous data of an `H x W` or `H x W x C` uint8 image.
pub struct ImageArg<'a> {
    pub data: &'a [u8],
    pub height: usize,
    pub width: usize,
    pub channels: usize,
}

/// Borrows an image as a C-contiguous slice; names `name` in every error.
pub fn image_u8<'a>(arr: &'a PyReadonlyArrayDyn<'_, u8>, name: &str) -> PyResult<ImageArg<'a>> {
    let shape = arr.shape();
    let (height, width, channels) = match *shape {
        [h, w] => (h, w, 1),
        [h, w, c] => (h, w, c),
        _ => {
            return Err(PyValueError::new_err(format!(
                "{name}: expected an H x W or H x W x C image; got shape {shape:?}"
            )))
        }
    };
    let data = arr
        .as_slice()
        .map_err(|_| PyValueError::new_err(format!("{name}: array must be C-contiguous")))?;
    Ok(ImageArg {
        data,
        height,
        width,
        channels,
    })
}

/// Borrows an `N x 2` float32 array as points.
pub fn points_f32(arr: &PyReadonlyArray2<'_, f32>, name: &str) -> PyResult<Vec<[f32; 2]>> {
    let shape = arr.shape();
    if shape[1] != 2 {
        return Err(PyValueError::new_err(format!(
            "{name}: expected an N x 2 array of (x, y); got shape {shape:?}"
        )));
    }
    let view = arr.as_array();
    Ok(view.rows().into_iter().map(|r| [r[0], r[1]]).collect())
}

/// Borrows a 1-D bool array.
pub fn bools(arr: &PyReadonlyArray1<'_, bool>) -> Vec<bool> {
    arr.as_array().iter().copied().collect()
}

/// `N x 2` float32 array from points.
pub fn points_to_py<'py>(py: Python<'py>, pts: &[[f32; 2]]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f32> = pts.iter().flat_map(|p| [p[0], p[1]]).collect();
    let arr = PyArray1::from_vec(py, flat).reshape([pts.len(), 2])?;
    Ok(arr.into_any())
}

/// Raises `TypeError` naming `name` when an optional float is not finite where required.
pub fn finite_opt(v: Option<f32>, name: &str) -> PyResult<Option<f32>> {
    match v {
        Some(x) if x.is_nan() => Err(PyTypeError::new_err(format!(
            "{name}: must be a number, not NaN"
        ))),
        other => Ok(other),
    }
}
