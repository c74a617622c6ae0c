//! Regressor columns of non-smooth terms for a measurement whose lines are not harmonics of one
//! frequency (two incommensurate tones; issue 36 item 2): the torus of the drive's generators.
//!
//! Each line is its lowest-order integer vector `k_r` over the generators (the drive tones and
//! half of each pump, as the simulator's [`harmonid_sim::Grid`] finds them), a signal
//! `x(t) = Σ_r Re(X_r e^{iΩ_r t})` is the torus function `x(θ) = Σ_r Re(X_r e^{i k_r·θ})`, and
//! for generators without a low-order rational relation the time average of any function of the
//! signals is its torus average (Weyl). The torus is sampled on the simulator's grid (powers of
//! two per axis, 32 samples per period of the highest multiple of each generator, at least 128),
//! and a column is `ĝ_r = (2/N) Σ_j g(θ_j) e^{−i k_r·θ_j}` (`1/N` at the static line): the same
//! sampled convention as the simulator's non-smooth forces, so the equation-error regressor
//! and the output-error forward model see the same term. `sign` and `tanh` are cell averages
//! along the grid's diagonal ([`harmonid_model::NonSmooth::cell_average`]), as the simulator
//! takes them. Aliasing: `|x|x` falls like `N^{-3}` per axis (about 1e-8 relative at 128 per
//! axis); a cell-averaged jump like `N^{-2}`.

use harmonid_model::NonSmooth;
use harmonid_sim::{Grid, GridSampler, RoughTerm};
use num_complex::Complex64;

/// The sampling of one measurement's torus: the simulator's sampler of its grid, and where each
/// input and measured line sits among the grid's lines.
#[derive(Debug, Clone)]
pub(crate) struct Torus {
    sampler: GridSampler,
    /// Grid line of each input line.
    line_in: Vec<usize>,
    /// Grid line of each measured line.
    line_out: Vec<usize>,
}

impl Torus {
    /// The torus of `generators` (Hz) for the input lines `input_hz` and measured lines
    /// `output_hz` (Hz, ≥ 0), or why there is none (a sentence from the simulator's grid).
    pub(crate) fn new(
        generators: &[f64],
        input_hz: &[f64],
        output_hz: &[f64],
    ) -> Result<Self, String> {
        let top = input_hz
            .iter()
            .chain(output_hz)
            .copied()
            .fold(0.0f64, f64::max);
        let tol = 1e-9 * top.max(1.0);
        let mut lines: Vec<f64> = input_hz.iter().chain(output_hz).copied().collect();
        lines.sort_by(f64::total_cmp);
        lines.dedup_by(|a, b| (*a - *b).abs() <= tol);
        let grid = Grid::choose(generators, &lines)?;
        let at = |f: &f64| {
            lines
                .iter()
                .position(|x| (x - f).abs() <= tol)
                .unwrap_or_default()
        };
        Ok(Self {
            line_in: input_hz.iter().map(at).collect(),
            line_out: output_hz.iter().map(at).collect(),
            sampler: GridSampler::new(&grid),
        })
    }

    /// Samples on the torus, `Π N_i`.
    pub(crate) fn samples(&self) -> usize {
        self.sampler.samples()
    }

    /// The variables' samples `[v·N + j]` from their spectra on the input lines.
    fn synthesise(&self, spectra: &[&[Complex64]]) -> Vec<f64> {
        let nt = self.samples();
        let mut xs = vec![0.0; nt * spectra.len()];
        for (x, sp) in xs.chunks_exact_mut(nt).zip(spectra) {
            for (&z, &l) in sp.iter().zip(&self.line_in) {
                self.sampler.add_line(l, z, x, None);
            }
        }
        xs
    }

    /// The measured lines of the samples `g` into `out`.
    fn project(&self, g: &[f64], out: &mut [Complex64]) {
        for (o, &l) in out.iter_mut().zip(&self.line_out) {
            *o = self.sampler.coefficient(l, g);
        }
    }

