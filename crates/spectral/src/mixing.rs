//! Symbolic mixing tables: which lines a monomial generates under a tone assignment, with exact
//! rational coefficients (Supplementary Note II of the method's paper, Eq. S1–S3, Table S1).
//!
//! Each mode moves as a sum of real components `q_n(t) = Σ_c X_c cos(2π f_c t)`, each with a
//! symbolic real amplitude `X_c` and a frequency that is an exact [`Combination`] of the drive
//! tones. Expanding the monomial with `cos a = ½(e^{ia} + e^{-ia})` gives every output line with
//! a coefficient that is a polynomial in the `X_c` with rational coefficients.
//!
//! **Convention.** A line's coefficient `C` is the amplitude of `cos(2π f t)` in the product, as
//! in the paper; for `f = 0` it is the constant (DC) value. With the DATA_FORMAT convention
//! (`Re[X e^{i2πft}]`), a component `X_c cos(2π f_c t)` has the real complex amplitude `X_c`, and
//! the product's complex amplitude at the line is exactly `C` evaluated at those real values:
//! the numeric [`crate::ProductPlan`] gives the same number (tested). With phases (complex
//! amplitudes) the table still gives every line and which amplitudes meet there, but the
//! numeric value needs the conjugate-aware [`crate::ProductPlan`].

use crate::lattice::{nearest_mode, Combination, ToneSet};
use crate::{SpectralError, FREQ_TOLERANCE_HZ};
use harmonid_poly::{Coeff, PowerProduct, Rational, VarId};
use std::collections::BTreeMap;

/// Most (line, component) products the symbolic expansion may visit (memory bound).
pub const MAX_EXPANSION_TERMS: usize = 1 << 20;

/// Where a mode's motion has a component.
#[derive(Debug, Clone, PartialEq)]
pub enum ComponentKind {
    /// Drive tone `d` of the [`ToneSet`].
    Drive(usize),
    /// A sideband of the mode's own tones (an intermodulation product near its resonance).
    Sideband,
    /// The response of a mode without a tone of its own at a line that a term of its equation,
    /// made of other modes' motion, forces on it (e.g. `q1·q2` in the equation of `q3` with
    /// tones on `q1` and `q2` only: `q3` moves at `Ω1 + Ω2` and `|Ω1 − Ω2|`). See
    /// [`ToneAssignment::add_responses`].
    Response,
}

/// One real component `X_c cos(2π f_c t)` of a mode's motion.
#[derive(Debug, Clone, PartialEq)]
pub struct Component {
    /// Mode index (declaration order).
    pub mode: usize,
    /// Its frequency as a combination of the tones.
    pub combination: Combination,
    /// What it is.
    pub kind: ComponentKind,
    /// Its symbolic amplitude's name (`X1`, `X3_q2`, `Y1`, ...).
    pub symbol: String,
}

/// Which components each mode's motion has: the tones (with symbolic amplitudes) and
/// optionally the mode's own sidebands.
///
/// Symbols: drive tone `d` (1-based, tone-set order) in one mode only is `Xd`; a tone in the
/// motion of several modes is `Xd_<mode>`; sidebands are `Y1`, `Y2`, ... and responses of modes
/// without a tone `Z1`, `Z2`, ..., each in order of addition.
/// Symbol `i` is variable `VarId(i)` of the coefficients.
#[derive(Debug, Clone, PartialEq)]
pub struct ToneAssignment {
    tones: ToneSet,
    mode_names: Vec<String>,
    components: Vec<Component>,
}

impl ToneAssignment {
    /// An assignment with no components yet.
    pub fn new(tones: ToneSet, mode_names: Vec<String>) -> Self {
        Self {
            tones,
            mode_names,
            components: Vec::new(),
        }
    }

    /// Tones per mode by name, e.g. `[("q1", [207572, 207592]), ("q2", [415842])]` (Hz); the
    /// tones are numbered `f1, f2, ...` in the order given, each in the motion of its mode.
    ///
    /// Errors: an undeclared mode, a tone ≤ 0 Hz, coincident tones, too many tones.
    pub fn from_drives(
        mode_names: &[impl AsRef<str>],
        drives: &[(String, Vec<f64>)],
    ) -> Result<Self, SpectralError> {
        let names: Vec<String> = mode_names.iter().map(|s| s.as_ref().to_string()).collect();
        let mut hz = Vec::new();
        let mut owner = Vec::new();
        for (mode, tones) in drives {
            let n =
                names
                    .iter()
                    .position(|m| m == mode)
                    .ok_or_else(|| SpectralError::UnknownMode {
                        mode: mode.clone(),
                        declared: names.join(", "),
                    })?;
            for &f in tones {
                hz.push(f);
                owner.push(n);
            }
        }
        let tones = ToneSet::new(&hz)?;
        let mut a = Self::new(tones, names);
        for (d, &n) in owner.iter().enumerate() {
            a.assign(n, d)?;
        }
        Ok(a)
    }

