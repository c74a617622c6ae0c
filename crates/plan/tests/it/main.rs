//! The integration tests of `harmonid-plan`, one test binary (`cargo test --release -p harmonid-plan --test it`):
//! one module per subject, built and linked once.

mod plan;
mod range_design;
