//! The single-harmonic (one-frequency) harmonic balance of a model as a polynomial system.
//!
//! With every mode at one frequency `Ω` (the drive tone, or half the pump's), `q_n = Re[X_n
//! e^{iθ}]`, `θ = Ω t`, `X_n = u_n + i v_n`, and the pump `Re[P e^{2iθ}]`, the fundamental
//! component of the equation of motion of mode `n` (DATA_FORMAT conventions) is
//!
//! ```text
//! R_n = (ω_n² − Ω² + iΩγ_n) X_n + Σ_t b_t [m_t(q, q̇, pump)]_1 − F_n = 0,
//! ```
//!
//! `[s]_1` the complex amplitude of `s(θ)` at `e^{iθ}` (`s ≈ Re[[s]_1 e^{iθ}]`). Each factor is
//! `q = (X e^{iθ} + X̄ e^{−iθ})/2`, `q̇ = (iΩX e^{iθ} − iΩX̄ e^{−iθ})/2`, `pump = (P e^{2iθ} +
//! P̄ e^{−2iθ})/2`; expanding the product and keeping the terms at `e^{iθ}` (times two) is exact.
//! `Re R_n = 0`, `Im R_n = 0` are `2N` real polynomial equations in `(u, v)`; terms of even
//! degree in the modes have no fundamental and drop out here (their static offset and second
//! harmonic are the lattice's, see [`crate::states`]).
//!
//! The unknowns are scaled, `X = s·x`, and each mode's pair of equations divided by its largest
//! coefficient, so that the homotopy works with numbers of order one (amplitudes are ~1e-9 m
//! and coefficients up to 1e23 in SI).

use crate::system::{PolySystem, Term, ZERO};
use crate::ExploreError;
use harmonid_sim::NumericModel;
use num_complex::Complex64;
use std::collections::BTreeMap;

/// The excitation of the single-harmonic system.
#[derive(Debug, Clone, PartialEq)]
pub struct Tone {
    /// Response frequency, Hz: the drive tone, or half the pump frequency.
    pub hz: f64,
    /// Force of the tone on each mode, N/kg (complex amplitude; zero without a drive).
    pub force: Vec<Complex64>,
    /// Complex pump amplitude at `2·hz` (zero without a pump).
    pub pump: Complex64,
}

impl Tone {
    /// `Ω = 2π·hz`, rad/s.
    pub fn omega(&self) -> f64 {
        std::f64::consts::TAU * self.hz
    }
}

/// One contribution to a coefficient of `R_eq`: `coef · b_term · Ω^omega_pow · P^pump ·
/// P̄^pump_conj` at monomial `mono`.
#[derive(Debug, Clone, PartialEq)]
struct Entry {
    eq: usize,
    mono: usize,
    term: usize,
    coef: Complex64,
    omega_pow: i32,
    pump: i32,
    pump_conj: i32,
}

/// The single-harmonic system of a model, expanded once; [`SingleHarmonic::system`] evaluates
/// it at a tone and set of values without expanding again.
#[derive(Debug, Clone, PartialEq)]
pub struct SingleHarmonic {
    n_modes: usize,
    /// The distinct monomials over `(u_0, v_0, u_1, v_1, …)` (exponent vectors).
    monos: Vec<Vec<u32>>,
    entries: Vec<Entry>,
    /// Number of model terms expanded (a model of other terms is refused).
    n_terms: usize,
}

/// A sparse polynomial over the `2N` real unknowns with complex coefficients.
type Poly = BTreeMap<Vec<u32>, Complex64>;

fn mul(a: &Poly, b: &Poly) -> Poly {
    let mut out = Poly::new();
    for (ea, ca) in a {
        for (eb, cb) in b {
            let e: Vec<u32> = ea.iter().zip(eb).map(|(x, y)| x + y).collect();
            *out.entry(e).or_insert(ZERO) += ca * cb;
        }
    }
    out
}

fn pow(p: &Poly, k: u32, nv: usize) -> Poly {
    let mut out = Poly::from([(vec![0; nv], Complex64::new(1.0, 0.0))]);
    for _ in 0..k {
        out = mul(&out, p);
    }
    out
}

fn binom(n: u32, k: u32) -> f64 {
    (0..k).fold(1.0, |a, i| a * (n - i) as f64 / (i + 1) as f64)
}

