//! Alternating frequency–time harmonic balance for one tone: the engine of the single-tone
//! sweep and the backbone, whose frequency is an unknown of the continuation (the lattice
//! solver's frequencies are fixed, so these do not run on [`super::HbSolver`]).

mod jumps;

use crate::NumericModel;
use jumps::{Jumps, Tables};
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
    /// The terms with a jump (`sign`, `tanh`), averaged over each sample's cell.
    jumps: Option<Jumps>,
    // Buffers.
    /// The variables at the samples, `[j·V + v]`: displacements, then velocities (models
    /// with velocity terms).
    xs: Vec<f64>,
    pows: Vec<f64>,
    fnl: Vec<f64>,
    /// `∂f_n/∂x_v` at one sample (`N × V`, `V` = [`NumericModel::n_vars`]).
    fj: Vec<f64>,
    nl_t: Vec<f64>,
    jac_t: Vec<f64>,
    /// `∂f_n/∂ω` at each sample through the velocities (`q̇ = ω dq/dθ`), `[j·N + n]`.
    dfdw_t: Vec<f64>,
}

impl Aft {
    pub(super) fn new(model: &NumericModel, force: &[Complex64], hmax: usize) -> Self {
        let pump = 2 * model.n_modes();
        let odd = model.terms().iter().all(|t| t.degree() % 2 == 1)
            && model.rough_terms().iter().all(|t| t.is_odd(pump));
        let harm: Vec<usize> = (0..=hmax.max(1))
            .filter(|&h| if odd { h % 2 == 1 } else { true })
            .collect();
        let d = model.max_degree().max(1) as usize;
        let need = (d + 1) * hmax.max(1) + 1;
        // Non-smooth terms have no last harmonic: sample as the lattice's AFT does.
        let min_nt = if model.has_nonsmooth() {
            super::rough_aft::ROUGH_MIN_SAMPLES
        } else {
            16
        };
        let nt = need.next_power_of_two().max(min_nt);
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
        let nv = model.n_vars();
        Self {
            model: model.clone(),
            jumps: Jumps::new(model, nt, nh),
            harm,
            nt,
            cos,
            sin,
            force: force.to_vec(),
            xs: vec![0.0; nt * nv],
            pows: vec![0.0; model.pow_len()],
            fnl: vec![0.0; nm],
            fj: vec![0.0; nm * nv],
            nl_t: vec![0.0; nt * nm],
            jac_t: vec![0.0; nt * nm * nv],
            dfdw_t: vec![0.0; if nv > nm { nt * nm } else { 0 }],
        }
    }

    /// Number of modes.
    pub(super) fn n_modes(&self) -> usize {
        self.model.n_modes()
    }

    /// Number of real unknowns.
    pub(super) fn n(&self) -> usize {
        2 * self.model.n_modes() * self.harm.len()
    }

