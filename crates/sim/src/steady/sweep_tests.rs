use super::test_models::duffing;
use super::*;
use crate::linear_response;
use std::f64::consts::TAU;

#[test]
fn vanishing_drive_sweep_is_linear_frf() {
    let m = duffing(1e12, 200.0);
    let f = [Complex64::new(1e-6, 0.0)];
    let s = SweepSettings {
        f_start_hz: 980.0,
        f_stop_hz: 1020.0,
        points: 200,
        ..Default::default()
    };
    let r = sweep(&m, &f, &s).expect("sweep");
    assert!(r.complete);
    assert!(r.folds.is_empty());
    assert!(r.points.len() > 50);
    for p in &r.points {
        let want = linear_response(m.omega(0), m.gamma(0), p.f_hz, f[0]);
        let got = p.amplitudes[0][0];
        assert!(
            (got - want).norm() <= 1e-8 * want.norm(),
            "{} Hz: {got} vs {want}",
            p.f_hz
        );
        assert!(p.stable);
    }
}

#[test]
fn folds_are_named_the_same_followed_up_or_down() {
    // The upper fold (a local maximum of f, where an up-sweep jumps) is the one at the
    // higher frequency, whichever way the curve is followed.
    let m = duffing(1e14, 200.0);
    let f = [Complex64::new(20.0, 0.0)];
    for (from, to) in [(990.0, 1030.0), (1030.0, 990.0)] {
        let s = SweepSettings {
            f_start_hz: from,
            f_stop_hz: to,
            points: 2000,
            ..Default::default()
        };
        let r = sweep(&m, &f, &s).expect("sweep");
        assert_eq!(r.folds.len(), 2, "{from} → {to}: {:?}", r.folds);
        let up = r.folds.iter().find(|x| x.upper).expect("an upper fold");
        let low = r.folds.iter().find(|x| !x.upper).expect("a lower fold");
        assert!(up.f_hz > low.f_hz, "{from} → {to}: {:?}", r.folds);
    }
}

#[test]
fn backbone_reaches_large_amplitudes_in_big_steps() {
    // One harmonic: the balance is exactly ω² = ω0² + (3/4)·β·a². Amplitudes far apart
    // (the frequency grows 4× and 14×) and out of order: each is reached by continuation
    // from the last converged state, none is lost after a hard one.
    let beta = 1e14;
    let m = duffing(beta, 200.0);
    let w0 = m.omega(0);
    let amps = [1e-6, 3e-3, 1e-2, 2e-4];
    let bb = backbone(&m, 0, &amps, 1).expect("backbone");
    for (&a, f) in amps.iter().zip(&bb) {
        let f = f.expect("converged");
        let want = (w0 * w0 + 0.75 * beta * a * a).sqrt() / TAU;
        assert!((f - want).abs() < 1e-9 * want, "a = {a}: {f} vs {want}");
    }
}

#[test]
fn duffing_backbone_matches_analytic() {
    let beta = 1e14;
    let m = duffing(beta, 200.0);
    let w = m.omega(0);
    let amps = [1e-5, 3e-5, 1e-4];
    let bb = backbone(&m, 0, &amps, 5).expect("backbone");
    for (&a, f) in amps.iter().zip(&bb) {
        let f = f.expect("converged");
        let want = 1000.0 * (1.0 + 3.0 * beta * a * a / (8.0 * w * w));
        let shift = want - 1000.0;
        assert!((f - want).abs() < 0.02 * shift, "a = {a}: {f} vs {want}");
    }
}

#[test]
fn duffing_sweep_folds_and_peak_follow_backbone() {
    let beta = 1e14;
    let m = duffing(beta, 200.0);
    let w = m.omega(0);
    let f = [Complex64::new(20.0, 0.0)];
    let s = SweepSettings {
        f_start_hz: 990.0,
        f_stop_hz: 1030.0,
        points: 2000,
        ..Default::default()
    };
    let r = sweep(&m, &f, &s).expect("sweep");
    assert!(
        r.complete,
        "stopped at {:?}",
        r.points.last().map(|p| p.f_hz)
    );
    assert_eq!(r.folds.len(), 2, "{:?}", r.folds);
    let (up, down) = r.jumps();
    assert!(up[0] > down[0]);
    // Peak amplitude and its frequency against the backbone ω(1 + 3βa²/(8ω²)).
    let (i, p) = r
        .points
        .iter()
        .enumerate()
        .max_by(|a, b| {
            a.1.amplitudes[0][0]
                .norm()
                .total_cmp(&b.1.amplitudes[0][0].norm())
        })
        .expect("points");
    let a = p.amplitudes[0][0].norm();
    let want = 1000.0 * (1.0 + 3.0 * beta * a * a / (8.0 * w * w));
    assert!(
        (p.f_hz - want).abs() < 0.02 * (want - 1000.0),
        "peak at {} Hz, backbone {want}",
        p.f_hz
    );
    // The peak lies on the stable upper branch; the middle branch is unstable.
    assert!(r.points[i].stable);
    assert!(r.points.iter().any(|p| !p.stable));
    // Peak amplitude ≈ F Q / ω² (damping balances drive at the peak).
    let a_lin = 20.0 * 200.0 / (w * w);
    assert!((a - a_lin).abs() < 0.02 * a_lin, "{a} vs {a_lin}");
}
