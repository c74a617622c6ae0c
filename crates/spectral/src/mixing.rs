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
//!
//! **Velocities.** A monomial may hold velocities (variable `n_modes + n` is `q̇_n`, the
//! model's layout). The velocity of a component `X_c cos(2π f_c t)` is
//! `Re[i ω_c X_c e^{i2π f_c t}]`, `ω_c = 2π f_c`: in the two-sided expansion it puts
//! `+½ i ω_c X_c` at `+f_c` and `−½ i ω_c X_c` at `−f_c`. With `k` velocity factors every
//! product carries `i^k`, which the table factors out ([`MixingTable::velocity_factors`]): a
//! line's complex amplitude is `i^k · C`, with `C` a polynomial with rational coefficients in
//! the amplitudes `X_c` and the angular frequencies `ω_c` (variable `components + c`, named
//! `ω(X1)`, ... by [`ToneAssignment::symbols_with_frequencies`]). For `k = 1` the line is
//! `−C sin(2π f t)`: a damping force in quadrature with the motion.

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
                    let nm = self.mode_names.len();
                    if m.factors().iter().any(|&(v, _)| v.index() % nm == n) {
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

    /// The symbol names of a table with velocities: the components' amplitudes, then their
    /// angular frequencies `ω(X1)`, ... (`2π` times the component's frequency, rad/s), indexed
    /// by variable.
    pub fn symbols_with_frequencies(&self) -> Vec<String> {
        let mut s = self.symbols();
        s.extend(self.components.iter().map(|c| frequency_symbol(&c.symbol)));
        s
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

/// The name of a component's angular frequency: `ω(X1)`.
pub fn frequency_symbol(amplitude_symbol: &str) -> String {
    format!("ω({amplitude_symbol})")
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
    /// amplitudes (variable `i` = component `i` of the [`ToneAssignment`]); with velocity
    /// factors, the line's complex amplitude over `i^k` (see the module documentation), also
    /// in the components' angular frequencies (variable `components + i`).
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

    /// The coefficient evaluated at real amplitudes (`amplitudes[i]` for variable `i`; with
    /// velocities, the angular frequencies follow the amplitudes).
    pub fn eval(&self, amplitudes: &[f64]) -> f64 {
        self.coefficient.eval(amplitudes)
    }
}

/// Every line a monomial generates under a tone assignment, sorted by frequency.
#[derive(Debug, Clone, PartialEq)]
pub struct MixingTable {
    /// The monomial (over mode indices, then velocities).
    pub monomial: PowerProduct,
    /// `k`, the number of velocity factors of the monomial (with multiplicity): every line's
    /// complex amplitude is `i^k` times its coefficient.
    pub velocity_factors: u32,
    /// The lines, by increasing frequency.
    pub lines: Vec<Line>,
}

impl MixingTable {
    /// `i^k` as text (`""`, `"i·"`, `"−"`, `"−i·"`), to put before a coefficient.
    pub fn i_power_prefix(&self) -> &'static str {
        match self.velocity_factors % 4 {
            0 => "",
            1 => "i·",
            2 => "−",
            _ => "−i·",
        }
    }

    /// A line's coefficient as text over `symbols` (those of
    /// [`ToneAssignment::symbols_with_frequencies`]), with `i^k` in front when the monomial
    /// has velocity factors: `i·(1/4*X1^3*ω(X1))`, the line's complex amplitude.
    pub fn coefficient_text(&self, line: &Line, symbols: &[impl AsRef<str>]) -> String {
        let c = line.coefficient.to_string_with(symbols);
        match self.i_power_prefix() {
            "" => c,
            p => format!("{p}({c})"),
        }
    }

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

/// Expands monomial `m` (over mode indices, then velocities: variable `n_modes + n` is the
/// velocity of mode `n`) under `assignment`.
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
    let n_comp = assignment.components.len();
    for &(v, _) in m.factors() {
        if v.index() >= 2 * n_modes {
            return Err(SpectralError::Invalid(format!(
                "monomial uses variable {} but the assignment has {n_modes} modes (and their velocities)",
                v.index()
            )));
        }
    }
    let velocity_factors: u32 = m
        .factors()
        .iter()
        .filter(|&&(v, _)| v.index() >= n_modes)
        .map(|&(_, k)| k)
        .sum();
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
    for var in m.flat_factors() {
        let velocity = var.index() >= n_modes;
        let mode = var.index() % n_modes;
        let comps: Vec<(usize, &Component)> = assignment
            .components
            .iter()
            .enumerate()
            .filter(|(_, c)| c.mode == mode)
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
                // ½X at ±f; a velocity ±½ω X (its i factored out).
                let x = PowerProduct::var(VarId(i as u32));
                let factor = if velocity {
                    let w = PowerProduct::var(VarId((n_comp + i) as u32));
                    Coeff::term(x.checked_mul(&w).map_err(overflow)?, half)
                } else {
                    Coeff::term(x, half)
                };
                let term = p.checked_mul(&factor).map_err(overflow)?;
                let minus = if velocity {
                    term.checked_neg().map_err(overflow)?
                } else {
                    term.clone()
                };
                for (shifted, term) in [
                    (k.checked_add(&c.combination), &term),
                    (k.checked_sub(&c.combination), &minus),
                ] {
                    let shifted = shifted.ok_or(SpectralError::Overflow {
                        context: "adding combinations",
                    })?;
                    match next.get_mut(&shifted) {
                        Some(acc) => {
                            *acc = acc.checked_add(term).map_err(overflow)?;
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
        velocity_factors,
        lines,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64;
    use std::f64::consts::TAU;

    #[test]
    fn velocity_lines_match_a_brute_force_product_in_time() {
        // q1 at 3 and 5 Hz, q2 at 7 Hz: every product is periodic in 1 s, and 4096 samples
        // resolve each of its lines exactly.
        let names = ["q1", "q2"];
        let drives = vec![
            ("q1".to_string(), vec![3.0, 5.0]),
            ("q2".to_string(), vec![7.0]),
        ];
        let a = ToneAssignment::from_drives(&names, &drives).expect("tones");
        let amps = [0.7, -1.3, 0.9];
        let hz: Vec<f64> = a
            .components()
            .iter()
            .map(|c| c.combination.hz(a.tones()))
            .collect();
        let mut values = amps.to_vec();
        values.extend(hz.iter().map(|f| TAU * f));
        assert_eq!(
            a.symbols_with_frequencies(),
            ["X1", "X2", "X3", "ω(X1)", "ω(X2)", "ω(X3)"]
        );
        // Variables: q1, q2, d(q1), d(q2).
        let v = |i: u32| VarId(i);
        let monomials = [
            PowerProduct::from_factors([(v(0), 2), (v(2), 1)]),
            PowerProduct::from_factors([(v(1), 1), (v(2), 1), (v(3), 1)]),
            PowerProduct::from_factors([(v(2), 3)]),
            PowerProduct::from_factors([(v(0), 1), (v(1), 2), (v(3), 1)]),
            PowerProduct::from_factors([(v(2), 2), (v(3), 2)]),
        ];
        let n = 4096;
        for m in monomials {
            let m = m.expect("monomial");
            let table =
                mixing_table(&m, &a, &[Some(4.0), Some(7.0)], Window::default()).expect("table");
            let k = table.velocity_factors;
            let ik = Complex64::new(0.0, 1.0).powu(k);
            // The product sampled in time, projected on each frequency.
            let signal: Vec<f64> = (0..n)
                .map(|j| {
                    let t = j as f64 / n as f64;
                    let mut q = [0.0; 2];
                    let mut dq = [0.0; 2];
                    for (c, comp) in a.components().iter().enumerate() {
                        let w = TAU * hz[c];
                        q[comp.mode] += amps[c] * (w * t).cos();
                        dq[comp.mode] -= amps[c] * w * (w * t).sin();
                    }
                    let vars = [q[0], q[1], dq[0], dq[1]];
                    m.factors()
                        .iter()
                        .map(|&(x, e)| vars[x.index()].powi(e as i32))
                        .product()
                })
                .collect();
            let line_at = |f: usize| -> Complex64 {
                let sum: Complex64 = signal
                    .iter()
                    .enumerate()
                    .map(|(j, &x)| x * Complex64::from_polar(1.0, -TAU * (f * j) as f64 / n as f64))
                    .sum();
                sum * if f == 0 { 1.0 } else { 2.0 } / n as f64
            };
            let scale = signal.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
            for f in 0..40usize {
                let want = line_at(f);
                let got = table
                    .lines
                    .iter()
                    .find(|l| (l.hz - f as f64).abs() < 1e-9)
                    .map_or(Complex64::new(0.0, 0.0), |l| ik * l.eval(&values));
                assert!(
                    (got - want).norm() <= 1e-9 * scale,
                    "{}: {f} Hz: table {got}, time domain {want}",
                    m.name(&["q1", "q2", "d(q1)", "d(q2)"])
                );
            }
        }
    }

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
