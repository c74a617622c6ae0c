//! Linear response about a driven steady state (issue 38, item 4), against brute force and
//! closed forms: a weak second tone in the full nonlinear harmonic balance (signal and idler),
//! the slow flow's eigenfrequencies (the probe response's peaks), and the degenerate
//! parametric amplifier below threshold.

use harmonid_sim::{
    probe_response, steady_state, Excitation, HbSettings, HbSolver, NumericModel, PumpTone, Term,
};
use num_complex::Complex64;
use std::f64::consts::TAU;

const F0: f64 = 1000.0;
const Q: f64 = 1000.0;

/// One Duffing mode at 1 kHz, Q = 1000 (linewidth 1 Hz).
fn duffing(alpha: f64) -> NumericModel {
    let terms = vec![Term {
        eq: 0,
        coef: alpha,
        factors: vec![(0, 3)],
    }];
    NumericModel::new(vec!["q".into()], vec![F0], vec![Q], terms).expect("model")
}

/// Every combination of order ≤ 5 wherever it falls (3f, 5f, f_p + 2f_d, ...), so that the
/// brute force below holds the lines the linear response couples.
fn wide() -> HbSettings {
    let mut s = HbSettings::default();
    s.lattice.order = 5;
    s.lattice.window_rel = 10.0;
    s
}

/// Drive at `F0 + 8 Hz` with a Duffing shift of about 1.5 linewidths: the ramp's state on
/// the lower branch above the resonance, its slow flow a complex pair (about ±5 Hz) well
/// apart from the linewidth (1 Hz).
fn driven_state() -> (NumericModel, Excitation, harmonid_sim::SteadyState) {
    let m = duffing(4e15);
    let drive = Excitation::new(vec![F0 + 8.0], vec![vec![Complex64::new(3.0, 0.0)]]);
    let st = steady_state(&m, &drive, &wide()).expect("solves");
    assert!(st.converged(), "{:?}", st.status);
    (m, drive, st)
}

#[test]
fn signal_and_idler_match_a_weak_second_tone_in_the_nonlinear_balance() {
    let (m, drive, st) = driven_state();
    let fd = drive.tones_hz[0];
    let fp = fd + 3.7;
    let eps = Complex64::new(2e-7, 1e-7);
    let r = probe_response(&m, Some(&st), &[], 0, &[fp], eps, false).expect("response");
    let idler = r.line(-2.0 * fd).expect("idler line");
    let (f_idler, x_idler) = r.physical(0, 0, idler);
    assert!((f_idler - (2.0 * fd - fp)).abs() < 1e-9);
    let x_signal = r.amplitudes[0][0][0];
    // Brute force: the same drive plus the probe as a second tone, solved by the full
    // nonlinear harmonic balance (its lattice holds f_p and 2f_d − f_p).
    let two = Excitation::new(vec![fd, fp], vec![vec![Complex64::new(3.0, 0.0), eps]]);
    let full = steady_state(&m, &two, &wide()).expect("two tones");
    assert!(full.converged(), "{:?}", full.status);
    let hb_signal = full.amplitude(0, fp);
    let hb_idler = full.amplitude(0, 2.0 * fd - fp);
    let e_s = (x_signal - hb_signal).norm() / hb_signal.norm();
    let e_i = (x_idler - hb_idler).norm() / hb_idler.norm();
    eprintln!("signal {x_signal:.4e} vs {hb_signal:.4e} ({e_s:.1e}); idler {x_idler:.4e} vs {hb_idler:.4e} ({e_i:.1e})");
    assert!(hb_idler.norm() > 0.05 * hb_signal.norm(), "a real idler");
    assert!(e_s < 1e-6 && e_i < 1e-6, "{e_s:.2e} {e_i:.2e}");
}

/// The local maxima of `y` over the grid `x`, refined by a parabola through three points.
fn peaks(x: &[f64], y: &[f64]) -> Vec<f64> {
    (1..x.len() - 1)
        .filter(|&i| y[i] > y[i - 1] && y[i] >= y[i + 1])
        .map(|i| {
            let (a, b, c) = (y[i - 1], y[i], y[i + 1]);
            x[i] + 0.5 * (a - c) / (a - 2.0 * b + c) * (x[i + 1] - x[i])
        })
        .collect()
}

