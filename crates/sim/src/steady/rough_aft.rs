//! Alternating frequency–time for the non-smooth terms on a lattice (issue 36).
//!
//! The signals are sampled on a grid (see [`grid`]): over one common period when the lattice's
//! lines are harmonics `k_r f_0` of one frequency, else on the torus of the drive's generators
//! (`θ_i = ω_i t`, each line a combination `k_r·ω`), whose average equals the time average of a
//! quasi-periodic signal. Each evaluation synthesises the modes, velocities and pump at the
//! `N` samples, `x_j = Σ_r Re(X_r e^{iφ_{j,r}})` with `φ_{j,r} = k_r·θ_j`, evaluates the
//! non-smooth terms there, and projects back onto the lines: `F_r = (2/N) Σ_j f_j
//! e^{−iφ_{j,r}}` (`F_0 = (1/N) Σ_j f_j` for the static line), the convention of the exact
//! spectral products (`x(t) = Σ_r Re(X_r e^{iΩ_r t})`).
//!
//! A non-smooth spectrum never ends, so some aliasing is always left: for `|x| x` (a jump in
//! the second derivative) the error falls like `N^{-3}` along each axis, far below 1e-9
//! relative at 4096 samples of one period (5e-8 at the 512 a model without jumps takes,
//! [`ROUGH_MIN_SAMPLES_SMOOTH`]), about 1e-8 with 128 samples per axis of a two-tone torus.
//! The sampling itself (synthesis, evaluation, projection) is [`GridSampler`], shared with the
//! identification's torus columns and `harmonid mix`. A jump (`sign`) or a near-jump (`tanh` of a small scale) is evaluated as its average
//! over each sample's cell along the grid's diagonal (the time axis of one period; on a torus
//! the straight line `(1, …, 1)` in samples, close to the flow `θ = ω t` of tones near one
//! frequency), the variable interpolated linearly across the cell (`sign`: the crossing's
//! position; `tanh(x/c)`: `c·ln cosh(x/c)` differenced): the coefficients then move
//! continuously with the amplitudes, so Newton converges, and the error is `O(h^2)` in the cell
//! width `h` (about 2e-7 relative for Coulomb friction at 4096 samples of one period).
//!
//! The Jacobian of these terms is taken by central differences of the projected forces in
//! each real unknown (the pointwise derivative of `sign` is zero, which the harmonic
//! coefficients' derivative is not).

mod grid;
mod jacobian;
mod sampler;

use super::{HbSettings, HbSolver, HbStatus, SteadyState};
use crate::rough::RoughTerm;
use crate::{Excitation, NumericModel, SimError};
pub use grid::Grid;
pub use grid::{ROUGH_MIN_SAMPLES, ROUGH_MIN_SAMPLES_SMOOTH};
use jacobian::SpectralJacobian;
use num_complex::Complex64;
pub use sampler::GridSampler;
use std::f64::consts::TAU;

/// The non-smooth terms of a model on one lattice: the sampler and buffers, allocated once.
#[derive(Debug, Clone)]
pub(crate) struct RoughAft {
    terms: Vec<RoughTerm>,
    nm: usize,
    nr: usize,
    nv: usize,
    nt: usize,
    /// The grid's sampler (synthesis, evaluation, projection).
    sampler: GridSampler,
    /// Angular frequency of each line, rad/s.
    omega: Vec<f64>,
    /// Samples of the variables, `[v·N + j]`.
    xs: Vec<f64>,
    /// Forces at the samples, `[n·N + j]`.
    fs: Vec<f64>,
    /// Projected forces for differences, `[n·R + r]`.
    plus: Vec<Complex64>,
    minus: Vec<Complex64>,
    /// The Jacobian from the derivatives' spectra, for terms without jumps (`None`: central
    /// differences).
    spectral: Option<SpectralJacobian>,
}

impl RoughAft {
    /// The set-up for `model`'s non-smooth terms on `lattice` (Hz, sorted) under `drive`'s
    /// generators, or `None` for a model without. Errors: lines that are neither harmonics of
    /// one frequency nor combinations of the generators, or a torus grid too large.
    pub(crate) fn new(
        model: &NumericModel,
        drive: &Excitation,
        lattice: &[f64],
    ) -> Result<Option<Self>, SimError> {
        if !model.has_nonsmooth() {
            return Ok(None);
        }
        // Without a jump the aliasing of one period falls like N^-3: fewer samples suffice.
        let least = if model.rough_terms().iter().any(RoughTerm::has_jump) {
            ROUGH_MIN_SAMPLES
        } else {
            ROUGH_MIN_SAMPLES_SMOOTH
        };
        let grid = Grid::choose_with(&drive.generators_hz(), lattice, least).map_err(|why| {
            SimError::NonSmooth {
                what: "harmonic balance",
                terms: names(model),
                why: format!(
                    "they are evaluated by sampling the signals, and the lattice ({}) has no grid: {why}",
                    line_list(lattice)
                ),
            }
        })?;
        Ok(Some(Self::with_grid(model, &grid, lattice)))
    }

