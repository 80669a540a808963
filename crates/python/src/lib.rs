//! `pganeus._pganeus`: the Rust half of the Python package `pganeus`. It holds what must be fast or must be the
//! method's own code: the stages (through the same argument parsers as the `pganeus` command, so a call and a
//! command line do the same), the simulator with its exact gradients, and the readers of the project's binary
//! files. The Python half (`python/pganeus/`) gives the stages keyword arguments, reads run folders back and
//! wraps the simulator for PyTorch.

mod commands;
mod errors;
mod files;
mod world;

use pyo3::prelude::*;

#[pymodule]
fn _pganeus(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_function(wrap_pyfunction!(commands::run_command, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_sdf_grid, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_cameras, m)?)?;
    m.add_class::<world::World>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