    /// Time samples of the variables at `u`, `ω = w` (q, and q̇ = ω Σ h (−Re X sin hθ −
    /// Im X cos hθ) for velocity terms), the nonlinear forces there, and with `with_jacobian`
    /// their derivatives (and `∂f/∂ω` through the velocities). Jump terms are cell averages
    /// ([`Jumps::correct`]).
    fn sample(&mut self, u: &[f64], w: f64, with_jacobian: bool) {
        let nm = self.model.n_modes();
        let nv = self.model.n_vars();
        let nh = self.harm.len();
        for (j, x) in self.xs.chunks_exact_mut(nv).enumerate() {
            for n in 0..nm {
                let mut v = 0.0;
                for i in 0..nh {
                    let k = 2 * (n * nh + i);
                    v += u[k] * self.cos[j * nh + i] - u[k + 1] * self.sin[j * nh + i];
                }
                x[n] = v;
            }
            for n in 0..nv - nm {
                let mut v = 0.0;
                for (i, &h) in self.harm.iter().enumerate() {
                    let k = 2 * (n * nh + i);
                    v -= h as f64 * (u[k] * self.sin[j * nh + i] + u[k + 1] * self.cos[j * nh + i]);
                }
                x[nm + n] = w * v;
            }
        }
        for (j, x) in self.xs.chunks_exact(nv).enumerate() {
            self.model.forces(x, &mut self.pows, &mut self.fnl);
            self.nl_t[j * nm..(j + 1) * nm].copy_from_slice(&self.fnl);
            if with_jacobian {
                self.model.force_jacobian(x, &mut self.pows, &mut self.fj);
                self.jac_t[j * nm * nv..(j + 1) * nm * nv].copy_from_slice(&self.fj);
            }
        }
        if let Some(jumps) = self.jumps.as_mut() {
            let jac = with_jacobian.then_some(&mut self.jac_t[..]);
            jumps.correct(&self.xs, &mut self.nl_t, jac);
        }
        if with_jacobian && nv > nm {
            for (j, x) in self.xs.chunks_exact(nv).enumerate() {
                let fj = &self.jac_t[j * nm * nv..(j + 1) * nm * nv];
                for n in 0..nm {
                    let mut d = 0.0;
                    for m in 0..nm {
                        d += fj[n * nv + nm + m] * x[nm + m];
                    }
                    self.dfdw_t[j * nm + n] = if w != 0.0 { d / w } else { 0.0 };
                }
            }
        }
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
        let nv = self.model.n_vars();
        let nh = self.harm.len();
        let nt = self.nt;
        self.sample(u, w, jac.is_some());
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
                    let mut dl = Complex64::new(-2.0 * h as f64 * hw, h as f64 * g) * x;
                    if nv > nm {
                        // The velocity terms' force moves with ω at fixed X.
                        let mut acc = Complex64::new(0.0, 0.0);
                        for j in 0..nt {
                            let f = self.dfdw_t[j * nm + n];
                            acc +=
                                Complex64::new(f * self.cos[j * nh + i], -f * self.sin[j * nh + i]);
                        }
                        dl += acc * norm;
                    }
                    jw[k] = dl.re;
                    jw[k + 1] = if h == 0 { 0.0 } else { dl.im };
                }
            }
        }
        if let Some((ju, jw)) = jac {
            self.assemble_ju(w, damping, ju);
            if let Some(jumps) = self.jumps.as_mut() {
                let tab = Tables {
                    cos: &self.cos,
                    sin: &self.sin,
                    harm: &self.harm,
                };
                jumps.add_jacobian(&self.xs, &tab, w, ju, jw);
            }
        }
    }

    /// `∂R/∂u` (row-major `n × n`) from the linear part and the sampled force derivatives of
    /// the last [`Aft::sample`] with its Jacobian.
    fn assemble_ju(&self, w: f64, damping: f64, ju: &mut [f64]) {
        let nm = self.model.n_modes();
        let nv = self.model.n_vars();
        let nh = self.harm.len();
        let nt = self.nt;
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
                    for (i2, &h2) in self.harm.iter().enumerate() {
                        let col = 2 * (m * nh + i2);
                        // ∂q_m(t)/∂Re X = cos(h2 θ), ∂/∂Im X = −sin(h2 θ); for the
                        // velocity, −ω h2 sin(h2 θ) and −ω h2 cos(h2 θ).
                        let mut a = Complex64::new(0.0, 0.0);
                        let mut b = Complex64::new(0.0, 0.0);
                        for j in 0..nt {
                            let d = self.jac_t[j * nm * nv + n * nv + m];
                            let e = Complex64::new(self.cos[j * nh + i], -self.sin[j * nh + i]) * d;
                            a += e * self.cos[j * nh + i2];
                            b -= e * self.sin[j * nh + i2];
                        }
                        if nv > nm {
                            let wh2 = w * h2 as f64;
                            for j in 0..nt {
                                let d = self.jac_t[j * nm * nv + n * nv + nm + m];
                                let e =
                                    Complex64::new(self.cos[j * nh + i], -self.sin[j * nh + i]) * d;
                                a -= e * (wh2 * self.sin[j * nh + i2]);
                                b -= e * (wh2 * self.cos[j * nh + i2]);
                            }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Term;

    /// Two modes with Duffing, a dispersive coupling and velocity terms of both kinds.
    fn damped() -> NumericModel {
        let t = |eq, coef, factors: Vec<(usize, u32)>| Term { eq, coef, factors };
        NumericModel::new(
            vec!["a".into(), "b".into()],
            vec![1000.0, 1500.0],
            vec![50.0, 80.0],
            vec![
                t(0, 3e9, vec![(0, 3)]),
                t(0, 2e8, vec![(0, 2), (2, 1)]),
                t(0, 1e8, vec![(1, 2), (2, 1)]),
                t(1, 1e9, vec![(0, 2), (1, 1)]),
                t(1, -5e7, vec![(1, 1), (3, 2)]),
            ],
        )
        .expect("model")
    }

    #[test]
    fn jacobian_matches_central_differences_with_velocity_terms() {
        let m = damped();
        let force = [Complex64::new(30.0, 5.0), Complex64::new(-10.0, 20.0)];
        let mut aft = Aft::new(&m, &force, 5);
        let n = aft.n();
        let u: Vec<f64> = (0..n)
            .map(|k| 1e-3 * ((k as f64 * 0.7).sin() + 0.3))
            .collect();
        let w = TAU * 1010.0;
        let (mut res, mut ju, mut jw) = (vec![0.0; n], vec![0.0; n * n], vec![0.0; n]);
        aft.eval(&u, w, 1.0, 1.0, &mut res, Some((&mut ju, &mut jw)));
        let mut eval = |u: &[f64], w: f64| {
            let mut r = vec![0.0; n];
            aft.eval(u, w, 1.0, 1.0, &mut r, None);
            r
        };
        let scale = ju.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let mut worst: f64 = 0.0;
        for c in 0..n {
            let h = 1e-7;
            let (mut up, mut dn) = (u.clone(), u.clone());
            up[c] += h;
            dn[c] -= h;
            let (rp, rm) = (eval(&up, w), eval(&dn, w));
            for r in 0..n {
                let fd = (rp[r] - rm[r]) / (2.0 * h);
                worst = worst.max((fd - ju[r * n + c]).abs() / scale);
            }
        }
        assert!(worst < 1e-6, "dR/du: worst {worst:e}");
        let h = 1e-3;
        let (rp, rm) = (eval(&u, w + h), eval(&u, w - h));
        let jscale = jw.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for r in 0..n {
            let fd = (rp[r] - rm[r]) / (2.0 * h);
            assert!(
                (fd - jw[r]).abs() < 1e-6 * jscale,
                "dR/dw row {r}: {fd} vs {}",
                jw[r]
            );
        }
    }
}