impl SingleHarmonic {
    /// Expands the fundamental of every term of `model`. Errors: a term whose expansion
    /// would be too large (a total degree above 9).
    pub fn new(model: &NumericModel) -> Result<Self, ExploreError> {
        let nm = model.n_modes();
        let nv = 2 * nm;
        let mut index: BTreeMap<Vec<u32>, usize> = BTreeMap::new();
        let mut monos = Vec::new();
        let mut entries = Vec::new();
        // X_m/2 and X̄_m/2 as polynomials in (u, v).
        let half = |m: usize, conj: bool| {
            let mut e = vec![0; nv];
            e[2 * m] = 1;
            let mut p = Poly::from([(e.clone(), Complex64::new(0.5, 0.0))]);
            e[2 * m] = 0;
            e[2 * m + 1] = 1;
            p.insert(e, Complex64::new(0.0, if conj { -0.5 } else { 0.5 }));
            p
        };
        for (t, term) in model.terms().iter().enumerate() {
            if term.degree() > 9 {
                return Err(ExploreError::TooComplex {
                    what: format!(
                        "a term of degree {} in the equation of {}",
                        term.degree(),
                        model.mode_names[term.eq]
                    ),
                    limit: "degree 9",
                });
            }
            // Per factor: (variable, power, frequency of its positive part, Ω power, ±i).
            let mut combos: Vec<(Poly, i32, i32, i32, Complex64)> =
                vec![(pow(&Poly::new(), 0, nv), 0, 0, 0, Complex64::new(2.0, 0.0))];
            for &(var, k) in &term.factors {
                let mut next = Vec::new();
                for (p, freq, pp, pc, c) in &combos {
                    for j in 0..=k {
                        let (mut q, mut f, mut a, mut b, mut cc) =
                            (p.clone(), *freq, *pp, *pc, *c * binom(k, j));
                        if var == 2 * nm {
                            // The pump: (P e^{2iθ})/2 j times, (P̄ e^{−2iθ})/2 k−j times.
                            f += 2 * (2 * j as i32 - k as i32);
                            a += j as i32;
                            b += (k - j) as i32;
                            cc *= 0.5f64.powi(k as i32);
                        } else {
                            let (m, vel) = if var < nm {
                                (var, false)
                            } else {
                                (var - nm, true)
                            };
                            q = mul(
                                &mul(&q, &pow(&half(m, false), j, nv)),
                                &pow(&half(m, true), k - j, nv),
                            );
                            f += 2 * j as i32 - k as i32;
                            if vel {
                                // iΩ per positive part, −iΩ per negative part.
                                cc *= Complex64::new(0.0, 1.0).powi(j as i32)
                                    * Complex64::new(0.0, -1.0).powi((k - j) as i32);
                            }
                        }
                        next.push((q, f, a, b, cc));
                    }
                }
                combos = next;
            }
            let omega_pow = term
                .factors
                .iter()
                .filter(|f| (nm..2 * nm).contains(&f.0))
                .map(|f| f.1 as i32)
                .sum();
            for (p, f, a, b, c) in combos {
                if f != 1 {
                    continue;
                }
                for (e, v) in p {
                    if v == ZERO {
                        continue;
                    }
                    let len = monos.len();
                    let mono = *index.entry(e.clone()).or_insert(len);
                    if mono == len {
                        monos.push(e);
                    }
                    entries.push(Entry {
                        eq: term.eq,
                        mono,
                        term: t,
                        coef: c * v,
                        omega_pow,
                        pump: a,
                        pump_conj: b,
                    });
                }
            }
        }
        // The linear part and the force: monomials u_n, v_n and 1.
        for e in (0..nv)
            .map(|k| {
                let mut e = vec![0; nv];
                e[k] = 1;
                e
            })
            .chain(std::iter::once(vec![0; nv]))
        {
            if !index.contains_key(&e) {
                index.insert(e.clone(), monos.len());
                monos.push(e);
            }
        }
        Ok(Self {
            n_modes: nm,
            monos,
            entries,
            n_terms: model.terms().len(),
        })
    }

    /// Number of modes (the system has `2N` unknowns `u_0, v_0, u_1, …`).
    pub fn n_modes(&self) -> usize {
        self.n_modes
    }

