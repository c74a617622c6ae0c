//! The integration tests of `harmonid-experiment`, one test binary (`cargo test --release -p harmonid-experiment --test it`):
//! one module per subject, built and linked once.

mod truncation;
mod truncation_nonsmooth;