    /// The amplitudes at the measured lines of the term `Π x_v^e · Π f(x)^e` (`poly` the
    /// polynomial factors `(variable, exponent)`, `factors` the non-smooth ones) from the
    /// variables' spectra on the input lines (`spectra[v][r]`, variables numbered as the
    /// problem's: modes, velocities, pump), into `out` (one per measured line).
    pub(crate) fn amplitudes(
        &self,
        poly: &[(usize, u32)],
        factors: &[(NonSmooth, u32)],
        spectra: &[&[Complex64]],
        out: &mut [Complex64],
    ) {
        let xs = self.synthesise(spectra);
        let mut g = vec![0.0; self.samples()];
        self.sampler.add_term(1.0, poly, factors, &xs, &mut g);
        self.project(&g, out);
    }

    /// The derivatives of [`Torus::amplitudes`] by the real and imaginary parts of the
    /// amplitude of variable `q` at input line `s`, variable `v` (its velocity, or `None`)
    /// moving with it as `iΩ` times it (`Ω` rad/s): `(∂ĝ/∂Re X, ∂ĝ/∂Im X)` per measured line.
    /// Without a jump, exactly, from the pointwise gradient (the sampled `|x|` term is
    /// differentiable wherever no sample sits on a zero); with `sign` or `tanh` (cell averages
    /// of the neighbours too), by central differences of the samples of `q` and `v` alone.
    pub(crate) fn jacobian(
        &self,
        poly: &[(usize, u32)],
        factors: &[(NonSmooth, u32)],
        spectra: &[&[Complex64]],
        (q, v, omega, s): (usize, Option<usize>, f64, usize),
    ) -> (Vec<Complex64>, Vec<Complex64>) {
        let nt = self.samples();
        let mut xs = self.synthesise(spectra);
        let line = self.line_in[s];
        let n_out = self.line_out.len();
        let (mut dre, mut dim) = (
            vec![Complex64::new(0.0, 0.0); n_out],
            vec![Complex64::new(0.0, 0.0); n_out],
        );
        // The basis of Re X and Im X at q (and v): cos φ, −Ω sin φ; −sin φ, −Ω cos φ.
        let basis = |a: Complex64| {
            let (mut bq, mut bv) = (vec![0.0; nt], vec![0.0; nt]);
            self.sampler
                .add_line(line, a, &mut bq, Some((omega, &mut bv)));
            (bq, bv)
        };
        let bases = [
            basis(Complex64::new(1.0, 0.0)),
            basis(Complex64::new(0.0, 1.0)),
        ];
        let jump = factors.iter().any(|(f, _)| !matches!(f, NonSmooth::Abs(_)));
        let mut h = vec![0.0; nt];
        if !jump {
            let term = RoughTerm {
                eq: 0,
                coef: 1.0,
                factors: poly.to_vec(),
                nonsmooth: factors.to_vec(),
                name: String::new(),
            };
            let nv = spectra.len();
            let (mut x, mut grad) = (vec![0.0; nv], vec![0.0; nv]);
            let (mut gq, mut gv) = (vec![0.0; nt], vec![0.0; nt]);
            for j in 0..nt {
                for (i, xi) in x.iter_mut().enumerate() {
                    *xi = xs[i * nt + j];
                }
                grad.fill(0.0);
                term.add_gradient(&x, &mut grad);
                gq[j] = grad[q];
                gv[j] = v.map_or(0.0, |v| grad[v]);
            }
            for ((bq, bv), out) in bases.iter().zip([&mut dre, &mut dim]) {
                for j in 0..nt {
                    h[j] = gq[j] * bq[j] + gv[j] * bv[j];
                }
                self.project(&h, out);
            }
            return (dre, dim);
        }
        let scale = spectra[q].iter().map(|z| z.norm()).fold(0.0, f64::max);
        let step = 1e-6 * scale.max(f64::MIN_POSITIVE);
        let mut g = vec![Complex64::new(0.0, 0.0); n_out];
        for ((bq, bv), out) in bases.iter().zip([&mut dre, &mut dim]) {
            for sign in [1.0, -1.0] {
                let d = sign * step;
                let shift = |xs: &mut [f64], d: f64| {
                    xs[q * nt..(q + 1) * nt]
                        .iter_mut()
                        .zip(bq)
                        .for_each(|(x, b)| *x += d * b);
                    if let Some(v) = v {
                        xs[v * nt..(v + 1) * nt]
                            .iter_mut()
                            .zip(bv)
                            .for_each(|(x, b)| *x += d * b);
                    }
                };
                shift(&mut xs, d);
                h.fill(0.0);
                self.sampler.add_term(1.0, poly, factors, &xs, &mut h);
                shift(&mut xs, -d);
                self.project(&h, &mut g);
                for (o, gi) in out.iter_mut().zip(&g) {
                    *o += gi * (sign / (2.0 * step));
                }
            }
        }
        (dre, dim)
    }
}