    /// The set-up on a given grid (whose lines are `lattice`'s, Hz).
    pub(crate) fn with_grid(model: &NumericModel, grid: &Grid, lattice: &[f64]) -> Self {
        let sampler = GridSampler::new(grid);
        let nt = sampler.samples();
        let nm = model.n_modes();
        let nv = model.n_vars();
        let mut aft = Self {
            terms: model.rough_terms().to_vec(),
            nm,
            nr: lattice.len(),
            nv,
            nt,
            sampler,
            omega: lattice.iter().map(|&f| TAU * f).collect(),
            xs: vec![0.0; nt * nv],
            fs: vec![0.0; nt * nm],
            plus: vec![Complex64::new(0.0, 0.0); nm * lattice.len()],
            minus: vec![Complex64::new(0.0, 0.0); nm * lattice.len()],
            spectral: None,
        };
        if !aft.has_jump() {
            aft.spectral = Some(SpectralJacobian::new(&aft, grid));
        }
        aft
    }

    /// Whether a term holds a jump (`sign`) or a near-jump (`tanh`).
    pub(crate) fn has_jump(&self) -> bool {
        self.terms.iter().any(RoughTerm::has_jump)
    }

    /// Sets new coefficients (same terms).
    pub(crate) fn set_terms(&mut self, model: &NumericModel) {
        self.terms = model.rough_terms().to_vec();
    }

    /// Samples the modes (`x`, `[n·R + r]`), their velocities and the pump (`pump`, `R`
    /// lines, empty without pump terms) over the grid into `xs`.
    fn synthesise(&mut self, x: &[Complex64], pump: &[Complex64]) {
        let (nm, nr, nv, nt) = (self.nm, self.nr, self.nv, self.nt);
        self.xs.fill(0.0);
        let (q, rest) = self.xs.split_at_mut(nm * nt);
        for n in 0..nm {
            let qn = &mut q[n * nt..(n + 1) * nt];
            for r in 0..nr {
                let z = x[n * nr + r];
                if nv > nm {
                    let vn = &mut rest[n * nt..(n + 1) * nt];
                    self.sampler.add_line(r, z, qn, Some((self.omega[r], vn)));
                } else {
                    self.sampler.add_line(r, z, qn, None);
                }
            }
        }
        if nv > 2 * nm && !pump.is_empty() {
            let p = &mut self.xs[2 * nm * nt..(2 * nm + 1) * nt];
            for (r, &z) in pump.iter().enumerate().take(nr) {
                self.sampler.add_line(r, z, p, None);
            }
        }
    }

    /// The forces of the terms at every sample (`fs`), from `xs`.
    fn evaluate(&mut self) {
        let nt = self.nt;
        self.fs.fill(0.0);
        for t in &self.terms {
            let out = &mut self.fs[t.eq * nt..(t.eq + 1) * nt];
            self.sampler
                .add_term(t.coef, &t.factors, &t.nonsmooth, &self.xs, out);
        }
    }

    /// Projects `fs` onto the lines into `out` (`[n·R + r]`), added when `add`.
    fn project(&self, out: &mut [Complex64], add: bool) {
        let (nm, nr, nt) = (self.nm, self.nr, self.nt);
        for n in 0..nm {
            let f = &self.fs[n * nt..(n + 1) * nt];
            for r in 0..nr {
                let z = self.sampler.coefficient(r, f);
                if add {
                    out[n * nr + r] += z;
                } else {
                    out[n * nr + r] = z;
                }
            }
        }
    }

    /// Adds the non-smooth terms' forces on the lines at amplitudes `x` to `out`.
    pub(crate) fn add_forces(
        &mut self,
        x: &[Complex64],
        pump: &[Complex64],
        out: &mut [Complex64],
    ) {
        self.synthesise(x, pump);
        self.evaluate();
        self.project(out, true);
    }

    /// The lines of each term with coefficient 1 at amplitudes `x`: `out[t·R + r]`, for
    /// sensitivities with respect to the parameters (`∂R/∂θ = Σ_t ∂b_t/∂θ · [term_t]_r`).
    pub(crate) fn term_lines(
        &mut self,
        x: &[Complex64],
        pump: &[Complex64],
        out: &mut [Complex64],
    ) {
        self.synthesise(x, pump);
        let (nr, nt) = (self.nr, self.nt);
        let f = &mut self.fs[..nt];
        for (t, term) in self.terms.iter().enumerate() {
            f.fill(0.0);
            self.sampler
                .add_term(1.0, &term.factors, &term.nonsmooth, &self.xs, f);
            for r in 0..nr {
                out[t * nr + r] = self.sampler.coefficient(r, f);
            }
        }
    }