#[test]
fn its_peaks_sit_at_the_slow_flow_eigenfrequencies() {
    let (m, drive, st) = driven_state();
    let fd = drive.tones_hz[0];
    let mut solver = HbSolver::with_lattice(&m, &drive, st.lattice_hz.clone()).expect("solver");
    let eig = solver.slow_flow_eigenvalues(&st).expect("eigenvalues");
    let w = eig.iter().map(|z| z.im).fold(0.0, f64::max) / TAU;
    let decay = -eig[0].re / TAU;
    assert!(w > 10.0 * decay, "a well separated pair: {eig:?}");
    let fp: Vec<f64> = (0..3001).map(|i| fd - 15.0 + 0.01 * i as f64).collect();
    let r = probe_response(&m, Some(&st), &[], 0, &fp, Complex64::ONE, true).expect("response");
    let idler = r.line(-2.0 * fd).expect("idler");
    let offsets = |y: Vec<f64>| -> Vec<f64> { peaks(&fp, &y).iter().map(|f| f - fd).collect() };
    let signal = offsets(r.amplitudes.iter().map(|a| a[0][0].norm()).collect());
    let idlers = offsets(r.amplitudes.iter().map(|a| a[0][idler].norm()).collect());
    let psd = offsets(
        r.noise_psd
            .as_ref()
            .expect("psd")
            .iter()
            .map(|s| s[0])
            .collect(),
    );
    eprintln!("slow flow ±{w:.4} Hz (decay {decay:.3} Hz); peaks from the drive: signal {signal:?}, idler {idlers:?}, noise {psd:?} Hz");
    // The idler and the noise spectrum peak at both eigenfrequencies, the signal at the one on
    // the resonance's side (its other pole is nearly cancelled). Each peak within 1 % of `w`:
    // the other pole's tail moves a peak by ~(decay)²/w (0.04 Hz here).
    assert_eq!(signal.len(), 1, "{signal:?}");
    assert!((signal[0] + w).abs() < 0.01 * w, "{signal:?}");
    for found in [idlers, psd] {
        assert_eq!(found.len(), 2, "{found:?}");
        for (p, want) in found.iter().zip([-w, w]) {
            assert!(
                (p - want).abs() < 0.01 * w,
                "peak at {p} Hz, slow flow {want} Hz"
            );
        }
    }
}

#[test]
fn the_parametric_amplifier_below_threshold_has_its_closed_form_gain() {
    // q̈ + γq̇ + ω²q + λ pump q = probe, pump = P cos(2Ω₀t) at half the threshold: the lines
    // f_p and f_P − f_p couple through λP/2; the far lines (f_p + f_P, ...) change the
    // two-line closed form by ~(λP/2)²/|L(f_p + f_P)·L(f_p)| ≈ 1/(32 Q) = 3e-5.
    let lambda_p = 0.5 * 2.0 * (TAU * F0).powi(2) / Q;
    let m = NumericModel::new(
        vec!["q".into()],
        vec![F0],
        vec![Q],
        vec![Term {
            eq: 0,
            coef: 1.0,
            factors: vec![(0, 1), (2, 1)],
        }],
    )
    .expect("model");
    let pump = [PumpTone {
        hz: 2.0 * F0,
        amplitude: Complex64::new(lambda_p, 0.0),
    }];
    let fp = F0 + 0.01;
    let r = probe_response(&m, None, &pump, 0, &[fp], Complex64::ONE, false).expect("response");
    let l = |f: f64| {
        let o = TAU * f;
        let w = TAU * F0;
        Complex64::new(w * w - o * o, o * w / Q)
    };
    let k = lambda_p / 2.0;
    // L(Ω_p) X + k Y = 1, L(Ω_p − Ω_P) Y + k X = 0 (Y on the line f_p − f_P < 0).
    let li = l(fp - 2.0 * F0);
    let x = Complex64::ONE / (l(fp) - k * k / li);
    let y = -k * x / li;
    let idler = r.line(-2.0 * F0).expect("idler");
    let (ex, ey) = (
        (r.amplitudes[0][0][0] - x).norm() / x.norm(),
        (r.amplitudes[0][0][idler] - y).norm() / y.norm(),
    );
    assert!(ex < 1e-4 && ey < 1e-4, "{ex:.2e} {ey:.2e}");
    // The gain over the unpumped Lorentzian: 1/(1 − (λP/2γω)²) = 4/3 on resonance (here
    // 1% of a half linewidth off it).
    let g = r.amplitudes[0][0][0].norm() * l(fp).norm();
    assert!((g - 4.0 / 3.0).abs() < 1e-3, "gain {g}");
}

#[test]
fn a_two_tone_state_is_refused() {
    // About two tones 1.2 Hz apart the response disagreed with a weak third tone in the full
    // balance by 6 % (signal) to 78 % (an idler), not understood yet: refused, saying so.
    let m = duffing(4e15);
    let f = vec![vec![Complex64::new(0.3, 0.0), Complex64::new(0.3, 0.0)]];
    let d = Excitation::new(vec![1000.1, 1001.3], f);
    let st = steady_state(&m, &d, &HbSettings::default()).expect("two tones");
    let e = probe_response(&m, Some(&st), &[], 0, &[1002.05], Complex64::ONE, false)
        .expect_err("refused");
    assert!(e.to_string().contains("multi-tone"), "{e}");
}
