//! The integration tests of `harmonid-sim`, one test binary (`cargo test --release -p harmonid-sim --test it`):
//! one module per subject, built and linked once.

mod bounded;
mod coulomb_sweep;
mod decoupled_modes;
mod finite_inputs;
mod hopf;
mod linear_response;
mod nonsmooth;
mod nonsmooth_torus;
mod pumping;
mod quasi_periodic;
mod ramp_past_fold;
mod reduced_modes;
mod sensitivity;
mod stepped_fold;
mod stop_at_fold;
mod velocity_terms;