    /// Adds the Jacobian of the projected forces `∂(Re F, Im F)/∂(Re X, Im X)` at `x` to
    /// `jac` (row-major, `2·N·R` unknowns interleaved re/im, `[n·R + r]` order), and marks the
    /// coupled `(equation, mode)` blocks in `coupled`: from the spectra of the pointwise
    /// derivatives for terms without jumps (`jacobian.rs`), else by central differences.
    pub(crate) fn add_jacobian(
        &mut self,
        x: &[Complex64],
        pump: &[Complex64],
        jac: &mut [f64],
        coupled: &mut [bool],
    ) {
        if self.spectral.is_some() {
            self.add_spectral_jacobian(x, pump, jac, coupled);
        } else {
            self.add_difference_jacobian(x, pump, jac, coupled);
        }
    }

    /// [`RoughAft::add_jacobian`] by central differences of the projected forces in each real
    /// unknown.
    fn add_difference_jacobian(
        &mut self,
        x: &[Complex64],
        pump: &[Complex64],
        jac: &mut [f64],
        coupled: &mut [bool],
    ) {
        let (nm, nr) = (self.nm, self.nr);
        let nu = 2 * nm * nr;
        self.synthesise(x, pump);
        let scale = x.iter().map(|z| z.norm()).fold(0.0, f64::max).max(1e-15);
        let h = 1e-6 * scale;
        for m in 0..nm {
            for r in 0..nr {
                for part in 0..2 {
                    // The samples of mode m (and its velocity) move by ±h times the line's
                    // cosine (Re) or −sine (Im).
                    let col = 2 * (m * nr + r) + part;
                    for (sgn, which) in [(1.0, true), (-1.0, false)] {
                        self.shift(m, r, part, sgn * h);
                        self.evaluate();
                        self.shift(m, r, part, -sgn * h);
                        let mut buf = if which {
                            std::mem::take(&mut self.plus)
                        } else {
                            std::mem::take(&mut self.minus)
                        };
                        self.project(&mut buf, false);
                        if which {
                            self.plus = buf;
                        } else {
                            self.minus = buf;
                        }
                    }
                    for n in 0..nm {
                        let mut any = false;
                        for o in 0..nr {
                            let d = (self.plus[n * nr + o] - self.minus[n * nr + o]) / (2.0 * h);
                            let row = 2 * (n * nr + o);
                            jac[row * nu + col] += d.re;
                            jac[(row + 1) * nu + col] += d.im;
                            any |= d.re != 0.0 || d.im != 0.0;
                        }
                        if any {
                            coupled[n * nm + m] = true;
                        }
                    }
                }
            }
        }
    }

    /// Moves the samples of mode `m` (and its velocity) by `d` times line `r`'s basis
    /// function (`part` 0: `Re X`, 1: `Im X`).
    fn shift(&mut self, m: usize, r: usize, part: usize, d: f64) {
        let (nm, nv, nt) = (self.nm, self.nv, self.nt);
        let a = if part == 0 {
            Complex64::new(d, 0.0)
        } else {
            Complex64::new(0.0, d)
        };
        let (q, rest) = self.xs.split_at_mut(nm * nt);
        let qm = &mut q[m * nt..(m + 1) * nt];
        if nv > nm {
            let vm = &mut rest[m * nt..(m + 1) * nt];
            self.sampler.add_line(r, a, qm, Some((self.omega[r], vm)));
        } else {
            self.sampler.add_line(r, a, qm, None);
        }
    }
}

impl HbSolver {
    /// For a model with a jump (Coulomb friction): Newton at full drive from the linear
    /// response, `None` when it does not converge. The drive ramp cannot start there: at a
    /// small drive such a resonator sticks (no sliding state exists below the friction force),
    /// and its residual has no usable derivative at rest.
    pub(super) fn solve_from_linear(&mut self, settings: &HbSettings) -> Option<SteadyState> {
        if !self.rough.as_ref().is_some_and(RoughAft::has_jump) {
            return None;
        }
        for i in 0..self.x.len() {
            self.x[i] = self.force[i] / self.lin[i];
        }
        self.have_lu = false;
        let (ok, it, res) = self.newton(1.0, settings.tol, settings.max_iter);
        ok.then(|| {
            self.finish(
                HbStatus::Converged { iterations: it },
                res,
                0,
                false,
                Vec::new(),
            )
        })
    }
}

