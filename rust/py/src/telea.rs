//! `inpaint_telea`: binding of `tacswitch_core::telea`.

use numpy::{Element, PyArray1, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use tacswitch_core::image::ImageView;
use tacswitch_core::telea::{inpaint_telea as core_inpaint, Sample};

use crate::errors::to_py;

/// `(height, width, channels)` of an `H x W` or `H x W x C` array; errors name `name`.
pub fn image_shape(shape: &[usize], name: &str) -> PyResult<(usize, usize, usize)> {
    match *shape {
        [h, w] => Ok((h, w, 1)),
        [h, w, c] => Ok((h, w, c)),
        _ => Err(PyValueError::new_err(format!(
            "{name}: expected an H x W or H x W x C image; got shape {shape:?}"
        ))),
    }
}

/// A C-contiguous slice of `arr`; errors name `name`.
pub fn contiguous<'a, T: Element>(
    arr: &'a PyReadonlyArrayDyn<'_, T>,
    name: &str,
) -> PyResult<&'a [T]> {
    arr.as_slice()
        .map_err(|_| PyValueError::new_err(format!("{name}: array must be C-contiguous")))
}

/// Borrows the `H x W` uint8 mask (nonzero = fill).
fn mask_arg<'a>(mask: &'a PyReadonlyArrayDyn<'_, u8>, h: usize, w: usize) -> PyResult<&'a [u8]> {
    if mask.shape() != [h, w] {
        return Err(PyValueError::new_err(format!(
            "mask: expected shape ({h}, {w}) to match img; got {:?}",
            mask.shape()
        )));
    }
    contiguous(mask, "mask")
}

/// Validates `arr` and `mask`, runs `solve` on zero-copy views with the GIL released, and
/// returns its output as an array of `arr`'s shape (shared by the inpainting bindings).
pub fn inpaint_with<'py, T, F>(
    py: Python<'py>,
    arr: PyReadonlyArrayDyn<'py, T>,
    mask: &PyReadonlyArrayDyn<'py, u8>,
    solve: F,
) -> PyResult<Bound<'py, PyAny>>
where
    T: Sample + Element,
    F: FnOnce(&ImageView<'_, T>, &[u8]) -> tacswitch_core::Result<Vec<T>> + Send,
{
    let shape = arr.shape().to_vec();
    let (h, w, c) = image_shape(&shape, "img")?;
    let data = contiguous(&arr, "img")?;
    let m = mask_arg(mask, h, w)?;
    let view = ImageView::new(data, h, w, c, "img").map_err(to_py)?;
    let out = py.detach(|| solve(&view, m)).map_err(to_py)?;
    Ok(PyArray1::from_vec(py, out).reshape(shape)?.into_any())
}

fn run<'py, T: Sample + Element>(
    py: Python<'py>,
    arr: PyReadonlyArrayDyn<'py, T>,
    mask: &PyReadonlyArrayDyn<'py, u8>,
    radius: usize,
) -> PyResult<Bound<'py, PyAny>> {
    inpaint_with(py, arr, mask, |view, m| core_inpaint(view, m, radius))
}

/// Telea inpainting of a uint8 / uint16 / float32 image (1 to 4 channels); returns a new array.
#[pyfunction]
#[pyo3(signature = (img, mask, radius))]
fn inpaint_telea<'py>(
    py: Python<'py>,
    img: &Bound<'py, PyAny>,
    mask: PyReadonlyArrayDyn<'py, u8>,
    radius: usize,
) -> PyResult<Bound<'py, PyAny>> {
    if let Ok(arr) = img.extract::<PyReadonlyArrayDyn<'py, u8>>() {
        run(py, arr, &mask, radius)
    } else if let Ok(arr) = img.extract::<PyReadonlyArrayDyn<'py, u16>>() {
        run(py, arr, &mask, radius)
    } else if let Ok(arr) = img.extract::<PyReadonlyArrayDyn<'py, f32>>() {
        run(py, arr, &mask, radius)
    } else {
        Err(PyTypeError::new_err(
            "img: expected a numpy array of dtype uint8, uint16 or float32",
        ))
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(inpaint_telea, m)?)
}
