//! The one sampler of non-smooth terms on a [`Grid`] (issue 36): signals synthesised at the
//! grid's samples from their lines, a term `c · Π x_v^e · Π f(x)^e` evaluated there (`abs`
//! pointwise; `sign` and `tanh` as their average over each sample's cell along the grid's
//! diagonal, [`harmonid_model::NonSmooth::cell_average`]), and the samples projected back on
//! the lines. The simulator's harmonic balance ([`super::RoughAft`]), the identification's
//! regressor columns on a torus and `harmonid mix`'s non-smooth lines all sample through it,
//! so the three see the same numbers.
//!
//! Conventions: a line `r` has the grid's integer vector `k_r` ([`Grid::k`]), its phase at
//! sample `j` is `φ_{j,r} = k_r·θ_j` with `θ_{j,i} = 2π j_i / N_i` (samples in row-major
//! order, the last axis fastest), a signal is `x_j = Σ_r Re(X_r e^{iφ_{j,r}})`, its velocity
//! `Re(iΩ_r X_r e^{iφ_{j,r}})` (`Ω_r` in rad/s, given by the caller), and a projected line is
//! `F_r = (2/N) Σ_j f_j e^{−iφ_{j,r}}` (`1/N` on the static line `k_r = 0`). Samples of several
//! variables are stored variable after variable, `[v·N + j]`.
//!
//! Phases are exact in integers: every `φ` is a multiple of `2π/B`, `B` the longest axis (each
//! `N_i` divides `B`), and one table of `B` cosines and sines serves every line, so the memory
//! does not grow with the number of lines (a `harmonid mix` torus of 512² samples with dozens of
//! lines would need hundreds of megabytes of per-line tables). The loops over samples do not
//! allocate.

