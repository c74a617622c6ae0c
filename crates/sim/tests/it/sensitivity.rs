//! Sensitivities by implicit differentiation against central finite differences of re-solved
//! steady states (same lattice, Newton from the unperturbed state to machine precision).

use harmonid_sim::{
    Excitation, HbSettings, HbSolver, ModeValues, ModelValues, NumericModel, Observation, PumpTone,
    SensParam, Sensitivity, SteadyState,
};
use num_complex::Complex64;
use std::f64::consts::TAU;

const NANOSTRING: &str = "
    mode q1 at 207.58 kHz
    mode q2 at 415.84 kHz
    param beta1, beta2, g12
    potential: beta1/4*q1^4 + beta2/4*q2^4 + g12/2*q1^2*q2^2
";

const THREE_WAVE: &str = "
    mode q1 at 1.0 MHz
    mode q2 at 1.6 MHz
    mode q3 at 2.6 MHz
    param kappa
    for i in 1..3: param beta[i]
    potential: kappa * q1*q2*q3
    for i in 1..3: potential: beta[i]/4 * q[i]^4
";

/// Everything the steady state depends on, in the parametrisation of [`SensParam`].
#[derive(Clone)]
struct Theta {
    w2: Vec<f64>,
    gamma: Vec<f64>,
    params: Vec<f64>,
    force: Vec<Vec<Complex64>>,
    pumps: Vec<PumpTone>,
}

impl Theta {
    fn get_mut(&mut self, p: SensParam) -> &mut f64 {
        match p {
            SensParam::OmegaSq(n) => &mut self.w2[n],
            SensParam::Gamma(n) => &mut self.gamma[n],
            SensParam::Param(k) => &mut self.params[k],
            SensParam::Force { tone, mode, quad } => {
                let z = &mut self.force[mode][tone];
                if quad == 0 {
                    &mut z.re
                } else {
                    &mut z.im
                }
            }
        }
    }

    fn build(&self, model: &harmonid_model::Model, tones: &[f64]) -> (NumericModel, Excitation) {
        let mut v = ModelValues::default();
        for (n, m) in model.modes.iter().enumerate() {
            let w = self.w2[n].sqrt();
            v.modes.insert(
                m.name.clone(),
                ModeValues {
                    f_hz: Some(w / TAU),
                    q: Some(w / self.gamma[n]),
                },
            );
        }
        for (p, par) in model.params.iter().enumerate() {
            v.parameters.insert(par.name.clone(), self.params[p]);
        }
        let nm = NumericModel::from_model(model, &v).expect("numeric model");
        let drive = Excitation {
            pumps: self.pumps.clone(),
            tones_hz: tones.to_vec(),
            force: self.force.clone(),
        };
        (nm, drive)
    }
}

fn observe(state: &SteadyState, obs: &[Observation]) -> Vec<Complex64> {
    obs.iter()
        .map(|o| state.at_point(&o.shape, o.f_hz))
        .collect()
}

/// Newton from `start` on `lattice`, pushed to the rounding floor.
fn resolve(
    model: &harmonid_model::Model,
    theta: &Theta,
    tones: &[f64],
    lattice: &[f64],
    start: &SteadyState,
) -> SteadyState {
    let (nm, drive) = theta.build(model, tones);
    let mut solver = HbSolver::with_lattice(&nm, &drive, lattice.to_vec()).expect("solver");
    let settings = HbSettings {
        tol: 1e-15,
        max_iter: 4,
        ..HbSettings::default()
    };
    let st = solver.solve_from(&start.amplitudes, &settings);
    assert!(st.residual < 1e-11, "re-solve residual {:e}", st.residual);
    st
}

