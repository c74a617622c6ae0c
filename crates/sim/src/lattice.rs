//! Automatic choice of the harmonic-balance frequency lattice.

use crate::{Excitation, NumericModel, SimError};

/// How the lattice of response frequencies is chosen.
#[derive(Debug, Clone, PartialEq)]
pub struct LatticeSettings {
    /// Intermodulation order `K`: combinations `Σ_d k_d f_d` with `Σ |k_d| ≤ K` are candidates.
    pub order: usize,
    /// Half-width of the band kept around each resonance, relative to its frequency
    /// (combinations within `window_rel · f_n` of some `f_n` are kept).
    pub window_rel: f64,
    /// Also keep every combination of order up to the model's degree wherever it falls (the
    /// main harmonics and intermodulation products the nonlinearity makes directly).
    pub harmonics: bool,
    /// Frequencies always kept (e.g. every measured frequency), Hz.
    pub extra_hz: Vec<f64>,
}

impl Default for LatticeSettings {
    fn default() -> Self {
        Self {
            order: 9,
            window_rel: 0.005,
            harmonics: false,
            extra_hz: Vec::new(),
        }
    }
}

/// Most candidate combinations enumerated before asking for a lower order.
const MAX_CANDIDATES: usize = 2_000_000;

/// Frequencies closer than this are one lattice line (Hz); matches the product plans.
pub const LINE_TOL_HZ: f64 = harmonid_spectral::FREQ_TOLERANCE_HZ;

/// The lattice: sorted distinct positive frequencies (Hz) where the steady state is solved for.
///
/// For a model whose terms all have odd degree, only odd-order combinations can respond and
/// even ones are left out. DC is not part of the lattice (see the crate docs).
pub fn choose_lattice(
    model: &NumericModel,
    drive: &Excitation,
    s: &LatticeSettings,
) -> Result<Vec<f64>, SimError> {
    let nd = drive.tones_hz.len();
    let odd_only = model.terms().iter().all(|t| t.degree() % 2 == 1);
    let dmax = model.max_degree().max(1) as usize;
    let mut out: Vec<f64> = drive.tones_hz.clone();
    out.extend(s.extra_hz.iter().copied().filter(|&f| f > LINE_TOL_HZ));
    let mut k = vec![0i64; nd];
    let mut count = 0usize;
    let mut err = false;
    enumerate(&mut k, 0, s.order as i64, &mut |k| {
        count += 1;
        if count > MAX_CANDIDATES {
            err = true;
            return;
        }
        let ord: i64 = k.iter().map(|x| x.abs()).sum();
        if ord == 0 || (odd_only && ord % 2 == 0) {
            return;
        }
        let f: f64 = k
            .iter()
            .zip(&drive.tones_hz)
            .map(|(&a, &b)| a as f64 * b)
            .sum();
        if f <= LINE_TOL_HZ {
            return;
        }
        let near = model
            .f_hz
            .iter()
            .any(|&fn_| (f - fn_).abs() <= s.window_rel * fn_);
        if near || (s.harmonics && ord as usize <= dmax) {
            out.push(f);
        }
    });
    if err {
        return Err(SimError::Hb(format!(
            "order {} with {nd} tones gives more than {MAX_CANDIDATES} combinations; use a lower order",
            s.order
        )));
    }
    out.sort_by(f64::total_cmp);
    out.dedup_by(|a, b| (*a - *b).abs() <= LINE_TOL_HZ);
    Ok(out)
}

fn enumerate(k: &mut [i64], d: usize, budget: i64, f: &mut impl FnMut(&[i64])) {
    if d == k.len() {
        f(k);
        return;
    }
    for v in -budget..=budget {
        k[d] = v;
        enumerate(k, d + 1, budget - v.abs(), f);
    }
    k[d] = 0;
}
