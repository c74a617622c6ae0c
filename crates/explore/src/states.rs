//! Every steady state at one point of parameters: all real solutions of the single-harmonic
//! system ([`crate::SingleHarmonic`]) by the total-degree homotopy, each with its slow-flow
//! eigenvalues, then continued onto the full harmonic lattice by the simulation crate's
//! Newton ([`harmonid_sim::HbSolver`]) and judged there by its stability check.

use crate::harmonic::{SingleHarmonic, Tone};
use crate::homotopy::{push_distinct, total_degree};
use crate::system::{norm, PolySystem, ZERO};
use crate::ExploreError;
use harmonid_sim::{Excitation, HbSettings, HbSolver, NumericModel, SteadyState};
use num_complex::Complex64;

/// A solution is real when every imaginary part is below this, relative to `1 + ‖x‖`
/// (scaled unknowns).
pub const REAL_TOL: f64 = 1e-6;
/// Seed of the homotopy's random `γ` and chart (the results do not depend on it).
pub const SEED: u64 = 38;

/// How [`states`] runs.
#[derive(Debug, Clone, PartialEq)]
pub struct StatesSettings {
    /// Continue each state onto the full lattice (`hb.lattice`); `false`: the
    /// single-harmonic states only.
    pub lattice: bool,
    /// The lattice solve's settings.
    pub hb: HbSettings,
}

impl Default for StatesSettings {
    /// The lattice keeps, besides the lines near resonances, every combination up to the
    /// model's degree wherever it falls (`3Ω` of a cubic model, the offset and `2Ω` of a
    /// quadratic one): the harmonics the single-harmonic system leaves out.
    fn default() -> Self {
        let mut hb = HbSettings::default();
        hb.lattice.harmonics = true;
        Self { lattice: true, hb }
    }
}

/// The single-harmonic system at one tone and its real solutions: what [`states`] and the
/// phase diagrams share.
#[derive(Debug, Clone, PartialEq)]
pub struct Solved {
    /// Real solutions, `X_n` per mode (m), at the tone.
    pub amplitudes: Vec<Vec<Complex64>>,
    /// Their slow-flow eigenvalues, 1/s.
    pub eigenvalues: Vec<Vec<Complex64>>,
    /// Every finite complex solution, scaled (`X / scale`): the start of a neighbour's
    /// parameter homotopy.
    pub complex: Vec<Vec<Complex64>>,
}

/// One steady state.
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    /// Complex amplitude of each mode at the tone, m (single harmonic).
    pub amplitudes: Vec<Complex64>,
    /// Eigenvalues of the single-harmonic slow flow `(γ_n + 2iΩ) Ẋ_n = −R_n(X)` linearised
    /// at the state, 1/s (`Re` growth rates, `Im` angular frequencies about the state).
    pub eigenvalues: Vec<Complex64>,
    /// Stable in the single-harmonic slow flow: every growth rate below `1e-6 ·` the slowest
    /// linear decay rate (the simulation crate's rule).
    pub stable: bool,
    /// The state continued onto the lattice, or why not.
    pub lattice: Continued,
}

/// A state on the full lattice.
#[derive(Debug, Clone, PartialEq)]
pub enum Continued {
    /// Not asked for.
    NotAsked,
    /// Newton on the lattice converged from the single-harmonic state.
    Yes {
        /// The lattice state.
        state: Box<SteadyState>,
        /// Its stability by [`HbSolver::stability`].
        stable: bool,
        /// Its largest slow-flow growth rate, 1/s.
        growth_rate: f64,
        /// The eigenvalues of its slow flow on the full lattice, 1/s
        /// ([`HbSolver::slow_flow_eigenvalues`]: the lines near the resonances, the far ones
        /// condensed), which [`HbSolver::stability`] judges; beside the single harmonic's
        /// [`State::eigenvalues`], they include the harmonics' effect.
        eigenvalues: Vec<Complex64>,
        /// `‖X_lattice − X_single‖ / ‖X_single‖` at the tone.
        shift: f64,
        /// Index of an earlier state that reached the same lattice state.
        same_as: Option<usize>,
    },
    /// Newton did not converge (the harmonics move the state too far from the single
    /// harmonic's), with the residual reached.
    No {
        /// Why.
        why: String,
    },
}

/// All steady states at one point.
#[derive(Debug, Clone, PartialEq)]
pub struct States {
    /// The response frequency, Hz.
    pub tone_hz: f64,
    /// The states, largest total amplitude last.
    pub states: Vec<State>,
    /// Paths tracked (the Bézout number of the single-harmonic system).
    pub paths: usize,
    /// Finite complex solutions found (real and not).
    pub complex_solutions: usize,
    /// Paths that ended at infinity.
    pub at_infinity: usize,
    /// Paths that neither reached a solution nor went to infinity (0 when all went well).
    pub failed: usize,
}

