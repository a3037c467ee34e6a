//! `tile` and `merge_patches`: bindings of `tacswitch_core::merge`.

use numpy::{
    Element, PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use tacswitch_core::image::ImageView;
use tacswitch_core::merge::{self, MergeMode};
use tacswitch_core::telea::Sample;

use crate::errors::to_py;
use crate::telea::{contiguous, image_shape};

type Tiles<'py> = (Bound<'py, PyAny>, Bound<'py, PyAny>);

fn origins_to_py<'py>(py: Python<'py>, origins: &[[usize; 2]]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<i64> = origins
        .iter()
        .flat_map(|o| [o[0] as i64, o[1] as i64])
        .collect();
    Ok(PyArray1::from_vec(py, flat)
        .reshape([origins.len(), 2])?
        .into_any())
}

fn run_tile<'py, T: Element + Copy>(
    py: Python<'py>,
    arr: PyReadonlyArrayDyn<'py, T>,
    patch: usize,
    overlap: usize,
) -> PyResult<Tiles<'py>> {
    let shape = arr.shape().to_vec();
    let (h, w, c) = image_shape(&shape, "img")?;
    let view = ImageView::new(contiguous(&arr, "img")?, h, w, c, "img").map_err(to_py)?;
    let (patches, origins) = py
        .detach(|| merge::tile(&view, patch, overlap))
        .map_err(to_py)?;
    let mut out_shape = vec![origins.len(), patch, patch];
    if shape.len() == 3 {
        out_shape.push(c);
    }
    let patches = PyArray1::from_vec(py, patches)
        .reshape(out_shape)?
        .into_any();
    Ok((patches, origins_to_py(py, &origins)?))
}

/// Cuts an image into overlapping square patches; returns `(patches, origins (x, y))`.
#[pyfunction]
#[pyo3(signature = (img, patch, overlap))]
fn tile<'py>(
    py: Python<'py>,
    img: &Bound<'py, PyAny>,
    patch: usize,
    overlap: usize,
) -> PyResult<Tiles<'py>> {
    if let Ok(arr) = img.extract::<PyReadonlyArrayDyn<'py, u8>>() {
        run_tile(py, arr, patch, overlap)
    } else if let Ok(arr) = img.extract::<PyReadonlyArrayDyn<'py, u16>>() {
        run_tile(py, arr, patch, overlap)
    } else if let Ok(arr) = img.extract::<PyReadonlyArrayDyn<'py, f32>>() {
        run_tile(py, arr, patch, overlap)
    } else {
        Err(PyTypeError::new_err(
            "img: expected a numpy array of dtype uint8, uint16 or float32",
        ))
    }
}

fn run_merge<'py, T: Sample + Element>(
    py: Python<'py>,
    arr: PyReadonlyArrayDyn<'py, T>,
    origins: &[[usize; 2]],
    height: usize,
    width: usize,
    mode: MergeMode,
) -> PyResult<Bound<'py, PyAny>> {
    let shape = arr.shape().to_vec();
    let (n, patch, channels) = match *shape {
        [n, p, q] if p == q => (n, p, 1),
        [n, p, q, c] if p == q => (n, p, c),
        _ => {
            return Err(PyValueError::new_err(format!(
                "patches: expected N x P x P or N x P x P x C; got shape {shape:?}"
            )))
        }
    };
    let data = contiguous(&arr, "patches")?;
    let out = py
        .detach(|| merge::merge_patches(data, n, patch, channels, origins, height, width, mode))
        .map_err(to_py)?;
    let out_shape = if shape.len() == 4 {
        vec![height, width, channels]
    } else {
        vec![height, width]
    };
    Ok(PyArray1::from_vec(py, out).reshape(out_shape)?.into_any())
}

/// Merges patches at `origins` `(x, y)` into a `height x width` image ("average" or "feather").
#[pyfunction]
#[pyo3(signature = (patches, origins, height, width, mode="average"))]
fn merge_patches<'py>(
    py: Python<'py>,
    patches: &Bound<'py, PyAny>,
    origins: PyReadonlyArray2<'py, i64>,
    height: usize,
    width: usize,
    mode: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let mode = match mode {
        "average" => MergeMode::Average,
        "feather" => MergeMode::Feather,
        other => {
            return Err(PyValueError::new_err(format!(
                "mode: must be 'average' or 'feather'; got {other:?}"
            )))
        }
    };
    if origins.shape()[1] != 2 {
        return Err(PyValueError::new_err(format!(
            "origins: expected an N x 2 array of (x, y); got shape {:?}",
            origins.shape()
        )));
    }
    let o: Vec<[usize; 2]> = origins
        .as_array()
        .rows()
        .into_iter()
        .map(|r| match (usize::try_from(r[0]), usize::try_from(r[1])) {
            (Ok(x), Ok(y)) => Ok([x, y]),
            _ => Err(PyValueError::new_err(format!(
                "origins: must be non-negative; got ({}, {})",
                r[0], r[1]
            ))),
        })
        .collect::<PyResult<_>>()?;
    if let Ok(arr) = patches.extract::<PyReadonlyArrayDyn<'py, u8>>() {
        run_merge(py, arr, &o, height, width, mode)
    } else if let Ok(arr) = patches.extract::<PyReadonlyArrayDyn<'py, u16>>() {
        run_merge(py, arr, &o, height, width, mode)
    } else if let Ok(arr) = patches.extract::<PyReadonlyArrayDyn<'py, f32>>() {
        run_merge(py, arr, &o, height, width, mode)
    } else {
        Err(PyTypeError::new_err(
            "patches: expected a numpy array of dtype uint8, uint16 or float32",
        ))
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(tile, m)?)?;
    m.add_function(wrap_pyfunction!(merge_patches, m)?)
}
