//! Integration tests of harmonid-explore: one binary, one module per behaviour
//! (`cargo test --release -p harmonid-explore --test it -- duffing::`).

mod bad_input;
mod duffing;
mod hopf_type;
mod models;
mod parametron;
mod two_mode;
