//! Regressor columns of terms with a non-smooth factor (`kappa1*abs(q1)*q1`,
//! `drag1*abs(d(q1))*d(q1)`, `mu1*sign(d(q1))`, `mu1*tanh(d(q1)/1e-3)`; issue 36) by
//! alternating frequency–time: the measured modal spectra are turned into the periodic signals
//! `q(t)`, `q̇(t)` on the measurement's common period, the term is evaluated in time and
//! projected onto the measured lines. A polynomial term has an exact closed form
//! ([`harmonid_spectral::monomial_amplitudes`]); these do not.
//!
//! **Common period, or the torus.** When every input and measured line of the measurement is a
//! whole multiple `k f₀` of one base frequency `f₀` (to 10⁻⁶ of `f₀`) with `k ≤`
//! [`MAX_HARMONIC`] (a stepped sweep's step, one tone and its harmonics, always is) the columns
//! are integrated over the common period as below. Otherwise (two incommensurate tones) they are
//! sampled on the torus of the drive's generators ([`torus`]), the simulator's grid; a
//! measurement whose lines are not low-order combinations of the generators is refused by
//! [`lattices`], naming it.
//!
//! **Quadrature, and why there is no aliasing.** Uniform samples (the usual AFT) alias the
//! infinitely many harmonics of `|x|` or `sign x` back onto the measured lines: the error falls
//! like `1/N` for `sign` and `1/N³` for `|x|x`. Instead, the period `θ = 2π f₀ t ∈ [0, 2π)` is cut
//! at every zero crossing of the argument of each non-smooth factor (found on a grid of
//! `32 k_max` points and refined by bisection to 1e-15 rad), where the term is analytic between
//! cuts; each piece is integrated by 16-point Gauss–Legendre panels no wider than `2π / h`
//! (`h` the highest harmonic the term's polynomial content can reach, at least 4 panels per
//! period), which integrate a trigonometric polynomial of that order to round-off
//! (the truncation term is `π³²/32! ≈ 10⁻²⁰`). Near a crossing of the argument of `tanh(x/c)`
//! the panels are graded geometrically from the width `c/|ẋ|` of the transition, so a steep
//! `tanh` is resolved as well (a `tanh` that comes close to zero without crossing is not graded:
//! there the error is that of plain panels). Measured: Coulomb `sign(cos θ)` gives `4/π` and
//! `|cos θ| cos θ` gives `8/(3π)` to 1e-14.

mod torus;

use super::{IdentError, Problem};
use harmonid_model::NonSmooth;
use num_complex::Complex64;
use std::f64::consts::{PI, TAU};
use torus::Torus;

/// Highest harmonic of the base frequency a measured line of a measurement with non-smooth
/// terms may be.
pub const MAX_HARMONIC: usize = 4096;

/// Where a measurement's non-smooth columns are evaluated.
#[derive(Debug, Clone)]
pub(super) enum Lattice {
    /// Over the common period: the harmonics of its input lines and of its measured lines.
    Period(Vec<usize>, Vec<usize>),
    /// On the torus of the drive's generators (lines not harmonics of one frequency).
    Torus(Box<Torus>),
}

/// Gauss–Legendre nodes per panel.
const GAUSS: usize = 16;

/// A term with non-smooth factors, split for evaluation: its polynomial factors
/// `(variable, exponent)` (variables numbered as the spectra: modes, velocities, pump) and its
/// non-smooth factors with their exponents.
#[derive(Debug, Clone)]
pub(super) struct NsMonomial {
    pub(super) poly: Vec<(usize, u32)>,
    pub(super) factors: Vec<(NonSmooth, u32)>,
}

impl NsMonomial {
    /// Highest power of a polynomial's harmonic content: the polynomial degree, plus one per
    /// `abs` factor (`|x|` is about as rough as `x` on each piece).
    fn degree(&self) -> usize {
        let p: u32 = self.poly.iter().map(|&(_, e)| e).sum();
        let a: u32 = self
            .factors
            .iter()
            .filter(|(f, _)| matches!(f, NonSmooth::Abs(_)))
            .map(|&(_, e)| e)
            .sum();
        (p + a) as usize
    }

