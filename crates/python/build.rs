//! Lets this crate's own tests (`cargo test`), which embed Python, find the libpython of the
//! interpreter PyO3 was configured with: an rpath to its library directory, PyO3's
//! documented way (`pyo3_build_config::add_libpython_rpath_link_args`). Without it the
//! test binary would load whichever libpython the system's loader finds first, or none.
//! When maturin builds the wheel (PYO3_BUILD_EXTENSION_MODULE set) nothing links libpython
//! and this adds nothing.

fn main() {
    pyo3_build_config::add_libpython_rpath_link_args();
}
