use super::test_models::duffing;
use super::*;
use crate::{linear_response, Excitation, NumericModel, Term};
use num_complex::Complex64;
use std::f64::consts::TAU;

#[test]
fn status_reads_as_words() {
    let s = HbStatus::NotConverged {
        drive_fraction: 0.8996,
    };
    assert_eq!(s.to_string(), "stopped at 90.0 % of the drive");
    assert!(!s.to_string().contains('{'));
    let short = HbStatus::NotConverged {
        drive_fraction: 0.99996,
    };
    assert_eq!(short.to_string(), "stopped at 99.996 % of the drive");
    let full = HbStatus::NotConverged {
        drive_fraction: 1.0,
    };
    assert_eq!(
        full.to_string(),
        "no steady state settled at the full drive"
    );
}

#[test]
fn vanishing_drive_is_linear_frf() {
    let m = duffing(1e12, 100.0);
    let drive = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![995.0, 1005.0],
        force: vec![vec![Complex64::new(1e-6, 0.0), Complex64::new(0.0, 2e-6)]],
    };
    let st = steady_state(&m, &drive, &HbSettings::default()).expect("solve");
    assert!(st.converged(), "{:?}", st.status);
    for (d, &f) in drive.tones_hz.iter().enumerate() {
        let want = linear_response(m.omega(0), m.gamma(0), f, drive.force[0][d]);
        let got = st.amplitude(0, f);
        assert!((got - want).norm() <= 1e-9 * want.norm(), "{got} vs {want}");
    }
}

#[test]
fn single_tone_matches_cubic_balance() {
    // One harmonic: (ω² − Ω² + iΩγ) X + 3/4 β |X|² X = F, checked on the solution.
    let beta = 4e13;
    let m = duffing(beta, 100.0);
    let drive = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![1003.0],
        force: vec![vec![Complex64::new(30.0, 0.0)]],
    };
    let mut s = HbSettings::default();
    s.lattice.window_rel = 0.01; // only the fundamental (3f is far)
    let st = steady_state(&m, &drive, &s).expect("solve");
    assert!(st.converged());
    assert_eq!(st.lattice_hz, vec![1003.0]);
    let x = st.amplitude(0, 1003.0);
    let o = TAU * 1003.0;
    let l = Complex64::new(m.omega(0).powi(2) - o * o, o * m.gamma(0));
    let r = l * x + x * x.norm_sqr() * 0.75 * beta - 30.0;
    assert!(r.norm() < 1e-9 * 30.0, "{r}");
    // Nonlinear: differs clearly from the linear response.
    let lin = linear_response(m.omega(0), m.gamma(0), 1003.0, Complex64::new(30.0, 0.0));
    assert!((x - lin).norm() > 0.05 * lin.norm());
}