    /// The term's value at one time, from the variables' values `x`.
    fn value(&self, x: &[f64]) -> f64 {
        let mut v = 1.0;
        for &(i, e) in &self.poly {
            v *= x[i].powi(e as i32);
        }
        for &(f, e) in &self.factors {
            v *= f.value(x[f.var().index()]).powi(e as i32);
        }
        v
    }
}

/// Whole-multiple harmonics of one base frequency: `(f₀, k of each of freqs)`, `f₀` the largest
/// frequency of which every one of `freqs` (Hz, ≥ 0; a 0 Hz line is harmonic 0) is a multiple
/// to 1e-6 of `f₀`, with every `k ≤` [`MAX_HARMONIC`]; `None` otherwise. Euclid's algorithm on
/// the positive lines, the divisor snapped to the largest line after each step so that rounding
/// does not accumulate.
pub(super) fn base_harmonics(freqs: &[f64]) -> Option<(f64, Vec<usize>)> {
    let top = freqs.iter().copied().fold(0.0f64, f64::max);
    if !(top.is_finite() && top > 0.0) {
        return None;
    }
    let min_hz = top / MAX_HARMONIC as f64;
    let tol = 1e-3 * min_hz;
    let mut g = 0.0f64;
    let mut big = 0.0f64;
    for &f in freqs.iter().filter(|&&f| f > tol) {
        let (mut a, mut b) = (g.max(f), g.min(f));
        while b > tol {
            let r = a % b;
            a = b;
            b = if r > b - tol { 0.0 } else { r };
            if a < min_hz {
                return None;
            }
        }
        big = big.max(f);
        g = big / (big / a).round().max(1.0);
    }
    let ks: Vec<usize> = freqs.iter().map(|&f| (f / g).round() as usize).collect();
    let whole = freqs
        .iter()
        .zip(&ks)
        .all(|(&f, &k)| (f / g - k as f64).abs() <= 1e-6 && k <= MAX_HARMONIC);
    whole.then_some((g, ks))
}

/// Where each measurement's non-smooth columns are evaluated, for a model with non-smooth
/// terms: over the common period of its lines, else on the torus of its drive's generators
/// (tones and half of each pump); refuses a measurement whose lines are neither.
pub(super) fn lattices(
    prob: &Problem,
    ds: &harmonid_data::Dataset,
) -> Result<Vec<Lattice>, IdentError> {
    let mut out = Vec::with_capacity(prob.meas.len());
    for (mi, prep) in prob.meas.iter().enumerate() {
        let m = &ds.measurements[mi];
        let mut all = prep.input_hz.clone();
        all.extend_from_slice(&m.freqs_hz);
        if let Some((_, ks)) = base_harmonics(&all) {
            let (kin, kout) = ks.split_at(prep.input_hz.len());
            out.push(Lattice::Period(kin.to_vec(), kout.to_vec()));
            continue;
        }
        let generators: Vec<f64> = m
            .spec
            .drives_hz
            .iter()
            .copied()
            .chain(m.spec.pumps_hz.iter().map(|&p| 0.5 * p))
            .collect();
        match Torus::new(&generators, &prep.input_hz, &m.freqs_hz) {
            Ok(t) => out.push(Lattice::Torus(Box::new(t))),
            Err(why) => {
                return Err(IdentError::Unsupported(format!(
                    "{}: measurement \"{}\" has lines ({} Hz) that are not harmonics of one frequency (at most the {MAX_HARMONIC}th), and the non-smooth terms ({}) cannot be sampled on the torus of its drive's tones either: {why}; identify them from measurements with fewer intermodulation lines, or leave this measurement out",
                    prob.manifest_path,
                    m.spec.name,
                    m.freqs_hz.iter().map(|f| format!("{f}")).collect::<Vec<_>>().join(", "),
                    prob.nonsmooth_names.join(", ")
                )))
            }
        }
    }
    Ok(out)
}

/// 16-point Gauss–Legendre nodes and weights on [−1, 1] (Newton on `P₁₆`).
fn gauss_legendre() -> ([f64; GAUSS], [f64; GAUSS]) {
    let n = GAUSS;
    let mut x = [0.0; GAUSS];
    let mut w = [0.0; GAUSS];
    for i in 0..n {
        let mut z = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, z);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (z * p1 - p0) / (z * z - 1.0);
            let dz = p1 / dp;
            z -= dz;
            if dz.abs() < 1e-16 {
                break;
            }
        }
        x[i] = z;
        w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
    }
    (x, w)
}

