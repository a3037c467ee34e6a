//! Mapping of core errors to Python exceptions.

use pyo3::exceptions::PyValueError;
use pyo3::PyErr;
use tacswitch_core::CoreError;

/// Core errors become `ValueError`s whose message starts with the argument's name.
pub fn to_py(err: CoreError) -> PyErr {
    PyValueError::new_err(err.to_string())
}
