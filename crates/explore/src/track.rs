//! Predictor–corrector path tracking of a linear homotopy
//! `H(x, t) = (1 − t) F(x) + t γ G(x)` from `t = 1` (a solution of `G`) to `t = 0` (one of
//! `F`), in complex arithmetic: a fourth-order Runge–Kutta predictor on the Davidenko equation
//! `dx/dt = −H_x⁻¹ H_t`, Newton as corrector, the step halved when the corrector does not
//! converge in three iterations and doubled after three good steps in a row.
//!
//! With a random complex `γ` (the "gamma trick"), the path avoids the finitely many `t` where
//! `H` is singular with probability one, so every isolated solution of `F` is the end of a
//! path from a solution of `G` (total-degree homotopy), or of one of a neighbouring `F₀` with
//! the same number of solutions (parameter homotopy).

use crate::system::{norm, solve_in_place, PolySystem, ONE, ZERO};
use num_complex::Complex64;

/// Largest step in `t`.
const H_MAX: f64 = 0.1;
/// Smallest step in `t` before the path is given up.
const H_MIN: f64 = 1e-11;
/// Corrector tolerance during tracking (relative to `1 + ‖x‖`).
const TRACK_TOL: f64 = 1e-8;
/// Most steps on one path.
const MAX_STEPS: usize = 1500;

/// `H(x, t) = (1 − t) F(x) + t γ G(x)`, and, when `patch` is given, a last equation
/// `patch · x − 1 = 0` (projective coordinates on a random affine chart).
pub(crate) struct Linear<'a> {
    pub target: &'a PolySystem,
    pub start: &'a PolySystem,
    pub gamma: Complex64,
    pub patch: Option<&'a [Complex64]>,
}

/// Buffers of one path.
pub(crate) struct Work {
    n: usize,
    pw_f: Vec<Complex64>,
    pw_g: Vec<Complex64>,
    f: Vec<Complex64>,
    g: Vec<Complex64>,
    jf: Vec<Complex64>,
    jg: Vec<Complex64>,
    hx: Vec<Complex64>,
    ht: Vec<Complex64>,
    h: Vec<Complex64>,
}

/// How a path ended.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum PathEnd {
    /// Reached `t = 0` with the corrector converged.
    Reached(Vec<Complex64>),
    /// Stopped at `t` (the step vanished or the step budget was spent): near a singular
    /// end (a solution at infinity, or a multiple root) or a failure.
    Stopped { t: f64, x: Vec<Complex64> },
}