/// Positive roots `a = |X|²` of the one-harmonic Duffing balance
/// `k² a³ + 2pk a² + (p² + q²) a − |F|² = 0` (`L = p + iq`, `k = 3β/4`).
fn duffing_roots(l: Complex64, k: f64, f: f64) -> Vec<f64> {
    let g = |a: f64| k * k * a * a * a + 2.0 * l.re * k * a * a + l.norm_sqr() * a - f * f;
    let grid: Vec<f64> = (0..4000)
        .map(|i| 1e-16 * 10f64.powf(i as f64 / 250.0))
        .collect();
    let mut out = Vec::new();
    for w in grid.windows(2) {
        let (mut lo, mut hi) = (w[0], w[1]);
        if g(lo).signum() == g(hi).signum() {
            continue;
        }
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if g(mid).signum() == g(lo).signum() {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        out.push(0.5 * (lo + hi));
    }
    out
}

#[test]
fn duffing_branches_stability() {
    // Hardening Duffing, f0 = 1 kHz, Q = 100, strongly driven: three branches above resonance.
    let beta = 4e13;
    let m = duffing(beta, 100.0);
    let force = 300.0;
    let k = 0.75 * beta;
    let (w, g) = (m.omega(0), m.gamma(0));
    let mut found = None;
    for i in 0..400 {
        let f = 1000.0 + 0.5 * i as f64;
        let o = TAU * f;
        let l = Complex64::new(w * w - o * o, o * g);
        let roots = duffing_roots(l, k, force);
        if roots.len() == 3 {
            found = Some((f, l, roots));
            break;
        }
    }
    let (f, l, roots) = found.expect("a frequency with three branches");
    let drive = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![f],
        force: vec![vec![Complex64::new(force, 0.0)]],
    };
    let mut solver = HbSolver::with_lattice(&m, &drive, vec![f]).expect("solver");
    let mut verdicts = Vec::new();
    for &a in &roots {
        let x = Complex64::new(force, 0.0) / (l + k * a);
        let st = solver.solve_from(&[vec![x]], &HbSettings::default());
        assert!(st.converged());
        assert!((st.amplitudes[0][0] - x).norm() < 1e-8 * x.norm());
        let v = solver.stability(&st).expect("verdict");
        verdicts.push((v, st));
    }
    // Lower and upper branches stable, the middle one a saddle.
    assert!(verdicts[0].0.stable && verdicts[2].0.stable, "{verdicts:?}");
    assert!(!verdicts[1].0.stable, "{:?}", verdicts[1].0);
    assert!(verdicts[1].0.growth_rate > 1e-3 * verdicts[1].0.linear_decay_rate);
    // Stable branches decay no faster than the linear resonator (rate γ/2).
    for i in [0, 2] {
        let v = verdicts[i].0;
        assert!(
            v.growth_rate < 0.0 && v.growth_rate >= -1.1 * v.linear_decay_rate,
            "{v:?}"
        );
    }
    // check_stability agrees, and a linear-regime state is stable at rate ≈ γ/2.
    let v = check_stability(&m, &drive, &verdicts[1].1).expect("verdict");
    assert!(!v.stable);
    let weak = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![1000.0],
        force: vec![vec![Complex64::new(1e-3, 0.0)]],
    };
    let st = steady_state(&m, &weak, &HbSettings::default()).expect("solve");
    let v = check_stability(&m, &weak, &st).expect("verdict");
    assert!(v.stable);
    assert!((v.growth_rate + 0.5 * g).abs() < 1e-3 * g, "{v:?}");
}

/// The nanostring of the method's paper (two coupled Duffing modes).
fn nanostring() -> NumericModel {
    let t = |eq, coef, factors: Vec<(usize, u32)>| Term { eq, coef, factors };
    NumericModel::new(
        vec!["q1".into(), "q2".into()],
        vec![207582.0, 415842.0],
        vec![116232.0, 599173.0],
        vec![
            t(0, 2.68e22, vec![(0, 3)]),
            t(0, 8.57e22, vec![(0, 1), (1, 2)]),
            t(1, 8.57e22, vec![(0, 2), (1, 1)]),
            t(1, 3.70e23, vec![(1, 3)]),
        ],
    )
    .expect("model")
}

/// Largest amplitude difference relative to the largest amplitude.
fn rel_change(a: &SteadyState, b: &SteadyState) -> f64 {
    let big = a
        .amplitudes
        .iter()
        .flatten()
        .map(|z| z.norm())
        .fold(0.0, f64::max);
    let diff = a
        .amplitudes
        .iter()
        .flatten()
        .zip(b.amplitudes.iter().flatten())
        .map(|(x, y)| (x - y).norm())
        .fold(0.0, f64::max);
    diff / big
}

/// The paper's coupled measurement of the nanostring: a pair on q1, one tone on q2.
fn three_tone_drive() -> Excitation {
    let c = |x: f64| Complex64::new(x, 0.0);
    Excitation {
        pumps: Vec::new(),
        tones_hz: vec![207572.5, 207592.5, 415841.5],
        force: vec![vec![c(3.5), c(3.5), c(0.0)], vec![c(0.0), c(0.0), c(1.81)]],
    }
}