/// The single-harmonic tone of an excitation: one drive tone `f` (response at `f`), one pump
/// `f_p` (response at `f_p/2`), or both with `f_p = 2f`. Refuses non-smooth terms, whose
/// single-harmonic system is not polynomial.
pub fn tone_of(model: &NumericModel, drive: &Excitation) -> Result<Tone, ExploreError> {
    if model.has_nonsmooth() {
        let names: Vec<&str> = model
            .rough_terms()
            .iter()
            .map(|t| t.name.as_str())
            .collect();
        return Err(ExploreError::NonSmooth {
            terms: names.join(", "),
        });
    }
    let nm = model.n_modes();
    let forced = drive.force.iter().flatten().any(|z| z.norm() > 0.0);
    if drive.pumps.len() > 1 || drive.tones_hz.len() > 1 {
        return Err(ExploreError::NoSingleTone {
            what: format!(
                "{} drive tones and {} pumps",
                drive.tones_hz.len(),
                drive.pumps.len()
            ),
        });
    }
    let pump = drive.pumps.first();
    if model.has_pump_terms() && pump.is_none() {
        return Err(harmonid_sim::SimError::NoPump {
            terms: model.pump_term_names().join(", "),
        }
        .into());
    }
    let pump_amp = if model.has_pump_terms() {
        pump.map_or(ZERO, |p| p.amplitude)
    } else {
        ZERO
    };
    let hz = match (drive.tones_hz.first(), pump) {
        (Some(&f), Some(p)) if forced && (p.hz - 2.0 * f).abs() > 1e-9 * f => {
            return Err(ExploreError::NoSingleTone {
                what: format!(
                    "a drive at {f} Hz and a pump at {} Hz (not twice the drive)",
                    p.hz
                ),
            })
        }
        (Some(&f), _) if forced => f,
        (_, Some(p)) => 0.5 * p.hz,
        (Some(&f), None) => f,
        (None, None) => {
            return Err(ExploreError::NoSingleTone {
                what: "no drive tone and no pump".into(),
            })
        }
    };
    if !(hz.is_finite() && hz > 0.0) {
        return Err(ExploreError::BadValue {
            what: "the response frequency (Hz)".into(),
            value: hz,
            why: "it must be a finite positive frequency",
        });
    }
    let force = (0..nm)
        .map(|n| {
            if forced {
                drive
                    .force
                    .get(n)
                    .and_then(|r| r.first())
                    .copied()
                    .unwrap_or(ZERO)
            } else {
                ZERO
            }
        })
        .collect();
    Ok(Tone {
        hz,
        force,
        pump: pump_amp,
    })
}

/// Every finite solution of `sys` (the system at `tone` scaled by `scale`, with mode norms
/// `norms`) sorted into the real ones with their eigenvalues.
pub(crate) fn classify(
    model: &NumericModel,
    tone: &Tone,
    sys: &PolySystem,
    norms: &[f64],
    scale: f64,
    complex: Vec<Vec<Complex64>>,
) -> Solved {
    let mut amplitudes = Vec::new();
    let mut eigenvalues = Vec::new();
    let mut pw = sys.scratch();
    let n = sys.n;
    let mut f = vec![ZERO; n];
    let mut j = vec![ZERO; n * n];
    let mut real_pts: Vec<Vec<Complex64>> = Vec::new();
    for x in &complex {
        let s = 1.0 + norm(x);
        if x.iter().any(|z| z.im.abs() > REAL_TOL * s) {
            continue;
        }
        // Real; parts at the rounding level are zero (the rest state of an undriven model).
        let xr: Vec<Complex64> = x
            .iter()
            .map(|z| Complex64::new(if z.re.abs() > 1e-13 * s { z.re } else { 0.0 }, 0.0))
            .collect();
        if !push_distinct(&mut real_pts, xr.clone()) {
            continue;
        }
        sys.eval(&xr, &mut f, &mut j, &mut pw);
        eigenvalues.push(slow_flow_eigenvalues(model, tone, &j, norms, scale));
        amplitudes.push(
            (0..n / 2)
                .map(|m| Complex64::new(xr[2 * m].re, xr[2 * m + 1].re) * scale)
                .collect(),
        );
    }
    Solved {
        amplitudes,
        eigenvalues,
        complex,
    }
}

