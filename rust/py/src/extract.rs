//! `extract_markers`: binding of `tacswitch_core::extract`.

use numpy::{
    PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use tacswitch_core::extract::{
    dilate_cross_n, extract_markers_with, ExtractParams, ExtractWorkspace, Extraction, MaskGrowth,
    Polarity,
};
use tacswitch_core::image::ImageView;

use crate::arrays::{image_u8, points_to_py};
use crate::errors::to_py;

/// Parses the polarity name.
pub fn parse_polarity(polarity: &str) -> PyResult<Polarity> {
    match polarity {
        "dark" => Ok(Polarity::Dark),
        "bright" => Ok(Polarity::Bright),
        other => Err(PyValueError::new_err(format!(
            "polarity: must be 'dark' or 'bright'; got {other:?}"
        ))),
    }
}

/// Builds core parameters from the keyword arguments shared by extraction and tracking.
#[allow(clippy::too_many_arguments)]
pub fn params_from_args(
    polarity: &str,
    block_size: Option<usize>,
    threshold: Option<f32>,
    min_area: Option<usize>,
    max_area: Option<usize>,
    min_fill: f32,
    max_aspect: f32,
    grow: MaskGrowth,
    exclude_border: bool,
) -> PyResult<ExtractParams> {
    Ok(ExtractParams {
        polarity: parse_polarity(polarity)?,
        block_size,
        threshold,
        min_area,
        max_area,
        min_fill,
        max_aspect,
        grow,
        exclude_border,
    })
}

/// Runs extraction on a borrowed image with the GIL released.
pub fn run_extract(
    py: Python<'_>,
    img: &PyReadonlyArrayDyn<'_, u8>,
    params: &ExtractParams,
    ws: &mut ExtractWorkspace,
    want_mask: bool,
) -> PyResult<Extraction> {
    let arg = image_u8(img, "img")?;
    let view =
        ImageView::new(arg.data, arg.height, arg.width, arg.channels, "img").map_err(to_py)?;
    py.detach(|| extract_markers_with(&view, params, ws, want_mask))
        .map_err(to_py)
}

/// Converts an extraction into a dict of numpy arrays.
pub fn extraction_to_py<'py>(
    py: Python<'py>,
    ex: Extraction,
    height: usize,
    width: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let n = ex.markers.len();
    let centres: Vec<[f32; 2]> = ex.markers.iter().map(|m| m.centre).collect();
    let areas: Vec<u32> = ex.markers.iter().map(|m| m.area).collect();
    let contrast: Vec<f32> = ex.markers.iter().map(|m| m.contrast).collect();
    let bbox: Vec<i32> = ex
        .markers
        .iter()
        .flat_map(|m| m.bbox.map(|v| v as i32))
        .collect();
    let d = PyDict::new(py);
    d.set_item("centres", points_to_py(py, &centres)?)?;
    d.set_item("areas", PyArray1::from_vec(py, areas))?;
    d.set_item("bboxes", PyArray1::from_vec(py, bbox).reshape([n, 4])?)?;
    d.set_item("contrast", PyArray1::from_vec(py, contrast))?;
    d.set_item(
        "mask",
        PyArray1::from_vec(py, ex.mask).reshape([height, width])?,
    )?;
    d.set_item("threshold", ex.threshold)?;
    d.set_item("background_level", ex.background_level)?;
    d.set_item("noise_sigma", ex.noise_sigma)?;
    d.set_item("block_size", ex.block_size)?;
    d.set_item("n_components", ex.n_components)?;
    d.set_item("grow_rings", PyArray1::from_vec(py, ex.grow_rings))?;
    Ok(d)
}

/// Extracts markers from a uint8 BGR/BGRA/grey image; returns a dict of arrays and scalars.
#[pyfunction]
#[pyo3(signature = (img, *, polarity="dark", block_size=None, threshold=None, min_area=None,
    max_area=None, min_fill=0.35, max_aspect=3.0, dilate=0, adaptive=false, exclude_border=true))]
#[allow(clippy::too_many_arguments)]
fn extract_markers<'py>(
    py: Python<'py>,
    img: PyReadonlyArrayDyn<'py, u8>,
    polarity: &str,
    block_size: Option<usize>,
    threshold: Option<f32>,
    min_area: Option<usize>,
    max_area: Option<usize>,
    min_fill: f32,
    max_aspect: f32,
    dilate: usize,
    adaptive: bool,
    exclude_border: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let grow = match (adaptive, dilate) {
        (false, k) => MaskGrowth::Dilate(k),
        (true, 0) => MaskGrowth::Adaptive,
        (true, k) => {
            return Err(PyValueError::new_err(format!(
                "dilate: must be 0 with adaptive growth; got {k}"
            )))
        }
    };
    let params = params_from_args(
        polarity,
        block_size,
        threshold,
        min_area,
        max_area,
        min_fill,
        max_aspect,
        grow,
        exclude_border,
    )?;
    let mut ws = ExtractWorkspace::default();
    let ex = run_extract(py, &img, &params, &mut ws, true)?;
    let arg = image_u8(&img, "img")?;
    extraction_to_py(py, ex, arg.height, arg.width)
}

/// Dilates a bool mask `iterations` times by a 3x3 cross (cv2's 3x3 `MORPH_ELLIPSE`), stopping
/// once it no longer changes.
#[pyfunction]
#[pyo3(signature = (mask, iterations=1))]
fn dilate_mask<'py>(
    py: Python<'py>,
    mask: PyReadonlyArray2<'py, bool>,
    iterations: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let (h, w) = (mask.shape()[0], mask.shape()[1]);
    let src = mask
        .as_slice()
        .map_err(|_| PyValueError::new_err("mask: array must be C-contiguous"))?;
    let src = src.to_vec();
    let out = py.detach(|| dilate_cross_n(src, h, w, iterations));
    Ok(PyArray1::from_vec(py, out).reshape([h, w])?.into_any())
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(extract_markers, m)?)?;
    m.add_function(wrap_pyfunction!(dilate_mask, m)?)
}
