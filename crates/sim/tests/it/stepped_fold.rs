//! Stepped sweeps through strong folds: a stepped-sine measurement follows its branch up to the
//! fold where that branch ends and jumps there, as the device does, so an up- and a down-sweep
//! end on different branches. Against the closed form: the saddle-nodes of the single-harmonic
//! Duffing cubic, and its three roots in between.

use harmonid_sim::{
    stepped_sweep, Excitation, HbSettings, ModeValues, ModelValues, NumericModel, SteadyState,
};
use num_complex::Complex64;
use std::f64::consts::TAU;

const F0: f64 = 10_000.0;
const Q: f64 = 1000.0;

/// `q̈ + γq̇ + ω0²q + βq³ = F cos Ωt` at 10 kHz, Q = 1000 (linewidth 10 Hz).
fn duffing(beta: f64) -> NumericModel {
    let src = "mode q1, f = 10 kHz, Q = 1000\nparam beta1\neom q1 += beta1*q1^3\n";
    let m = harmonid_model::parse_str(src, "duffing.hb").expect("parses");
    let mut v = ModelValues::default();
    v.parameters.insert("beta1".into(), beta);
    NumericModel::from_model(&m, &v).expect("numeric model")
}

/// The single-harmonic cubic in `u = a²`: `c²u³ + 2cd u² + (d² + (γΩ)²) u − F² = 0`,
/// `c = ¾β`, `d = ω0² − Ω²`, as its coefficients `[a3, a2, a1, a0]`.
fn cubic(beta: f64, force: f64, w: f64) -> [f64; 4] {
    let (w0, g) = (TAU * F0, TAU * F0 / Q);
    let (c, d) = (0.75 * beta, w0 * w0 - w * w);
    [c * c, 2.0 * c * d, d * d + (g * w).powi(2), -force * force]
}

/// The cubic's discriminant at `f_hz`: positive where it has three real roots (bistable).
fn discriminant(beta: f64, force: f64, f_hz: f64) -> f64 {
    let [a, b, c, d] = cubic(beta, force, TAU * f_hz);
    18.0 * a * b * c * d - 4.0 * b.powi(3) * d + b * b * c * c
        - 4.0 * a * c.powi(3)
        - 27.0 * a * a * d * d
}

/// The saddle-nodes (Hz, ascending): where the discriminant changes sign, bisected from a
/// 0.01 Hz scan of `[lo, hi]`.
fn saddle_nodes(beta: f64, force: f64, lo: f64, hi: f64) -> Vec<f64> {
    let n = ((hi - lo) / 0.01) as usize;
    let disc = |f: f64| discriminant(beta, force, f);
    let mut out = Vec::new();
    for k in 0..n {
        let (mut a, mut b) = (lo + 0.01 * k as f64, lo + 0.01 * (k + 1) as f64);
        if disc(a).signum() == disc(b).signum() {
            continue;
        }
        for _ in 0..60 {
            let m = 0.5 * (a + b);
            if disc(m).signum() == disc(a).signum() {
                a = m;
            } else {
                b = m;
            }
        }
        out.push(0.5 * (a + b));
    }
    out
}

/// The cubic's real roots as amplitudes `a = √u` (ascending), by bisection between the
/// stationary points of the cubic.
fn amplitudes(beta: f64, force: f64, f_hz: f64) -> Vec<f64> {
    let [a, b, c, d] = cubic(beta, force, TAU * f_hz);
    let p = |u: f64| ((a * u + b) * u + c) * u + d;
    let mut knots = vec![0.0];
    let disc = b * b - 3.0 * a * c;
    if disc > 0.0 {
        for s in [-1.0, 1.0] {
            let u = (-b + s * disc.sqrt()) / (3.0 * a);
            if u > 0.0 {
                knots.push(u);
            }
        }
    }
    knots.sort_by(f64::total_cmp);
    let mut top = knots.last().copied().unwrap_or(0.0).max(1e-30) * 2.0;
    while p(top) < 0.0 {
        top *= 2.0;
    }
    knots.push(top);
    let mut roots = Vec::new();
    for w in knots.windows(2) {
        let (mut lo, mut hi) = (w[0], w[1]);
        if p(lo).signum() == p(hi).signum() {
            continue;
        }
        for _ in 0..200 {
            let m = 0.5 * (lo + hi);
            if p(m).signum() == p(lo).signum() {
                lo = m;
            } else {
                hi = m;
            }
        }
        roots.push((0.5 * (lo + hi)).sqrt());
    }
    roots
}

/// The stepped sweep over `steps_hz` in that order under the force `force` (N/kg).
fn stepped(m: &NumericModel, force: f64, steps_hz: &[f64]) -> Vec<SteadyState> {
    let drives: Vec<Excitation> = steps_hz
        .iter()
        .map(|&f| Excitation {
            pumps: Vec::new(),
            tones_hz: vec![f],
            force: vec![vec![Complex64::new(force, 0.0)]],
        })
        .collect();
    stepped_sweep(m, &drives, &HbSettings::default()).expect("sweep")
}

/// Where a sweep's amplitude changes most from one step to the next: the two steps'
/// frequencies (in the sweep's order).
fn jump(steps_hz: &[f64], states: &[SteadyState]) -> (f64, f64) {
    let a: Vec<f64> = steps_hz
        .iter()
        .zip(states)
        .map(|(&f, s)| s.amplitude(0, f).norm())
        .collect();
    let k = (0..a.len() - 1)
        .max_by(|&i, &j| {
            let r = |k: usize| (a[k + 1] / a[k]).ln().abs();
            r(i).total_cmp(&r(j))
        })
        .expect("steps");
    (steps_hz[k], steps_hz[k + 1])
}