/// Checks every parameter's sensitivity against central differences with a step that moves
/// no observed component by more than ~1e-4 of itself; returns the worst error relative to
/// the parameter's largest sensitivity.
fn check_against_fd(
    model: &harmonid_model::Model,
    theta: &Theta,
    tones: &[f64],
    params: &[SensParam],
    obs_of: impl Fn(&SteadyState) -> Vec<Observation>,
) -> (f64, SteadyState, Vec<Observation>, Vec<Complex64>) {
    let (nm, drive) = theta.build(model, tones);
    let mut solver = HbSolver::new(&nm, &drive, &HbSettings::default().lattice).expect("solver");
    let state = solver.solve(&HbSettings::default());
    assert!(state.converged(), "{:?}", state.status);
    let obs = obs_of(&state);
    let mut sens = Sensitivity::new(&solver, tones, params, &obs).expect("set-up");
    let no = obs.len();
    let mut out = vec![Complex64::new(0.0, 0.0); params.len() * no];
    sens.compute(&mut solver, &state, &mut out)
        .expect("sensitivities");
    let x0 = observe(&state, &obs);
    let mut worst: f64 = 0.0;
    for (k, &p) in params.iter().enumerate() {
        let d = &out[k * no..(k + 1) * no];
        let dmax = d.iter().map(|z| z.norm()).fold(0.0, f64::max);
        assert!(dmax > 0.0, "{p:?}: zero sensitivity everywhere");
        // No observed component the parameter moves changes by more than 1e-4 of itself.
        let h = (0..no)
            .filter(|&o| d[o].norm() > 1e-3 * dmax)
            .map(|o| 1e-4 * x0[o].norm() / d[o].norm())
            .fold(f64::INFINITY, f64::min);
        let mut plus = theta.clone();
        *plus.get_mut(p) += h;
        let mut minus = theta.clone();
        *minus.get_mut(p) -= h;
        let xp = observe(
            &resolve(model, &plus, tones, &state.lattice_hz, &state),
            &obs,
        );
        let xm = observe(
            &resolve(model, &minus, tones, &state.lattice_hz, &state),
            &obs,
        );
        let err = (0..no)
            .map(|o| ((xp[o] - xm[o]) / (2.0 * h) - d[o]).norm())
            .fold(0.0, f64::max)
            / dmax;
        println!("{p:?}: max |dX/dθ| {dmax:.3e}, step {h:.3e}, relative error {err:.2e}");
        worst = worst.max(err);
    }
    (worst, state, obs, out)
}

fn all_params(n_modes: usize, n_params: usize, n_tones: usize) -> Vec<SensParam> {
    let mut v = Vec::new();
    for n in 0..n_modes {
        v.push(SensParam::OmegaSq(n));
        v.push(SensParam::Gamma(n));
    }
    v.extend((0..n_params).map(SensParam::Param));
    for tone in 0..n_tones {
        for mode in 0..n_modes {
            for quad in 0..2 {
                v.push(SensParam::Force { tone, mode, quad });
            }
        }
    }
    v
}

/// Observations at every positive lattice line, at each of `points`.
fn every_line(points: &[Vec<f64>]) -> impl Fn(&SteadyState) -> Vec<Observation> + '_ {
    move |st: &SteadyState| {
        st.lattice_hz
            .iter()
            .filter(|&&f| f > 0.0)
            .flat_map(|&f| {
                points.iter().map(move |s| Observation {
                    f_hz: f,
                    shape: s.clone(),
                })
            })
            .collect()
    }
}

/// The nanostring of the paper (Table S2) with coupling `g12` and the given forces.
fn nanostring_theta(g12: f64, force: Vec<Vec<Complex64>>) -> Theta {
    let w = |f: f64| (TAU * f).powi(2);
    Theta {
        w2: vec![w(207582.0), w(415842.0)],
        gamma: vec![TAU * 207582.0 / 116232.0, TAU * 415842.0 / 599173.0],
        params: vec![2.68e22, 3.70e23, g12],
        force,
        pumps: Vec::new(),
    }
}

#[test]
fn nanostring_three_tones_match_finite_differences() {
    let model = harmonid_model::parse_str(NANOSTRING, "nanostring.hb").expect("model");
    let c = |x: f64| Complex64::new(x, 0.0);
    let theta = nanostring_theta(
        8.57e22,
        vec![
            vec![c(3.5), c(3.5), c(0.0)],
            vec![c(0.0), Complex64::new(0.0, 0.2), c(1.81)],
        ],
    );
    let tones = [207572.5, 207592.5, 415841.5];
    let points = vec![vec![0.309, 0.588], vec![1.0, -0.5]];
    let params = all_params(2, 3, 3);
    let (worst, ..) = check_against_fd(&model, &theta, &tones, &params, every_line(&points));
    assert!(worst < 1e-6, "worst relative error {worst:e}");
}

