//! `SlipDetector`: binding of `tacswitch_core::slip`.

use numpy::{PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use tacswitch_core::slip::{SlipDetector as CoreSlip, SlipParams};

use crate::arrays::{bools, finite_opt, points_f32};
use crate::errors::to_py;

/// Streaming slip detector over marker motion fields.
#[pyclass(module = "tacswitch._native")]
pub struct SlipDetector {
    inner: CoreSlip,
}

#[pymethods]
impl SlipDetector {
    #[new]
    #[pyo3(signature = (threshold_px, rigid_threshold_px=None, active_fraction=0.5, points=None))]
    fn new(
        threshold_px: Option<f32>,
        rigid_threshold_px: Option<f32>,
        active_fraction: f32,
        points: Option<PyReadonlyArray2<'_, f32>>,
    ) -> PyResult<Self> {
        let params = SlipParams {
            threshold_px: finite_opt(threshold_px, "threshold_px")?,
            rigid_threshold_px: finite_opt(rigid_threshold_px, "rigid_threshold_px")?,
            active_fraction,
        };
        let points = points.map(|p| points_f32(&p, "points")).transpose()?;
        Ok(Self {
            inner: CoreSlip::new(params, points).map_err(to_py)?,
        })
    }

    /// Feeds one motion field (`N x 2` float32) with its validity flags; returns the state as a dict.
    fn update<'py>(
        &mut self,
        py: Python<'py>,
        motion: PyReadonlyArray2<'py, f32>,
        valid: PyReadonlyArray1<'py, bool>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let m = points_f32(&motion, "motion")?;
        let v = bools(&valid);
        let st = self.inner.update(&m, &v).map_err(to_py)?;
        let d = PyDict::new(py);
        d.set_item("slip", st.slip)?;
        d.set_item("by_displacement", st.by_displacement)?;
        d.set_item("by_rigid", st.by_rigid)?;
        d.set_item("max_displacement", st.max_displacement)?;
        d.set_item("marker", st.marker)?;
        d.set_item("rigid_residual", st.rigid_residual)?;
        d.set_item("rigid_marker", st.rigid_marker)?;
        d.set_item("n_compared", st.n_compared)?;
        d.set_item("frame", st.frame)?;
        Ok(d)
    }

    /// Starts a new grasp.
    fn reset(&mut self) {
        self.inner.reset();
    }

    /// First frame of the grasp where slip fired, or None.
    #[getter]
    fn first_slip(&self) -> Option<u64> {
        self.inner.first_slip()
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<SlipDetector>()
}
