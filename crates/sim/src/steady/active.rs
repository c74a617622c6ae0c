//! The modes a drive can reach, decided from the model's structure.
//!
//! Under a drive, the set `A` of modes that can respond is a closure: it starts with the modes
//! a drive tone forces (or a caller names), the modes whose equation holds a term without any
//! mode factor (a constant or pump-only force), and the modes whose equation holds the pump
//! (a pump above its threshold sustains an oscillation from rest); it then takes in mode `j`
//! whenever some term of `j`'s equation (polynomial or non-smooth) has all of its mode factors
//! (positions, velocities, functions of them) in `A`. Every other term of an equation outside
//! `A` holds a factor of a mode outside `A`, so `q_k ≡ 0` for every `k ∉ A` is an exact steady
//! state for every value of the coefficients: the problem restricted to `A`
//! ([`crate::NumericModel::restricted`]) has the same state. The set depends on which terms
//! the model holds, never on their values (a coefficient that is zero here still has a
//! sensitivity).
//!
//! Stability: at such a state the Jacobian is block-triangular (the idle equations do not
//! depend on the active amplitudes: each of their terms keeps an idle factor), so its
//! spectrum is that of the active block and that of the idle block, the idle equations
//! linearised in the idle amplitudes: their terms with exactly one idle factor, the others
//! active (`γ q_j q_a²` pumps an idle mode `j` parametrically). The idle modes fall apart into
//! [`ActiveModes::idle_parts`] that such terms join.

use super::SteadyState;
use crate::{Excitation, NumericModel};
use num_complex::Complex64;

/// The modes a drive reaches and the idle rest (see the module documentation).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ActiveModes {
    n_modes: usize,
    /// The active modes, ascending.
    active: Vec<usize>,
    /// The idle modes joined by terms with exactly one idle factor, each part ascending; only
    /// parts whose linearisation holds such a term (a part that has none is a set of linear
    /// resonators at rest, stable).
    idle_parts: Vec<Vec<usize>>,
}

/// A term's equation, its mode factors `(mode, exponent)` (velocities count as their mode,
/// non-smooth functions as a factor of their variable's mode), and whether it holds the pump.
type TermModes = (usize, Vec<(usize, u32)>, bool);

/// Every term (polynomial and non-smooth) of `model` as [`TermModes`].
fn term_factors(model: &NumericModel) -> Vec<TermModes> {
    let n = model.n_modes();
    let mode_of = |v: usize| (v < 2 * n).then_some(v % n);
    let pump = |v: usize| v == 2 * n;
    let mut out = Vec::new();
    for t in model.terms() {
        let f = t
            .factors
            .iter()
            .filter_map(|&(v, e)| Some((mode_of(v)?, e)))
            .collect();
        out.push((t.eq, f, t.factors.iter().any(|&(v, _)| pump(v))));
    }
    for t in model.rough_terms() {
        let f = t
            .factors
            .iter()
            .filter_map(|&(v, e)| Some((mode_of(v)?, e)))
            .chain(
                t.nonsmooth
                    .iter()
                    .filter_map(|&(g, e)| Some((mode_of(g.var().index())?, e))),
            )
            .collect();
        out.push((t.eq, f, t.factors.iter().any(|&(v, _)| pump(v))));
    }
    out
}

impl ActiveModes {
    /// The modes `drive` reaches in `model`: the closure from the modes with a nonzero force
    /// (and those `forced` names: modes whose force is a free quantity that happens to be zero
    /// now, so that its sensitivity is defined).
    pub fn of(model: &NumericModel, drive: &Excitation, forced: &[usize]) -> Self {
        let n = model.n_modes();
        let terms = term_factors(model);
        let mut on = vec![false; n];
        for (m, row) in drive.force.iter().enumerate().take(n) {
            on[m] = row.iter().any(|z| *z != Complex64::new(0.0, 0.0));
        }
        for &m in forced.iter().filter(|&&m| m < n) {
            on[m] = true;
        }
        for (eq, f, pump) in &terms {
            on[*eq] |= f.is_empty() || *pump;
        }
        loop {
            let mut grew = false;
            for (eq, f, _) in &terms {
                if !on[*eq] && f.iter().all(|&(m, _)| on[m]) {
                    on[*eq] = true;
                    grew = true;
                }
            }
            if !grew {
                break;
            }
        }
        let idle_parts = idle_parts(n, &on, &terms);
        Self {
            n_modes: n,
            active: (0..n).filter(|&m| on[m]).collect(),
            idle_parts,
        }
    }

