//! The Jacobian of the sampled forces of terms without jumps (`abs`), from the spectra of their
//! pointwise derivatives.
//!
//! With `g(θ) = ∂f_n/∂x` sampled on the grid and `Ĝ(κ) = (1/N) Σ_j g_j e^{−iκ·θ_j}`, the
//! projected force `F_o = (2/N) Σ_j f_j e^{−ik_o·θ_j}` moves with the amplitude `X_r` of a
//! position (`x = Re(X_r e^{ik_r·θ})`) as
//!
//! ```text
//! ∂F_o/∂Re X_r = Ĝ(k_o − k_r) + Ĝ(k_o + k_r),   ∂F_o/∂Im X_r = i (Ĝ(k_o − k_r) − Ĝ(k_o + k_r)),
//! ```
//!
//! and of a velocity (`v = Re(iΩ_r X_r e^{ik_r·θ})`) as `iΩ_r (Ĝ₋ − Ĝ₊)` and `−Ω_r (Ĝ₋ + Ĝ₊)`;
//! half of that on the static line. So the Jacobian needs `Ĝ` at the distinct sums and
//! differences of the lines' vectors only: `pairs × κ × N` operations instead of central
//! differences' `4 R² N`. The derivative of `|x|x` (`2|x|`) is continuous, so the sampled
//! derivative is the derivative of the sampled force up to the same aliasing; `sign` and `tanh`
//! keep central differences (the pointwise derivative of a jump misses its delta).

use super::{Grid, RoughAft};
use num_complex::Complex64;

/// The tables of the spectral Jacobian, allocated once.
#[derive(Debug, Clone)]
pub(super) struct SpectralJacobian {
    /// Distinct `(equation, variable)` pairs with a derivative (variables: modes, then
    /// velocities; the pump is not an unknown).
    pairs: Vec<(usize, usize)>,
    /// Distinct vectors `κ`, `[c·d + i]`.
    kappa: Vec<i64>,
    /// Index in `kappa` of `k_o − k_r` and `k_o + k_r`, `[o·R + r]`.
    minus: Vec<u32>,
    plus: Vec<u32>,
    /// `e^{−2πi m/N_i}` per axis.
    roots: Vec<Vec<Complex64>>,
    /// Samples per axis.
    dims: Vec<usize>,
    /// `g` of each pair at each sample, `[p·N + j]`.
    g: Vec<f64>,
    /// `Ĝ` of each pair at each `κ`, `[p·K + c]`.
    spectra: Vec<Complex64>,
    /// A gradient row over the variables (scratch).
    row: Vec<f64>,
    /// The variables at one sample (scratch).
    x: Vec<f64>,
    /// The outer axes' phase of each κ for one row (scratch).
    outer: Vec<Complex64>,
}

impl SpectralJacobian {
    /// The tables for `terms` (equation, variables) on `grid` with `nr` lines, `nm` modes,
    /// `nv` variables.
    pub(super) fn new(aft: &RoughAft, grid: &Grid) -> Self {
        let (nm, nr, d) = (aft.nm, aft.nr, grid.axes());
        let mut pairs = Vec::new();
        for t in &aft.terms {
            let vars = t
                .factors
                .iter()
                .map(|&(v, _)| v)
                .chain(t.nonsmooth.iter().map(|(f, _)| f.var().index()));
            for v in vars.filter(|&v| v < 2 * nm) {
                if !pairs.contains(&(t.eq, v)) {
                    pairs.push((t.eq, v));
                }
            }
        }
        let mut kappa: Vec<i64> = Vec::new();
        let mut index = |k: Vec<i64>| -> u32 {
            let c = (0..kappa.len() / d.max(1)).find(|&c| kappa[c * d..(c + 1) * d] == k[..]);
            c.unwrap_or_else(|| {
                kappa.extend_from_slice(&k);
                kappa.len() / d - 1
            }) as u32
        };
        let (mut minus, mut plus) = (vec![0u32; nr * nr], vec![0u32; nr * nr]);
        for o in 0..nr {
            for r in 0..nr {
                let (ko, kr) = (&grid.k[o * d..(o + 1) * d], &grid.k[r * d..(r + 1) * d]);
                minus[o * nr + r] = index(ko.iter().zip(kr).map(|(a, b)| a - b).collect());
                plus[o * nr + r] = index(ko.iter().zip(kr).map(|(a, b)| a + b).collect());
            }
        }
        let nk = kappa.len() / d.max(1);
        let roots = grid
            .dims
            .iter()
            .map(|&n| {
                (0..n)
                    .map(|m| {
                        Complex64::from_polar(1.0, -std::f64::consts::TAU * m as f64 / n as f64)
                    })
                    .collect()
            })
            .collect();
        Self {
            g: vec![0.0; pairs.len() * aft.nt],
            spectra: vec![Complex64::new(0.0, 0.0); pairs.len() * nk],
            row: vec![0.0; aft.nv],
            x: vec![0.0; aft.nv],
            outer: vec![Complex64::new(0.0, 0.0); nk],
            pairs,
            kappa,
            minus,
            plus,
            roots,
            dims: grid.dims.clone(),
        }
    }