#[test]
fn coarse_ramp_lands_where_the_full_ramp_does() {
    let c = |x: f64| Complex64::new(x, 0.0);
    let model = nanostring();
    let three_tone = three_tone_drive();
    // Two tones above resonance, strong enough for the two-tone response to be bistable:
    // the drive-up branch is the low one, which a direct solve at full drive can miss.
    let bistable = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![207590.0, 207600.0],
        force: vec![vec![c(4.0), c(0.4)], vec![c(0.0), c(0.0)]],
    };
    let settings = HbSettings::default();
    for drive in [three_tone, bistable] {
        let mut solver = HbSolver::new(&model, &drive, &settings.lattice).expect("solver");
        let (coarse, lines) = solver.coarse.as_ref().expect("a coarse ramp lattice");
        assert!(lines.len() < solver.lattice.len() && coarse.lattice.len() == lines.len());
        let fast = solver.solve(&settings);
        let full = solver.solve_ramp(&settings);
        assert!(fast.converged() && full.converged(), "{fast:?} {full:?}");
        assert!(fast.residual <= settings.tol, "{}", fast.residual);
        let d = rel_change(&fast, &full);
        assert!(d < 1e-9, "coarse and full ramps differ by {d:e}");
        if drive.tones_hz[1] - drive.tones_hz[0] < 15.0 {
            // Bistable indeed: from a large guess Newton finds another steady state.
            let mut guess = fast.amplitudes.clone();
            guess[0].iter_mut().for_each(|z| *z *= 2.5);
            let other = solver.solve_from(&guess, &settings);
            assert!(other.converged() && rel_change(&fast, &other) > 0.1);
        }
    }
}

#[test]
fn drive_ramp_jumps_at_a_fold_like_the_experiment() {
    // Hardening Duffing above resonance: driven up at a fixed frequency, the low branch
    // ends at a fold in the force and the state jumps to the high branch, which is the
    // only state left beyond the fold.
    let beta = 4e13;
    let m = duffing(beta, 100.0);
    let k = 0.75 * beta;
    let (w, g) = (m.omega(0), m.gamma(0));
    let f = 1030.0;
    let o = TAU * f;
    let l = Complex64::new(w * w - o * o, o * g);
    // The fold: the largest force with three branches.
    let fold = (1..4000)
        .map(|i| 0.5 * i as f64)
        .filter(|&force| duffing_roots(l, k, force).len() == 3)
        .fold(0.0, f64::max);
    assert!(fold > 0.0, "no bistable range at {f} Hz");
    let force = 1.25 * fold;
    let roots = duffing_roots(l, k, force);
    assert_eq!(
        roots.len(),
        1,
        "beyond the fold only the high branch is left"
    );
    let want = Complex64::new(force, 0.0) / (l + k * roots[0]);
    let drive = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![f],
        force: vec![vec![Complex64::new(force, 0.0)]],
    };
    let st = steady_state(&m, &drive, &HbSettings::default()).expect("solve");
    assert!(st.converged(), "{:?}", st.status);
    let got = st.amplitude(0, f);
    assert!((got - want).norm() < 1e-8 * want.norm(), "{got} vs {want}");
    // One jump, where the low branch ends (fold / force), located to the ramp's step.
    assert_eq!(st.drive_jumps.len(), 1, "{:?}", st.drive_jumps);
    let at = st.drive_jumps[0] * force;
    assert!(
        (at - fold).abs() < 0.01 * fold,
        "jump at {at}, fold at {fold}"
    );
    assert!(check_stability(&m, &drive, &st).expect("verdict").stable);
}