    /// Puts tone `d` into the motion of mode `mode` (no effect if already there).
    pub fn assign(&mut self, mode: usize, d: usize) -> Result<(), SpectralError> {
        if mode >= self.mode_names.len() {
            return Err(SpectralError::Invalid(format!(
                "mode index {mode} but only {} modes",
                self.mode_names.len()
            )));
        }
        if d >= self.tones.len() {
            return Err(SpectralError::Invalid(format!(
                "tone index {d} but only {} tones",
                self.tones.len()
            )));
        }
        let exists = self
            .components
            .iter()
            .any(|c| c.mode == mode && c.kind == ComponentKind::Drive(d));
        if !exists {
            self.components.push(Component {
                mode,
                combination: self.tones.unit(d),
                kind: ComponentKind::Drive(d),
                symbol: String::new(),
            });
            self.rename();
        }
        Ok(())
    }

    /// Lets every mode with at least two tones carry its own sidebands: the combinations
    /// `Σ k_d f_d` of its tones with `Σ k_d = 1` and `3 ≤ Σ|k_d| ≤ max_order` (for tones
    /// `ω1 ± δ`: `ω1 ± 3δ` at order 3, `ω1 ± 5δ` at order 5), each with its own amplitude `Yj`.
    /// Returns how many sidebands were added.
    pub fn add_own_sidebands(&mut self, max_order: u32) -> Result<usize, SpectralError> {
        let mut added = 0;
        for mode in 0..self.mode_names.len() {
            let own: Vec<usize> = self
                .components
                .iter()
                .filter_map(|c| match c.kind {
                    ComponentKind::Drive(d) if c.mode == mode => Some(d),
                    _ => None,
                })
                .collect();
            if own.len() < 2 {
                continue;
            }
            let sub: Vec<f64> = own.iter().map(|&d| self.tones.hz()[d]).collect();
            let sub = ToneSet::new(&sub)?;
            let mut candidates: Vec<Combination> = Vec::new();
            for p in sub.lattice(max_order)? {
                let k = p.combination.coeffs();
                // Lattice points are canonical (≥ 0 Hz); sidebands near the tones have net 1.
                if p.combination.net() != 1 || p.combination.order() < 3 {
                    continue;
                }
                let mut full = vec![0i32; self.tones.len()];
                for (&d, &kd) in own.iter().zip(k) {
                    full[d] = kd;
                }
                candidates.push(self.tones.combination(&full)?);
            }
            candidates.sort_by_key(|c| (c.order(), c.hz(&self.tones).to_bits()));
            for c in candidates {
                let hz = c.hz(&self.tones);
                let clash = self.components.iter().any(|e| {
                    e.mode == mode
                        && (e.combination.hz(&self.tones) - hz).abs() <= FREQ_TOLERANCE_HZ
                });
                if clash || hz <= FREQ_TOLERANCE_HZ {
                    continue;
                }
                self.components.push(Component {
                    mode,
                    combination: c,
                    kind: ComponentKind::Sideband,
                    symbol: String::new(),
                });
                added += 1;
            }
        }
        self.rename();
        Ok(added)
    }

