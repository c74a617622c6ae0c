//! Two-tone sweeps (`harmonid_sim::sweep_two_tone`): linear limit, hysteresis of a hardening
//! Duffing mode, agreement of the directions away from it.

use harmonid::sim::{self, NumericModel, Term, TwoToneSettings, TwoToneStatus, TwoToneSweep};
use num_complex::Complex64;
use std::f64::consts::TAU;

const F0: f64 = 1000.0;
const Q: f64 = 500.0;
const BETA: f64 = 2.0e16;

fn duffing(beta: f64) -> NumericModel {
    NumericModel::new(
        vec!["q1".into()],
        vec![F0],
        vec![Q],
        vec![Term {
            eq: 0,
            coef: beta,
            factors: vec![(0, 3)],
        }],
    )
    .expect("model")
}

fn settings(force: f64, from: f64, to: f64, points: usize) -> TwoToneSettings {
    let mut s = TwoToneSettings {
        c_start_hz: from,
        c_end_hz: to,
        spacing_hz: 20.0,
        force_low: vec![Complex64::new(force, 0.0)],
        force_high: vec![Complex64::new(force, 0.0)],
        points,
        ..TwoToneSettings::default()
    };
    s.hb.lattice.window_rel = 0.01;
    s
}

fn complete(r: &TwoToneSweep) {
    assert_eq!(
        r.up.status,
        TwoToneStatus::Complete,
        "up: {:?}",
        r.up.status
    );
    assert_eq!(
        r.down.status,
        TwoToneStatus::Complete,
        "down: {:?}",
        r.down.status
    );
}

#[test]
fn vanishing_drive_is_the_linear_frf() {
    let m = duffing(BETA);
    let force = 1e-6;
    let r = sim::sweep_two_tone(&m, &settings(force, 990.0, 1010.0, 40)).expect("sweep");
    complete(&r);
    let (w, g) = (TAU * F0, TAU * F0 / Q);
    let mut worst: f64 = 0.0;
    for p in r.up.points.iter().chain(&r.down.points) {
        for (l, &o) in r.lines_offset_hz.iter().enumerate() {
            if o.abs() != 10.0 {
                continue;
            }
            let lin = sim::linear_response(w, g, p.centre_hz + o, Complex64::new(force, 0.0));
            worst = worst.max((p.amplitudes[0][l] - lin).norm() / lin.norm());
        }
        assert!(p.stable);
    }
    assert!(r.up.jumps.is_empty() && r.down.jumps.is_empty());
    assert!(
        worst < 1e-6,
        "worst relative deviation from the linear FRF {worst:.2e}"
    );
}

/// Lower tone strong (a Duffing response curve), upper tone a weak probe 20 Hz above.
fn hard(from: f64, to: f64, points: usize) -> TwoToneSettings {
    let mut s = settings(1.0, from, to, points);
    s.force_high = vec![Complex64::new(0.02, 0.0)];
    s
}

#[test]
fn hardening_duffing_hysteresis() {
    let m = duffing(BETA);
    let r = sim::sweep_two_tone(&m, &hard(995.0, 1045.0, 250)).expect("sweep");
    complete(&r);
    eprintln!("{:?}\n{:?}", r.up.jumps, r.down.jumps);
    assert_eq!(r.up.jumps.len(), 1, "{:?}", r.up.jumps);
    assert_eq!(r.down.jumps.len(), 1, "{:?}", r.down.jumps);
    let (ju, jd) = (r.up.jumps[0], r.down.jumps[0]);
    eprintln!("up jump {ju:?}\ndown jump {jd:?}");
    // Lower tone at c − 10 Hz: the fold of a hardening mode lies above f0 + 10 for the up-sweep.
    assert!(
        ju.from_hz > jd.from_hz + 2.0,
        "up {} vs down {}",
        ju.from_hz,
        jd.from_hz
    );
    assert!(ju.to_hz > ju.from_hz && jd.to_hz < jd.from_hz);
    // Amplitude of the lower tone falls at the up-sweep jump and rises at the down-sweep one.
    let a = |c: &sim::TwoToneCurve, i: usize| c.points[i].amplitudes[0][1].norm();
    assert!(a(&r.up, ju.index) < 0.5 * a(&r.up, ju.index - 1));
    eprintln!(
        "down jump amplitude {:.3e} -> {:.3e}; up {:.3e} -> {:.3e}",
        a(&r.down, jd.index - 1),
        a(&r.down, jd.index),
        a(&r.up, ju.index - 1),
        a(&r.up, ju.index)
    );
    assert!(a(&r.down, jd.index) > 1.5 * a(&r.down, jd.index - 1));
    // Every point is converged; all are stable but those within 0.05 Hz before a fold (the
    // slow flow reports a small positive growth, < 0.1 of the linear decay rate, there).
    for (c, j) in [(&r.up, ju), (&r.down, jd)] {
        for (i, p) in c.points.iter().enumerate() {
            assert!(p.residual < 1e-9, "{p:?}");
            assert!(
                p.stable || (i < j.index && (p.centre_hz - j.from_hz).abs() < 0.05),
                "{i} {p:?}"
            );
        }
    }
    // Outside the bistable interval both directions agree point by point.
    let mut compared = 0;
    let mut worst: f64 = 0.0;
    for p in &r.up.points {
        if p.centre_hz > jd.from_hz - 0.5 && p.centre_hz < ju.from_hz + 0.5 {
            continue;
        }
        if let Some(q) = r
            .down
            .points
            .iter()
            .find(|q| (q.centre_hz - p.centre_hz).abs() < 1e-9)
        {
            compared += 1;
            for (x, y) in p.amplitudes[0].iter().zip(&q.amplitudes[0]) {
                let scale = p.amplitudes[0].iter().map(|z| z.norm()).fold(0.0, f64::max);
                worst = worst.max((x - y).norm() / scale);
            }
        }
    }
    eprintln!("compared {compared} centres, worst relative difference {worst:.2e}");
    assert!(compared > 50);
    assert!(worst < 1e-8, "{worst:.2e}");
}
