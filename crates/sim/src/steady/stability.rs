//! Stability of a steady state by Hill's method in slow-flow form.

use super::{HbSolver, Stability, SteadyState, MAX_MODES, Z};
use crate::linalg::coupled_parts;
use crate::{Excitation, NumericModel, SimError};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// How many times the flow's coupling scale a line's linear rate must exceed for the stability
/// check to condense it: eigenvalues then move by `~separation⁻²` of themselves (`1e-3`).
pub const CONDENSE_SEPARATION: f64 = 30.0;

impl HbSolver {
    /// Stability of the steady state `state` (amplitudes on this solver's lattice) by Hill's
    /// method in its slow-flow (first-order) form: with `X_{n,r}` slowly varying,
    /// `q̈` contributes `(2iΩ_r + γ_n) Ẋ_{n,r}` and the amplitudes obey
    /// `(2iΩ_r + γ_n) Ẋ = −R(X)`; the state is stable when every eigenvalue of the linearised
    /// flow `−(2iΩ + γ)⁻¹ ∂R/∂X` has a negative real part. The neglected `Ẍ` term is
    /// `O(λ/Ω)` relative, negligible for the high-Q resonators this crate is for (`Q ≫ 1`).
    /// Velocity terms also add `∂f/∂q̇ · Ẋ` to the flow's left side; like the linear damping
    /// beside `2iΩ`, that is a relative correction of the damping rate over `Ω`, neglected.
    ///
    /// The spectrum is that of the lines near their modes' resonances, with the far ones (the
    /// harmonics, the lines far below; [`CONDENSE_SEPARATION`]) condensed statically onto them:
    /// the Schur complement `J_NN − J_NF J_FF⁻¹ J_FN`, exact at `λ = 0` (folds) and within
    /// `~separation⁻²` of each eigenvalue elsewhere. The slow flow describes a line only where
    /// its offset from the resonance is small beside `Ω`; on the far lines it puts copies of the
    /// resonances' decay at rates up to `γ/4` instead of `γ/2`, which the whole spectrum would
    /// report as the slowest decay. And the cost falls from `~10 n³` (15 s for the 4 000
    /// unknowns of a four-tone, four-mode measurement) to one LU of the far block and the
    /// near block's spectrum (1 s).
    pub fn stability(&mut self, state: &SteadyState) -> Result<Stability, SimError> {
        self.slow_flow_stability(state, true)
    }

    /// The eigenvalues of the linearised slow flow at `state` that [`HbSolver::stability`]
    /// judges (1/s; the far lines condensed): `Re λ` the growth rates, `Im λ` the angular
    /// frequencies (rad/s) at which perturbations oscillate about the state, offset from the
    /// lines they sit on (a driven resonator's probe response peaks there, and a complex pair
    /// crossing `Re λ = 0` is a Hopf point). Conjugate pairs for a real flow.
    pub fn slow_flow_eigenvalues(
        &mut self,
        state: &SteadyState,
    ) -> Result<Vec<Complex64>, SimError> {
        self.slow_flow_spectrum(state, true)
    }

    /// [`HbSolver::stability`], on every line of the lattice when `condense` is false (the
    /// tests compare both).
    pub(super) fn slow_flow_stability(
        &mut self,
        state: &SteadyState,
        condense: bool,
    ) -> Result<Stability, SimError> {
        let growth = self
            .slow_flow_spectrum(state, condense)?
            .iter()
            .map(|z| z.re)
            .fold(f64::NEG_INFINITY, f64::max);
        let decay = (0..self.model.n_modes())
            .map(|n| 0.5 * self.model.gamma(n))
            .fold(f64::INFINITY, f64::min);
        Ok(Stability {
            stable: growth < 1e-6 * decay,
            growth_rate: growth,
            linear_decay_rate: decay,
        })
    }

    /// The largest growth rate (1/s) of the slow flow's block of the modes `modes` alone (this
    /// solver's indices), the far lines condensed: the spectrum of an idle block of a
    /// block-triangular Jacobian (modes a drive does not reach, [`super::ActiveModes`]), which
    /// no other block feeds.
    pub(super) fn part_growth(
        &mut self,
        state: &SteadyState,
        modes: &[usize],
    ) -> Result<f64, SimError> {
        Ok(self
            .slow_flow_spectrum_of(state, true, Some(modes))?
            .iter()
            .map(|z| z.re)
            .fold(f64::NEG_INFINITY, f64::max))
    }