use super::grid::Grid;
use harmonid_model::NonSmooth;
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Samples a [`Grid`]: synthesis, evaluation of non-smooth terms and projection (see the
/// module's text).
#[derive(Debug, Clone)]
pub struct GridSampler {
    grid: Grid,
    nt: usize,
    /// The longest axis `B`.
    big: usize,
    /// `B / N_i` per axis.
    step: Vec<usize>,
    /// `cos(2π m/B)`, `sin(2π m/B)`.
    cos: Vec<f64>,
    sin: Vec<f64>,
    /// The samples one step back and on along the grid's diagonal.
    prev: Vec<u32>,
    next: Vec<u32>,
}

impl GridSampler {
    /// The sampler of `grid` (a grid without axes is taken as one sample).
    pub fn new(grid: &Grid) -> Self {
        let mut grid = grid.clone();
        if grid.dims.is_empty() {
            grid.dims = vec![1];
        }
        let big = grid.dims.iter().copied().max().unwrap_or(1).max(1);
        let th = |m: usize| TAU * m as f64 / big as f64;
        let (prev, next) = grid.neighbours();
        Self {
            nt: grid.samples(),
            step: grid.dims.iter().map(|&n| big / n.max(1)).collect(),
            cos: (0..big).map(|m| th(m).cos()).collect(),
            sin: (0..big).map(|m| th(m).sin()).collect(),
            big,
            prev,
            next,
            grid,
        }
    }

    /// The grid sampled.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Number of samples `N`.
    pub fn samples(&self) -> usize {
        self.nt
    }

    /// Number of lines of the grid.
    pub fn lines(&self) -> usize {
        self.grid.k.len() / self.grid.axes().max(1)
    }

    /// Whether line `r` is the static line (`k_r = 0`).
    pub fn is_static(&self, r: usize) -> bool {
        let d = self.grid.axes();
        self.grid.k[r * d..(r + 1) * d].iter().all(|&k| k == 0)
    }

    /// Calls `f(j, m)` for every sample `j` with line `r`'s phase `2π m / B`.
    #[inline]
    fn for_each_phase(&self, r: usize, mut f: impl FnMut(usize, usize)) {
        let d = self.grid.axes();
        let k = &self.grid.k[r * d..(r + 1) * d];
        let big = self.big as i64;
        let last = self.grid.dims[d - 1];
        let inc = (k[d - 1] * self.step[d - 1] as i64).rem_euclid(big) as usize;
        let mut j = 0;
        for row in 0..self.nt / last {
            let (mut rest, mut base) = (row, 0i64);
            for i in (0..d - 1).rev() {
                let n = self.grid.dims[i];
                base += k[i] * ((rest % n) * self.step[i]) as i64;
                rest /= n;
            }
            let mut m = base.rem_euclid(big) as usize;
            for _ in 0..last {
                f(j, m);
                j += 1;
                m += inc;
                if m >= self.big {
                    m -= self.big;
                }
            }
        }
    }

    /// Adds line `r` with complex amplitude `a` to the samples `q` (`N` values):
    /// `q_j += Re(a e^{iφ_{j,r}})`; with `velocity = Some((Ω, v))` also its time derivative
    /// `v_j += Re(iΩ a e^{iφ_{j,r}})` (`Ω` in rad/s).
    pub fn add_line(
        &self,
        r: usize,
        a: Complex64,
        q: &mut [f64],
        velocity: Option<(f64, &mut [f64])>,
    ) {
        if a == Complex64::new(0.0, 0.0) {
            return;
        }
        let (cos, sin) = (&self.cos, &self.sin);
        match velocity {
            Some((w, v)) => {
                // Re(iΩ X e^{iφ}) = −Ω (Re X sin φ + Im X cos φ).
                let (wr, wi) = (w * a.re, w * a.im);
                self.for_each_phase(r, |j, m| {
                    q[j] += a.re * cos[m] - a.im * sin[m];
                    v[j] -= wr * sin[m] + wi * cos[m];
                });
            }
            None => self.for_each_phase(r, |j, m| q[j] += a.re * cos[m] - a.im * sin[m]),
        }
    }

    /// The complex amplitude of line `r` in the samples `f` (`N` values):
    /// `(2/N) Σ_j f_j e^{−iφ_{j,r}}`, `(1/N) Σ_j f_j` on the static line.
    pub fn coefficient(&self, r: usize, f: &[f64]) -> Complex64 {
        let (mut re, mut im) = (0.0, 0.0);
        let (cos, sin) = (&self.cos, &self.sin);
        self.for_each_phase(r, |j, m| {
            re += f[j] * cos[m];
            im -= f[j] * sin[m];
        });
        let norm = if self.is_static(r) { 1.0 } else { 2.0 } / self.nt as f64;
        Complex64::new(re * norm, im * norm)
    }

    /// Adds the term `coef · Π x_v^e · Π f(x_u)^e` at every sample to `out` (`N` values), from
    /// the variables' samples `xs` (`[v·N + j]`; `poly` the `(variable, exponent)` factors,
    /// `factors` the non-smooth ones, whose variable indexes `xs` too): `abs` pointwise, `sign`
    /// and `tanh` averaged over each sample's cell along the grid's diagonal.
    pub fn add_term(
        &self,
        coef: f64,
        poly: &[(usize, u32)],
        factors: &[(NonSmooth, u32)],
        xs: &[f64],
        out: &mut [f64],
    ) {
        let nt = self.nt;
        for (j, o) in out.iter_mut().enumerate().take(nt) {
            let mut v = coef;
            for &(m, e) in poly {
                v *= pow(xs[m * nt + j], e);
            }
            for &(f, e) in factors {
                let at = f.var().index() * nt;
                let x = xs[at + j];
                let y = match f {
                    NonSmooth::Abs(_) => x.abs(),
                    _ => {
                        let p = xs[at + self.prev[j] as usize];
                        let n = xs[at + self.next[j] as usize];
                        jump_average(f, p, x, n)
                    }
                };
                v *= pow(y, e);
            }
            *o += v;
        }
    }
}

/// The cell average of a jump factor ([`NonSmooth::cell_average`]), without its arithmetic on
/// the cells the variable does not come near zero in (most of them): there `sign` is exactly
/// `±1`, and `tanh(x/c)` with the variable beyond `20c` at the cell's three samples (so over
/// the whole cell, the variable linear between them) lies within `1 − tanh 20 = 8.5e-18` of
/// `±1`, below the formula's own rounding.
#[inline]
fn jump_average(f: NonSmooth, p: f64, x: f64, n: f64) -> f64 {
    let lim = match f {
        NonSmooth::Tanh(_, c) => 20.0 * c,
        _ => 0.0,
    };
    if p > lim && x > lim && n > lim {
        1.0
    } else if p < -lim && x < -lim && n < -lim {
        -1.0
    } else {
        f.cell_average(p, x, n)
    }
}

/// `x^e` for a small whole exponent without a library call.
#[inline]
pub(crate) fn pow(x: f64, e: u32) -> f64 {
    match e {
        0 => 1.0,
        1 => x,
        2 => x * x,
        3 => x * x * x,
        _ => x.powi(e as i32),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_round_trip_and_match_the_phases_on_a_torus() {
        // Lines 2 g1 − g2, g1, g2 and the static line on a 16 × 8 torus.
        let grid = Grid {
            dims: vec![16, 8],
            k: vec![2, -1, 1, 0, 0, 1, 0, 0],
        };
        let s = GridSampler::new(&grid);
        let amps = [
            Complex64::new(0.3, -0.2),
            Complex64::new(1.0, 0.5),
            Complex64::new(-0.4, 0.7),
            Complex64::new(0.25, 0.0),
        ];
        let mut q = vec![0.0; s.samples()];
        let mut v = vec![0.0; s.samples()];
        let omega = [3.0, 5.0, 7.0, 0.0];
        for (r, &a) in amps.iter().enumerate() {
            s.add_line(r, a, &mut q, Some((omega[r], &mut v)));
        }
        // Sample (j1, j2) = (3, 5) against the formula.
        let (t1, t2) = (TAU * 3.0 / 16.0, TAU * 5.0 / 8.0);
        let ph = [2.0 * t1 - t2, t1, t2, 0.0];
        let want_q: f64 = (0..4)
            .map(|r| (amps[r] * Complex64::from_polar(1.0, ph[r])).re)
            .sum();
        let want_v: f64 = (0..4)
            .map(|r| {
                (Complex64::new(0.0, omega[r]) * amps[r] * Complex64::from_polar(1.0, ph[r])).re
            })
            .sum();
        let j = 3 * 8 + 5;
        assert!((q[j] - want_q).abs() < 1e-14, "{} vs {want_q}", q[j]);
        assert!((v[j] - want_v).abs() < 1e-13, "{} vs {want_v}", v[j]);
        for (r, &a) in amps.iter().enumerate() {
            assert!((s.coefficient(r, &q) - a).norm() < 1e-14, "line {r}");
        }
    }
}
