//! Harmonic balance on a 2-torus: a quasi-periodic response with two base frequencies, the
//! drive's `Ω_d` and a second one `Ω_2` (a self-oscillation beside the drive), by the
//! alternating frequency–time method on a grid of the two angles.
//!
//! Unknowns `X_{n,k}` for multi-indices `k = (k₁, k₂)` in a half plane (`k₂ > 0`, or `k₂ = 0`
//! and `k₁ ≥ 0`) with `|k₁| + |k₂| ≤ H` (and `k₁ + k₂` odd when every term has odd degree):
//! `q_n(θ) = Σ_k Re[X_{n,k} e^{i k·θ}]`, `θ = (Ω_d t, Ω_2 t)`, line `k` at the frequency
//! `Ω_k = k₁Ω_d + k₂Ω_2` (negative for some `k`: that line oscillates at `|Ω_k|` with the
//! conjugate amplitude). Residual, as on a one-tone lattice (DATA_FORMAT conventions):
//!
//! ```text
//! R_{n,k} = (ω_n² − Ω_k² + iΩ_k γ_n) X_{n,k} + [f_n(q, q̇)]_k − F_n δ_{k,(1,0)},
//! ```
//!
//! `[f]_k` the coefficient of `e^{ik·θ}` in the `Re` convention (twice the Fourier coefficient,
//! once at `k = 0`), exact: the forces are sampled on `N₁ × N₂` points with
//! `N_i = (d + 1)H + 1` for degree `d`, so no product aliases onto a kept line. The offset
//! line `(0,0)` is real; its imaginary row is `ω_n² Im X = 0`.
//!
//! The Jacobian is analytic: with `A = ∂f/∂q`, `B = ∂f/∂q̇` along the torus and `a_d`, `b_d`
//! their Fourier coefficients, `∂[f]_{k'}/∂X_k = a_{k'−k} + iΩ_k b_{k'−k}` and
//! `∂[f]_{k'}/∂X̄_k = a_{k'+k} − iΩ_k b_{k'+k}` (halved at `k' = 0`).

use crate::{NumericModel, SimError};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// The problem on the torus: index set, grid and tables, with the buffers of one evaluation.
#[derive(Debug, Clone)]
pub(super) struct Torus {
    model: NumericModel,
    /// Multi-indices of the lines, `(0,0)` first when present.
    pub(super) idx: Vec<(i64, i64)>,
    /// Highest `|k₁| + |k₂|` kept.
    h: i64,
    /// Grid points along each angle.
    n1: usize,
    n2: usize,
    /// Force on each mode at the drive line `(1,0)`, N/kg.
    force: Vec<Complex64>,
    /// `e^{i j θ}` for `j` in `−2H..=2H` along each angle, `[(j + 2H)·N + p]`.
    e1: Vec<Complex64>,
    e2: Vec<Complex64>,
}

impl Torus {
    /// The torus of `model` driven by `force` (N/kg on each mode at the drive), lines up to
    /// `|k₁| + |k₂| ≤ harmonics`. Errors: pump terms (a pump is a third base frequency),
    /// non-smooth terms (not resolved exactly on the grid), a harmonic count of 0 or above 31.
    pub(super) fn new(
        model: &NumericModel,
        force: &[Complex64],
        harmonics: usize,
    ) -> Result<Self, SimError> {
        if model.has_pump_terms() {
            return Err(SimError::PumpTerms {
                what: "the quasi-periodic (two-frequency) harmonic balance",
                terms: model.pump_term_names().join(", "),
                instead: "a pump is a third base frequency: continue the limit cycle of a model without pump terms",
            });
        }
        if model.has_nonsmooth() {
            return Err(SimError::BadValue {
                what: "non-smooth terms (abs, sign, tanh) in the quasi-periodic balance".into(),
                value: model.rough_terms().len() as f64,
                why: "its grid resolves polynomial forces exactly and a non-smooth one would alias onto the kept lines: continue limit cycles of a polynomial model".into(),
            });
        }
        if harmonics == 0 || harmonics > 31 {
            return Err(SimError::BadValue {
                what: "highest order |k1| + |k2| of the quasi-periodic lines".into(),
                value: harmonics as f64,
                why: "give between 1 and 31".into(),
            });
        }
        let h = harmonics as i64;
        let odd = model.terms().iter().all(|t| t.degree() % 2 == 1);
        let mut idx = Vec::new();
        for k2 in 0..=h {
            for k1 in -h..=h {
                let half = k2 > 0 || k1 >= 0;
                if half && k1.abs() + k2 <= h && (!odd || (k1 + k2).rem_euclid(2) == 1) {
                    idx.push((k1, k2));
                }
            }
        }
        let d = model.max_degree().max(1) as usize;
        let n = (d + 1) * harmonics + 1;
        let table = |n: usize| -> Vec<Complex64> {
            (-2 * h..=2 * h)
                .flat_map(|j| {
                    (0..n).map(move |p| {
                        Complex64::from_polar(1.0, TAU * (j * p as i64) as f64 / n as f64)
                    })
                })
                .collect()
        };
        Ok(Self {
            model: model.clone(),
            idx,
            h,
            n1: n,
            n2: n,
            force: force.to_vec(),
            e1: table(n),
            e2: table(n),
        })
    }