#[test]
fn convergence_report_sees_the_far_harmonics() {
    // single_q1 of the nanostring: the lines near resonance are converged in the order
    // (1e-9), but the third harmonics near 623 kHz, outside the window, change them by
    // 1.2e-7 of the largest amplitude, 1.2e-6 relative on the sidebands (the time domain
    // agrees with the widened lattice to 2e-8).
    let c = |x: f64| Complex64::new(x, 0.0);
    let drive = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![207572.5, 207592.5],
        force: vec![vec![c(3.5), c(3.5)], vec![c(0.0), c(0.0)]],
    };
    let rep =
        convergence_report(&nanostring(), &drive, &HbSettings::default(), &[]).expect("report");
    assert!(rep.state.converged());
    assert!(rep.lattice_sizes.1 > rep.lattice_sizes.0);
    assert!(rep.change > 3e-8 && rep.change < 1e-5, "{:e}", rep.change);
}

/// A degenerate parametric pair: q1 at 1 kHz and q2 at 2 kHz (Q = 100 each) coupled by
/// `α q1² q2` (forces `2α q1 q2` on q1, `α q1²` on q2).
fn parametric_pair(alpha: f64) -> NumericModel {
    let t = |eq, coef, factors: Vec<(usize, u32)>| Term { eq, coef, factors };
    NumericModel::new(
        vec!["q1".into(), "q2".into()],
        vec![1000.0, 2000.0],
        vec![100.0, 100.0],
        vec![
            t(0, 2.0 * alpha, vec![(0, 1), (1, 1)]),
            t(1, alpha, vec![(0, 2)]),
        ],
    )
    .expect("model")
}

#[test]
fn condensed_stability_finds_the_parametric_threshold_of_the_closed_form() {
    // q2 driven at 2 f1 pumps q1 parametrically: averaging gives the slow flow
    // Ẋ1 = −γ/2 X1 + iα X2/(2ω1) X1*, whose growth rate is −γ/2 + α|X2|/(2ω1) (threshold at
    // |X2| = γω1/α). A weak probe 3 Hz above f1 puts q1's lines near its resonance (1003 Hz
    // and the idler at 997 Hz) on the lattice.
    let alpha = 1e10;
    let m = parametric_pair(alpha);
    let (w1, g1) = (m.omega(0), m.gamma(0));
    let (w2, g2) = (m.omega(1), m.gamma(1));
    let threshold_force = g1 * w1 / alpha * g2 * w2;
    let settings = HbSettings::default();
    for ratio in [0.8, 0.95, 1.05, 1.3] {
        let drive = Excitation {
            pumps: Vec::new(),
            tones_hz: vec![1003.0, 2000.0],
            force: vec![
                vec![Complex64::new(1e-3, 0.0), Complex64::new(0.0, 0.0)],
                vec![
                    Complex64::new(0.0, 0.0),
                    Complex64::new(ratio * threshold_force, 0.0),
                ],
            ],
        };
        let mut solver = HbSolver::new(&m, &drive, &settings.lattice).expect("solver");
        let st = solver.solve_from(&vec![vec![Z; solver.lattice.len()]; 2], &settings);
        assert!(st.converged(), "{:?}", st.status);
        let want = -0.5 * g1 + alpha * st.amplitude(1, 2000.0).norm() / (2.0 * w1);
        let condensed = solver.slow_flow_stability(&st, true).expect("verdict");
        let whole = solver.slow_flow_stability(&st, false).expect("verdict");
        assert!(
            (condensed.growth_rate - want).abs() < 0.02 * g1,
            "{ratio}: growth {} against the closed form {want}",
            condensed.growth_rate
        );
        // Here the slowest mode is physical, so the whole flow has it too.
        assert!(
            (condensed.growth_rate - whole.growth_rate).abs() < 1e-3 * g1,
            "{ratio}: condensed {} whole {}",
            condensed.growth_rate,
            whole.growth_rate
        );
        assert_eq!(condensed.stable, ratio < 1.0, "{ratio}: {condensed:?}");
    }
}

