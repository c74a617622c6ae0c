//! The jump terms (`sign`, `tanh`) of the single-tone AFT: a jump sampled pointwise puts an
//! error of about one sample's weight, `~1/N`, into every harmonic (3e-4 relative for
//! Coulomb friction at 4096 samples), and its pointwise derivative (zero for `sign`) is not
//! the derivative of its harmonics. So, as the lattice's AFT does, each sample takes the
//! factor's average over its cell ([`harmonid_model::NonSmooth::cell_average`]; error
//! `O(N^{-2})`), and the Jacobian of these terms' harmonics is taken by central differences
//! in each real unknown and in `ω` (velocities move with `ω` at fixed amplitudes).

use crate::rough::RoughTerm;
use crate::NumericModel;
use harmonid_model::NonSmooth;

/// The sampling of one period: `cos(hθ_j)`, `sin(hθ_j)` at `[j·H + i]` for the harmonics
/// `harm[i]`, `N` samples.
pub(super) struct Tables<'a> {
    pub(super) cos: &'a [f64],
    pub(super) sin: &'a [f64],
    pub(super) harm: &'a [usize],
}

/// The jump terms of a model and their buffers.
pub(super) struct Jumps {
    terms: Vec<RoughTerm>,
    nm: usize,
    nv: usize,
    /// Forces of the jump terms at the samples, `[j·N + n]`.
    fs: Vec<f64>,
    /// Shifted samples for differences, `[j·V + v]`.
    xs: Vec<f64>,
    /// Projected forces at `±h`, `[2(n·H + i) + part]`.
    plus: Vec<f64>,
    minus: Vec<f64>,
    /// One sample's pointwise gradient.
    grad: Vec<f64>,
}

impl Jumps {
    /// The jump terms of `model` sampled at `nt` points of a period with `nh` harmonics, or
    /// `None` when it has none.
    pub(super) fn new(model: &NumericModel, nt: usize, nh: usize) -> Option<Self> {
        let terms: Vec<RoughTerm> = model
            .rough_terms()
            .iter()
            .filter(|t| t.has_jump())
            .cloned()
            .collect();
        if terms.is_empty() {
            return None;
        }
        let (nm, nv) = (model.n_modes(), model.n_vars());
        Some(Self {
            terms,
            nm,
            nv,
            fs: vec![0.0; nt * nm],
            xs: vec![0.0; nt * nv],
            plus: vec![0.0; 2 * nm * nh],
            minus: vec![0.0; 2 * nm * nh],
            grad: vec![0.0; nv],
        })
    }

    /// Replaces the jump terms' pointwise values in `nl` (`[j·N + n]`, the model's forces at
    /// the samples `xs`, `[j·V + v]`) by their cell averages and, with `jac` (`[j·N·V + n·V
    /// + v]`), removes their pointwise gradients (their derivative is added in
    /// [`Jumps::add_jacobian`]).
    pub(super) fn correct(&mut self, xs: &[f64], nl: &mut [f64], mut jac: Option<&mut [f64]>) {
        let (nm, nv) = (self.nm, self.nv);
        evaluate(&self.terms, xs, nm, nv, &mut self.fs);
        for (j, x) in xs.chunks_exact(nv).enumerate() {
            for t in &self.terms {
                nl[j * nm + t.eq] -= t.value(x);
                if let Some(jac) = jac.as_deref_mut() {
                    self.grad.fill(0.0);
                    t.add_gradient(x, &mut self.grad);
                    let row = &mut jac[(j * nm + t.eq) * nv..(j * nm + t.eq + 1) * nv];
                    for (r, g) in row.iter_mut().zip(&self.grad) {
                        *r -= g;
                    }
                }
            }
        }
        for (n, f) in nl.iter_mut().zip(&self.fs) {
            *n += f;
        }
    }

