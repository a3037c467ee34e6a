//! `tacswitch._native`: PyO3 bindings over `tacswitch-core`.
//!
//! Every function here does four things in order: validate arguments (errors name the argument),
//! take zero-copy views of the numpy arrays, run the core with the GIL released, map the core's
//! error to a Python exception. Algorithms live in the core crate only.

mod arrays;
mod biharmonic;
mod errors;
mod extract;
mod matching;
mod merge;
mod slip;
mod slip_features;
mod telea;
mod tracker;

use pyo3::prelude::*;

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    extract::register(m)?;
    matching::register(m)?;
    tracker::register(m)?;
    slip::register(m)?;
    slip_features::register(m)?;
    telea::register(m)?;
    biharmonic::register(m)?;
    merge::register(m)?;
    Ok(())
}