    /// Every mode of a model of `n_modes` active (no reduction).
    pub fn all(n_modes: usize) -> Self {
        Self {
            n_modes,
            active: (0..n_modes).collect(),
            idle_parts: Vec::new(),
        }
    }

    /// The active modes, ascending.
    pub fn modes(&self) -> &[usize] {
        &self.active
    }

    /// Number of modes of the whole model.
    pub fn n_modes(&self) -> usize {
        self.n_modes
    }

    /// Whether every mode is active.
    pub fn is_all(&self) -> bool {
        self.active.len() == self.n_modes
    }

    /// The idle modes that terms with exactly one idle factor join into blocks of the
    /// linearisation (each ascending); idle modes without such a term are left out (linear
    /// resonators at rest).
    pub fn idle_parts(&self) -> &[Vec<usize>] {
        &self.idle_parts
    }

    /// `rows[n]` (one per mode of the whole model) of the active modes.
    pub fn restrict_rows<T: Clone>(&self, rows: &[Vec<T>]) -> Vec<Vec<T>> {
        self.active
            .iter()
            .map(|&m| rows.get(m).cloned().unwrap_or_default())
            .collect()
    }

    /// `state` (of the whole model) on the active modes.
    pub fn restrict_state(&self, state: &SteadyState) -> SteadyState {
        SteadyState {
            amplitudes: self.restrict_rows(&state.amplitudes),
            lattice_hz: state.lattice_hz.clone(),
            drive_jumps: state.drive_jumps.clone(),
            ..*state
        }
    }

    /// `state` of the active modes as a state of the whole model, the idle modes zero.
    pub fn expand_state(&self, mut state: SteadyState) -> SteadyState {
        if self.is_all() {
            return state;
        }
        let nr = state.lattice_hz.len();
        let mut rows = vec![vec![Complex64::new(0.0, 0.0); nr]; self.n_modes];
        for (&m, row) in self.active.iter().zip(state.amplitudes.drain(..)) {
            rows[m] = row;
        }
        state.amplitudes = rows;
        state
    }
}

/// The idle modes' parts (see [`ActiveModes::idle_parts`]).
fn idle_parts(n: usize, on: &[bool], terms: &[TermModes]) -> Vec<Vec<usize>> {
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut live = vec![false; n];
    for (eq, f, _) in terms.iter().filter(|t| !on[t.0]) {
        let idle: u32 = f.iter().filter(|&&(m, _)| !on[m]).map(|&(_, e)| e).sum();
        if idle != 1 {
            continue;
        }
        live[*eq] = true;
        if let Some(&(k, _)) = f.iter().find(|&&(m, _)| !on[m]) {
            live[k] = true;
            let (a, b) = (root(&mut parent, *eq), root(&mut parent, k));
            parent[a.max(b)] = a.min(b);
        }
    }
    let roots: Vec<usize> = (0..n).map(|m| root(&mut parent, m)).collect();
    let mut parts: Vec<Vec<usize>> = Vec::new();
    for m in (0..n).filter(|&m| !on[m]) {
        match parts.iter_mut().find(|p| roots[p[0]] == roots[m]) {
            Some(p) => p.push(m),
            None => parts.push(vec![m]),
        }
    }
    parts.retain(|p| p.iter().any(|&m| live[m]));
    parts
}