    /// The slow flow's eigenvalues over every coupled part of the modes (see
    /// [`HbSolver::slow_flow_eigenvalues`]).
    fn slow_flow_spectrum(
        &mut self,
        state: &SteadyState,
        condense: bool,
    ) -> Result<Vec<Complex64>, SimError> {
        self.slow_flow_spectrum_of(state, condense, None)
    }

    /// [`HbSolver::slow_flow_spectrum`] over every coupled part, or over the one block of the
    /// modes `only`.
    fn slow_flow_spectrum_of(
        &mut self,
        state: &SteadyState,
        condense: bool,
        only: Option<&[usize]>,
    ) -> Result<Vec<Complex64>, SimError> {
        let nm = self.model.n_modes();
        let nr = self.lattice.len();
        self.load_state(state)?;
        self.assemble_jacobian();
        self.have_lu = false;
        let mut c = vec![Z; nm * nr];
        for n in 0..nm {
            let g = self.model.gamma(n);
            for (r, &f) in self.lattice.iter().enumerate() {
                c[n * nr + r] = Complex64::new(1.0, 0.0) / Complex64::new(g, 2.0 * TAU * f);
            }
        }
        // A = −C J with C the complex factors as real 2×2 blocks on the rows. C is diagonal
        // per mode, so A couples the modes as J does: modes J leaves uncoupled (an undriven
        // mode nothing forces) are blocks of their own, and the spectrum is the union of the
        // blocks' spectra (n³ → Σ nᵢ³).
        let mut parts: Vec<Vec<usize>> = Vec::new();
        coupled_parts(&self.coupled, nm, &mut [0; MAX_MODES], |n, first| {
            if first {
                parts.push(Vec::new());
            }
            if let Some(p) = parts.last_mut() {
                p.push(n);
            }
        });
        if let Some(modes) = only {
            parts = vec![modes.to_vec()];
        }
        let mut spectrum = Vec::new();
        for part in parts {
            let all: Vec<usize> = part.iter().flat_map(|&n| n * nr..(n + 1) * nr).collect();
            let (near, far) = if condense {
                self.far_lines(&all, &c)
            } else {
                (all.clone(), Vec::new())
            };
            // The slow flow on the near lines with the far ones condensed, or (nothing to
            // condense, or a singular far block) on every line.
            let (rows, j) = match self.schur_complement(&near, &far) {
                Some(s) => (near, s),
                None => {
                    let j = self.jacobian_block(&all, &all);
                    (all, j)
                }
            };
            let a = faer::Mat::<f64>::from_fn(j.nrows(), j.ncols(), |i, col| {
                let z = c[rows[i / 2]] * Complex64::new(j[(i & !1, col)], j[(i | 1, col)]);
                -if i % 2 == 0 { z.re } else { z.im }
            });
            if a.col_iter().any(|col| col.iter().any(|v| !v.is_finite())) {
                return Err(SimError::NonFiniteState);
            }
            let eig = a.eigenvalues().map_err(|_| SimError::NoEigenvalues)?;
            spectrum.extend(eig.iter().map(|z| Complex64::new(z.re, z.im)));
        }
        Ok(spectrum)
    }

