//! The integration tests of `harmonid-plot`, one test binary (`cargo test --release -p harmonid-plot --test it`):
//! one module per subject, built and linked once.

mod figures;