/// The lattice's lines for a message, the first eight and a count.
fn line_list(lattice: &[f64]) -> String {
    let mut out: Vec<String> = lattice.iter().take(8).map(|f| format!("{f} Hz")).collect();
    if lattice.len() > 8 {
        out.push(format!("... {} lines in all", lattice.len()));
    }
    out.join(", ")
}

fn names(model: &NumericModel) -> String {
    model
        .rough_terms()
        .iter()
        .map(|t| format!("{} in the equation of {}", t.name, model.mode_names[t.eq]))
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ModelValues;

    fn abs_model() -> NumericModel {
        let src = "mode q1, f = 10 kHz, Q = 1000\nparam kappa1, drag1\neom q1 += kappa1*abs(q1)*q1 + drag1*abs(d(q1))*d(q1)\n";
        let m = harmonid_model::parse_str(src, "test.hb").expect("parses");
        let mut v = ModelValues::default();
        v.parameters.insert("kappa1".into(), 3e13);
        v.parameters.insert("drag1".into(), 7e2);
        NumericModel::from_model(&m, &v).expect("numeric model")
    }

    fn forces(grid: &Grid, lattice: &[f64], x: &[Complex64]) -> Vec<Complex64> {
        let mut aft = RoughAft::with_grid(&abs_model(), grid, lattice);
        let mut out = vec![Complex64::new(0.0, 0.0); x.len()];
        aft.add_forces(x, &[], &mut out);
        out
    }

    #[test]
    fn spectral_jacobian_equals_central_differences_on_a_torus() {
        let g = [10_003.7, 10_011.2];
        let lattice = [
            2.0 * g[0] - g[1],
            g[0],
            g[1],
            2.0 * g[1] - g[0],
            2.0 * g[0] + g[1],
        ];
        let grid = Grid::choose(&g, &lattice).expect("a grid");
        assert_eq!(grid.axes(), 2);
        let x = [
            Complex64::new(3e-8, 1e-8),
            Complex64::new(0.7e-6, -0.4e-6),
            Complex64::new(-0.2e-6, 0.5e-6),
            Complex64::new(-2e-8, 4e-8),
            Complex64::new(1e-9, -3e-9),
        ];
        let nu = 2 * lattice.len();
        let mut aft = RoughAft::with_grid(&abs_model(), &grid, &lattice);
        let (mut a, mut b) = (vec![0.0; nu * nu], vec![0.0; nu * nu]);
        let mut coupled = [false];
        aft.add_jacobian(&x, &[], &mut a, &mut coupled);
        assert!(coupled[0]);
        aft.add_difference_jacobian(&x, &[], &mut b, &mut coupled);
        let big = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let worst = a
            .iter()
            .zip(&b)
            .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()));
        assert!(
            worst < 1e-6 * big,
            "worst {:e} of the largest entry",
            worst / big
        );
    }

    #[test]
    fn torus_grids_agree_with_one_period_on_harmonic_lattices() {
        // One tone and its harmonics 3 and 5: one period of 4096 samples against the torus
        // rule's 256 (32 per period of the 5th harmonic) and against a two-axis torus whose
        // second generator no line excites (its average over θ2 is trivial).
        let f = 10_003.7;
        let lattice = [f, 3.0 * f, 5.0 * f];
        let x = [
            Complex64::new(0.7e-6, -0.4e-6),
            Complex64::new(2e-8, 1e-8),
            Complex64::new(-3e-9, 0.0),
        ];
        let one = Grid::choose(&[f], &lattice).expect("a grid");
        assert_eq!(one.dims, vec![4096]);
        let reference = forces(&one, &lattice, &x);
        let coarse = Grid {
            dims: vec![256],
            k: vec![1, 3, 5],
        };
        let mut lat2 = lattice.to_vec();
        lat2.push(f * 1.37);
        let mut x2 = x.to_vec();
        x2.push(Complex64::new(0.0, 0.0));
        let two = Grid {
            dims: vec![256, 8],
            k: vec![1, 0, 3, 0, 5, 0, 0, 1],
        };
        let big = reference[0].norm();
        let a = forces(&coarse, &lattice, &x);
        let b = forces(&two, &lat2, &x2);
        for r in 0..3 {
            let (ea, eb) = ((a[r] - reference[r]).norm(), (b[r] - a[r]).norm());
            assert!(
                ea < 1e-6 * big,
                "line {r}: 256 vs 4096 samples {:e}",
                ea / big
            );
            assert!(eb < 1e-12 * big, "line {r}: two axes vs one {:e}", eb / big);
        }
        assert!(b[3].norm() < 1e-12 * big);
    }
}