#[test]
fn condensed_stability_leaves_out_the_harmonics_copies_of_the_decay() {
    // A stable single-tone Duffing state with its harmonics: the averaged flow's eigenvalues
    // are a complex pair with real part −γ/2 (trace −γ) when the state is far from a fold.
    // On each harmonic line the slow flow puts a copy decaying at γ(ω² + Ω²)/(4Ω²) (0.28 γ on
    // the third, 0.26 γ on the fifth), which the whole flow reports as the slowest decay.
    let m = duffing(4e13, 100.0);
    let g = m.gamma(0);
    let drive = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![990.0],
        force: vec![vec![Complex64::new(100.0, 0.0)]],
    };
    let settings = HbSettings::default();
    let mut solver =
        HbSolver::with_lattice(&m, &drive, vec![990.0, 2970.0, 4950.0]).expect("solver");
    let st = solver.solve(&settings);
    assert!(st.converged() && st.amplitude(0, 2970.0).norm() > 0.0);
    let condensed = solver.slow_flow_stability(&st, true).expect("verdict");
    let whole = solver.slow_flow_stability(&st, false).expect("verdict");
    assert!(
        (condensed.growth_rate + 0.5 * g).abs() < 0.01 * g,
        "{condensed:?}"
    );
    let copy = -g * (1.0 + (1000.0_f64 / 4950.0).powi(2)) / 4.0;
    assert!(
        (whole.growth_rate - copy).abs() < 0.01 * g,
        "{whole:?} against {copy}"
    );
}

#[test]
fn a_state_continued_onto_a_wider_lattice_is_the_one_the_ramp_finds_there() {
    // The truncation check's wider lattice: Newton from the narrower state lands on the state
    // the drive ramp from rest finds on the wider lattice, in a step or two, and keeps the
    // narrower state's jumps.
    let model = nanostring();
    let drive = three_tone_drive();
    let narrow = HbSettings::default();
    let mut wide = narrow.clone();
    wide.lattice.order += 2;
    wide.lattice.window_rel *= 1.5;
    wide.lattice.harmonics = true;
    let st = steady_state(&model, &drive, &narrow).expect("narrow");
    let from_rest = steady_state(&model, &drive, &wide).expect("wide");
    let continued = steady_state_from(&model, &drive, &wide, &st).expect("continued");
    assert!(continued.lattice_hz.len() > st.lattice_hz.len());
    assert_eq!(continued.lattice_hz, from_rest.lattice_hz);
    let HbStatus::Converged { iterations } = continued.status else {
        panic!("{:?}", continued.status);
    };
    assert!(iterations <= 2, "{iterations} Newton steps");
    let d = rel_change(&continued, &from_rest);
    assert!(d < 1e-9, "continued and ramped states differ by {d:e}");
    assert_eq!(continued.drive_jumps, st.drive_jumps);
    assert_eq!(continued.ramp_steps, st.ramp_steps);
}

/// States of the parametric pair on both sides of its threshold and of the nanostring under
/// three tones, each scaled from weak to far past its fold (`HbSolver`s with their states).
fn states_weak_to_strong() -> Vec<(HbSolver, Vec<SteadyState>)> {
    let settings = HbSettings::default();
    let scaled = |st: &SteadyState, k: f64| SteadyState {
        amplitudes: st
            .amplitudes
            .iter()
            .map(|row| row.iter().map(|z| z * k).collect())
            .collect(),
        lattice_hz: st.lattice_hz.clone(),
        drive_jumps: Vec::new(),
        ..*st
    };
    let mut out = Vec::new();
    let m = parametric_pair(1e10);
    let threshold = m.gamma(0) * m.omega(0) / 1e10 * m.gamma(1) * m.omega(1);
    for ratio in [0.3, 0.95, 1.3] {
        let c = |x: f64| Complex64::new(x, 0.0);
        let drive = Excitation {
            pumps: Vec::new(),
            tones_hz: vec![1003.0, 2000.0],
            force: vec![vec![c(1e-3), c(0.0)], vec![c(0.0), c(ratio * threshold)]],
        };
        let mut solver = HbSolver::new(&m, &drive, &settings.lattice).expect("solver");
        let st = solver.solve_from(&vec![vec![Z; solver.lattice.len()]; 2], &settings);
        assert!(st.converged());
        let states = [0.1, 1.0, 3.0].iter().map(|&k| scaled(&st, k)).collect();
        out.push((solver, states));
    }
    let drive = three_tone_drive();
    let mut solver = HbSolver::new(&nanostring(), &drive, &settings.lattice).expect("solver");
    let st = solver.solve(&settings);
    assert!(st.converged());
    let states = [0.05, 0.3, 1.0, 3.0]
        .iter()
        .map(|&k| scaled(&st, k))
        .collect();
    out.push((solver, states));
    out
}