#[test]
fn three_wave_with_a_shared_line_matches_finite_differences() {
    let model = harmonid_model::parse_str(THREE_WAVE, "three_wave.hb").expect("model");
    let f = [1.0e6, 1.6e6, 2.6e6];
    let q = 1e4;
    let c = |x: f64| Complex64::new(x, 0.0);
    // Tone 0 also pushes q2 (off resonance) hard enough that both q1 and q2 contribute to
    // the signal at that line.
    let theta = Theta {
        w2: f.iter().map(|&x| (TAU * x).powi(2)).collect(),
        gamma: f.iter().map(|&x| TAU * x / q).collect(),
        params: vec![5e18, 2e27, 1e27, 5e26],
        force: vec![
            vec![c(4.0), c(2.0), c(0.0)],
            vec![c(1.9e4), c(0.0), Complex64::new(1.0, 3.0)],
            vec![c(0.0), c(0.0), c(0.0)],
        ],
        pumps: Vec::new(),
    };
    let tones = [1.0e6 + 20.0, 1.0e6 + 60.0, 1.6e6 + 30.0];
    let points = vec![vec![0.3, 0.6, 0.8], vec![1.0, -0.5, 0.2]];
    let params = all_params(3, 4, 3);
    let (worst, state, obs, out) =
        check_against_fd(&model, &theta, &tones, &params, every_line(&points));
    assert!(worst < 1e-6, "worst relative error {worst:e}");
    // The shared line: q1 and q2 both carry a sizable part of the signal at tone 0.
    let r = state.index(tones[0]).expect("tone on the lattice");
    let (x1, x2) = (state.amplitudes[0][r], state.amplitudes[1][r]);
    assert!(
        x2.norm() > 0.1 * x1.norm() && x1.norm() > 0.1 * x2.norm(),
        "{x1} {x2}"
    );
    // ... and q3 is pumped at the sum frequency (three-wave mixing), seen by the sensitivities
    // to kappa.
    let sum = tones[0] + tones[2];
    let o = obs
        .iter()
        .position(|o| (o.f_hz - sum).abs() < 1e-6)
        .expect("sum line observed");
    let k = params
        .iter()
        .position(|&p| p == SensParam::Param(0))
        .expect("kappa");
    assert!(out[k * obs.len() + o].norm() > 0.0);
    assert!(state.amplitudes[2][state.index(sum).expect("sum line")].norm() > 1e-12);
}

#[test]
fn a_parameter_at_zero_keeps_its_sensitivity() {
    // g12 = 0: the term vanishes from the forces but its parameter still moves the state.
    let model = harmonid_model::parse_str(NANOSTRING, "nanostring.hb").expect("model");
    let c = |x: f64| Complex64::new(x, 0.0);
    let theta = nanostring_theta(0.0, vec![vec![c(3.5), c(0.0)], vec![c(0.0), c(1.81)]]);
    let tones = [207572.5, 415841.5];
    let points = vec![vec![0.309, 0.588]];
    let (worst, ..) = check_against_fd(
        &model,
        &theta,
        &tones,
        &[SensParam::Param(2)],
        every_line(&points),
    );
    assert!(worst < 1e-6, "worst relative error {worst:e}");
}

#[test]
fn nonlinear_damping_and_a_velocity_coupling_match_finite_differences() {
    // The nanostring with amplitude-dependent damping of q1 (eta1 q1^2 q1') and damping of q1
    // induced by q2 (eta12 q2^2 q1'), each about a linewidth's worth at the driven amplitude.
    let src = format!(
        "{NANOSTRING}\n param eta1, eta12\n eom q1 += eta1*q1^2*d(q1) + eta12*q2^2*d(q1)\n"
    );
    let model = harmonid_model::parse_str(&src, "damped.hb").expect("model");
    let c = |x: f64| Complex64::new(x, 0.0);
    let mut theta = nanostring_theta(
        8.57e22,
        vec![
            vec![c(3.5), c(3.5), c(0.0)],
            vec![c(0.0), Complex64::new(0.0, 0.2), c(1.81)],
        ],
    );
    theta.params.extend([3e14, 1e14]);
    let tones = [207572.5, 207592.5, 415841.5];
    let points = vec![vec![0.309, 0.588], vec![1.0, -0.5]];
    let params = all_params(2, 5, 3);
    let (worst, ..) = check_against_fd(&model, &theta, &tones, &params, every_line(&points));
    assert!(worst < 1e-6, "worst relative error {worst:e}");
}

#[test]
fn a_pumped_stiffness_matches_finite_differences() {
    // A Duffing mode with nonlinear damping, pumped at twice its resonance at half the
    // parametric threshold, driven by two tones: λ is an ordinary unknown.
    let src = "mode q1 at 1 kHz\n param beta, eta, lambda\n\
               eom q1 += beta*q1^3 + eta*q1^2*d(q1) + lambda*pump*q1";
    let model = harmonid_model::parse_str(src, "pumped.hb").expect("model");
    let w = TAU * 1000.0;
    let q = 1000.0;
    let theta = Theta {
        w2: vec![w * w],
        gamma: vec![w / q],
        params: vec![1e13, 1e12, 1.0],
        force: vec![vec![Complex64::new(3.0, 0.0), Complex64::new(1.0, 0.5)]],
        pumps: vec![PumpTone {
            hz: 2000.0,
            amplitude: Complex64::from_polar(w * w / q, 0.4),
        }],
    };
    let tones = [1001.0, 1002.0];
    let params = all_params(1, 3, 2);
    let (worst, ..) = check_against_fd(&model, &theta, &tones, &params, every_line(&[vec![1.0]]));
    assert!(worst < 1e-6, "worst relative error {worst:e}");
}