    /// Real unknowns: `2 · modes · lines`.
    pub(super) fn n(&self) -> usize {
        2 * self.model.n_modes() * self.idx.len()
    }

    /// Index of line `k`, if kept.
    pub(super) fn line(&self, k: (i64, i64)) -> Option<usize> {
        self.idx.iter().position(|&x| x == k)
    }

    /// `e^{i j θ_p}` along angle `axis` (0 or 1).
    #[inline]
    fn e(&self, axis: usize, j: i64, p: usize) -> Complex64 {
        let (t, n) = if axis == 0 {
            (&self.e1, self.n1)
        } else {
            (&self.e2, self.n2)
        };
        t[(j + 2 * self.h) as usize * n + p]
    }

    /// The residual at the unknowns `u` (`u[2(n·L + l)]`, `+1`: real and imaginary part of
    /// `X_{n,k_l}`) for the base angular frequencies `wd`, `w2` (rad/s), into `res`; with
    /// `jac`, also `∂R/∂u` (row-major `n × n`).
    pub(super) fn eval(
        &self,
        u: &[f64],
        (wd, w2): (f64, f64),
        res: &mut [f64],
        jac: Option<&mut [f64]>,
    ) {
        let nm = self.model.n_modes();
        let nv = self.model.n_vars();
        let nl = self.idx.len();
        let (n1, n2) = (self.n1, self.n2);
        let omega = |l: usize| self.idx[l].0 as f64 * wd + self.idx[l].1 as f64 * w2;
        let x = |n: usize, l: usize| Complex64::new(u[2 * (n * nl + l)], u[2 * (n * nl + l) + 1]);
        // Samples of every variable, then of the forces and their Jacobian.
        let np = n1 * n2;
        let mut vars = vec![0.0; np * nv.max(1)];
        for n in 0..nm {
            for l in 0..nl {
                let (k1, k2) = self.idx[l];
                let z = x(n, l);
                let zv = Complex64::new(0.0, omega(l)) * z;
                for p1 in 0..n1 {
                    let a = self.e(0, k1, p1);
                    for p2 in 0..n2 {
                        let e = a * self.e(1, k2, p2);
                        let p = p1 * n2 + p2;
                        vars[p * nv + n] += (z * e).re;
                        if nv > nm {
                            vars[p * nv + nm + n] += (zv * e).re;
                        }
                    }
                }
            }
        }
        let mut pows = vec![0.0; self.model.pow_len()];
        let mut f = vec![0.0; np * nm];
        let mut out = vec![0.0; nm];
        for p in 0..np {
            self.model
                .forces(&vars[p * nv..(p + 1) * nv], &mut pows, &mut out);
            f[p * nm..(p + 1) * nm].copy_from_slice(&out);
        }
        let fk = self.project(&f, nm, self.h);
        for n in 0..nm {
            let (w, g) = (self.model.omega(n), self.model.gamma(n));
            for l in 0..nl {
                let o = omega(l);
                let (k1, k2) = self.idx[l];
                let scale = if (k1, k2) == (0, 0) { 1.0 } else { 2.0 };
                let mut r = Complex64::new(w * w - o * o, o * g) * x(n, l)
                    + scale * fk[self.coef_at(k1, k2, self.h) * nm + n];
                if (k1, k2) == (1, 0) {
                    r -= self.force[n];
                }
                if (k1, k2) == (0, 0) {
                    r.im = w * w * x(n, l).im;
                }
                res[2 * (n * nl + l)] = r.re;
                res[2 * (n * nl + l) + 1] = r.im;
            }
        }
        if let Some(jac) = jac {
            self.jacobian(&vars, (wd, w2), jac);
        }
    }