    /// The complex coefficients of `R_n` per monomial, `[n · M + mono]`, at `tone` with the
    /// values of `model` (of the same terms as the one expanded).
    fn coefficients(
        &self,
        model: &NumericModel,
        tone: &Tone,
    ) -> Result<Vec<Complex64>, ExploreError> {
        if model.terms().len() != self.n_terms || model.n_modes() != self.n_modes {
            return Err(ExploreError::OtherModel);
        }
        let nm = self.n_modes;
        let nmono = self.monos.len();
        let w = tone.omega();
        let mut c = vec![ZERO; nm * nmono];
        let terms = model.terms();
        for e in &self.entries {
            let mut v = e.coef * terms[e.term].coef * w.powi(e.omega_pow);
            if e.pump + e.pump_conj > 0 {
                v *= tone.pump.powi(e.pump) * tone.pump.conj().powi(e.pump_conj);
            }
            c[e.eq * nmono + e.mono] += v;
        }
        let nv = 2 * nm;
        let find = |e: &[u32]| self.monos.iter().position(|m| m == e);
        for n in 0..nm {
            let (wn, g) = (model.omega(n), model.gamma(n));
            let lin = Complex64::new(wn * wn - w * w, w * g);
            let mut e = vec![0; nv];
            e[2 * n] = 1;
            let iu = find(&e).ok_or(ExploreError::OtherModel)?;
            e[2 * n] = 0;
            e[2 * n + 1] = 1;
            let iv = find(&e).ok_or(ExploreError::OtherModel)?;
            let i1 = find(&vec![0; nv]).ok_or(ExploreError::OtherModel)?;
            c[n * nmono + iu] += lin;
            c[n * nmono + iv] += lin * Complex64::new(0.0, 1.0);
            c[n * nmono + i1] -= tone.force.get(n).copied().unwrap_or(ZERO);
        }
        Ok(c)
    }

    /// The `2N` real equations `Re R_n / e_n`, `Im R_n / e_n` in the unknowns `x = X / scale`
    /// (`u_0, v_0, u_1, v_1, …`), `e_n` the largest coefficient of mode `n`'s pair after the
    /// scaling (1 when `normalise` is false). Returns the system and the `e_n`.
    pub fn system(
        &self,
        model: &NumericModel,
        tone: &Tone,
        scale: f64,
        normalise: bool,
    ) -> Result<(PolySystem, Vec<f64>), ExploreError> {
        let nm = self.n_modes;
        let nmono = self.monos.len();
        let c = self.coefficients(model, tone)?;
        let sdeg: Vec<f64> = self
            .monos
            .iter()
            .map(|m| scale.powi(m.iter().sum::<u32>() as i32))
            .collect();
        let mut eqs = Vec::with_capacity(2 * nm);
        let mut norms = Vec::with_capacity(nm);
        for n in 0..nm {
            let row = &c[n * nmono..(n + 1) * nmono];
            let e = if normalise {
                row.iter()
                    .zip(&sdeg)
                    .map(|(z, s)| z.norm() * s)
                    .fold(0.0, f64::max)
            } else {
                1.0
            };
            let e = if e > 0.0 && e.is_finite() { e } else { 1.0 };
            norms.push(e);
            for part in [0, 1] {
                let mut eq = Vec::new();
                for (k, z) in row.iter().enumerate() {
                    let v = if part == 0 { z.re } else { z.im } * sdeg[k] / e;
                    if v != 0.0 {
                        let factors = self.monos[k]
                            .iter()
                            .enumerate()
                            .filter(|(_, &p)| p > 0)
                            .map(|(var, &p)| (var, p))
                            .collect();
                        eq.push(Term {
                            coef: Complex64::new(v, 0.0),
                            factors,
                        });
                    }
                }
                eqs.push(eq);
            }
        }
        Ok((PolySystem { n: 2 * nm, eqs }, norms))
    }

    /// An amplitude scale, m: where a nonlinear term of mode `n`'s equation is as large as
    /// its damping force `Ωγ_n X` (the amplitude at which the response turns nonlinear), the
    /// smallest over the terms; `force / (Ωγ)` for a linear model, 1e-9 m without a force.
    pub fn natural_scale(&self, model: &NumericModel, tone: &Tone) -> f64 {
        let w = tone.omega();
        let terms = model.terms();
        let mut s = f64::INFINITY;
        for e in &self.entries {
            let d: u32 = self.monos[e.mono].iter().sum();
            if d < 2 {
                continue;
            }
            let mut v = (e.coef * terms[e.term].coef * w.powi(e.omega_pow)).norm();
            if e.pump + e.pump_conj > 0 {
                v *= tone.pump.norm().powi(e.pump + e.pump_conj);
            }
            let lin = w * model.gamma(e.eq);
            if v > 0.0 {
                s = s.min((lin / v).powf(1.0 / (d - 1) as f64));
            }
        }
        if s.is_finite() && s > 0.0 {
            return s;
        }
        let f = tone.force.iter().map(|z| z.norm()).fold(0.0, f64::max);
        let g = (0..model.n_modes())
            .map(|n| model.gamma(n))
            .fold(f64::INFINITY, f64::min);
        if f > 0.0 && (f / (w * g)).is_finite() {
            f / (w * g)
        } else {
            1e-9
        }
    }
}