/// Eigenvalues of the slow flow `Ẋ_n = −R_n / (γ_n + 2iΩ)` from the scaled system's Jacobian
/// `j` (rows `Re R_n/e_n`, `Im R_n/e_n`; columns `u_m, v_m` over the scale), 1/s.
fn slow_flow_eigenvalues(
    model: &NumericModel,
    tone: &Tone,
    j: &[Complex64],
    norms: &[f64],
    scale: f64,
) -> Vec<Complex64> {
    let n = j.len().isqrt();
    let w = tone.omega();
    let mut a = vec![0.0; n * n];
    for m in 0..n / 2 {
        let c = Complex64::new(1.0, 0.0) / Complex64::new(model.gamma(m), 2.0 * w);
        let e = norms[m] / scale;
        for col in 0..n {
            let (re, im) = (j[2 * m * n + col].re * e, j[(2 * m + 1) * n + col].re * e);
            a[2 * m * n + col] = -(c.re * re - c.im * im);
            a[(2 * m + 1) * n + col] = -(c.im * re + c.re * im);
        }
    }
    eigenvalues(&a, n)
}

/// Eigenvalues of the real `n × n` matrix `a` (row-major): closed form for `2 × 2`, faer
/// otherwise.
pub(crate) fn eigenvalues(a: &[f64], n: usize) -> Vec<Complex64> {
    if n == 2 {
        let tr = 0.5 * (a[0] + a[3]);
        let det = a[0] * a[3] - a[1] * a[2];
        let d = Complex64::new(tr * tr - det, 0.0).sqrt();
        return vec![tr + d, tr - d];
    }
    let m = faer::Mat::<f64>::from_fn(n, n, |i, k| a[i * n + k]);
    m.eigenvalues()
        .map(|v| v.iter().map(|z| Complex64::new(z.re, z.im)).collect())
        .unwrap_or_else(|_| vec![Complex64::new(f64::NAN, 0.0); n])
}

/// The growth rate a slow-flow eigenvalue must stay below for stability, 1/s: `1e-6 ·` the
/// slowest linear decay rate (the simulation crate's rule).
fn growth_threshold(model: &NumericModel) -> f64 {
    let decay = (0..model.n_modes())
        .map(|n| 0.5 * model.gamma(n))
        .fold(f64::INFINITY, f64::min);
    1e-6 * decay
}

/// Stable when every eigenvalue's real part is below `1e-6 ·` the slowest linear decay rate.
pub fn is_stable(model: &NumericModel, eig: &[Complex64]) -> bool {
    let threshold = growth_threshold(model);
    eig.iter().all(|z| z.re < threshold)
}

/// Whether a state is unstable through a complex pair of its slow flow: an oscillatory
/// (Hopf-type) instability, where an oscillation at the pair's frequency `|Im λ|/2π` grows
/// beside the driven response (sidebands at the tone ± that offset; `sweep --limit-cycles`
/// follows it from a Hopf point), rather than through a real eigenvalue only (a saddle, as on
/// the middle branch between two folds). False for a stable state.
pub fn unstable_through_complex_pair(model: &NumericModel, eig: &[Complex64]) -> bool {
    let threshold = growth_threshold(model);
    eig.iter()
        .any(|z| z.re >= threshold && z.im.abs() > 1e-8 * z.norm())
}

/// Every steady state of `model` under `drive` (one drive tone, one pump, or both with the
/// pump at twice the tone; forces N/kg, pump in the unit of the model's pump coefficients):
/// every real solution of the single-harmonic system by the total-degree homotopy (complete
/// for the single-harmonic system), sorted by total amplitude, each continued onto the
/// lattice when `settings.lattice`. Errors: an excitation without one response frequency, a
/// Bézout number above [`crate::MAX_PATHS`], the simulation crate's checks of the drive.
pub fn states(
    model: &NumericModel,
    drive: &Excitation,
    settings: &StatesSettings,
) -> Result<States, ExploreError> {
    let tone = tone_of(model, drive)?;
    let sh = SingleHarmonic::new(model)?;
    let scale = sh.natural_scale(model, &tone);
    let (sys, norms) = sh.system(model, &tone, scale, true)?;
    let sols = total_degree(&sys, SEED).ok_or_else(|| ExploreError::TooComplex {
        what: format!(
            "a single-harmonic system of degrees {:?} (Bézout number over {})",
            sys.degrees(),
            crate::MAX_PATHS
        ),
        limit: "the total-degree homotopy's path budget",
    })?;
    let solved = classify(model, &tone, &sys, &norms, scale, sols.points.clone());
    let mut states: Vec<State> = solved
        .amplitudes
        .into_iter()
        .zip(solved.eigenvalues)
        .map(|(amplitudes, eigenvalues)| State {
            stable: is_stable(model, &eigenvalues),
            amplitudes,
            eigenvalues,
            lattice: Continued::NotAsked,
        })
        .collect();
    states.sort_by(|a, b| norm(&a.amplitudes).total_cmp(&norm(&b.amplitudes)));
    if settings.lattice {
        continue_on_lattice(model, drive, &tone, &mut states, &settings.hb)?;
    }
    Ok(States {
        tone_hz: tone.hz,
        states,
        paths: sols.paths,
        complex_solutions: sols.points.len(),
        at_infinity: sols.at_infinity,
        failed: sols.failed,
    })
}

