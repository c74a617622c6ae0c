//! Sensitivities of harmonic-balance steady states by implicit differentiation.
//!
//! At a converged steady state the residual of [`crate::HbSolver`] vanishes,
//!
//! ```text
//! R_{n,r}(z, θ) = (ω_n² − Ω_r² + i Ω_r γ_n) X_{n,r} + Σ_t b_t [m_t(q)]_r − F_{n,r} = 0,
//! ```
//!
//! (`z` the real vector of the unknowns `Re X, Im X`, `Ω_r = 2π f_r`, `γ_n = ω_n/Q_n`), so for
//! any quantity `θ` the equations depend on, `dz/dθ = −J⁻¹ ∂R/∂θ` with `J = ∂R/∂z` the same
//! real Jacobian Newton uses (assembled and factorised by the solver; no finite differences).
//! The partial derivatives are closed forms:
//!
//! | θ | `∂R_{n,r}/∂θ` |
//! |---|---|
//! | `ω_m²` (rad²/s²) | `X_{m,r}` in the rows of mode `m` |
//! | `γ_m = ω_m/Q_m` (rad/s) | `i Ω_r X_{m,r}` in the rows of mode `m` |
//! | model parameter `p` | `Σ_t (∂b_t/∂p) [m_t(q)]_r` over the terms of equation `n` |
//! | `Re F` / `Im F` of tone `d` on mode `m` (N/kg) | `−1` / `−i` at the tone's line, rows of `m` |
//!
//! with `∂b_t/∂p` from [`NumericModel::term_param_grad`](crate::NumericModel::term_param_grad) (the model's coefficients are
//! polynomials, usually affine, in its parameters) and `[m_t(q)]_r` the exact amplitude of the
//! monomial on the lattice. The outputs are the complex amplitudes of the measured signal
//! `x = Σ_n shape_n q_n` at chosen lattice lines, so a line two modes contribute to is exact.

use crate::lattice::LINE_TOL_HZ;
use crate::linalg::ColumnScratch;
use crate::steady::{variable_spectra, HbSolver, ReducedSolver, SteadyState};
use crate::SimError;
use harmonid_poly::PowerProduct;
use harmonid_spectral::{SystemPlan, SystemScratch};
use num_complex::Complex64;
use std::f64::consts::TAU;

const Z: Complex64 = Complex64::new(0.0, 0.0);

/// A quantity the steady state depends on (units of the equations, `DATA_FORMAT.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SensParam {
    /// `ω_n²` of mode `n`, rad²/s² (with `γ_n` held: `Q_n` moves with it).
    OmegaSq(usize),
    /// `γ_n = ω_n/Q_n` of mode `n`, rad/s.
    Gamma(usize),
    /// Model parameter `p` (declaration order), in the SI units of the terms it multiplies.
    Param(usize),
    /// Real (`quad = 0`) or imaginary (`1`) part of the complex force of drive tone `tone` on
    /// mode `mode`, N/kg.
    Force {
        /// Drive tone index (order of [`crate::Excitation::tones_hz`]).
        tone: usize,
        /// Mode the force acts on.
        mode: usize,
        /// 0 real part, 1 imaginary part.
        quad: u8,
    },
}

/// Where the signal is observed: a lattice frequency and the shape of each mode at the point
/// (`x = Σ_n shape[n] q_n`; missing entries count as 0).
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// Frequency, Hz (must be a line of the solver's lattice).
    pub f_hz: f64,
    /// Mode shapes at the point, one per mode.
    pub shape: Vec<f64>,
}

