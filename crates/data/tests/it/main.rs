//! The integration tests of `harmonid-data`, one test binary (`cargo test --release -p harmonid-data --test it`):
//! one module per subject, built and linked once.

mod fixtures;
mod import_headerless;
mod import_passes;
mod import_roundtrip;
mod import_turns;
