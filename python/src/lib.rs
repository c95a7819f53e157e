//! # companion-py
//!
//! The Python package `companion`: researchers who apply the controller to a robot prototype
//! in Python reach the law and the simulator without the wire protocol. Nothing here is a
//! second implementation: [`law`] builds the runtime's controllers from the CLI's presets and
//! `--config` files (`companion_runtime::domain::scenario::Options`), [`plant`] is the simulator's plant
//! for a loop written in Python, [`batch`] steps many of them in
//! one call, [`simulate`] runs `companion sim`'s own loop (`companion_runtime::run::sim`,
//! `companion_runtime::run::spatial`). Errors are Python exceptions named after companion-core's
//! `StepError` and `ParamError` variants ([`errors`]); no Rust panic crosses the boundary
//! (pyo3 would turn one into `PanicException`; the law does not panic on any input).

pub mod arm;
pub mod batch;
pub mod errors;
pub mod law;
pub mod measurement;
pub mod plant;
pub mod simulate;

use pyo3::prelude::*;

/// The module `companion`.
#[pymodule]
fn companion(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<arm::Arm>()?;
    m.add_class::<law::Law>()?;
    m.add_class::<law::Output>()?;
    m.add_class::<measurement::Measurement>()?;
    m.add_class::<batch::LawBatch>()?;
    m.add_class::<plant::Plant>()?;
    m.add_function(wrap_pyfunction!(simulate::simulate, m)?)?;
    errors::register(m)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
