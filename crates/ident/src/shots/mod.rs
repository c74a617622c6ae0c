//! The shots of a measurement: their pooled mean with disturbed shots rejected and the noise
//! of every line from their scatter ([`pool`]), and robust statistics of per-shot estimates
//! ([`shot_stats`]).

mod pool;
mod stats;

pub use pool::{disturbed_shots, pool, Pooled, REJECTION_ALPHA};
pub use stats::{shot_stats, ShotStats};
