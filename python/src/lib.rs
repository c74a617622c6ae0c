//! Python bindings of harmonid: the compiled module `harmonid._harmonid`, wrapped by the pure
//! Python package `harmonid` (`python/harmonid/`), which adds the keyword-friendly signatures.
//!
//! Conventions are the library's (`DATA_FORMAT.md`): SI units, a complex amplitude `X` at `f`
//! means `Re[X e^{i2πft}]` (peak), frequencies in Hz. Long computations (identification,
//! simulation, sweeps, planning) run with the Python thread state detached, so other Python threads keep
//! running. Arrays handed to Python are moved into numpy without a copy where the library
//! produces them as owned vectors.
//!
//! Build: `pip install ./python` (maturin, which enables the `extension-module` feature). The
//! workspace's `cargo test` and `cargo clippy` compile this crate without that feature and never
//! link it, so they need no Python development files.

mod convert;
mod dataset;
mod errors;
mod explore;
mod identify;
mod io;
mod judge;
mod linear_response;
mod mix;
mod model;
mod plan;
mod response;
mod simulate;
mod sweep;
mod values;

use pyo3::prelude::*;

/// The compiled part of the `harmonid` package.
#[pymodule]
fn _harmonid(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    m.add_class::<model::Model>()?;
    m.add_class::<dataset::Dataset>()?;
    m.add_class::<identify::IdentifyResult>()?;
    m.add_function(wrap_pyfunction!(mix::mix, m)?)?;
    m.add_function(wrap_pyfunction!(identify::identify, m)?)?;
    m.add_function(wrap_pyfunction!(judge::compare, m)?)?;
    m.add_function(wrap_pyfunction!(judge::discover, m)?)?;
    m.add_function(wrap_pyfunction!(sweep::sweep, m)?)?;
    m.add_function(wrap_pyfunction!(response::response, m)?)?;
    m.add_function(wrap_pyfunction!(linear_response::linear_response, m)?)?;
    m.add_function(wrap_pyfunction!(explore::states, m)?)?;
    m.add_function(wrap_pyfunction!(explore::phase_diagram, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::simulate, m)?)?;
    m.add_class::<plan::PlanResult>()?;
    m.add_function(wrap_pyfunction!(plan::plan, m)?)?;
    m.add_function(wrap_pyfunction!(plan::evaluate_plan, m)?)?;
    m.add_function(wrap_pyfunction!(io::read_table, m)?)?;
    m.add_function(wrap_pyfunction!(io::read_zi_csv, m)?)?;
    m.add_function(wrap_pyfunction!(io::read_zi_hdf5, m)?)?;
    m.add_function(wrap_pyfunction!(io::read_zi_sweeper, m)?)?;
    m.add_function(wrap_pyfunction!(io::read_moku_csv, m)?)?;
    Ok(())
}