impl Linear<'_> {
    pub fn work(&self) -> Work {
        let n = self.target.n;
        Work {
            n,
            pw_f: self.target.scratch(),
            pw_g: self.start.scratch(),
            f: vec![ZERO; n],
            g: vec![ZERO; n],
            jf: vec![ZERO; n * n],
            jg: vec![ZERO; n * n],
            hx: vec![ZERO; n * n],
            ht: vec![ZERO; n],
            h: vec![ZERO; n],
        }
    }

    /// `w.h = H(x, t)`, `w.hx = H_x`, `w.ht = H_t`.
    fn eval(&self, x: &[Complex64], t: f64, w: &mut Work) {
        let n = w.n;
        let m = self.target.eqs.len();
        self.target
            .eval(x, &mut w.f[..m], &mut w.jf[..m * n], &mut w.pw_f);
        self.start
            .eval(x, &mut w.g[..m], &mut w.jg[..m * n], &mut w.pw_g);
        let a = Complex64::new(1.0 - t, 0.0);
        let b = self.gamma * t;
        for i in 0..m {
            w.h[i] = a * w.f[i] + b * w.g[i];
            w.ht[i] = self.gamma * w.g[i] - w.f[i];
            for j in 0..n {
                w.hx[i * n + j] = a * w.jf[i * n + j] + b * w.jg[i * n + j];
            }
        }
        if let Some(p) = self.patch {
            let mut s = -ONE;
            for j in 0..n {
                s += p[j] * x[j];
                w.hx[m * n + j] = p[j];
            }
            w.h[m] = s;
            w.ht[m] = ZERO;
        }
    }

    /// The tangent `dx/dt = −H_x⁻¹ H_t` at `(x, t)` into `out`; `false` when `H_x` is singular.
    fn tangent(&self, x: &[Complex64], t: f64, w: &mut Work, out: &mut [Complex64]) -> bool {
        self.eval(x, t, w);
        for (o, v) in out.iter_mut().zip(&w.ht) {
            *o = -v;
        }
        solve_in_place(&mut w.hx, out, w.n)
    }

    /// Newton on `H(·, t)` from `x` (in place), at most `iters` steps; converged when the last
    /// step is below `tol · (1 + ‖x‖)`.
    pub fn correct(
        &self,
        x: &mut [Complex64],
        t: f64,
        w: &mut Work,
        iters: usize,
        tol: f64,
    ) -> bool {
        let mut dx = vec![ZERO; w.n];
        let mut last = f64::INFINITY;
        for _ in 0..iters {
            self.eval(x, t, w);
            for (d, v) in dx.iter_mut().zip(&w.h) {
                *d = -v;
            }
            if !solve_in_place(&mut w.hx, &mut dx, w.n) {
                return false;
            }
            let s = norm(&dx);
            if !s.is_finite() || s > 2.0 * last {
                return false;
            }
            for (xi, d) in x.iter_mut().zip(&dx) {
                *xi += d;
            }
            last = s;
            if s <= tol * (1.0 + norm(x)) {
                return true;
            }
        }
        false
    }

    /// Tracks the path from `x0` at `t = 1` to `t = 0`.
    pub fn track(&self, x0: &[Complex64], w: &mut Work) -> PathEnd {
        let n = w.n;
        let mut x = x0.to_vec();
        let (mut k1, mut k2, mut k3, mut k4) =
            (vec![ZERO; n], vec![ZERO; n], vec![ZERO; n], vec![ZERO; n]);
        let mut y = vec![ZERO; n];
        let mut t = 1.0f64;
        let mut h = 0.05f64;
        let mut good = 0;
        for _ in 0..MAX_STEPS {
            if t <= 0.0 {
                break;
            }
            let dt = h.min(t);
            let t1 = if dt >= t { 0.0 } else { t - dt };
            let ok = self.tangent(&x, t, w, &mut k1)
                && rk_stage(&x, &k1, -0.5 * dt, &mut y)
                && self.tangent(&y, t - 0.5 * dt, w, &mut k2)
                && rk_stage(&x, &k2, -0.5 * dt, &mut y)
                && self.tangent(&y, t - 0.5 * dt, w, &mut k3)
                && rk_stage(&x, &k3, -dt, &mut y)
                && self.tangent(&y, t1, w, &mut k4);
            let mut moved = false;
            if ok {
                for i in 0..n {
                    y[i] = x[i] - (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) * (dt / 6.0);
                }
                moved = self.correct(&mut y, t1, w, 3, TRACK_TOL);
            }
            if moved {
                x.copy_from_slice(&y);
                t = t1;
                good += 1;
                if good >= 3 {
                    h = (2.0 * h).min(H_MAX);
                    good = 0;
                }
            } else {
                good = 0;
                h *= 0.5;
                if h < H_MIN {
                    return PathEnd::Stopped { t, x };
                }
            }
        }
        if t > 0.0 {
            return PathEnd::Stopped { t, x };
        }
        PathEnd::Reached(x)
    }
}

/// `y = x + s·k`; `false` when not finite.
fn rk_stage(x: &[Complex64], k: &[Complex64], s: f64, y: &mut [Complex64]) -> bool {
    let mut fin = true;
    for i in 0..x.len() {
        y[i] = x[i] + k[i] * s;
        fin &= y[i].re.is_finite() && y[i].im.is_finite();
    }
    fin
}
