//! `inpaint_biharmonic`: binding of `tacswitch_core::biharmonic`.

use numpy::{Element, PyArray1, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use tacswitch_core::biharmonic::inpaint_biharmonic as core_inpaint;
use tacswitch_core::image::ImageView;
use tacswitch_core::telea::Sample;

use crate::errors::to_py;
use crate::telea::{contiguous, image_shape, mask_arg};

fn run<'py, T: Sample + Element>(
    py: Python<'py>,
    arr: PyReadonlyArrayDyn<'py, T>,
    mask: &PyReadonlyArrayDyn<'py, u8>,
) -> PyResult<Bound<'py, PyAny>> {
    let shape = arr.shape().to_vec();
    let (h, w, c) = image_shape(&shape, "img")?;
    let data = contiguous(&arr, "img")?;
    let m = mask_arg(mask, h, w)?;
    let view = ImageView::new(data, h, w, c, "img").map_err(to_py)?;
    let out = py.detach(|| core_inpaint(&view, m)).map_err(to_py)?;
    Ok(PyArray1::from_vec(py, out).reshape(shape)?.into_any())
}

/// Biharmonic inpainting of a uint8 / uint16 / float32 image (1 to 4 channels); a new array.
#[pyfunction]
#[pyo3(signature = (img, mask))]
fn inpaint_biharmonic<'py>(
    py: Python<'py>,
    img: &Bound<'py, PyAny>,
    mask: PyReadonlyArrayDyn<'py, u8>,
) -> PyResult<Bound<'py, PyAny>> {
    if let Ok(arr) = img.extract::<PyReadonlyArrayDyn<'py, u8>>() {
        run(py, arr, &mask)
    } else if let Ok(arr) = img.extract::<PyReadonlyArrayDyn<'py, u16>>() {
        run(py, arr, &mask)
    } else if let Ok(arr) = img.extract::<PyReadonlyArrayDyn<'py, f32>>() {
        run(py, arr, &mask)
    } else {
        Err(PyTypeError::new_err(
            "img: expected a numpy array of dtype uint8, uint16 or float32",
        ))
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(inpaint_biharmonic, m)?)
}