/// Set-up of a sensitivity computation for one [`HbSolver`]: the parameters, the observations
/// and every buffer, so that [`Sensitivity::compute`] does not allocate.
#[derive(Debug, Clone)]
pub struct Sensitivity {
    params: Vec<SensParam>,
    /// Lattice index of each observation.
    obs_line: Vec<usize>,
    /// Shapes, `[o·N + n]`.
    obs_shape: Vec<f64>,
    /// Lattice index of each drive tone.
    tone_line: Vec<usize>,
    /// One output per distinct monomial of the model, coefficient 1.
    monomials: SystemPlan,
    mono_scratch: SystemScratch,
    /// Monomial (output of `monomials`) of each model term.
    mono_of_term: Vec<usize>,
    /// `[k·R + r]`: amplitude of monomial `k` on the lattice.
    mono_amp: Vec<Complex64>,
    /// The state's amplitudes `[n·R + r]` and velocity spectra (empty without velocity terms).
    x: Vec<Complex64>,
    vel: Vec<Complex64>,
    /// `∂R/∂θ`, complex, `[n·R + r]`.
    dres: Vec<Complex64>,
    /// Real right-hand sides / solutions, one column per parameter (`2·N·R` rows).
    rhs: faer::Mat<f64>,
    solve_scratch: ColumnScratch,
    /// `Ω_r = 2π f_r` of every lattice line, rad/s.
    omega: Vec<f64>,
    n_modes: usize,
    n_lines: usize,
    n_terms: usize,
}