/// A strong fold, hardening or softening: the backbone leans 8 linewidths at a linear peak of
/// 1 µm, the jumps are 4-6 times the amplitude. Stepped up and down in 0.5 Hz (1/20 linewidth)
/// steps, the up-sweep jumps between the two steps around the upper saddle-node, the down-sweep
/// around the lower one (to 0.1 Hz, the third harmonic's shift of the folds, which the
/// single-harmonic cubic leaves out: ~0.05 Hz here), and each step sits within 1 % on the
/// branch the cubic's roots say: the high one of the bistable range for the sweep that
/// entered it on the high branch, the low one for the other.
#[test]
fn stepped_sweeps_jump_at_the_closed_form_folds() {
    let w0 = TAU * F0;
    let a_peak = 1e-6;
    let force = a_peak * w0 * w0 / Q;
    let shift = 8.0 * TAU * F0 / Q;
    let beta_abs = shift * 8.0 * w0 / (3.0 * a_peak * a_peak);
    let step = 0.5;
    for beta in [beta_abs, -beta_abs] {
        let m = duffing(beta);
        let (lo, hi) = if beta > 0.0 {
            (F0 - 40.0, F0 + 120.0)
        } else {
            (F0 - 120.0, F0 + 40.0)
        };
        let folds = saddle_nodes(beta, force, lo, hi);
        assert_eq!(folds.len(), 2, "beta {beta:e}: saddle-nodes {folds:?}");
        let (f_lower, f_upper) = (folds[0], folds[1]);
        let n = ((hi - lo) / step) as usize;
        let up: Vec<f64> = (0..=n).map(|k| lo + step * k as f64 + 0.123).collect();
        let down: Vec<f64> = up.iter().rev().copied().collect();
        for (steps, fold, upward) in [(&up, f_upper, true), (&down, f_lower, false)] {
            let states = stepped(&m, force, steps);
            let mut bistable = 0;
            for (&f, s) in steps.iter().zip(&states) {
                assert!(
                    s.converged(),
                    "beta {beta:e} at {f} Hz: {} (folds {f_lower} {f_upper}) {:e} {:e}",
                    s.status,
                    s.residual,
                    s.amplitude(0, f).norm()
                );
                let roots = amplitudes(beta, force, f);
                // Which branch: the sweep entered the bistable range on the high branch
                // when it came from the side of the backbone's lean (hardening: up).
                let high = upward == (beta > 0.0);
                let want = match roots.len() {
                    3 => {
                        bistable += 1;
                        if high {
                            roots[2]
                        } else {
                            roots[0]
                        }
                    }
                    _ => roots[0],
                };
                let a = s.amplitude(0, f).norm();
                assert!(
                    (a - want).abs() < 0.01 * want,
                    "beta {beta:e}, {} at {f} Hz: {a:e} where the branch has {want:e} (roots {roots:?}, folds {f_lower} {f_upper})",
                    if upward { "up" } else { "down" }
                );
            }
            assert!(bistable > 100, "{bistable} steps in the bistable range");
            let (before, after) = jump(steps, &states);
            let (a, b) = (before.min(after), before.max(after));
            assert!(
                a - 0.1 <= fold && fold <= b + 0.1,
                "beta {beta:e}: the {} sweep jumps between {before} and {after} Hz, the fold is at {fold} Hz",
                if upward { "up" } else { "down" }
            );
            println!(
                "beta {beta:e}: {} sweep jumps between {before:.3} and {after:.3} Hz; closed-form fold {fold:.3} Hz",
                if upward { "up" } else { "down" }
            );
        }
    }
}

/// The held-back fold stand-in (`tests/it/held_back.rs`, `FOLD_VALUES=-2.4e18:0.25`): the
/// issue-36 beam (`examples/nonsmooth_beam`) softening by `κ|q|q` with κ six times the
/// example's and a quarter of its nonlinear damping. Its down-sweep at level 6 (linear peak
/// 5.9 nm) leaves the high branch 2.9 linewidths below the resonance; the landing there once
/// left the trajectory for a spurious 300 nm orbit and the step failed. It lands on the low
/// branch (about 1.3 nm) and every step converges.
#[test]
fn the_beam_stand_in_lands_on_the_low_branch_past_its_fold() {
    let src = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/nonsmooth_beam/model.hb"
    ))
    .expect("model");
    let model = harmonid_model::parse_str(&src, "model.hb").expect("model");
    let mut v = ModelValues::default();
    let (f, q) = (1e6, 2e4);
    v.modes.insert(
        "q1".into(),
        ModeValues {
            f_hz: Some(f),
            q: Some(q),
        },
    );
    for (n, x) in [
        ("beta1", 1e25),
        ("eta1", 0.25 * 5e18),
        ("kappa1", -2.4e18),
        ("drag1", 0.25 * 2e3),
    ] {
        v.parameters.insert(n.into(), x);
    }
    let m = NumericModel::from_model(&model, &v).expect("numeric");
    let (w, lw) = (TAU * f, f / q);
    let force = (1e-9 + 9e-9 * 6.0 / 11.0) * w * w / q;
    let down: Vec<f64> = (0..20)
        .rev()
        .map(|s| f + lw * (10.0 * f64::from(s) / 19.0 - 5.0))
        .collect();
    let states = stepped(&m, force, &down);
    for (k, (&fk, s)) in down.iter().zip(&states).enumerate() {
        assert!(s.converged(), "step {k} at {fk} Hz: {}", s.status);
    }
    let a = |k: usize| states[k].amplitude(0, down[k]).norm();
    assert!(a(14) > 4.5e-9, "step 14 on the high branch: {:e}", a(14));
    assert!(a(15) < 1.5e-9, "step 15 on the low branch: {:e}", a(15));
}