/// Real signals of complex amplitudes on harmonics: `x(θ) = Σ_r Re[X_r e^{i k_r θ}]` (a line at
/// harmonic 0 is the offset `Re X_0`).
struct Signals<'a> {
    k: &'a [usize],
    spectra: &'a [&'a [Complex64]],
}

impl Signals<'_> {
    fn value(&self, v: usize, th: f64) -> f64 {
        self.spectra[v]
            .iter()
            .zip(self.k)
            .map(|(x, &k)| (x * Complex64::from_polar(1.0, k as f64 * th)).re)
            .sum()
    }

    fn slope(&self, v: usize, th: f64) -> f64 {
        self.spectra[v]
            .iter()
            .zip(self.k)
            .map(|(x, &k)| {
                (x * Complex64::new(0.0, k as f64) * Complex64::from_polar(1.0, k as f64 * th)).re
            })
            .sum()
    }

    /// Zero crossings of variable `v` over the period, ascending (rad): sign changes on a grid
    /// of `grid` points, refined by bisection.
    fn crossings(&self, v: usize, grid: usize) -> Vec<f64> {
        let h = TAU / grid as f64;
        let mut out = Vec::new();
        let mut a = 0.0;
        let mut fa = self.value(v, a);
        for j in 1..=grid {
            let b = j as f64 * h;
            let fb = self.value(v, b);
            if fa == 0.0 {
                out.push(a);
            } else if fa * fb < 0.0 {
                let (mut lo, mut hi) = (a, b);
                for _ in 0..64 {
                    let mid = 0.5 * (lo + hi);
                    let fm = self.value(v, mid);
                    if fm != 0.0 && (fm < 0.0) == (fa < 0.0) {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                out.push(0.5 * (lo + hi));
            }
            a = b;
            fa = fb;
        }
        out
    }
}

/// The complex amplitudes (`DATA_FORMAT.md`: `g(t) = Re[G e^{i k θ}]`, the DC value at `k = 0`)
/// of `term` at the harmonics `k_out`, given the variables' spectra on the harmonics `k_in` of
/// the common period (variables numbered as in [`NsMonomial::poly`]). See the module
/// documentation for the quadrature.
pub(super) fn nonsmooth_amplitudes(
    term: &NsMonomial,
    k_in: &[usize],
    spectra: &[&[Complex64]],
    k_out: &[usize],
    out: &mut [Complex64],
) {
    let sig = Signals { k: k_in, spectra };
    let kin = k_in.iter().copied().max().unwrap_or(0).max(1);
    let kout = k_out.iter().copied().max().unwrap_or(0);
    let reach = (term.degree() + 1) * kin + kout;
    let width = TAU / reach.max(4) as f64;
    // Cuts at the crossings; a tanh crossing with the width of its transition.
    let mut cuts: Vec<(f64, Option<f64>)> = Vec::new();
    for &(f, _) in &term.factors {
        let v = f.var().index();
        for th in sig.crossings(v, 32 * kin) {
            let grade = match f {
                NonSmooth::Tanh(_, c) => {
                    let s = sig.slope(v, th).abs();
                    (s > 0.0).then(|| (c / s).min(width))
                }
                _ => None,
            };
            cuts.push((th, grade));
        }
    }
    cuts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let edges = panel_edges(&cuts, width);
    let (gx, gw) = gauss_legendre();
    for o in out.iter_mut() {
        *o = Complex64::new(0.0, 0.0);
    }
    let mut x = vec![0.0; spectra.len()];
    for p in edges.windows(2) {
        let (a, b) = (p[0], p[1]);
        let half = 0.5 * (b - a);
        if half <= 0.0 {
            continue;
        }
        for (z, w) in gx.iter().zip(&gw) {
            let th = a + half * (1.0 + z);
            for (v, xv) in x.iter_mut().enumerate() {
                *xv = sig.value(v, th);
            }
            let g = term.value(&x) * w * half;
            for (o, &k) in out.iter_mut().zip(k_out) {
                *o += Complex64::from_polar(g, -(k as f64) * th);
            }
        }
    }
    for (o, &k) in out.iter_mut().zip(k_out) {
        *o *= if k == 0 { 1.0 / TAU } else { 1.0 / PI };
    }
}

/// The panel edges over one period starting at the first cut (or at 0): every cut is an edge;
/// after and before a graded cut, edges at `w₀, 3w₀, 7w₀, …` from it; then no panel wider than
/// `width`.
fn panel_edges(cuts: &[(f64, Option<f64>)], width: f64) -> Vec<f64> {
    let start = cuts.first().map_or(0.0, |c| c.0);
    let mut pts: Vec<f64> = Vec::new();
    let n = cuts.len().max(1);
    for i in 0..n {
        let (a, ga) = cuts.get(i).copied().unwrap_or((start, None));
        let (b, gb) = match cuts.get(i + 1) {
            Some(&c) => c,
            None => (start + TAU, cuts.first().and_then(|c| c.1)),
        };
        let mut local = vec![a, b];
        for (from, grade, dir) in [(a, ga, 1.0), (b, gb, -1.0)] {
            if let Some(w0) = grade {
                let mut d = w0;
                while d < 0.5 * (b - a) && d < width {
                    local.push(from + dir * d);
                    d = 2.0 * d + w0;
                }
            }
        }
        local.sort_by(f64::total_cmp);
        for s in local.windows(2) {
            let m = ((s[1] - s[0]) / width).ceil().max(1.0) as usize;
            for j in 0..m {
                pts.push(s[0] + (s[1] - s[0]) * j as f64 / m as f64);
            }
        }
    }
    pts.push(start + TAU);
    pts
}

/// Each monomial's split for evaluation in time when it holds a non-smooth factor (`None` for a
/// polynomial one).
pub(super) fn split_monomials(
    model: &harmonid_model::Model,
    monomials: &[harmonid_poly::PowerProduct],
) -> Vec<Option<NsMonomial>> {
    let first = 2 * model.modes.len() + 1;
    monomials
        .iter()
        .map(|m| {
            if m.factors().iter().all(|(v, _)| v.index() < first) {
                return None;
            }
            let (poly, factors) = model.split_nonsmooth(m);
            let factors: Option<Vec<(NonSmooth, u32)>> = factors
                .into_iter()
                .map(|(k, e)| model.nonsmooth_factors.get(k).map(|f| (*f, e)))
                .collect();
            Some(NsMonomial {
                poly: poly
                    .factors()
                    .iter()
                    .map(|&(v, e)| (v.index(), e))
                    .collect(),
                factors: factors?,
            })
        })
        .collect()
}

impl Problem {
    /// The canonical name of an equation monomial of this problem (`q1^3`, `abs(q1)*q1`).
    pub fn monomial_name(&self, m: &harmonid_poly::PowerProduct) -> String {
        match self.monomials.iter().position(|x| x == m) {
            Some(i) => self.monomial_names[i].clone(),
            None => m.name(&self.variable_names),
        }
    }

    /// The columns `ĝ` of a non-smooth monomial at the measured lines of measurement `mi`, from
    /// the variables' spectra on its input lines.
    pub(super) fn nonsmooth_column(
        &self,
        mi: usize,
        term: &NsMonomial,
        spectra: &[&[Complex64]],
        out: &mut [Complex64],
    ) {
        match &self.ns_lattice[mi] {
            Lattice::Period(k_in, k_out) => nonsmooth_amplitudes(term, k_in, spectra, k_out, out),
            Lattice::Torus(t) => t.amplitudes(&term.poly, &term.factors, spectra, out),
        }
    }

    /// The derivatives of a non-smooth monomial's columns at the measured lines of measurement
    /// `mi` by the real and imaginary parts of the modal amplitude `X` of mode `mode` at input
    /// line `s` (its velocity `iΩX` moved with it): `(∂ĝ/∂Re X, ∂ĝ/∂Im X)` per measured line.
    /// Over one period by central differences (the term is not analytic); on a torus by
    /// [`Torus::jacobian`] (exact for `abs` terms).
    pub(super) fn nonsmooth_column_jacobian(
        &self,
        mi: usize,
        term: &NsMonomial,
        spectra: &[Vec<Complex64>],
        (mode, s, f_hz): (usize, usize, f64),
    ) -> (Vec<Complex64>, Vec<Complex64>) {
        let nm = self.mode_names.len();
        if let Lattice::Torus(t) = &self.ns_lattice[mi] {
            let r: Vec<&[Complex64]> = spectra.iter().map(|v| v.as_slice()).collect();
            let v = (spectra.len() > nm).then_some(nm + mode);
            return t.jacobian(&term.poly, &term.factors, &r, (mode, v, TAU * f_hz, s));
        }
        let nf = self.meas[mi].input_of.len();
        let scale = spectra[mode].iter().map(|z| z.norm()).fold(0.0, f64::max);
        let h = 1e-6 * scale.max(f64::MIN_POSITIVE);
        let mut work: Vec<Vec<Complex64>> = spectra.to_vec();
        let mut column = |dx: Complex64| {
            work[mode][s] = spectra[mode][s] + dx;
            if spectra.len() > nm {
                work[nm + mode][s] = Complex64::new(0.0, TAU * f_hz) * work[mode][s];
            }
            let r: Vec<&[Complex64]> = work.iter().map(|v| v.as_slice()).collect();
            let mut out = vec![Complex64::new(0.0, 0.0); nf];
            self.nonsmooth_column(mi, term, &r, &mut out);
            out
        };
        let mut d = |dir: Complex64| {
            let p = column(dir * h);
            let m = column(-dir * h);
            p.iter()
                .zip(&m)
                .map(|(a, b)| (a - b) / (2.0 * h))
                .collect::<Vec<_>>()
        };
        let dre = d(Complex64::new(1.0, 0.0));
        let dim = d(Complex64::new(0.0, 1.0));
        (dre, dim)
    }

    /// The modes a non-smooth monomial involves (its polynomial variables and the arguments of
    /// its factors; the pump none).
    pub(super) fn nonsmooth_modes(&self, term: &NsMonomial) -> Vec<usize> {
        let nm = self.mode_names.len();
        let vars = term
            .poly
            .iter()
            .map(|&(v, _)| v)
            .chain(term.factors.iter().map(|(f, _)| f.var().index()));
        vars.filter(|&v| v < 2 * nm).map(|v| v % nm).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::super::{testkit, Problem, Settings};
    use super::*;
    use harmonid_poly::{PowerProduct, VarId};
    use harmonid_spectral::{monomial_amplitudes, ProductPlan};

    fn one(k_in: &[usize], x: &[Complex64], term: &NsMonomial, k_out: &[usize]) -> Vec<Complex64> {
        let mut out = vec![Complex64::new(0.0, 0.0); k_out.len()];
        nonsmooth_amplitudes(term, k_in, &[x], k_out, &mut out);
        out
    }

    fn close(a: Complex64, b: Complex64, tol: f64) {
        assert!((a - b).norm() <= tol * b.norm().max(1.0), "{a} vs {b}");
    }

    #[test]
    fn base_harmonics_of_commensurate_lines() {
        let (f0, k) = base_harmonics(&[0.0, 985.0, 995.0, 1005.0]).expect("base");
        assert!((f0 - 5.0).abs() < 1e-9, "{f0}");
        assert_eq!(k, vec![0, 197, 199, 201]);
        let (f0, k) = base_harmonics(&[1234.5]).expect("one tone");
        assert_eq!((f0, k), (1234.5, vec![1]));
        assert!(base_harmonics(&[100.0, 100.0 * 2f64.sqrt()]).is_none());
        assert!(base_harmonics(&[]).is_none());
    }

    #[test]
    fn describing_functions_of_abs_and_sign() {
        // x = a cos(θ + φ): |x| x has fundamental 8/(3π) a² e^{iφ} and third harmonic
        // 8/(15π) a² e^{3iφ}; sign x: 4/π e^{iφ}, −4/(3π) e^{3iφ}.
        let a = 2.5;
        for phi in [0.0, 0.3, 1.0, -2.0] {
            let x = [Complex64::from_polar(a, phi)];
            let absq = NsMonomial {
                poly: vec![(0, 1)],
                factors: vec![(NonSmooth::Abs(VarId(0)), 1)],
            };
            let g = one(&[1], &x, &absq, &[1, 2, 3]);
            let e = |k: f64| Complex64::from_polar(1.0, k * phi);
            close(g[0], e(1.0) * 8.0 / (3.0 * PI) * a * a, 1e-13);
            close(g[1], Complex64::new(0.0, 0.0), 1e-13);
            close(g[2], e(3.0) * 8.0 / (15.0 * PI) * a * a, 1e-13);
            let sign = NsMonomial {
                poly: vec![],
                factors: vec![(NonSmooth::Sign(VarId(0)), 1)],
            };
            let g = one(&[1], &x, &sign, &[0, 1, 3]);
            close(g[0], Complex64::new(0.0, 0.0), 1e-13);
            close(g[1], e(1.0) * 4.0 / PI, 1e-13);
            close(g[2], -e(3.0) * 4.0 / (3.0 * PI), 1e-13);
        }
    }

    #[test]
    fn polynomials_written_with_abs_and_sign_agree_with_the_exact_products() {
        // |q|² q = sign(q) |q| q² = q³ on a three-line signal with an offset, whose zero
        // crossings are irregular: the cut-and-panel quadrature against the exact products.
        let freqs = [0.0, 100.0, 200.0, 300.0];
        let x = [
            Complex64::new(0.1, 0.0),
            Complex64::new(1.0, 0.4),
            Complex64::new(-0.3, 0.5),
            Complex64::new(0.2, -0.25),
        ];
        let cube = PowerProduct::from_factors(vec![(VarId(0), 3)]).expect("q^3");
        let out_hz = [0.0, 100.0, 200.0, 300.0, 500.0, 700.0];
        let plan = ProductPlan::new(&freqs, &out_hz, 3).expect("plan");
        let mut scratch = plan.scratch();
        let mut exact = vec![Complex64::new(0.0, 0.0); out_hz.len()];
        monomial_amplitudes(&plan, &cube, &[&x], &mut exact, &mut scratch);
        let k_out = [0, 1, 2, 3, 5, 7];
        for term in [
            NsMonomial {
                poly: vec![(0, 1)],
                factors: vec![(NonSmooth::Abs(VarId(0)), 2)],
            },
            NsMonomial {
                poly: vec![(0, 2)],
                factors: vec![
                    (NonSmooth::Sign(VarId(0)), 1),
                    (NonSmooth::Abs(VarId(0)), 1),
                ],
            },
        ] {
            let g = one(&[0, 1, 2, 3], &x, &term, &k_out);
            for (a, b) in g.iter().zip(&exact) {
                close(*a, *b, 1e-12);
            }
        }
    }

    #[test]
    fn a_steep_tanh_matches_dense_uniform_samples() {
        // tanh(x/c) is analytic: a fine uniform grid (h ≪ c/|ẋ|) converges exponentially and
        // is the reference; c/a = 1e-3, so the transition is 1e-3 rad wide.
        let x = [Complex64::from_polar(1.0, 0.4), Complex64::new(0.2, 0.1)];
        let k_in = [1, 3];
        let c = 1e-3;
        let term = NsMonomial {
            poly: vec![(0, 1)],
            factors: vec![(NonSmooth::Tanh(VarId(0), c), 1)],
        };
        let k_out = [1, 3, 5];
        let g = one(&k_in, &x, &term, &k_out);
        let n = 1 << 17;
        let sig = Signals {
            k: &k_in,
            spectra: &[&x],
        };
        let mut r = vec![Complex64::new(0.0, 0.0); 3];
        for j in 0..n {
            let th = TAU * j as f64 / n as f64;
            let v = sig.value(0, th);
            let f = v * (v / c).tanh();
            for (o, &k) in r.iter_mut().zip(&k_out) {
                *o += Complex64::from_polar(f * 2.0 / n as f64, -(k as f64) * th);
            }
        }
        for (a, b) in g.iter().zip(&r) {
            close(*a, *b, 1e-11);
        }
        // And it is close to |x| (c → 0), to O(c²).
        let abs = NsMonomial {
            poly: vec![],
            factors: vec![(NonSmooth::Abs(VarId(0)), 1)],
        };
        let h = one(&k_in, &x, &abs, &k_out);
        for (a, b) in g.iter().zip(&h) {
            close(*a, *b, 1e-5);
        }
    }

    #[test]
    fn a_problem_with_the_duffing_term_written_non_smooth_has_the_same_equations() {
        // beta*a^3 written as beta*abs(a)*abs(a)*a: the same rows to 1e-12 on the two-tone
        // test data (lines 985–3030 Hz, harmonics of 5 Hz).
        let ds = testkit::dataset(true, 1, 0.0, 1);
        let poly = testkit::model();
        let src = testkit::MODEL.replace(
            "potential: beta/4*a^4 + g/2*a^2*b^2\n",
            "potential: g/2*a^2*b^2\neom a += beta*abs(a)*abs(a)*a\n",
        );
        let ns = harmonid_model::parse_str(&src, "t.hb").expect("non-smooth model");
        assert!(ns.has_nonsmooth());
        let s = Settings::default();
        let p0 = Problem::new(&poly, &ds, &s).expect("problem");
        let p1 = Problem::new(&ns, &ds, &s).expect("problem");
        let (r0, r1) = (p0.shot_rows_all(&ds, 0), p1.shot_rows_all(&ds, 0));
        let beta = |p: &Problem| {
            p.param_names
                .iter()
                .position(|x| x == "beta")
                .expect("beta")
        };
        let col = |p: &Problem| {
            p.index_of(&super::super::Unknown::Param(beta(p)))
                .expect("beta column")
        };
        let (c0, c1) = (col(&p0), col(&p1));
        for (m0, m1) in r0.iter().zip(&r1) {
            for (a, b) in m0.rows.iter().zip(&m1.rows) {
                let ga = a.coefs.iter().find(|c| c.0 == c0).map(|c| c.1);
                let gb = b.coefs.iter().find(|c| c.0 == c1).map(|c| c.1);
                match (ga, gb) {
                    (Some(x), Some(y)) => assert!((x - y).norm() <= 1e-12 * x.norm().max(1e-300)),
                    (None, None) => {}
                    other => panic!("{other:?}"),
                }
                assert!((a.rhs - b.rhs).norm() <= 1e-12 * a.rhs.norm());
            }
        }
        assert!(
            p1.monomial_names.iter().any(|n| n == "abs(a)^2*a"),
            "{:?}",
            p1.monomial_names
        );
    }

    #[test]
    fn the_error_in_variables_weighting_of_a_non_smooth_term_matches_the_polynomial_one() {
        // The regressor's derivatives by the data (central differences for a non-smooth term,
        // exact products for a polynomial) give the same equation covariance.
        let ds = testkit::dataset(false, 1, 0.0, 1);
        let src = testkit::MODEL.replace(
            "potential: beta/4*a^4 + g/2*a^2*b^2\n",
            "potential: g/2*a^2*b^2\neom a += beta*abs(a)*abs(a)*a\n",
        );
        let ns = harmonid_model::parse_str(&src, "t.hb").expect("non-smooth model");
        let s = Settings::default();
        let (p0, p1) = (
            Problem::new(&testkit::model(), &ds, &s).expect("problem"),
            Problem::new(&ns, &ds, &s).expect("problem"),
        );
        let blocks = |p: &Problem| {
            let mut t = testkit::truth(p);
            let beta = p
                .param_names
                .iter()
                .position(|x| x == "beta")
                .expect("beta");
            let i = p
                .index_of(&super::super::Unknown::Param(beta))
                .expect("beta");
            // Large enough that beta a^2 is a tenth of omega^2 at the data's amplitudes.
            t[i] = 1e17;
            let var = p.relative_variances();
            let mut scratch: Vec<_> = p.meas.iter().map(|m| m.plan.scratch()).collect();
            p.equation_cov(&ds, &p.groups[0], 0, &t, &var, &mut scratch)
        };
        let (b0, b1) = (blocks(&p0), blocks(&p1));
        for (x, y) in b0.iter().zip(&b1) {
            let scale = x.amax();
            assert!((x - y).amax() <= 1e-7 * scale, "{x} vs {y}");
        }
        let nonlinear = b0[0][(0, 2)].abs() / b0[0][(0, 0)];
        assert!(
            nonlinear > 1e-3,
            "the test must see the cubic term: {nonlinear:e}"
        );
    }
}