    /// `Ĝ` of every pair at every `κ` from `g`.
    fn transform(&mut self) {
        let d = self.dims.len();
        let nk = self.outer.len();
        let last = self.dims[d - 1];
        let rows = self.g.len() / self.pairs.len().max(1) / last;
        let nt = rows * last;
        self.spectra.fill(Complex64::new(0.0, 0.0));
        let mut idx = vec![0usize; d];
        for row in 0..rows {
            // The outer axes' phase of each κ at this row.
            for c in 0..nk {
                let mut z = Complex64::new(1.0, 0.0);
                for i in 0..d - 1 {
                    let n = self.dims[i] as i64;
                    z *= self.roots[i]
                        [(self.kappa[c * d + i] * idx[i] as i64).rem_euclid(n) as usize];
                }
                self.outer[c] = z;
            }
            for p in 0..self.pairs.len() {
                let g = &self.g[p * nt + row * last..p * nt + (row + 1) * last];
                for c in 0..nk {
                    let kl = self.kappa[c * d + d - 1].rem_euclid(last as i64) as usize;
                    let roots = &self.roots[d - 1];
                    let (mut acc, mut m) = (Complex64::new(0.0, 0.0), 0usize);
                    for &gj in g {
                        acc += roots[m] * gj;
                        m = (m + kl) & (last - 1);
                    }
                    self.spectra[p * nk + c] += self.outer[c] * acc;
                }
            }
            // Next row of the outer axes.
            for i in (0..d - 1).rev() {
                idx[i] += 1;
                if idx[i] < self.dims[i] {
                    break;
                }
                idx[i] = 0;
            }
        }
        let inv = 1.0 / nt as f64;
        self.spectra.iter_mut().for_each(|z| *z *= inv);
    }
}

impl RoughAft {
    /// Adds the spectral Jacobian of terms without jumps at `x` (see the module's text) to
    /// `jac` (row-major, `2·N·R` unknowns interleaved re/im) and marks `coupled`.
    pub(super) fn add_spectral_jacobian(
        &mut self,
        x: &[Complex64],
        pump: &[Complex64],
        jac: &mut [f64],
        coupled: &mut [bool],
    ) {
        self.synthesise(x, pump);
        let Some(mut sj) = self.spectral.take() else {
            return;
        };
        let (nm, nr, nt) = (self.nm, self.nr, self.nt);
        let mut xj = std::mem::take(&mut sj.x);
        for j in 0..nt {
            for (v, x) in xj.iter_mut().enumerate() {
                *x = self.xs[v * nt + j];
            }
            // One gradient per equation, shared by its consecutive pairs.
            let mut eq_done = usize::MAX;
            for (p, &(eq, v)) in sj.pairs.iter().enumerate() {
                if eq != eq_done {
                    sj.row.fill(0.0);
                    for t in self.terms.iter().filter(|t| t.eq == eq) {
                        t.add_gradient(&xj, &mut sj.row);
                    }
                    eq_done = eq;
                }
                sj.g[p * nt + j] = sj.row[v];
            }
        }
        sj.x = xj;
        sj.transform();
        let nu = 2 * nm * nr;
        let nk = sj.outer.len();
        let i = Complex64::new(0.0, 1.0);
        for (p, &(n, v)) in sj.pairs.iter().enumerate() {
            let (m, velocity) = (v % nm, v >= nm);
            coupled[n * nm + m] = true;
            for o in 0..nr {
                let half = if self.omega[o] <= std::f64::consts::TAU * crate::lattice::LINE_TOL_HZ {
                    0.5
                } else {
                    1.0
                };
                for r in 0..nr {
                    let gm = sj.spectra[p * nk + sj.minus[o * nr + r] as usize];
                    let gp = sj.spectra[p * nk + sj.plus[o * nr + r] as usize];
                    let (dre, dim) = if velocity {
                        let w = self.omega[r];
                        (i * w * (gm - gp), -w * (gm + gp))
                    } else {
                        (gm + gp, i * (gm - gp))
                    };
                    let (dre, dim) = (dre * half, dim * half);
                    let (row, col) = (2 * (n * nr + o), 2 * (m * nr + r));
                    jac[row * nu + col] += dre.re;
                    jac[(row + 1) * nu + col] += dre.im;
                    jac[row * nu + col + 1] += dim.re;
                    jac[(row + 1) * nu + col + 1] += dim.im;
                }
            }
        }
        self.spectral = Some(sj);
    }
}