/// The norm bound that lets a verdict skip a block's spectrum (`HbSolver::growth_bound`) lies
/// above every growth rate of the condensed flow it stands for, and the verdict without the
/// blocks it proves (`unproven_growth`) is the full one, with the full growth rate whenever
/// a block is left to compute. Both proven and unproven blocks, stable and unstable
/// verdicts occur.
#[test]
fn the_growth_bound_holds_and_skipping_proven_blocks_keeps_the_verdict() {
    let (mut proven, mut unproven, mut unstable) = (0, 0, 0);
    for (mut solver, states) in states_weak_to_strong() {
        for st in &states {
            for (bound, growth) in solver.bounds_and_growths(st).expect("bounds") {
                assert!(growth <= bound, "growth {growth} above its bound {bound}");
                if bound < 0.0 {
                    proven += 1;
                } else {
                    unproven += 1;
                }
            }
            let exact = solver.stability(st).expect("verdict");
            let quick = solver.unproven_growth(st, None).expect("quick verdict");
            let threshold = 1e-6 * exact.linear_decay_rate;
            assert_eq!(exact.stable, quick < threshold, "{exact:?} vs {quick}");
            assert!(quick <= exact.growth_rate);
            if quick > f64::NEG_INFINITY {
                assert_eq!(quick, exact.growth_rate);
            }
            unstable += usize::from(!exact.stable);
        }
    }
    assert!(
        proven > 0 && unproven > 0 && unstable > 0,
        "proven {proven}, unproven {unproven}, unstable {unstable}"
    );
}

/// `check_stability` keeps its solvers between calls: over devices with other values on the
/// same lattice and tones (the parametric pair on both sides of its threshold), another
/// lattice and back, its verdicts and rates are bit for bit those of a solver set up for each
/// call.
#[test]
fn kept_stability_solvers_give_a_fresh_solvers_verdicts() {
    let settings = HbSettings::default();
    let c = |x: f64| Complex64::new(x, 0.0);
    let mut stable = [0, 0];
    for (k, (alpha, ratio)) in [
        (1e10, 0.8),
        (2e10, 1.3),
        (1e10, 1.2),
        (3e10, 0.5),
        (1e10, 0.8),
    ]
    .into_iter()
    .enumerate()
    {
        let m = parametric_pair(alpha);
        let threshold = m.gamma(0) * m.omega(0) / alpha * m.gamma(1) * m.omega(1);
        let probe = if k == 2 { 1005.0 } else { 1003.0 };
        let d = Excitation {
            pumps: Vec::new(),
            tones_hz: vec![probe, 2000.0],
            force: vec![vec![c(1e-3), c(0.0)], vec![c(0.0), c(ratio * threshold)]],
        };
        let mut solver = HbSolver::new(&m, &d, &settings.lattice).expect("solver");
        let st = solver.solve_from(&vec![vec![Z; solver.lattice.len()]; 2], &settings);
        let kept = check_stability(&m, &d, &st).expect("kept");
        let fresh = super::stability::check_stability_fresh(&m, &d, &st).expect("fresh");
        assert_eq!(kept.stable, fresh.stable, "{k}");
        assert_eq!(
            kept.growth_rate.to_bits(),
            fresh.growth_rate.to_bits(),
            "{k}"
        );
        assert_eq!(kept.linear_decay_rate, fresh.linear_decay_rate);
        stable[usize::from(kept.stable)] += 1;
    }
    assert_eq!(stable, [2, 3], "unstable above the threshold, stable below");
}