impl Sensitivity {
    /// Prepares sensitivities of `solver`'s steady states under a drive with tones `tones_hz`
    /// (Hz, the order of the [`crate::Excitation`] the solver was built with) with respect to
    /// `params`, observed at `observations`. Errors: an observation or tone off the lattice, a
    /// mode or tone index out of range, a shape of the wrong length.
    pub fn new(
        solver: &HbSolver,
        tones_hz: &[f64],
        params: &[SensParam],
        observations: &[Observation],
    ) -> Result<Self, SimError> {
        let model = solver.model();
        let nm = model.n_modes();
        let lattice = solver.lattice();
        let nr = lattice.len();
        let line = |f: f64, what: &'static str| -> Result<usize, SimError> {
            let i = lattice.partition_point(|&x| x < f - LINE_TOL_HZ);
            match lattice.get(i) {
                Some(&x) if (x - f).abs() <= LINE_TOL_HZ => Ok(i),
                _ => Err(SimError::NotALine { what, hz: f }),
            }
        };
        let tone_line = tones_hz
            .iter()
            .map(|&f| line(f, "drive tone"))
            .collect::<Result<Vec<_>, _>>()?;
        let mut obs_line = Vec::with_capacity(observations.len());
        let mut obs_shape = Vec::with_capacity(observations.len() * nm);
        for o in observations {
            obs_line.push(line(o.f_hz, "observed frequency")?);
            if o.shape.len() > nm {
                return Err(SimError::Length {
                    what: "an observation's mode shape",
                    found: o.shape.len(),
                    expected: nm,
                    per: "at most one per mode".into(),
                });
            }
            obs_shape.extend((0..nm).map(|n| o.shape.get(n).copied().unwrap_or(0.0)));
        }
        let n_params = model
            .terms()
            .iter()
            .enumerate()
            .flat_map(|(t, _)| model.term_param_grad(t).iter().map(|&(p, _)| p + 1))
            .max()
            .unwrap_or(0);
        for p in params {
            let ok = match *p {
                SensParam::OmegaSq(n) | SensParam::Gamma(n) => n < nm,
                // A parameter no term depends on has zero sensitivity; any index is accepted.
                SensParam::Param(_) => true,
                SensParam::Force { tone, mode, quad } => {
                    tone < tones_hz.len() && mode < nm && quad < 2
                }
            };
            if !ok {
                return Err(SimError::ParamOutOfRange {
                    param: format!("{p:?}"),
                    modes: nm,
                    tones: tones_hz.len(),
                    params: n_params,
                });
            }
        }
        // Distinct monomials, one output each.
        let mut monos: Vec<PowerProduct> = Vec::new();
        let mut mono_of_term = Vec::with_capacity(model.terms().len());
        for t in model.terms() {
            let pp = model.term_monomial(&t.factors);
            let k = match monos.iter().position(|x| *x == pp) {
                Some(k) => k,
                None => {
                    monos.push(pp);
                    monos.len() - 1
                }
            };
            mono_of_term.push(k);
        }
        let terms: Vec<(usize, PowerProduct, f64)> = monos
            .iter()
            .enumerate()
            .map(|(k, m)| (k, m.clone(), 1.0))
            .collect();
        let n_vars = model.n_vars();
        let monomials = SystemPlan::new(solver.product_plan().clone(), n_vars, monos.len(), &terms)
            .map_err(|e| SimError::Hb(format!("cannot plan the monomials: {e}")))?;
        let mono_scratch = monomials.scratch();
        Ok(Self {
            params: params.to_vec(),
            obs_line,
            obs_shape,
            tone_line,
            mono_scratch,
            mono_amp: vec![Z; monos.len() * nr],
            x: vec![Z; nm * nr],
            vel: if n_vars > nm {
                vec![Z; nm * nr]
            } else {
                Vec::new()
            },
            monomials,
            mono_of_term,
            dres: vec![Z; nm * nr],
            rhs: faer::Mat::zeros(2 * nm * nr, params.len()),
            solve_scratch: solver.columns_scratch(params.len()),
            omega: lattice.iter().map(|&f| TAU * f).collect(),
            n_modes: nm,
            n_lines: nr,
            n_terms: model.terms().len(),
        })
    }

    /// The parameters, in the order of the output's blocks.
    pub fn params(&self) -> &[SensParam] {
        &self.params
    }

    /// Number of observations.
    pub fn n_observations(&self) -> usize {
        self.obs_line.len()
    }

    /// Sensitivities at `state`, a steady state `solver` converged to (the solver this was set
    /// up with, possibly with other parameter values but the same terms): `out[k·O + o] =
    /// ∂X_o/∂θ_k`, the derivative of the complex amplitude of the observed signal `o` (m)
    /// with respect to parameter `k` of [`Sensitivity::params`] (`O` observations). `out`
    /// holds `params.len() · O` entries. Does not allocate.
    ///
    /// Errors: a state of another lattice, a model whose terms differ from the set-up's, a
    /// singular Jacobian (at a fold the sensitivities are unbounded). An unconverged state
    /// gives the sensitivities of that state, which mean nothing: check
    /// [`SteadyState::converged`] first.
    pub fn compute(
        &mut self,
        solver: &mut HbSolver,
        state: &SteadyState,
        out: &mut [Complex64],
    ) -> Result<(), SimError> {
        let (nm, nr) = (self.n_modes, self.n_lines);
        let n_obs = self.obs_line.len();
        if out.len() != self.params.len() * n_obs {
            return Err(SimError::Length {
                what: "the sensitivity output",
                found: out.len(),
                expected: self.params.len() * n_obs,
                per: format!("{} parameters × {n_obs} observations", self.params.len()),
            });
        }
        if solver.model().n_modes() != nm
            || solver.lattice().len() != nr
            || solver
                .lattice()
                .iter()
                .zip(&self.omega)
                .any(|(&f, &w)| (TAU * f - w).abs() > TAU * LINE_TOL_HZ)
            || solver.model().terms().len() != self.n_terms
        {
            return Err(SimError::SetUpFor {
                what: "the sensitivity",
            });
        }
        solver.factor_at(state)?;
        let needs_monomials = self.params.iter().any(|p| matches!(p, SensParam::Param(_)));
        if needs_monomials {
            for n in 0..nm {
                self.x[n * nr..(n + 1) * nr].copy_from_slice(&state.amplitudes[n]);
            }
            harmonid_spectral::velocity_spectrum(&state.lattice_hz, &self.x, &mut self.vel);
            let refs = variable_spectra(&self.x, &self.vel, solver.pump_spectrum(), nm, nr);
            let nv = solver.model().n_vars();
            self.monomials
                .forces(&refs[..nv], &mut self.mono_amp, &mut self.mono_scratch);
        }
        for (k, p) in self.params.iter().enumerate() {
            self.dres.fill(Z);
            match *p {
                SensParam::OmegaSq(m) => {
                    self.dres[m * nr..(m + 1) * nr].copy_from_slice(&state.amplitudes[m]);
                }
                SensParam::Gamma(m) => {
                    for r in 0..nr {
                        self.dres[m * nr + r] =
                            Complex64::new(0.0, self.omega[r]) * state.amplitudes[m][r];
                    }
                }
                SensParam::Param(p) => {
                    add_rough_param(solver, state, p, &mut self.dres);
                    let model = solver.model();
                    for t in 0..self.n_terms {
                        let Some(&(_, g)) = model.term_param_grad(t).iter().find(|&&(q, _)| q == p)
                        else {
                            continue;
                        };
                        let eq = model.terms()[t].eq;
                        let mk = self.mono_of_term[t];
                        for r in 0..nr {
                            self.dres[eq * nr + r] += self.mono_amp[mk * nr + r] * g;
                        }
                    }
                }
                SensParam::Force { tone, mode, quad } => {
                    self.dres[mode * nr + self.tone_line[tone]] = if quad == 0 {
                        Complex64::new(-1.0, 0.0)
                    } else {
                        Complex64::new(0.0, -1.0)
                    };
                }
            }
            let col = self
                .rhs
                .col_mut(k)
                .try_as_col_major_mut()
                .expect("contiguous column");
            let col = col.as_slice_mut();
            for (i, z) in self.dres.iter().enumerate() {
                col[2 * i] = -z.re;
                col[2 * i + 1] = -z.im;
            }
        }
        // Every parameter's `dz/dθ_k = −J⁻¹ ∂R/∂θ_k` in one blocked solve.
        solver.solve_factored_columns(self.rhs.as_mut(), &mut self.solve_scratch);
        for k in 0..self.params.len() {
            let col = self
                .rhs
                .col(k)
                .try_as_col_major()
                .expect("contiguous column");
            let col = col.as_slice();
            for (o, &r) in self.obs_line.iter().enumerate() {
                let mut s = Z;
                for n in 0..nm {
                    let i = n * nr + r;
                    s += Complex64::new(col[2 * i], col[2 * i + 1]) * self.obs_shape[o * nm + n];
                }
                out[k * n_obs + o] = s;
            }
        }
        Ok(())
    }
}

