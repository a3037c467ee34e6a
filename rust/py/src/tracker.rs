//! `Tracker`: binding of `tacswitch_core::tracker`, with marker extraction fused in so that a
//! frame goes from pixels to motion in one native call with the GIL released.

use numpy::{PyArray1, PyReadonlyArray2, PyReadonlyArrayDyn};
use pyo3::prelude::*;
use tacswitch_core::extract::{ExtractParams, ExtractWorkspace, MaskGrowth};
use tacswitch_core::tracker::{TrackState, Tracker as CoreTracker};

use crate::arrays::{finite_opt, points_f32, points_to_py};
use crate::errors::to_py;
use crate::extract::{params_from_args, run_extract};

/// Frame-to-frame marker tracker against a fixed reference grid.
#[pyclass(module = "tacswitch._native")]
pub struct Tracker {
    inner: CoreTracker,
    params: ExtractParams,
    ws: ExtractWorkspace,
}

type Update<'py> = (Bound<'py, PyAny>, Bound<'py, PyAny>, u64);

fn state_to_py<'py>(py: Python<'py>, st: TrackState) -> PyResult<Update<'py>> {
    Ok((
        points_to_py(py, &st.motion)?,
        PyArray1::from_vec(py, st.valid).into_any(),
        st.frame,
    ))
}

#[pymethods]
impl Tracker {
    #[new]
    #[pyo3(signature = (ref_pts, max_dist=None, *, polarity="dark", block_size=None,
        threshold=None, min_area=None, max_area=None, min_fill=0.35, max_aspect=3.0,
        exclude_border=true))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        ref_pts: PyReadonlyArray2<'_, f32>,
        max_dist: Option<f32>,
        polarity: &str,
        block_size: Option<usize>,
        threshold: Option<f32>,
        min_area: Option<usize>,
        max_area: Option<usize>,
        min_fill: f32,
        max_aspect: f32,
        exclude_border: bool,
    ) -> PyResult<Self> {
        let r = points_f32(&ref_pts, "ref_pts")?;
        let max_dist = finite_opt(max_dist, "max_dist")?;
        let params = params_from_args(
            polarity,
            block_size,
            threshold,
            min_area,
            max_area,
            min_fill,
            max_aspect,
            MaskGrowth::Dilate(0),
            exclude_border,
        )?;
        Ok(Self {
            inner: CoreTracker::new(r, max_dist).map_err(to_py)?,
            params,
            ws: ExtractWorkspace::default(),
        })
    }

    /// Tracks already-detected marker centres (`N x 2` float32, (x, y)).
    fn update_points<'py>(
        &mut self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f32>,
    ) -> PyResult<Update<'py>> {
        let p = points_f32(&points, "points")?;
        let inner = &mut self.inner;
        let st = py.detach(|| inner.update(&p)).map_err(to_py)?;
        state_to_py(py, st)
    }

    /// Extracts markers from a uint8 image and tracks them.
    fn update_image<'py>(
        &mut self,
        py: Python<'py>,
        img: PyReadonlyArrayDyn<'py, u8>,
    ) -> PyResult<Update<'py>> {
        let ex = run_extract(py, &img, &self.params, &mut self.ws, false)?;
        let pts: Vec<[f32; 2]> = ex.markers.iter().map(|m| m.centre).collect();
        let inner = &mut self.inner;
        let st = py.detach(|| inner.update(&pts)).map_err(to_py)?;
        state_to_py(py, st)
    }

    /// Forgets the motion history (markers expected back at the reference).
    fn reset(&mut self) {
        self.inner.reset();
    }

    /// Reference marker positions, `N x 2` float32.
    #[getter]
    fn reference<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_to_py(py, self.inner.reference())
    }

    /// Last tracked positions, `N x 2` float32.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        points_to_py(py, self.inner.positions())
    }

    /// Per-frame matching gate, pixels.
    #[getter]
    fn max_dist(&self) -> f32 {
        self.inner.gate()
    }

    /// Frames processed since construction or the last reset.
    #[getter]
    fn frame(&self) -> u64 {
        self.inner.frame()
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Tracker>()
}
