//! `inpaint_biharmonic`: binding of `tacswitch_core::biharmonic`.

use numpy::{Element, PyReadonlyArrayDyn};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use tacswitch_core::biharmonic::inpaint_biharmonic as core_inpaint;
use tacswitch_core::telea::Sample;

use crate::telea::inpaint_with;

fn run<'py, T: Sample + Element>(
    py: Python<'py>,
    arr: PyReadonlyArrayDyn<'py, T>,
    mask: &PyReadonlyArrayDyn<'py, u8>,
) -> PyResult<Bound<'py, PyAny>> {
    inpaint_with(py, arr, mask, |view, m| core_inpaint(view, m))
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
