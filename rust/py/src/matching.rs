//! `match_markers` and `estimate_pitch`: bindings of `tacswitch_core::matching` / `geometry`.

use numpy::{PyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use tacswitch_core::geometry;

use crate::arrays::{finite_opt, points_f32, points_to_py};
use crate::errors::to_py;

/// `(motion, valid, index, max_dist)` as returned to Python.
type MatchOut<'py> = (Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>, f32);

/// Mutual nearest-neighbour matching; returns `(motion, valid, index, max_dist)`.
#[pyfunction]
#[pyo3(signature = (ref_pts, cur_pts, max_dist=None))]
fn match_markers<'py>(
    py: Python<'py>,
    ref_pts: PyReadonlyArray2<'py, f32>,
    cur_pts: PyReadonlyArray2<'py, f32>,
    max_dist: Option<f32>,
) -> PyResult<MatchOut<'py>> {
    let r = points_f32(&ref_pts, "ref_pts")?;
    let c = points_f32(&cur_pts, "cur_pts")?;
    let max_dist = finite_opt(max_dist, "max_dist")?;
    let m = py
        .detach(|| tacswitch_core::matching::match_markers(&r, &c, max_dist))
        .map_err(to_py)?;
    Ok((
        points_to_py(py, &m.motion)?,
        PyArray1::from_vec(py, m.valid).into_any(),
        PyArray1::from_vec(py, m.index).into_any(),
        m.max_dist,
    ))
}

/// Median nearest-neighbour distance of a point set (pixels, float64); None with fewer than 2
/// distinct points.
#[pyfunction]
fn estimate_pitch(py: Python<'_>, points: PyReadonlyArray2<'_, f32>) -> PyResult<Option<f64>> {
    let p = points_f32(&points, "points")?;
    geometry::check_finite(&p, "points").map_err(to_py)?;
    Ok(py.detach(|| geometry::estimate_pitch_f64(&p)))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(match_markers, m)?)?;
    m.add_function(wrap_pyfunction!(estimate_pitch, m)?)
}
