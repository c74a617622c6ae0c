//! The integration tests of `harmonid-spectral`, one test binary (`cargo test --release -p harmonid-spectral --test it`):
//! one module per subject, built and linked once.

mod mixing_paper;
mod mixing_responses;
mod product_dft;
mod symbolic_numeric;