    /// Splits the complex unknowns `unknowns` (`n·R + r`) of a coupled part into the lines the
    /// stability check keeps and those it condenses. Line `k` is far when
    /// - its linear slow-flow rate `|a_k| = |(ω_n² − Ω_r² + iΩ_rγ_n)/(γ_n + 2iΩ_r)|` (its
    ///   detuning from the resonance, for lines near it) exceeds [`CONDENSE_SEPARATION`] times
    ///   the flow's rate scale `σ`: the largest damping rate and nonlinear row sum of the flow
    ///   over the lines within half a resonance frequency of their mode's (where the slow flow
    ///   describes the motion; below, its `1/(2Ω)` makes rates of quasi-static lines look
    ///   large), and
    /// - its own nonlinear row sum in the Jacobian is below `|ω_n² − Ω_r² + iΩ_rγ_n|` by the same
    ///   factor, so eliminating it barely couples the near lines through it.
    ///
    /// The line nearest each mode's resonance is always kept.
    fn far_lines(&self, unknowns: &[usize], c: &[Complex64]) -> (Vec<usize>, Vec<usize>) {
        let nr = self.lattice.len();
        let nu = self.unknowns();
        // Each line's nonlinear row sum of the Jacobian (the pair of real rows, less the
        // linear diagonal block [[Re l, −Im l], [Im l, Re l]]).
        let coupling: Vec<f64> = unknowns
            .iter()
            .map(|&k| {
                let l = self.lin[k];
                let mut sum = 0.0;
                for (i, row) in [2 * k, 2 * k + 1].into_iter().enumerate() {
                    let row = &self.jac[row * nu..(row + 1) * nu];
                    let (d0, d1) = if i == 0 { (l.re, -l.im) } else { (l.im, l.re) };
                    sum += row.iter().map(|v| v.abs()).sum::<f64>();
                    sum += (row[2 * k] - d0).abs() - row[2 * k].abs();
                    sum += (row[2 * k + 1] - d1).abs() - row[2 * k + 1].abs();
                }
                sum
            })
            .collect();
        let in_band = |k: usize| {
            let f = self.model.omega(k / nr) / TAU;
            (self.lattice[k % nr] - f).abs() < 0.5 * f
        };
        let mut scale = 0.0_f64;
        let mut nearest = vec![usize::MAX; self.model.n_modes()];
        for (&k, &rho) in unknowns.iter().zip(&coupling) {
            let n = k / nr;
            scale = scale.max(self.model.gamma(n));
            if in_band(k) {
                scale = scale.max(c[k].norm() * rho);
            }
            let off = |k: usize| (self.lattice[k % nr] - self.model.omega(n) / TAU).abs();
            if nearest[n] == usize::MAX || off(k) < off(nearest[n]) {
                nearest[n] = k;
            }
        }
        let (mut near, mut far) = (Vec::new(), Vec::new());
        for (&k, &rho) in unknowns.iter().zip(&coupling) {
            let l = self.lin[k];
            let is_far = (l * c[k]).norm() > CONDENSE_SEPARATION * scale
                && CONDENSE_SEPARATION * rho < l.norm()
                && nearest[k / nr] != k;
            if is_far {
                far.push(k)
            } else {
                near.push(k)
            }
        }
        (near, far)
    }

    /// The Jacobian's real block of the complex unknowns `rows` × `cols` (2 × 2 per pair).
    fn jacobian_block(&self, rows: &[usize], cols: &[usize]) -> faer::Mat<f64> {
        let nu = self.unknowns();
        faer::Mat::from_fn(2 * rows.len(), 2 * cols.len(), |i, j| {
            self.jac[(2 * rows[i / 2] + i % 2) * nu + 2 * cols[j / 2] + j % 2]
        })
    }

    /// The Jacobian with the `far` lines condensed statically onto the `near` ones, the Schur
    /// complement `J_NN − J_NF J_FF⁻¹ J_FN`; `None` when there is nothing to condense or the far
    /// block is singular.
    ///
    /// Why this keeps the spectrum that matters: `λ` is an eigenvalue of the flow `−C J` when
    /// `det(−C_N S(λ)) = 0` with `S(λ) = J_NN − J_NF (J_FF + C_F⁻¹λ)⁻¹ J_FN`. For far lines
    /// `C_F⁻¹λ` is small beside `J_FF` (their rates exceed the coupling scale and so the
    /// physical growth and frequency offsets by [`CONDENSE_SEPARATION`]), so `S(λ) ≈ S(0)`:
    /// relative error `O(separation⁻²)`, and none at `λ = 0`, where folds are (`det J =
    /// det J_FF · det S(0)`). The far lines' own eigenvalues are copies of the near lines'
    /// shifted by lattice differences, which the slow flow represents only roughly (their
    /// offsets are not small beside `Ω`); they carry no growth of their own.
    fn schur_complement(&self, near: &[usize], far: &[usize]) -> Option<faer::Mat<f64>> {
        use faer::linalg::solvers::Solve;
        if far.is_empty() || near.is_empty() {
            return None;
        }
        let jff = self.jacobian_block(far, far);
        let x = jff.partial_piv_lu().solve(self.jacobian_block(far, near));
        let s = self.jacobian_block(near, near) - self.jacobian_block(near, far) * x;
        let finite = s.col_iter().all(|col| col.iter().all(|v| v.is_finite()));
        finite.then_some(s)
    }
}

/// Stability of `state`, a steady state of `model` under `drive` (solved on its own lattice),
/// by Hill's method in slow-flow form (see [`HbSolver::stability`]), on the modes the drive
/// reaches and the idle modes' own block ([`super::ReducedSolver::stability`]).
pub fn check_stability(
    model: &NumericModel,
    drive: &Excitation,
    state: &SteadyState,
) -> Result<Stability, SimError> {
    let mut solver =
        super::ReducedSolver::with_lattice(model, drive, state.lattice_hz.clone(), &[])?;
    solver.stability(state)
}
