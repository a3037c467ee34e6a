//! `SlipFeatures`: binding of `tacswitch_core::slip_features`.

use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use tacswitch_core::slip_features::{
    SlipFeatures as CoreFeatures, N_BASE_FEATURES, N_FEATURES, N_FRAME, N_SNAP,
};

use crate::arrays::{bools, points_f32};
use crate::errors::to_py;

/// Streaming features of a tracked marker field for the learned slip detector.
#[pyclass(module = "tacswitch._native")]
pub struct SlipFeatures {
    inner: CoreFeatures,
}

#[pymethods]
impl SlipFeatures {
    #[new]
    #[pyo3(signature = (points, pitch, still_filter = false))]
    fn new(points: PyReadonlyArray2<'_, f32>, pitch: f32, still_filter: bool) -> PyResult<Self> {
        let pts = points_f32(&points, "points")?;
        let inner = CoreFeatures::new(&pts, pitch).map_err(to_py)?;
        Ok(Self {
            inner: if still_filter {
                inner.with_still_filter()
            } else {
                inner
            },
        })
    }

    /// Whether the motion is read through the still-marker filter.
    #[getter]
    fn still_filter(&self) -> bool {
        self.inner.still_filter()
    }

    /// Feeds one motion field (`N x 2` float32 px since the first frame) and its validity;
    /// returns the frame's feature vector (float32).
    fn update<'py>(
        &mut self,
        py: Python<'py>,
        motion: PyReadonlyArray2<'py, f32>,
        valid: PyReadonlyArray1<'py, bool>,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let m = points_f32(&motion, "motion")?;
        let v = bools(&valid);
        let out = self.inner.update(&m, &v).map_err(to_py)?;
        Ok(PyArray1::from_slice(py, &out))
    }

    /// Forgets the history.
    fn reset(&mut self) {
        self.inner.reset();
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<SlipFeatures>()?;
    m.add("SLIP_N_FEATURES", N_FEATURES)?;
    m.add("SLIP_N_FRAME", N_FRAME)?;
    m.add("SLIP_N_SNAP", N_SNAP)?;
    m.add("SLIP_N_BASE_FEATURES", N_BASE_FEATURES)?;
    Ok(())
}
