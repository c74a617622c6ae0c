//! harmonid: identify nonlinear multimode resonator models from multi-tone sideband spectra.
//!
//! This facade re-exports the workspace crates.

pub use harmonid_data as data;
pub use harmonid_experiment as experiment;
pub use harmonid_ident as ident;
pub use harmonid_model as model;
pub use harmonid_poly as poly;
pub use harmonid_sim as sim;
pub use harmonid_spectral as spectral;