    /// Gives every mode that does not move yet (no tone, no component) its response through
    /// the coupling: mode `n` moves at every line that the terms of its equation without `q_n`
    /// (`equations[n]`: the monomials of mode `n`'s equation) make from the other modes'
    /// components, each line a component of kind [`ComponentKind::Response`] with its own
    /// amplitude `Zj` (terms holding `q_n` vanish while the mode is at rest). Repeated while a
    /// mode gains components, so a chain `q1 → q2 → q3` is followed. Returns how many components
    /// were added.
    ///
    /// The mixing tables of terms that hold such a mode then give the second-order lines
    /// through the coupling ([`ToneAssignment::responses_in`] names the modes a line goes
    /// through): with `U = κ q1 q2 q3` and tones `Ω1` on `q1`, `Ω2` on `q2`, `q3` moves at
    /// `Ω1 + Ω2` and `Ω2 − Ω1`, and `κ q2 q3` in the equation of `q1` puts lines at `Ω1`
    /// (and `2Ω2 ± Ω1`).
    ///
    /// Errors: as [`mixing_table`].
    pub fn add_responses(
        &mut self,
        equations: &[Vec<PowerProduct>],
    ) -> Result<usize, SpectralError> {
        let nominal = vec![None; self.mode_names.len()];
        let mut added = 0;
        loop {
            let mut changed = false;
            for n in 0..self.mode_names.len() {
                if self.components.iter().any(|c| c.mode == n) {
                    continue;
                }
                let mut lines: Vec<(f64, Combination)> = Vec::new();
                for m in equations.get(n).map_or(&[][..], |v| &v[..]) {
                    if m.factors().iter().any(|&(v, _)| v.index() == n) {
                        continue;
                    }
                    for l in mixing_table(m, self, &nominal, Window::default())?.lines {
                        if !lines
                            .iter()
                            .any(|(hz, _)| (hz - l.hz).abs() <= FREQ_TOLERANCE_HZ)
                        {
                            lines.push((l.hz, l.combination));
                        }
                    }
                }
                lines.sort_by(|a, b| a.0.total_cmp(&b.0));
                for (_, combination) in lines {
                    self.components.push(Component {
                        mode: n,
                        combination,
                        kind: ComponentKind::Response,
                        symbol: String::new(),
                    });
                    added += 1;
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
        self.rename();
        Ok(added)
    }

    /// The modes (ascending) whose responses through the coupling
    /// ([`ComponentKind::Response`]) the coefficient `c` (a line's, variable `i` = component
    /// `i`) holds: empty for a first-order line, e.g. `[q3]` for a line that goes through
    /// `q3`'s response.
    pub fn responses_in(&self, c: &Coeff) -> Vec<usize> {
        let mut modes: Vec<usize> = c
            .variables()
            .iter()
            .filter_map(|v| self.components.get(v.index()))
            .filter(|c| c.kind == ComponentKind::Response)
            .map(|c| c.mode)
            .collect();
        modes.sort_unstable();
        modes.dedup();
        modes
    }

    fn rename(&mut self) {
        let mut z = 0;
        let mut y = 0;
        let counts: Vec<usize> = (0..self.tones.len())
            .map(|d| {
                self.components
                    .iter()
                    .filter(|c| c.kind == ComponentKind::Drive(d))
                    .count()
            })
            .collect();
        for c in &mut self.components {
            c.symbol = match c.kind {
                ComponentKind::Drive(d) if counts[d] > 1 => {
                    format!("X{}_{}", d + 1, self.mode_names[c.mode])
                }
                ComponentKind::Drive(d) => format!("X{}", d + 1),
                ComponentKind::Sideband => {
                    y += 1;
                    format!("Y{y}")
                }
                ComponentKind::Response => {
                    z += 1;
                    format!("Z{z}")
                }
            };
        }
    }

    /// The tones.
    pub fn tones(&self) -> &ToneSet {
        &self.tones
    }

    /// The mode names, declaration order.
    pub fn mode_names(&self) -> &[String] {
        &self.mode_names
    }

    /// The components; component `i`'s amplitude is variable `VarId(i)` of the coefficients.
    pub fn components(&self) -> &[Component] {
        &self.components
    }

    /// The symbol names, indexed by variable.
    pub fn symbols(&self) -> Vec<String> {
        self.components.iter().map(|c| c.symbol.clone()).collect()
    }

    /// Fills every `None` in `nominal_hz` (per mode, Hz) with the mean frequency of that mode's
    /// own drive tones, if it has any: where a mode without a nominal resonance is taken to sit.
    pub fn fill_nominal_from_drives(&self, nominal_hz: &mut [Option<f64>]) {
        for (n, f) in nominal_hz.iter_mut().enumerate() {
            if f.is_some() {
                continue;
            }
            let own: Vec<f64> = self
                .components
                .iter()
                .filter(|c| c.mode == n && matches!(c.kind, ComponentKind::Drive(_)))
                .map(|c| c.combination.hz(&self.tones))
                .collect();
            if !own.is_empty() {
                *f = Some(own.iter().sum::<f64>() / own.len() as f64);
            }
        }
    }
}

/// What counts as "near" a resonance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Window {
    /// Within this many Hz of the nominal resonance.
    Hz(f64),
    /// Within this fraction of the nominal resonance frequency (e.g. `0.01` = 1 %).
    Relative(f64),
}

impl Default for Window {
    /// 1 % of the resonance frequency.
    fn default() -> Self {
        Window::Relative(0.01)
    }
}

impl Window {
    fn contains(&self, distance_hz: f64, nominal_hz: f64) -> bool {
        match *self {
            Window::Hz(w) => distance_hz.abs() <= w,
            Window::Relative(r) => distance_hz.abs() <= r * nominal_hz.abs(),
        }
    }
}

/// One output line of a monomial.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    /// The line's frequency as a combination of the tones (canonical: ≥ 0 Hz, lowest order
    /// among those that land here).
    pub combination: Combination,
    /// Other combinations landing on the same frequency (only with commensurate tones).
    pub aliases: Vec<Combination>,
    /// Frequency, Hz (≥ 0).
    pub hz: f64,
    /// Amplitude of `cos(2π hz t)` (DC value at 0 Hz), a polynomial in the component
    /// amplitudes (variable `i` = component `i` of the [`ToneAssignment`]).
    pub coefficient: Coeff,
    /// The mode whose nominal resonance is closest, with the signed distance `hz − f_n` (Hz),
    /// if any mode has a nominal frequency.
    pub nearest: Option<(usize, f64)>,
    /// Whether the line is within the window of that mode.
    pub near: bool,
}

impl Line {
    /// The mode this line is near (within the window), if any.
    pub fn near_mode(&self) -> Option<usize> {
        if self.near {
            self.nearest.map(|(n, _)| n)
        } else {
            None
        }
    }

