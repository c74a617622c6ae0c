//! The integration tests of `harmonid-ident`, one test binary (`cargo test --release -p harmonid-ident --test it`):
//! one module per subject, built and linked once.

mod crlb;
mod disturbed_shots_mc;
mod finite_inputs;
mod ml_fallback;
mod near_resonance;
mod shared_dataset;
mod unfit;