    /// Position of coefficient `(d1, d2)` in a table of `|d_i| ≤ top` (row-major).
    #[inline]
    fn coef_at(&self, d1: i64, d2: i64, top: i64) -> usize {
        let w = (2 * top + 1) as usize;
        (d1 + top) as usize * w + (d2 + top) as usize
    }

    /// Fourier coefficients `c_d = mean(s e^{−i d·θ})` for `|d_i| ≤ top` of the `m` real
    /// sample series `s[p·m + c]`, separably (first angle, then second): `[coef_at(d)·m + c]`.
    fn project(&self, s: &[f64], m: usize, top: i64) -> Vec<Complex64> {
        let (n1, n2) = (self.n1, self.n2);
        let w = (2 * top + 1) as usize;
        // Along the second angle: t[(p1·w + d2)·m + c].
        let mut t = vec![Complex64::ZERO; n1 * w * m];
        for p1 in 0..n1 {
            for (i2, d2) in (-top..=top).enumerate() {
                for p2 in 0..n2 {
                    let e = self.e(1, -d2, p2);
                    let row = &s[(p1 * n2 + p2) * m..(p1 * n2 + p2 + 1) * m];
                    for (c, v) in row.iter().enumerate() {
                        t[(p1 * w + i2) * m + c] += e * v;
                    }
                }
            }
        }
        let mut out = vec![Complex64::ZERO; w * w * m];
        let norm = 1.0 / (n1 * n2) as f64;
        for (i1, d1) in (-top..=top).enumerate() {
            for p1 in 0..n1 {
                let e = self.e(0, -d1, p1) * norm;
                for i2 in 0..w {
                    for c in 0..m {
                        out[(i1 * w + i2) * m + c] += e * t[(p1 * w + i2) * m + c];
                    }
                }
            }
        }
        out
    }