/// [`Sensitivity`] of a [`ReducedSolver`]'s steady states: the same parameters and
/// observations over the whole model, computed on the modes the solver solves for. A
/// quantity of an idle mode (its `ω²`, `γ`, a parameter only terms with an idle factor
/// hold) moves nothing, since the idle modes stay exactly
/// zero for every value of the parameters: its sensitivities are zero. A force on an idle mode
/// would move it: it is refused ([`SimError::IdleForce`]; name the mode among the solver's
/// forced modes). When the solver was set up again on other modes (its drive now reaches
/// others), the set-up follows.
#[derive(Debug, Clone)]
pub struct ReducedSensitivity {
    tones_hz: Vec<f64>,
    params: Vec<SensParam>,
    observations: Vec<Observation>,
    /// The active modes the set-up is for.
    modes: Vec<usize>,
    inner: Sensitivity,
    /// Per parameter, its block in `inner`'s output (`None`: zero).
    slot: Vec<Option<usize>>,
    buf: Vec<Complex64>,
}

impl ReducedSensitivity {
    /// As [`Sensitivity::new`] for `solver`, with `params` and `observations` (shapes) of the
    /// whole model. Errors: those of [`Sensitivity::new`], a mode index beyond the model, a
    /// force on an idle mode.
    pub fn new(
        solver: &ReducedSolver,
        tones_hz: &[f64],
        params: &[SensParam],
        observations: &[Observation],
    ) -> Result<Self, SimError> {
        let nm = solver.model().n_modes();
        let modes = solver.active().modes().to_vec();
        let local = |n: usize| -> Result<Option<usize>, SimError> {
            if n >= nm {
                return Err(SimError::ModeIndex {
                    index: n,
                    n_modes: nm,
                });
            }
            Ok(modes.iter().position(|&m| m == n))
        };
        // The parameters a kept term depends on (the others' terms all hold an idle factor).
        let sub = solver.inner.model();
        let used: std::collections::BTreeSet<usize> = (0..sub.terms().len())
            .flat_map(|t| sub.term_param_grad(t).iter().map(|&(p, _)| p))
            .chain(
                (0..sub.rough_terms().len())
                    .flat_map(|t| sub.rough_param_grad(t).iter().map(|&(p, _)| p)),
            )
            .collect();
        let mut inner_params = Vec::new();
        let mut slot = Vec::with_capacity(params.len());
        for &p in params {
            let q = match p {
                SensParam::OmegaSq(n) => local(n)?.map(SensParam::OmegaSq),
                SensParam::Gamma(n) => local(n)?.map(SensParam::Gamma),
                SensParam::Param(k) => used.contains(&k).then_some(p),
                SensParam::Force { tone, mode, quad } => match local(mode)? {
                    Some(m) => Some(SensParam::Force {
                        tone,
                        mode: m,
                        quad,
                    }),
                    None => return Err(SimError::IdleForce { mode }),
                },
            };
            slot.push(q.map(|q| {
                inner_params.push(q);
                inner_params.len() - 1
            }));
        }
        let mut local_obs = Vec::with_capacity(observations.len());
        for o in observations {
            if o.shape.len() > nm {
                return Err(SimError::Length {
                    what: "an observation's mode shape",
                    found: o.shape.len(),
                    expected: nm,
                    per: "at most one per mode".into(),
                });
            }
            local_obs.push(Observation {
                f_hz: o.f_hz,
                shape: modes
                    .iter()
                    .map(|&m| o.shape.get(m).copied().unwrap_or(0.0))
                    .collect(),
            });
        }
        let inner = Sensitivity::new(&solver.inner, tones_hz, &inner_params, &local_obs)?;
        Ok(Self {
            tones_hz: tones_hz.to_vec(),
            params: params.to_vec(),
            observations: observations.to_vec(),
            modes,
            buf: vec![Z; inner_params.len() * observations.len()],
            inner,
            slot,
        })
    }