#[cfg(test)]
mod tests {
    use super::super::{base_harmonics, nonsmooth_amplitudes, NsMonomial};
    use super::*;
    use harmonid_poly::VarId;
    use std::f64::consts::TAU;

    fn abs_q() -> NsMonomial {
        NsMonomial {
            poly: vec![(0, 1)],
            factors: vec![(NonSmooth::Abs(VarId(0)), 1)],
        }
    }

    fn sign_q() -> NsMonomial {
        NsMonomial {
            poly: vec![],
            factors: vec![(NonSmooth::Sign(VarId(0)), 1)],
        }
    }

    fn on_torus(t: &Torus, term: &NsMonomial, x: &[Complex64], n_out: usize) -> Vec<Complex64> {
        let mut out = vec![Complex64::new(0.0, 0.0); n_out];
        t.amplitudes(&term.poly, &term.factors, &[x], &mut out);
        out
    }

    fn worst(a: &[Complex64], b: &[Complex64]) -> f64 {
        let scale = b.iter().map(|z| z.norm()).fold(0.0, f64::max);
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).norm())
            .fold(0.0, f64::max)
            / scale
    }

    #[test]
    fn on_a_harmonic_two_tone_lattice_the_torus_equals_one_period() {
        // 9995 + 10000 Hz (harmonics 1999, 2000 of 5 Hz): four input lines, six measured.
        let g = [9995.0, 10000.0];
        let input = [9990.0, 9995.0, 10000.0, 10005.0];
        let output = [9985.0, 9990.0, 9995.0, 10000.0, 10005.0, 10010.0];
        let x = [
            Complex64::new(0.05, -0.02),
            Complex64::from_polar(1.0, 0.3),
            Complex64::from_polar(0.6, -1.1),
            Complex64::new(-0.03, 0.04),
        ];
        let t = Torus::new(&g, &input, &output).expect("a torus");
        assert_eq!(t.sampler.grid().dims, vec![128, 128]);
        let mut all = input.to_vec();
        all.extend_from_slice(&output);
        let (_, ks) = base_harmonics(&all).expect("harmonics of 5 Hz");
        let (kin, kout) = ks.split_at(input.len());
        for (term, tol) in [(abs_q(), 1e-6), (sign_q(), 3e-4)] {
            let mut period = vec![Complex64::new(0.0, 0.0); output.len()];
            nonsmooth_amplitudes(&term, kin, &[&x], kout, &mut period);
            let err = worst(&on_torus(&t, &term, &x, output.len()), &period);
            eprintln!("harmonic two-tone, torus vs one period: {err:.2e}");
            assert!(err < tol, "{err:e}");
        }
    }

    #[test]
    fn the_column_jacobian_equals_differences_of_the_columns() {
        // abs(q)*q and abs(d(q))*d(q) (exact from the gradient) and sign(q) (differences of the
        // moved samples) against central differences of whole columns in Re X and Im X of g2.
        let g = [9996.3, 10001.7];
        let lines = [2.0 * g[0] - g[1], g[0], g[1], 2.0 * g[1] - g[0]];
        let t = Torus::new(&g, &lines, &lines).expect("a torus");
        let x = [
            Complex64::new(0.02, 0.01),
            Complex64::from_polar(1.0, 0.4),
            Complex64::from_polar(0.45, -0.7),
            Complex64::new(0.0, 0.0),
        ];
        let w: Vec<f64> = lines.iter().map(|f| TAU * f).collect();
        let v: Vec<Complex64> = x
            .iter()
            .zip(&w)
            .map(|(z, w)| Complex64::new(0.0, *w) * z)
            .collect();
        let drag = NsMonomial {
            poly: vec![(1, 1)],
            factors: vec![(NonSmooth::Abs(VarId(1)), 1)],
        };
        let s = 2;
        for term in [abs_q(), drag, sign_q()] {
            let (dre, dim) =
                t.jacobian(&term.poly, &term.factors, &[&x, &v], (0, Some(1), w[s], s));
            for (dir, exact) in [
                (Complex64::new(1.0, 0.0), &dre),
                (Complex64::new(0.0, 1.0), &dim),
            ] {
                let h = 1e-6;
                let column = |sgn: f64| {
                    let (mut x2, mut v2) = (x.to_vec(), v.clone());
                    x2[s] += dir * h * sgn;
                    v2[s] = Complex64::new(0.0, w[s]) * x2[s];
                    let mut out = vec![Complex64::new(0.0, 0.0); lines.len()];
                    t.amplitudes(&term.poly, &term.factors, &[&x2, &v2], &mut out);
                    out
                };
                let (p, m) = (column(1.0), column(-1.0));
                let fd: Vec<Complex64> =
                    p.iter().zip(&m).map(|(a, b)| (a - b) / (2.0 * h)).collect();
                let err = worst(exact, &fd);
                assert!(err < 1e-6, "{:?}: {err:e}", term.factors);
            }
        }
    }

    /// The torus coefficient of `term` at `k = (k1, k2)` for `x = Re(a e^{iθ1}) + Re(b e^{iθ2})`
    /// by nested quadrature: the inner integral over `θ1` exact (the one-period cut-and-panel
    /// quadrature with `Re(b e^{iθ2})` as a static line), the outer one by the trapezoidal rule,
    /// exponentially convergent as the inner integral is analytic in `θ2` for `|b| < |a|`.
    fn nested(term: &NsMonomial, a: Complex64, b: Complex64, k: (usize, i64)) -> Complex64 {
        let m = 256;
        let mut acc = Complex64::new(0.0, 0.0);
        for j in 0..m {
            let th2 = TAU * j as f64 / m as f64;
            let c = (b * Complex64::from_polar(1.0, th2)).re;
            let mut inner = [Complex64::new(0.0, 0.0)];
            nonsmooth_amplitudes(term, &[0, 1], &[&[c.into(), a]], &[k.0], &mut inner);
            acc += inner[0] * Complex64::from_polar(1.0, -(k.1 as f64) * th2);
        }
        // The inner static line is normalised by 1/(2π), a line by 1/π.
        let whole = if k.0 == 0 && k.1 != 0 { 2.0 } else { 1.0 };
        acc * whole / m as f64
    }

    #[test]
    fn on_incommensurate_tones_the_torus_equals_the_nested_time_average() {
        // 9996.3 + 10001.7 Hz: the lines' common divisor is 0.1 Hz, far beyond any harmonic.
        let g = [9996.3, 10001.7];
        let lines = [2.0 * g[0] - g[1], g[0], g[1], 2.0 * g[1] - g[0]];
        assert!(base_harmonics(&lines).is_none());
        let k = [(2, -1), (1, 0), (0, 1), (1, 2)];
        let (a, b) = (
            Complex64::from_polar(1.0, 0.4),
            Complex64::from_polar(0.45, -0.7),
        );
        let x = [Complex64::new(0.0, 0.0), a, b, Complex64::new(0.0, 0.0)];
        let t = Torus::new(&g, &lines, &lines).expect("a torus");
        for (term, tol) in [(abs_q(), 1e-6), (sign_q(), 3e-4)] {
            let torus = on_torus(&t, &term, &x, lines.len());
            // Line 2 g2 − g1 is k = (−1, 2): its conjugate's coefficient at (1, −2).
            let reference: Vec<Complex64> = k
                .iter()
                .map(|&(k1, k2)| match (k1, k2) {
                    (1, 2) => nested(&term, a, b, (1, -2)).conj(),
                    (k1, k2) => nested(&term, a, b, (k1, k2)),
                })
                .collect();
            let err = worst(&torus, &reference);
            eprintln!("incommensurate two-tone, torus vs nested quadrature: {err:.2e}");
            assert!(err < tol, "{err:e}");
        }
    }
}
