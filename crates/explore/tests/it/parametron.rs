//! The parametron (Duffing + `lambda*pump*q1`, no drive): the rest state is unstable exactly
//! inside the tongue `|λP|/2 > √((ω₀² − ω²)² + (γω)²)`, `ω = π f_pump`, and there the two
//! phase states `±X` are the stable ones.

use super::models::{parametron, F0, Q};
use harmonid_explore::{
    phase_diagram, states, Axis, AxisRange, PhaseSettings, Problem, StatesSettings,
};
use harmonid_sim::{Excitation, PumpTone};
use num_complex::Complex64;
use std::f64::consts::{PI, TAU};

fn inside(pump_hz: f64, level: f64) -> bool {
    let w = PI * pump_hz;
    let w0 = TAU * F0;
    0.5 * level > ((w0 * w0 - w * w).powi(2) + (w * w0 / Q).powi(2)).sqrt()
}

fn pumped(hz: f64, level: f64) -> Excitation {
    Excitation {
        tones_hz: vec![],
        force: vec![vec![]],
        pumps: vec![PumpTone {
            hz,
            amplitude: Complex64::new(level, 0.0),
        }],
    }
}

#[test]
fn inside_the_tongue_the_rest_state_is_unstable_and_the_phase_states_stable() {
    let (model, values, _) = parametron();
    let drive = pumped(2000.0, 1e5);
    let x = AxisRange {
        axis: Axis::PumpHz,
        from: 1990.0,
        to: 2010.0,
        n: 100,
    };
    let y = AxisRange {
        axis: Axis::PumpLevel,
        from: 1e3,
        to: 4e5,
        n: 100,
    };
    let p = Problem {
        model: &model,
        values: &values,
        drive: &drive,
    };
    let settings = PhaseSettings {
        keep_states: true,
        ..PhaseSettings::default()
    };
    let t = std::time::Instant::now();
    let d = phase_diagram(&p, &x, &y, &settings, &|_| {}).expect("runs");
    let secs = t.elapsed().as_secs_f64();
    let (nx, ny) = (x.n, y.n);
    let want = |ix: usize, iy: usize| inside(d.x[ix], d.y[iy]);
    let (mut n_in, mut n_out, mut skipped) = (0, 0, 0);
    for iy in 0..ny {
        for ix in 0..nx {
            let w = want(ix, iy);
            if (iy.saturating_sub(1)..(iy + 2).min(ny))
                .any(|j| (ix.saturating_sub(1)..(ix + 2).min(nx)).any(|i| want(i, j) != w))
            {
                skipped += 1;
                continue;
            }
            let at = format!("f_p = {} Hz, P = {}", d.x[ix], d.y[iy]);
            let c = d.counts[iy * nx + ix].expect("done");
            let pts = &d.states[iy * nx + ix];
            let rest = pts
                .iter()
                .find(|p| p.amplitudes[0].norm() < 1e-12)
                .expect("the rest state is a state");
            if w {
                n_in += 1;
                assert!(!rest.stable, "rest state stable inside the tongue at {at}");
                assert_eq!((c.stable, c.unstable), (2, 1), "at {at}");
                let st: Vec<Complex64> = pts
                    .iter()
                    .filter(|p| p.stable)
                    .map(|p| p.amplitudes[0])
                    .collect();
                assert!(
                    (st[0] + st[1]).norm() < 1e-9 * st[0].norm(),
                    "the stable states are ±X at {at}"
                );
            } else {
                n_out += 1;
                assert!(
                    rest.stable,
                    "rest state unstable outside the tongue at {at}"
                );
                assert!(c.unstable.is_multiple_of(2), "at {at}: {c:?}");
            }
        }
    }
    println!("{n_in} points inside, {n_out} outside agree; {skipped} within a cell of the boundary; {} full homotopies, {} parameter homotopies; {secs:.3} s", d.full_solves, d.parameter_homotopies);
    assert!(n_in > 1000 && n_out > 1000);
}

#[test]
fn states_of_the_parametron_above_threshold_continue_on_the_lattice() {
    let (_, _, m) = parametron();
    let s = states(&m, &pumped(2000.0, 2e5), &StatesSettings::default()).expect("solves");
    let summary: Vec<(f64, bool)> = s
        .states
        .iter()
        .map(|x| (x.amplitudes[0].norm(), x.stable))
        .collect();
    println!("{summary:?}");
    assert_eq!(summary.len(), 3);
    assert!(!summary[0].1 && summary[0].0 < 1e-20 && summary[1].1 && summary[2].1);
    // Closed form at f_p = 2 f0: a² = (4/3β)·√((λP/2)² − (ωγ)²).
    let wg = (TAU * F0).powi(2) / Q;
    let want = (4.0 / 3.0 / super::models::BETA * (1e10f64 - wg * wg).sqrt()).sqrt();
    assert!(
        (summary[1].0 / want - 1.0).abs() < 1e-9,
        "{} vs {want}",
        summary[1].0
    );
    for st in &s.states {
        assert!(
            matches!(st.lattice, harmonid_explore::Continued::Yes { stable, .. } if stable == st.stable),
            "{:?}",
            st.lattice
        );
    }
}