    /// `∂R/∂u` from the samples `vars` of the variables (see the module docs).
    fn jacobian(&self, vars: &[f64], (wd, w2): (f64, f64), jac: &mut [f64]) {
        let nm = self.model.n_modes();
        let nv = self.model.n_vars();
        let nl = self.idx.len();
        let nu = self.n();
        let np = self.n1 * self.n2;
        let mut pows = vec![0.0; self.model.pow_len()];
        let mut js = vec![0.0; np * nm * nv];
        for p in 0..np {
            self.model.force_jacobian(
                &vars[p * nv..(p + 1) * nv],
                &mut pows,
                &mut js[p * nm * nv..(p + 1) * nm * nv],
            );
        }
        let top = 2 * self.h;
        let c = self.project(&js, nm * nv, top);
        jac.iter_mut().for_each(|v| *v = 0.0);
        let omega = |l: usize| self.idx[l].0 as f64 * wd + self.idx[l].1 as f64 * w2;
        for n in 0..nm {
            for (r, &(a1, a2)) in self.idx.iter().enumerate() {
                let half = if (a1, a2) == (0, 0) { 1.0 } else { 2.0 };
                let row = 2 * (n * nl + r);
                for m in 0..nm {
                    for (l, &(b1, b2)) in self.idx.iter().enumerate() {
                        let ol = Complex64::new(0.0, omega(l));
                        let at = |d1: i64, d2: i64, var: usize| {
                            c[self.coef_at(d1, d2, top) * nm * nv + n * nv + var]
                        };
                        let vel = |d1: i64, d2: i64| {
                            if nv > nm {
                                at(d1, d2, nm + m)
                            } else {
                                Complex64::ZERO
                            }
                        };
                        // The coefficient of e^{ik'θ} is twice c (once at k' = 0): the
                        // derivative of Σ-convention [f]_{k'} = half·c_{k'}, and δq = (δX e + c.c.)/2.
                        let s = 0.5 * half;
                        let p = s * (at(a1 - b1, a2 - b2, m) + ol * vel(a1 - b1, a2 - b2));
                        let q = s * (at(a1 + b1, a2 + b2, m) - ol * vel(a1 + b1, a2 + b2));
                        let cx = p + q;
                        let cy = Complex64::i() * (p - q);
                        let col = 2 * (m * nl + l);
                        jac[row * nu + col] += cx.re;
                        jac[(row + 1) * nu + col] += cx.im;
                        jac[row * nu + col + 1] += cy.re;
                        jac[(row + 1) * nu + col + 1] += cy.im;
                    }
                }
                // Linear part, and the offset line's decoupled imaginary row.
                let (w, g) = (self.model.omega(n), self.model.gamma(n));
                let o = omega(r);
                let lin = Complex64::new(w * w - o * o, o * g);
                if (a1, a2) == (0, 0) {
                    jac[row * nu + row] += w * w;
                    for col in 0..nu {
                        jac[(row + 1) * nu + col] = 0.0;
                    }
                    jac[(row + 1) * nu + row + 1] = w * w;
                } else {
                    jac[row * nu + row] += lin.re;
                    jac[row * nu + row + 1] -= lin.im;
                    jac[(row + 1) * nu + row] += lin.im;
                    jac[(row + 1) * nu + row + 1] += lin.re;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Term;

    /// A two-mode model with cubic, quadratic and velocity terms.
    fn model() -> NumericModel {
        let t = |eq, coef, factors| Term { eq, coef, factors };
        NumericModel::new(
            vec!["a".into(), "b".into()],
            vec![1000.0, 1300.0],
            vec![100.0, 80.0],
            vec![
                t(0, 3e13, vec![(0, 3)]),
                t(0, 2e8, vec![(0, 1), (1, 1)]),
                t(1, 1e12, vec![(0, 2), (3, 1)]),
                t(1, -0.5, vec![(3, 1)]),
                t(0, 5e9, vec![(0, 2)]),
            ],
        )
        .expect("model")
    }

    #[test]
    fn the_analytic_jacobian_equals_finite_differences() {
        let m = model();
        let force = [Complex64::new(40.0, 5.0), Complex64::new(-3.0, 1.0)];
        let t = Torus::new(&m, &force, 4).expect("torus");
        let nu = t.n();
        let u: Vec<f64> = (0..nu)
            .map(|i| 1e-5 * ((i as f64 * 0.731).sin() + 0.2) / (1.0 + i as f64 / 8.0))
            .collect();
        let w = (TAU * 1010.0, TAU * 1290.0);
        let mut r0 = vec![0.0; nu];
        let mut jac = vec![0.0; nu * nu];
        t.eval(&u, w, &mut r0, Some(&mut jac));
        let mut worst = 0.0f64;
        let scale = jac.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for col in 0..nu {
            let h = 1e-12;
            let (mut up, mut dn) = (u.clone(), u.clone());
            up[col] += h;
            dn[col] -= h;
            let (mut ru, mut rd) = (vec![0.0; nu], vec![0.0; nu]);
            t.eval(&up, w, &mut ru, None);
            t.eval(&dn, w, &mut rd, None);
            for row in 0..nu {
                let fd = (ru[row] - rd[row]) / (2.0 * h);
                worst = worst.max((fd - jac[row * nu + col]).abs() / scale);
            }
        }
        assert!(worst < 1e-7, "worst {worst:e}");
    }

    #[test]
    fn a_linear_oscillator_with_two_tones_off_the_drive_has_only_the_drive_line() {
        // No nonlinear term: the (1,0) line is the Lorentzian, every other line zero.
        let m = NumericModel::new(vec!["q".into()], vec![1000.0], vec![100.0], vec![]).expect("m");
        let t = Torus::new(&m, &[Complex64::new(2.0, 0.0)], 3).expect("torus");
        let nu = t.n();
        let mut jac = vec![0.0; nu * nu];
        let mut r = vec![0.0; nu];
        let w = (TAU * 990.0, TAU * 1003.0);
        t.eval(&vec![0.0; nu], w, &mut r, Some(&mut jac));
        let mut lu = crate::linalg::DenseLu::dense(nu);
        assert!(lu.factor(&jac));
        r.iter_mut().for_each(|v| *v = -*v);
        lu.solve(&mut r);
        let l = t.line((1, 0)).expect("drive line");
        let want = crate::linear_response(m.omega(0), m.gamma(0), 990.0, Complex64::new(2.0, 0.0));
        let got = Complex64::new(r[2 * l], r[2 * l + 1]);
        assert!((got - want).norm() < 1e-12 * want.norm(), "{got} {want}");
    }
}
