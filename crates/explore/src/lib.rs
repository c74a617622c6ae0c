//! Exploring a model: every steady state at one point of parameters, and phase diagrams
//! (how many stable and unstable states) over two parameters.
//!
//! The equations are those of the simulation crate (DATA_FORMAT conventions, per mode `n`):
//!
//! ```text
//! q̈_n + (ω_n/Q_n) q̇_n + ω_n² q_n + Σ_m b_m^(n) m(q, q̇, pump) = Re[F_n e^{iΩt}].
//! ```
//!
//! With one response frequency `Ω` the harmonic balance of one harmonic is a polynomial system
//! ([`SingleHarmonic`]); its isolated solutions are all found by a total-degree homotopy
//! ([`total_degree`], complete by construction: every isolated solution ends a path), the real
//! ones are the steady states, each judged by its slow-flow eigenvalues and continued onto the
//! full harmonic lattice ([`states`]). A phase diagram ([`phase_diagram`]) counts the stable and
//! unstable single-harmonic states over a grid, each point's complex solutions continued from
//! its neighbour's by a parameter homotopy, with a full homotopy wherever the count of complex
//! solutions drops (so no branch is lost between points).
//!
//! ```
//! use harmonid_explore::{states, StatesSettings};
//! use harmonid_sim::{Excitation, NumericModel, Term};
//! use num_complex::Complex64;
//! // A hardening Duffing at 1 kHz, Q = 1000, driven 10 Hz above resonance: bistable.
//! let duffing = NumericModel::new(
//!     vec!["q1".into()], vec![1000.0], vec![1000.0],
//!     vec![Term { eq: 0, coef: 1e12, factors: vec![(0, 3)] }],
//! ).unwrap();
//! let drive = Excitation::new(vec![1010.0], vec![vec![Complex64::new(60.0, 0.0)]]);
//! let s = states(&duffing, &drive, &StatesSettings::default()).unwrap();
//! assert_eq!(s.states.len(), 3);
//! assert_eq!(s.states.iter().filter(|s| s.stable).count(), 2);
//! ```

#![warn(missing_docs)]
#![allow(clippy::needless_range_loop)]

mod error;
mod harmonic;
mod homotopy;
mod phase;
mod states;
mod system;
mod track;

pub use error::ExploreError;
pub use harmonic::{SingleHarmonic, Tone};
pub use homotopy::{bezout, parameter, total_degree, Solutions, MAX_PATHS};
pub use phase::{
    phase_diagram, Axis, AxisRange, Count, PhaseDiagram, PhaseSettings, PointState, Problem,
    MAX_GRID_POINTS,
};
pub use states::{
    is_stable, residual, states, tone_of, unstable_through_complex_pair, Continued, Solved, State,
    States, StatesSettings, REAL_TOL,
};
pub use system::{PolySystem, Term};