/// Newton on the lattice from each single-harmonic state (the tone's line set, the rest zero).
fn continue_on_lattice(
    model: &NumericModel,
    drive: &Excitation,
    tone: &Tone,
    states: &mut [State],
    hb: &HbSettings,
) -> Result<(), ExploreError> {
    // A pump alone: the lattice needs a tone, at f_p/2 with no force.
    let exc = if drive.tones_hz.is_empty() || tone.force.iter().all(|z| z.norm() == 0.0) {
        Excitation {
            tones_hz: vec![tone.hz],
            force: vec![vec![ZERO]; model.n_modes()],
            pumps: drive.pumps.clone(),
        }
    } else {
        drive.clone()
    };
    let mut solver = HbSolver::new(model, &exc, &hb.lattice)?;
    let lattice = solver.lattice().to_vec();
    let r = lattice
        .iter()
        .position(|&f| (f - tone.hz).abs() <= harmonid_sim::LINE_TOL_HZ);
    let Some(r) = r else {
        return Err(harmonid_sim::SimError::NotOnLattice { hz: tone.hz }.into());
    };
    let mut done: Vec<(usize, SteadyState)> = Vec::new();
    for (i, s) in states.iter_mut().enumerate() {
        let guess: Vec<Vec<Complex64>> = s
            .amplitudes
            .iter()
            .map(|&x| {
                (0..lattice.len())
                    .map(|k| if k == r { x } else { ZERO })
                    .collect()
            })
            .collect();
        let st = solver.solve_from(&guess, hb);
        if !st.converged() {
            s.lattice = Continued::No {
                why: format!(
                    "Newton on the {}-line lattice stopped at a relative residual {:.1e}",
                    lattice.len(),
                    st.residual
                ),
            };
            continue;
        }
        let stab = solver.stability(&st)?;
        let eigenvalues = solver.slow_flow_eigenvalues(&st)?;
        let at: Vec<Complex64> = (0..model.n_modes()).map(|n| st.amplitudes[n][r]).collect();
        let diff: Vec<Complex64> = at.iter().zip(&s.amplitudes).map(|(a, b)| a - b).collect();
        let size = norm(&s.amplitudes).max(norm(&at)).max(f64::MIN_POSITIVE);
        let same_as = done.iter().find_map(|(k, d)| {
            let dd: Vec<Complex64> = (0..model.n_modes())
                .map(|n| d.amplitudes[n][r] - st.amplitudes[n][r])
                .collect();
            (norm(&dd) <= 1e-6 * size).then_some(*k)
        });
        s.lattice = Continued::Yes {
            stable: stab.stable,
            growth_rate: stab.growth_rate,
            eigenvalues,
            shift: norm(&diff) / size,
            same_as,
            state: Box::new(st.clone()),
        };
        done.push((i, st));
    }
    Ok(())
}

/// The complex single-harmonic residuals `R_n` (N/kg) at physical amplitudes `x` (m): for
/// checks (brute force, tests) against the polynomial system.
pub fn residual(
    model: &NumericModel,
    tone: &Tone,
    x: &[Complex64],
) -> Result<Vec<Complex64>, ExploreError> {
    let sh = SingleHarmonic::new(model)?;
    let (sys, _) = sh.system(model, tone, 1.0, false)?;
    let xs: Vec<Complex64> = x
        .iter()
        .flat_map(|z| [Complex64::new(z.re, 0.0), Complex64::new(z.im, 0.0)])
        .collect();
    let mut f = vec![ZERO; sys.n];
    let mut pw = sys.scratch();
    sys.eval(&xs, &mut f, &mut [], &mut pw);
    Ok((0..x.len())
        .map(|n| Complex64::new(f[2 * n].re, f[2 * n + 1].re))
        .collect())
}
