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
use harmonid_sim::Grid;
use num_complex::Complex64;
use std::f64::consts::TAU;

/// The sampling of one measurement's torus: the grid, and where each input and measured line
/// sits among the grid's lines.
#[derive(Debug, Clone)]
pub(crate) struct Torus {
    grid: Grid,
    /// Grid line of each input line.
    line_in: Vec<usize>,
    /// Grid line of each measured line.
    line_out: Vec<usize>,
    /// The sample one step back and one step on along the diagonal (cell averages).
    prev: Vec<u32>,
    next: Vec<u32>,
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
        let (prev, next) = grid.neighbours();
        Ok(Self {
            line_in: input_hz.iter().map(at).collect(),
            line_out: output_hz.iter().map(at).collect(),
            grid,
            prev,
            next,
        })
    }

    /// Samples on the torus, `Π N_i`.
    pub(crate) fn samples(&self) -> usize {
        self.grid.samples()
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
        let nt = self.samples();
        let nv = spectra.len();
        let phases = Phases::new(&self.grid);
        // The variables at every sample, [j·V + v].
        let mut xs = vec![0.0; nt * nv];
        let mut idx = vec![0usize; self.grid.axes()];
        for j in 0..nt {
            for (r, &l) in self.line_in.iter().enumerate() {
                let (c, s) = phases.at(l, &idx);
                for (v, sp) in spectra.iter().enumerate() {
                    let z = sp[r];
                    xs[j * nv + v] += z.re * c - z.im * s;
                }
            }
            advance(&mut idx, &self.grid.dims);
        }
        out.fill(Complex64::new(0.0, 0.0));
        idx.fill(0);
        for j in 0..nt {
            let x = &xs[j * nv..(j + 1) * nv];
            let mut g = 1.0;
            for &(v, e) in poly {
                g *= x[v].powi(e as i32);
            }
            for &(f, e) in factors {
                let i = f.var().index();
                let y = match f {
                    NonSmooth::Abs(_) => f.value(x[i]),
                    _ => {
                        let p = xs[self.prev[j] as usize * nv + i];
                        let n = xs[self.next[j] as usize * nv + i];
                        f.cell_average(p, x[i], n)
                    }
                };
                g *= y.powi(e as i32);
            }
            if g != 0.0 {
                for (o, &l) in out.iter_mut().zip(&self.line_out) {
                    let (c, s) = phases.at(l, &idx);
                    *o += Complex64::new(g * c, -g * s);
                }
            }
            advance(&mut idx, &self.grid.dims);
        }
        for (o, &l) in out.iter_mut().zip(&self.line_out) {
            let d = self.grid.axes();
            let static_line = self.grid.k[l * d..(l + 1) * d].iter().all(|&k| k == 0);
            *o *= if static_line { 1.0 } else { 2.0 } / nt as f64;
        }
    }
}

/// `cos` and `sin` of a line's phase `k_r·θ_j` at a multi-index, exact in integers: every
/// phase is a multiple of `2π/big`, `big` the largest axis.
struct Phases<'a> {
    grid: &'a Grid,
    big: usize,
    cos: Vec<f64>,
    sin: Vec<f64>,
}

impl<'a> Phases<'a> {
    fn new(grid: &'a Grid) -> Self {
        let big = grid.dims.iter().copied().max().unwrap_or(1);
        let th = |m: usize| TAU * m as f64 / big as f64;
        Self {
            grid,
            big,
            cos: (0..big).map(|m| th(m).cos()).collect(),
            sin: (0..big).map(|m| th(m).sin()).collect(),
        }
    }

    fn at(&self, line: usize, idx: &[usize]) -> (f64, f64) {
        let d = self.grid.axes();
        let mut m: i64 = 0;
        for (i, &n) in self.grid.dims.iter().enumerate() {
            let step = (self.big / n) as i64;
            m += (self.grid.k[line * d + i] * idx[i] as i64).rem_euclid(n as i64) * step;
        }
        let m = m.rem_euclid(self.big as i64) as usize;
        (self.cos[m], self.sin[m])
    }
}

/// The next multi-index in row-major order (the last axis fastest, as the grid's samples).
fn advance(idx: &mut [usize], dims: &[usize]) {
    for i in (0..idx.len()).rev() {
        idx[i] += 1;
        if idx[i] < dims[i] {
            return;
        }
        idx[i] = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::super::{base_harmonics, nonsmooth_amplitudes, NsMonomial};
    use super::*;
    use harmonid_poly::VarId;

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
        assert_eq!(t.grid.dims, vec![128, 128]);
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
