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

/// Order of the combinations an even-degree model keeps wherever they fall: the direct
/// second-order products of the drive (`2f_1`, `f_1 + f_2`, `|f_2 − f_1|`, DC).
pub const EVEN_DIRECT_ORDER: i64 = 2;

/// The lattice: sorted distinct frequencies (Hz, ≥ 0) where the steady state is solved for.
///
/// For a model whose terms all have odd degree, only odd-order combinations can respond and
/// even ones are left out. A model with an even-degree term (quadratic forces, `q1*q2`, …)
/// responds at even orders too: it gets the static offset (a 0 Hz line, first in the list) and
/// every combination of order ≤ `EVEN_DIRECT_ORDER` (2) wherever it falls, and the slow lines
/// within `2 · window_rel · max f_n` of 0 Hz (beats of the lines kept near resonances: their
/// response is quasi-static, as large as the offset's), besides those near a resonance. An odd model gets the 0 Hz line only when an allowed combination of commensurate
/// tones lands on 0 Hz (e.g. `2f_1 − f_2` with `f_2 = 2f_1`).
pub fn choose_lattice(
    model: &NumericModel,
    drive: &Excitation,
    s: &LatticeSettings,
) -> Result<Vec<f64>, SimError> {
    let generators = drive.generators_hz();
    let nd = generators.len();
    let pump_var = 2 * model.n_modes();
    let odd_only = model.terms().iter().all(|t| model.state_degree(t) % 2 == 1)
        && model.rough_terms().iter().all(|t| t.is_odd(pump_var));
    // A non-smooth term's spectrum does not end: it counts as its effective degree.
    let dmax = model
        .rough_terms()
        .iter()
        .map(|t| t.effective_degree())
        .fold(model.max_degree(), u32::max)
        .max(1) as usize;
    let mut out: Vec<f64> = drive.tones_hz.clone();
    // The pump's own lines: inputs of the products (an odd model does not respond there).
    out.extend(drive.pumps.iter().map(|p| p.hz));
    out.extend(s.extra_hz.iter().copied().filter(|&f| f > LINE_TOL_HZ));
    let nonlinear = !model.terms().is_empty() || model.has_nonsmooth();
    let mut dc = !odd_only && nonlinear;
    // Slow lines of an even model: beats of two lines near resonances, |f_a − f_b| ≤ 2 w f_n;
    // their response is quasi-static (like the offset), not small.
    let slow_band = 2.0 * s.window_rel * model.f_hz.iter().copied().fold(0.0, f64::max);
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
        let f: f64 = k.iter().zip(&generators).map(|(&a, &b)| a as f64 * b).sum();
        if f.abs() <= LINE_TOL_HZ {
            // An allowed combination on 0 Hz: the response has a static offset.
            dc |= nonlinear;
            return;
        }
        if f < 0.0 {
            return;
        }
        let near = model
            .f_hz
            .iter()
            .any(|&fn_| (f - fn_).abs() <= s.window_rel * fn_);
        let direct = !odd_only && (ord <= EVEN_DIRECT_ORDER || f <= slow_band);
        if near || direct || (s.harmonics && ord as usize <= dmax) {
            out.push(f);
        }
    });
    if err {
        return Err(SimError::TooLarge {
            what: "combination frequencies of the lattice",
            count: MAX_CANDIDATES + 1,
            limit: MAX_CANDIDATES,
            help: "use a lower order or fewer tones",
        });
    }
    if dc {
        out.push(0.0);
    }
    out.sort_by(f64::total_cmp);
    out.dedup_by(|a, b| (*a - *b).abs() <= LINE_TOL_HZ);
    Ok(out)
}

/// Calls `f` with every integer vector `k` (over the tones) with `Σ_{i≥d} |k_i| ≤ budget`,
/// entries before `d` held; the combinations `Σ k_i f_i` of intermodulation order ≤ `budget`.
pub(crate) fn enumerate(k: &mut [i64], d: usize, budget: i64, f: &mut impl FnMut(&[i64])) {
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

/// The lines of `lattice_hz` (sorted, Hz) that are combinations `Σ_d k_d f_d` of the drive tones
/// of intermodulation order `Σ |k_d| ≤ order` (the static offset counts as order 0), in lattice
/// order. The drive ramp runs on these (see [`crate::HbSolver::solve`]): the low orders carry
/// the branch structure, the higher ones are small corrections.
pub fn low_order_lines(drive: &Excitation, lattice_hz: &[f64], order: usize) -> Vec<usize> {
    let mut keep = vec![false; lattice_hz.len()];
    let generators = drive.generators_hz();
    let mut k = vec![0i64; generators.len()];
    enumerate(&mut k, 0, order as i64, &mut |k| {
        let f: f64 = k.iter().zip(&generators).map(|(&a, &b)| a as f64 * b).sum();
        let f = f.abs();
        let i = lattice_hz.partition_point(|&x| x < f - LINE_TOL_HZ);
        if lattice_hz
            .get(i)
            .is_some_and(|&x| (x - f).abs() <= LINE_TOL_HZ)
        {
            keep[i] = true;
        }
    });
    (0..lattice_hz.len()).filter(|&i| keep[i]).collect()
}

/// The lattice lines a dataset measures by default (pump lines are not response lines): every drive tone and every line within
/// `window_rel · f_n` of a resonance `f_n`, Hz (sorted). Leaves out the static offset (datasets
/// hold positive frequencies only) and the even-order lines far from resonance that
/// [`choose_lattice`] keeps for the physics of even-degree models. For an odd model with default
/// settings this is the whole lattice.
pub fn measured_lines(
    model: &NumericModel,
    drive: &Excitation,
    lattice_hz: &[f64],
    window_rel: f64,
) -> Vec<f64> {
    lattice_hz
        .iter()
        .copied()
        .filter(|&f| {
            f > LINE_TOL_HZ
                && (drive.tones_hz.iter().any(|&d| (d - f).abs() <= LINE_TOL_HZ)
                    || model
                        .f_hz
                        .iter()
                        .any(|&fn_| (f - fn_).abs() <= window_rel * fn_))
        })
        .collect()
}