    /// Adds the derivatives of the jump terms' harmonics to `ju` (`∂R/∂u`, row-major) and
    /// `jw` (`∂R/∂ω`), by central differences around the samples `xs` at `ω = w`. The static
    /// line's imaginary row (which pins `Im X_0 = 0`) is left alone.
    pub(super) fn add_jacobian(
        &mut self,
        xs: &[f64],
        tab: &Tables,
        w: f64,
        ju: &mut [f64],
        jw: &mut [f64],
    ) {
        let nu = self.plus.len();
        let nh = tab.harm.len();
        let scale = xs
            .chunks_exact(self.nv)
            .flat_map(|x| &x[..self.nm])
            .fold(0.0f64, |m, v| m.max(v.abs()))
            .max(1e-300);
        let h = 1e-6 * scale;
        for col in 0..=nu {
            for (sgn, plus) in [(1.0, true), (-1.0, false)] {
                self.xs.copy_from_slice(xs);
                if col < nu {
                    self.shift(col, sgn * h, tab, w);
                } else {
                    // ω: every velocity scales with it at fixed amplitudes.
                    for x in self.xs.chunks_exact_mut(self.nv) {
                        x[self.nm..].iter_mut().for_each(|v| *v *= 1.0 + sgn * 1e-6);
                    }
                }
                evaluate(&self.terms, &self.xs, self.nm, self.nv, &mut self.fs);
                let out = if plus {
                    &mut self.plus
                } else {
                    &mut self.minus
                };
                project(&self.fs, self.nm, tab, out);
            }
            let step = if col < nu { 2.0 * h } else { 2e-6 * w };
            for row in 0..nu {
                let (n_i, part) = (row / 2, row % 2);
                if part == 1 && tab.harm[n_i % nh] == 0 {
                    continue;
                }
                let d = (self.plus[row] - self.minus[row]) / step;
                if col < nu {
                    ju[row * nu + col] += d;
                } else {
                    jw[row] += d;
                }
            }
        }
    }

    /// Moves the samples in `self.xs` by `d` times unknown `col`'s basis function:
    /// `q_m += d·cos(hθ)` (Re) or `−d·sin(hθ)` (Im), and the velocity by `ω` times its
    /// derivative in `θ`.
    fn shift(&mut self, col: usize, d: f64, tab: &Tables, w: f64) {
        let nh = tab.harm.len();
        let (m, i, part) = (col / 2 / nh, (col / 2) % nh, col % 2);
        let wh = w * tab.harm[i] as f64;
        let velocities = self.nv > self.nm;
        for (j, x) in self.xs.chunks_exact_mut(self.nv).enumerate() {
            let (c, s) = (tab.cos[j * nh + i], tab.sin[j * nh + i]);
            let (dq, dv) = if part == 0 {
                (c, -wh * s)
            } else {
                (-s, -wh * c)
            };
            x[m] += d * dq;
            if velocities {
                x[self.nm + m] += d * dv;
            }
        }
    }
}

/// The forces of `terms` at every sample of `xs` into `fs` (`[j·N + n]`), `sign` and `tanh`
/// factors averaged over each sample's cell (its neighbours taken cyclically).
fn evaluate(terms: &[RoughTerm], xs: &[f64], nm: usize, nv: usize, fs: &mut [f64]) {
    let nt = xs.len() / nv;
    fs.fill(0.0);
    for t in terms {
        for j in 0..nt {
            let x = &xs[j * nv..(j + 1) * nv];
            let mut v = t.coef;
            for &(m, k) in &t.factors {
                v *= x[m].powi(k as i32);
            }
            for &(f, k) in &t.nonsmooth {
                let i = f.var().index();
                let y = match f {
                    NonSmooth::Abs(_) => f.value(x[i]),
                    _ => {
                        let prev = xs[((j + nt - 1) % nt) * nv + i];
                        let next = xs[((j + 1) % nt) * nv + i];
                        f.cell_average(prev, x[i], next)
                    }
                };
                v *= y.powi(k as i32);
            }
            fs[j * nm + t.eq] += v;
        }
    }
}

/// The harmonics of the sampled forces `fs` (`[j·N + n]`) in the residual's layout
/// (`[2(n·H + i) + part]`): `(2/N) Σ_j f_j e^{−ihθ_j}`, `(1/N) Σ_j f_j` for `h = 0`.
fn project(fs: &[f64], nm: usize, tab: &Tables, out: &mut [f64]) {
    let nh = tab.harm.len();
    let nt = fs.len() / nm;
    for n in 0..nm {
        for (i, &h) in tab.harm.iter().enumerate() {
            let (mut re, mut im) = (0.0, 0.0);
            for j in 0..nt {
                let f = fs[j * nm + n];
                re += f * tab.cos[j * nh + i];
                im -= f * tab.sin[j * nh + i];
            }
            let norm = if h == 0 { 1.0 } else { 2.0 } / nt as f64;
            let k = 2 * (n * nh + i);
            out[k] = re * norm;
            out[k + 1] = if h == 0 { 0.0 } else { im * norm };
        }
    }
}
