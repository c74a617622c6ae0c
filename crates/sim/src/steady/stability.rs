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

    /// The largest growth rate (1/s) of the slow flow's blocks of the modes of each of `parts`
    /// alone (this solver's indices), the far lines condensed, from one assembly of the
    /// Jacobian: the spectra of idle blocks of a block-triangular Jacobian (modes a drive does
    /// not reach, [`super::ActiveModes`]), which no other block feeds. With `skip_proven`, as
    /// [`HbSolver::unproven_growth`].
    pub(super) fn parts_growth(
        &mut self,
        state: &SteadyState,
        parts: &[Vec<usize>],
        skip_proven: bool,
    ) -> Result<f64, SimError> {
        Ok(self
            .slow_flow_spectrum_of(state, true, Some(parts), skip_proven)?
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
        self.slow_flow_spectrum_of(state, condense, None, false)
    }

    /// The largest growth rate (1/s) over the coupled parts of the modes (or the one block of
    /// the modes `only`) that [`HbSolver::growth_bound`] does not prove decaying; `-∞` when it
    /// proves every one. Below [`HbSolver::stability`]'s threshold exactly when its verdict is
    /// stable: a proven part's eigenvalues all have `Re λ < 0`, and the others' are computed
    /// as it computes them.
    pub(super) fn unproven_growth(
        &mut self,
        state: &SteadyState,
        only: Option<&[Vec<usize>]>,
    ) -> Result<f64, SimError> {
        Ok(self
            .slow_flow_spectrum_of(state, true, only, true)?
            .iter()
            .map(|z| z.re)
            .fold(f64::NEG_INFINITY, f64::max))
    }

    /// [`HbSolver::slow_flow_spectrum`] over every coupled part, or over the blocks of the
    /// modes of each of `only`; with `skip_proven`, none for the parts (condensed) that
    /// [`HbSolver::growth_bound`] proves decaying.
    fn slow_flow_spectrum_of(
        &mut self,
        state: &SteadyState,
        condense: bool,
        only: Option<&[Vec<usize>]>,
        skip_proven: bool,
    ) -> Result<Vec<Complex64>, SimError> {
        let nr = self.lattice.len();
        self.load_state(state)?;
        self.assemble_jacobian();
        self.have_lu = false;
        let c = self.flow_factors();
        let parts = match only {
            Some(parts) => parts.to_vec(),
            None => self.mode_parts(),
        };
        let mut spectrum = Vec::new();
        for part in parts {
            let all: Vec<usize> = part.iter().flat_map(|&n| n * nr..(n + 1) * nr).collect();
            let (near, far) = if condense {
                self.far_lines(&all, &c)
            } else {
                (all.clone(), Vec::new())
            };
            if skip_proven && condense && self.growth_bound(&near, &far, &c) < 0.0 {
                continue;
            }
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

    /// The slow flow's factors `c_k = 1/(γ_n + 2iΩ_r)` of the lines (`k = n·R + r`): the flow
    /// is `A = −C J`, `C` acting on each row pair as the complex factor.
    fn flow_factors(&self) -> Vec<Complex64> {
        let nr = self.lattice.len();
        let mut c = vec![Z; self.model.n_modes() * nr];
        for n in 0..self.model.n_modes() {
            let g = self.model.gamma(n);
            for (r, &f) in self.lattice.iter().enumerate() {
                c[n * nr + r] = Complex64::new(1.0, 0.0) / Complex64::new(g, 2.0 * TAU * f);
            }
        }
        c
    }

    /// The modes the assembled Jacobian couples, part by part. `C` is diagonal per mode, so
    /// `A = −C J` couples the modes as `J` does: modes `J` leaves uncoupled (an undriven mode
    /// nothing forces) are blocks of their own, and the spectrum is the union of the blocks'
    /// spectra (`n³ → Σ nᵢ³`).
    fn mode_parts(&self) -> Vec<Vec<usize>> {
        let mut parts: Vec<Vec<usize>> = Vec::new();
        coupled_parts(
            &self.coupled,
            self.model.n_modes(),
            &mut [0; MAX_MODES],
            |n, first| {
                if first {
                    parts.push(Vec::new());
                }
                if let Some(p) = parts.last_mut() {
                    p.push(n);
                }
            },
        );
        parts
    }

    /// Per coupled part at `state`: [`HbSolver::growth_bound`] and the largest growth rate of
    /// the part's condensed flow, which it must not be below (the tests' check of the bound).
    #[cfg(test)]
    pub(super) fn bounds_and_growths(
        &mut self,
        state: &SteadyState,
    ) -> Result<Vec<(f64, f64)>, SimError> {
        self.load_state(state)?;
        self.assemble_jacobian();
        let (c, parts) = (self.flow_factors(), self.mode_parts());
        let nr = self.lattice.len();
        let mut out = Vec::new();
        for part in parts {
            self.load_state(state)?;
            self.assemble_jacobian();
            let all: Vec<usize> = part.iter().flat_map(|&n| n * nr..(n + 1) * nr).collect();
            let (near, far) = self.far_lines(&all, &c);
            let bound = self.growth_bound(&near, &far, &c);
            let growth = self.parts_growth(state, &[part], false)?;
            out.push((bound, growth));
        }
        Ok(out)
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

    /// An upper bound (1/s) on the growth rates `Re λ` of the slow flow on the lines `near`
    /// with the lines `far` condensed (the matrix [`HbSolver::stability`] takes the spectrum
    /// of), from norms of the Jacobian's blocks alone: no factorisation, no eigenvalues.
    /// `+∞` when it finds none (a far block it cannot prove regular, non-finite entries).
    ///
    /// Each line's diagonal block of `J` has a complex-linear part `l'_k` (the linear operator
    /// and the line's own nonlinear shift) and a rest; the flow is `−C J = D + E` with `D =
    /// diag(−c_k l'_k)` normal, so by Bauer–Fike every eigenvalue lies within `‖E‖₂` of some
    /// `−c_k l'_k`: `Re λ ≤ max_N Re(−c_k l'_k) + ‖E‖₂`. With far lines condensed, `E =
    /// −C_N R_NN + C_N J_NF J_FF⁻¹ J_FN` (`R` the rest of `J` beside `l'`), and `‖J_FF⁻¹‖₂ ≤
    /// 1/(min_F |l'_k| − ‖R_FF‖₂)`; each `‖X‖₂ ≤ √(‖X‖₁‖X‖_∞)`. A weakly driven block (the
    /// idle modes of most measurements, drives kept below their folds) is proven decaying
    /// with a fraction of the cost of its spectrum.
    fn growth_bound(&self, near: &[usize], far: &[usize], c: &[Complex64]) -> f64 {
        let mut re_d = f64::NEG_INFINITY;
        for &k in near {
            let d = -c[k] * self.line_part(k);
            if !d.re.is_finite() {
                return f64::INFINITY;
            }
            re_d = re_d.max(d.re);
        }
        let mut bound = re_d + self.norm2_bound(near, near, Some(c));
        if !far.is_empty() {
            let smallest = far
                .iter()
                .map(|&k| self.line_part(k).norm())
                .fold(f64::INFINITY, f64::min);
            let sigma = smallest - self.norm2_bound(far, far, None);
            if sigma.is_nan() || sigma <= 0.0 {
                return f64::INFINITY;
            }
            bound +=
                self.norm2_bound(near, far, Some(c)) * self.norm2_bound(far, near, None) / sigma;
        }
        if bound.is_nan() {
            f64::INFINITY
        } else {
            bound
        }
    }

    /// The complex-linear part `l'_k = p + iq` of the Jacobian's diagonal block of line `k`
    /// (the block `[[p, −q], [q, p]]` nearest to it).
    fn line_part(&self, k: usize) -> Complex64 {
        let nu = self.unknowns();
        let (top, bot) = (&self.jac[2 * k * nu..], &self.jac[(2 * k + 1) * nu..]);
        Complex64::new(
            0.5 * (top[2 * k] + bot[2 * k + 1]),
            0.5 * (bot[2 * k] - top[2 * k + 1]),
        )
    }

    /// `√(‖X‖₁‖X‖_∞) ≥ ‖X‖₂` of the Jacobian's real block `rows × cols` less each line's
    /// complex-linear diagonal part ([`HbSolver::line_part`]), its row pairs multiplied by
    /// `c_k` when `scale` is given; `+∞` when an entry is not finite.
    fn norm2_bound(&self, rows: &[usize], cols: &[usize], scale: Option<&[Complex64]>) -> f64 {
        let nu = self.unknowns();
        let mut col_sums = vec![0.0; 2 * cols.len()];
        let mut row_max = 0.0_f64;
        let mut finite = true;
        for &k in rows {
            let (top, bot) = (
                &self.jac[2 * k * nu..(2 * k + 1) * nu],
                &self.jac[(2 * k + 1) * nu..(2 * k + 2) * nu],
            );
            let own = self.line_part(k);
            let c = scale.map_or(Complex64::new(1.0, 0.0), |c| c[k]);
            let (mut sum_top, mut sum_bot) = (0.0, 0.0);
            for (jj, &m) in cols.iter().enumerate() {
                for e in 0..2 {
                    let col = 2 * m + e;
                    let (mut t, mut b) = (top[col], bot[col]);
                    if m == k {
                        // Less [[p, −q], [q, p]].
                        if e == 0 {
                            (t, b) = (t - own.re, b - own.im);
                        } else {
                            (t, b) = (t + own.im, b - own.re);
                        }
                    }
                    let (t, b) = (c.re * t - c.im * b, c.im * t + c.re * b);
                    finite &= t.is_finite() && b.is_finite();
                    sum_top += t.abs();
                    sum_bot += b.abs();
                    col_sums[2 * jj + e] += t.abs() + b.abs();
                }
            }
            row_max = row_max.max(sum_top).max(sum_bot);
        }
        let col_max = col_sums.iter().copied().fold(0.0, f64::max);
        if finite {
            (row_max * col_max).sqrt()
        } else {
            f64::INFINITY
        }
    }
}

/// Solvers [`check_stability`] keeps per thread for the next call (most recently used last).
const KEPT_STABILITY_SOLVERS: usize = 2;

thread_local! {
    /// The solvers of [`check_stability`]'s last calls on this thread.
    static STABILITY_SOLVERS: std::cell::RefCell<Vec<super::ReducedSolver>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// Stability of `state`, a steady state of `model` under `drive` (solved on its own lattice),
/// by Hill's method in slow-flow form (see [`HbSolver::stability`]), on the modes the drive
/// reaches and the idle modes' own block ([`super::ReducedSolver::stability`]).
///
/// A caller checking the same experiment on many devices (a planner's range, a simulation's
/// levels) would plan the lattice's products and allocate the solvers each time (a tenth of a
/// ten-mode plan went there): the solvers of the last `KEPT_STABILITY_SOLVERS` (2) calls are
/// kept per thread and given the new values ([`super::ReducedSolver::set_values`]) when the
/// lattice, the tones and the model's terms are theirs. The verdict is the fresh solver's
/// (a test compares them).
pub fn check_stability(
    model: &NumericModel,
    drive: &Excitation,
    state: &SteadyState,
) -> Result<Stability, SimError> {
    let kept = STABILITY_SOLVERS.with(|cell| {
        let mut list = cell.try_borrow_mut().ok()?;
        let k = list
            .iter()
            .position(|s| s.same_set_up(model, drive, &state.lattice_hz))?;
        Some(list.remove(k))
    });
    let reused = kept.and_then(|mut s| s.set_values(model, drive).is_ok().then_some(s));
    let mut solver = match reused {
        Some(s) => s,
        None => super::ReducedSolver::with_lattice(model, drive, state.lattice_hz.clone(), &[])?,
    };
    let verdict = solver.stability(state);
    STABILITY_SOLVERS.with(|cell| {
        if let Ok(mut list) = cell.try_borrow_mut() {
            list.push(solver);
            if list.len() > KEPT_STABILITY_SOLVERS {
                list.remove(0);
            }
        }
    });
    verdict
}

/// [`check_stability`] on a solver set up for this call alone (the tests compare both).
#[cfg(test)]
pub(crate) fn check_stability_fresh(
    model: &NumericModel,
    drive: &Excitation,
    state: &SteadyState,
) -> Result<Stability, SimError> {
    let mut solver =
        super::ReducedSolver::with_lattice(model, drive, state.lattice_hz.clone(), &[])?;
    solver.stability(state)
}
