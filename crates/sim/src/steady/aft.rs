//! Alternating frequency–time harmonic balance for one tone: the engine of the single-tone
//! sweep and the backbone, whose frequency is an unknown of the continuation (the lattice
//! solver's frequencies are fixed, so these do not run on [`super::HbSolver`]).

use crate::NumericModel;
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Alternating frequency–time harmonic balance for one tone.
pub(super) struct Aft {
    model: NumericModel,
    /// Harmonics of the tone solved for.
    pub(super) harm: Vec<usize>,
    nt: usize,
    cos: Vec<f64>,
    sin: Vec<f64>,
    /// Force on each mode at the fundamental (`[n]`).
    force: Vec<Complex64>,
    // Buffers.
    q: Vec<f64>,
    pows: Vec<f64>,
    fnl: Vec<f64>,
    fj: Vec<f64>,
    nl_t: Vec<f64>,
    jac_t: Vec<f64>,
}

impl Aft {
    pub(super) fn new(model: &NumericModel, force: &[Complex64], hmax: usize) -> Self {
        let odd = model.terms().iter().all(|t| t.degree() % 2 == 1);
        let harm: Vec<usize> = (0..=hmax.max(1))
            .filter(|&h| if odd { h % 2 == 1 } else { true })
            .collect();
        let d = model.max_degree().max(1) as usize;
        let need = (d + 1) * hmax.max(1) + 1;
        let nt = need.next_power_of_two().max(16);
        let nh = harm.len();
        let mut cos = vec![0.0; nt * nh];
        let mut sin = vec![0.0; nt * nh];
        for j in 0..nt {
            for (i, &h) in harm.iter().enumerate() {
                let th = TAU * ((h * j) % nt) as f64 / nt as f64;
                cos[j * nh + i] = th.cos();
                sin[j * nh + i] = th.sin();
            }
        }
        let nm = model.n_modes();
        Self {
            model: model.clone(),
            harm,
            nt,
            cos,
            sin,
            force: force.to_vec(),
            q: vec![0.0; nm],
            pows: vec![0.0; model.pow_len()],
            fnl: vec![0.0; nm],
            fj: vec![0.0; nm * nm],
            nl_t: vec![0.0; nt * nm],
            jac_t: vec![0.0; nt * nm * nm],
        }
    }

    /// Number of real unknowns.
    pub(super) fn n(&self) -> usize {
        2 * self.model.n_modes() * self.harm.len()
    }

    /// Residual `res` (real, [2(n·H + i) + part]) at unknowns `u` and angular frequency `w`
    /// with drive scale `s`; if `jac` is given, also `∂R/∂u` (row-major n×n) and `∂R/∂w`.
    pub(super) fn eval(
        &mut self,
        u: &[f64],
        w: f64,
        s: f64,
        damping: f64,
        res: &mut [f64],
        mut jac: Option<(&mut [f64], &mut [f64])>,
    ) {
        let nm = self.model.n_modes();
        let nh = self.harm.len();
        let nt = self.nt;
        // Time samples of q and the nonlinear forces.
        for j in 0..nt {
            for n in 0..nm {
                let mut v = 0.0;
                for i in 0..nh {
                    let k = 2 * (n * nh + i);
                    v += u[k] * self.cos[j * nh + i] - u[k + 1] * self.sin[j * nh + i];
                }
                self.q[n] = v;
            }
            self.model.forces(&self.q, &mut self.pows, &mut self.fnl);
            self.nl_t[j * nm..(j + 1) * nm].copy_from_slice(&self.fnl);
            if jac.is_some() {
                self.model
                    .force_jacobian(&self.q, &mut self.pows, &mut self.fj);
                self.jac_t[j * nm * nm..(j + 1) * nm * nm].copy_from_slice(&self.fj);
            }
        }
        for n in 0..nm {
            let (wn, g) = (self.model.omega(n), self.model.gamma(n) * damping);
            for (i, &h) in self.harm.iter().enumerate() {
                let k = 2 * (n * nh + i);
                let hw = h as f64 * w;
                let l = Complex64::new(wn * wn - hw * hw, hw * g);
                let x = Complex64::new(u[k], u[k + 1]);
                let mut r = l * x;
                if h == 1 {
                    r -= self.force[n] * s;
                }
                // DFT of the nonlinear force: (2/N) Σ f e^{-ihθ}; DC: (1/N) Σ f.
                let norm = if h == 0 {
                    1.0 / nt as f64
                } else {
                    2.0 / nt as f64
                };
                let mut acc = Complex64::new(0.0, 0.0);
                for j in 0..nt {
                    let f = self.nl_t[j * nm + n];
                    acc += Complex64::new(f * self.cos[j * nh + i], -f * self.sin[j * nh + i]);
                }
                r += acc * norm;
                res[k] = r.re;
                res[k + 1] = if h == 0 { u[k + 1] } else { r.im };
                if let Some((_, jw)) = jac.as_mut() {
                    let dl = Complex64::new(-2.0 * h as f64 * hw, h as f64 * g) * x;
                    jw[k] = dl.re;
                    jw[k + 1] = if h == 0 { 0.0 } else { dl.im };
                }
            }
        }
        if let Some((ju, _)) = jac {
            let nu = self.n();
            ju.iter_mut().for_each(|v| *v = 0.0);
            for n in 0..nm {
                let (wn, g) = (self.model.omega(n), self.model.gamma(n) * damping);
                for (i, &h) in self.harm.iter().enumerate() {
                    let row = 2 * (n * nh + i);
                    let hw = h as f64 * w;
                    let l = Complex64::new(wn * wn - hw * hw, hw * g);
                    if h == 0 {
                        ju[row * nu + row] = l.re;
                        ju[(row + 1) * nu + row + 1] = 1.0;
                    } else {
                        ju[row * nu + row] = l.re;
                        ju[row * nu + row + 1] = -l.im;
                        ju[(row + 1) * nu + row] = l.im;
                        ju[(row + 1) * nu + row + 1] = l.re;
                    }
                    let norm = if h == 0 {
                        1.0 / nt as f64
                    } else {
                        2.0 / nt as f64
                    };
                    for m in 0..nm {
                        for (i2, _) in self.harm.iter().enumerate() {
                            let col = 2 * (m * nh + i2);
                            // ∂q_m(t)/∂Re X = cos(h2 θ), ∂/∂Im X = −sin(h2 θ).
                            let mut a = Complex64::new(0.0, 0.0);
                            let mut b = Complex64::new(0.0, 0.0);
                            for j in 0..nt {
                                let d = self.jac_t[j * nm * nm + n * nm + m];
                                let e =
                                    Complex64::new(self.cos[j * nh + i], -self.sin[j * nh + i]) * d;
                                a += e * self.cos[j * nh + i2];
                                b -= e * self.sin[j * nh + i2];
                            }
                            a *= norm;
                            b *= norm;
                            ju[row * nu + col] += a.re;
                            ju[row * nu + col + 1] += b.re;
                            if h != 0 {
                                ju[(row + 1) * nu + col] += a.im;
                                ju[(row + 1) * nu + col + 1] += b.im;
                            }
                        }
                    }
                }
            }
        }
    }
}