    /// The parameters, in the order of the output's blocks.
    pub fn params(&self) -> &[SensParam] {
        &self.params
    }

    /// As [`Sensitivity::compute`]: `out[k·O + o] = ∂X_o/∂θ_k` at `state` (every mode of the
    /// model), a steady state `solver` converged to.
    pub fn compute(
        &mut self,
        solver: &mut ReducedSolver,
        state: &SteadyState,
        out: &mut [Complex64],
    ) -> Result<(), SimError> {
        if solver.active().modes() != self.modes {
            *self = Self::new(solver, &self.tones_hz, &self.params, &self.observations)?;
        }
        let n_obs = self.observations.len();
        if out.len() != self.params.len() * n_obs {
            return Err(SimError::Length {
                what: "the sensitivity output",
                found: out.len(),
                expected: self.params.len() * n_obs,
                per: format!("{} parameters × {n_obs} observations", self.params.len()),
            });
        }
        if state.amplitudes.len() != solver.model().n_modes() {
            return Err(SimError::OtherLattice);
        }
        let local = solver.active().restrict_state(state);
        self.inner
            .compute(&mut solver.inner, &local, &mut self.buf)?;
        for (k, s) in self.slot.iter().enumerate() {
            let block = &mut out[k * n_obs..(k + 1) * n_obs];
            match s {
                Some(j) => block.copy_from_slice(&self.buf[j * n_obs..(j + 1) * n_obs]),
                None => block.fill(Z),
            }
        }
        Ok(())
    }
}

/// Adds `Σ_t (∂b_t/∂p) [term_t]_r` of the non-smooth terms to `dres` (`[n·R + r]`): each
/// term's lines with coefficient 1, by alternating frequency–time at `state` (allocates, for
/// models with such terms only).
fn add_rough_param(solver: &mut HbSolver, state: &SteadyState, p: usize, dres: &mut [Complex64]) {
    let model = solver.model().clone();
    let nt = model.rough_terms().len();
    let uses: Vec<(usize, f64)> = (0..nt)
        .filter_map(|t| {
            model
                .rough_param_grad(t)
                .iter()
                .find(|&&(q, _)| q == p)
                .map(|&(_, g)| (t, g))
        })
        .collect();
    if uses.is_empty() {
        return;
    }
    let nr = state.lattice_hz.len();
    let x: Vec<Complex64> = state.amplitudes.iter().flatten().copied().collect();
    let pump = solver.pump_spectrum().to_vec();
    let Some(rough) = solver.rough.as_mut() else {
        return;
    };
    let mut lines = vec![Z; nt * nr];
    rough.term_lines(&x, &pump, &mut lines);
    for (t, g) in uses {
        let eq = model.rough_terms()[t].eq;
        for r in 0..nr {
            dres[eq * nr + r] += lines[t * nr + r] * g;
        }
    }
}