    /// The coefficient evaluated at real amplitudes (`amplitudes[i]` for variable `i`).
    pub fn eval(&self, amplitudes: &[f64]) -> f64 {
        self.coefficient.eval(amplitudes)
    }
}

/// Every line a monomial generates under a tone assignment, sorted by frequency.
#[derive(Debug, Clone, PartialEq)]
pub struct MixingTable {
    /// The monomial (over mode indices).
    pub monomial: PowerProduct,
    /// The lines, by increasing frequency.
    pub lines: Vec<Line>,
}

impl MixingTable {
    /// Lines within the window of mode `n`.
    pub fn near(&self, n: usize) -> impl Iterator<Item = &Line> {
        self.lines.iter().filter(move |l| l.near_mode() == Some(n))
    }

    /// Lines near no resonance.
    pub fn off_resonance(&self) -> impl Iterator<Item = &Line> {
        self.lines.iter().filter(|l| l.near_mode().is_none())
    }

    /// The line at a given combination (or one of its aliases, or its negative).
    pub fn line(&self, c: &Combination) -> Option<&Line> {
        let neg = c.neg();
        self.lines.iter().find(|l| {
            l.combination == *c
                || l.combination == neg
                || l.aliases.iter().any(|a| a == c || *a == neg)
        })
    }
}

/// Expands monomial `m` (over mode indices) under `assignment`.
///
/// `nominal_hz[n]` is mode `n`'s nominal resonance (Hz, `None` if unknown) and decides which
/// lines are near which resonance within `window`. A mode with no component does not move, so a
/// monomial containing it has no lines (give a mode without tones its response through the
/// coupling first: [`ToneAssignment::add_responses`]).
///
/// Errors: a mode of `m` beyond the assignment's modes, an expansion beyond
/// [`MAX_EXPANSION_TERMS`], or exact-arithmetic overflow.
pub fn mixing_table(
    m: &PowerProduct,
    assignment: &ToneAssignment,
    nominal_hz: &[Option<f64>],
    window: Window,
) -> Result<MixingTable, SpectralError> {
    let n_modes = assignment.mode_names.len();
    for &(v, _) in m.factors() {
        if v.index() >= n_modes {
            return Err(SpectralError::Invalid(format!(
                "monomial uses mode index {} but the assignment has {n_modes} modes",
                v.index()
            )));
        }
    }
    let half = Rational::new(1, 2);
    let overflow = |_| SpectralError::Overflow {
        context: "expanding a mixing table",
    };
    let tones = &assignment.tones;
    // Two-sided expansion: combination → coefficient of e^{i2π(Σk f)t}.
    let mut spectrum: BTreeMap<Combination, Coeff> = BTreeMap::new();
    spectrum.insert(
        Combination::zero(tones.len()),
        Coeff::constant(Rational::from_integer(1)),
    );
    for mode in m.flat_factors() {
        let comps: Vec<(usize, &Component)> = assignment
            .components
            .iter()
            .enumerate()
            .filter(|(_, c)| c.mode == mode.index())
            .collect();
        let visits = spectrum.len().saturating_mul(2 * comps.len());
        if visits > MAX_EXPANSION_TERMS {
            return Err(SpectralError::TooLarge {
                what: "the symbolic expansion",
                needed: visits,
                limit: MAX_EXPANSION_TERMS,
            });
        }
        let mut next: BTreeMap<Combination, Coeff> = BTreeMap::new();
        for (k, p) in &spectrum {
            for &(i, c) in &comps {
                let factor = Coeff::term(PowerProduct::var(VarId(i as u32)), half);
                let term = p.checked_mul(&factor).map_err(overflow)?;
                for shifted in [k.checked_add(&c.combination), k.checked_sub(&c.combination)] {
                    let shifted = shifted.ok_or(SpectralError::Overflow {
                        context: "adding combinations",
                    })?;
                    match next.get_mut(&shifted) {
                        Some(acc) => {
                            *acc = acc.checked_add(&term).map_err(overflow)?;
                        }
                        None => {
                            next.insert(shifted, term.clone());
                        }
                    }
                }
            }
        }
        next.retain(|_, p| !p.is_zero());
        spectrum = next;
    }
    // Fold the two-sided spectrum onto lines at f ≥ 0, merging coincident frequencies.
    let mut entries: Vec<(f64, Combination, Coeff)> = spectrum
        .into_iter()
        .map(|(k, p)| (k.hz(tones), k, p))
        .filter(|(hz, _, p)| *hz >= -FREQ_TOLERANCE_HZ && !p.is_zero())
        .collect();
    entries.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut lines: Vec<Line> = Vec::new();
    let mut i = 0;
    while i < entries.len() {
        let start = entries[i].0;
        let mut j = i;
        while j < entries.len() && entries[j].0 - start <= FREQ_TOLERANCE_HZ {
            j += 1;
        }
        let group = &entries[i..j];
        let dc = start.abs() <= FREQ_TOLERANCE_HZ;
        let mut coefficient = Coeff::zero();
        for (_, _, p) in group {
            coefficient = coefficient.checked_add(p).map_err(overflow)?;
        }
        if !dc {
            coefficient = coefficient
                .checked_scale_rational(&Rational::from_integer(2))
                .map_err(overflow)?;
        }
        // Representative: canonical (for DC), lowest order, then lexicographic.
        let mut combos: Vec<Combination> = group
            .iter()
            .map(|(_, k, _)| k.clone())
            .filter(|k| !dc || k.is_canonical())
            .collect();
        combos.sort_by(|a, b| a.order().cmp(&b.order()).then_with(|| b.cmp(a)));
        combos.dedup();
        if !coefficient.is_zero() && !combos.is_empty() {
            let combination = combos.remove(0);
            let hz = combination.hz(tones).max(0.0);
            let nearest = if dc {
                None
            } else {
                nearest_mode(hz, nominal_hz)
            };
            let near =
                nearest.is_some_and(|(n, d)| nominal_hz[n].is_some_and(|f| window.contains(d, f)));
            lines.push(Line {
                combination,
                aliases: combos,
                hz,
                coefficient,
                nearest,
                near,
            });
        }
        i = j;
    }
    Ok(MixingTable {
        monomial: m.clone(),
        lines,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mode_without_nominal_sits_at_its_drive_tones_mean() {
        let names = ["q1", "q2", "q3"];
        let drives = vec![
            ("q1".to_string(), vec![100.0, 110.0]),
            ("q2".to_string(), vec![300.0]),
        ];
        let mut a = ToneAssignment::from_drives(&names, &drives).expect("tones");
        a.add_own_sidebands(3).expect("sidebands");
        let mut nominal = [None, Some(290.0), None];
        a.fill_nominal_from_drives(&mut nominal);
        // q1: the mean of its two tones (its sidebands do not count); q2 keeps its own; q3 has
        // no tone and stays unknown.
        assert_eq!(nominal, [Some(105.0), Some(290.0), None]);
    }
}
