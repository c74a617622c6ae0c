//! One Duffing mode: the states against the single-harmonic cubic in `a = |X|²`,
//! `c² a³ + 2δc a² + (δ² + Ω²γ²) a − F² = 0` (`c = 3β/4`, `δ = ω₀² − Ω²`), whose discriminant
//! says whether there are three states (two stable) or one; and the single-harmonic residual
//! against a numerical DFT of the equation of motion.

use super::models::{duffing, BETA, F0, Q};
use harmonid_explore::{
    phase_diagram, states, Axis, AxisRange, PhaseSettings, Problem, StatesSettings, Tone,
};
use harmonid_sim::{Excitation, NumericModel};
use num_complex::Complex64;
use std::f64::consts::{PI, TAU};

/// The cubic's discriminant at drive `f_hz`, force `f` (positive: three states).
fn discriminant(f_hz: f64, force: f64) -> f64 {
    // In units of the amplitude scale a0 (a = a0 · α) and the damping force, to keep the
    // numbers near one.
    let w = TAU * f_hz;
    let w0 = TAU * F0;
    let g = w0 / Q;
    let k = w * g;
    let c = 0.75 * BETA;
    let a0 = k / c;
    let (d, e) = ((w0 * w0 - w * w) / k, force * force / (k * k * a0));
    let (a, b, cc, dd) = (1.0, 2.0 * d, d * d + 1.0, -e);
    18.0 * a * b * cc * dd - 4.0 * b.powi(3) * dd + b * b * cc * cc
        - 4.0 * a * cc.powi(3)
        - 27.0 * a * a * dd * dd
}

#[test]
fn bistable_duffing_has_three_states_two_stable_each_on_the_lattice() {
    let (_, _, m) = duffing();
    let (f_hz, force) = (1010.0, 60.0);
    assert!(
        discriminant(f_hz, force) > 0.0,
        "the test point is bistable by the closed form"
    );
    let drive = Excitation::new(vec![f_hz], vec![vec![Complex64::new(force, 0.0)]]);
    let s = states(&m, &drive, &StatesSettings::default()).expect("solves");
    assert_eq!(s.paths, 9, "Bézout number of two cubics");
    assert_eq!(s.complex_solutions, 3, "the cubic in |X|² has three roots");
    assert_eq!(s.states.len(), 3);
    let stable: Vec<bool> = s.states.iter().map(|x| x.stable).collect();
    assert_eq!(
        stable,
        [true, false, true],
        "lower and upper stable, the middle one not"
    );
    // Each amplitude solves the cubic.
    let (w, w0) = (TAU * f_hz, TAU * F0);
    for st in &s.states {
        let a = st.amplitudes[0].norm_sqr();
        let lin = Complex64::new(w0 * w0 - w * w + 0.75 * BETA * a, w * w0 / Q);
        let rel = (lin.norm_sqr() * a - force * force).abs() / (force * force);
        assert!(rel < 1e-9, "cubic residual {rel:e}");
        match &st.lattice {
            harmonid_explore::Continued::Yes {
                stable,
                shift,
                same_as,
                eigenvalues,
                ..
            } => {
                assert_eq!(*stable, st.stable, "the lattice agrees on stability");
                // The lattice's slow flow has the single harmonic's eigenvalues, moved by the
                // harmonics' weight (and those of the lines it keeps beside them).
                let scale = st.eigenvalues.iter().map(|z| z.norm()).fold(0.0, f64::max);
                for z in &st.eigenvalues {
                    let d = eigenvalues
                        .iter()
                        .map(|w| (w - z).norm())
                        .fold(f64::INFINITY, f64::min);
                    assert!(d < 1e-2 * scale, "{z} vs {eigenvalues:?}");
                }
                assert!(*shift < 1e-2, "harmonics move the tone's line by {shift:e}");
                assert!(same_as.is_none());
            }
            other => panic!("not continued: {other:?}"),
        }
    }
    println!(
        "states at {f_hz} Hz, {force} N/kg: {:?}",
        s.states
            .iter()
            .map(|x| (x.amplitudes[0].norm(), x.stable))
            .collect::<Vec<_>>()
    );
}

/// `[m(q, q̇, pump)]_1` by a numerical DFT of the model's forces over one period.
fn dft_residual(m: &NumericModel, tone: &Tone, x: &[Complex64]) -> Vec<Complex64> {
    let nm = m.n_modes();
    let k = 64;
    let w = tone.omega();
    let mut fund = vec![Complex64::new(0.0, 0.0); nm];
    let mut pows = vec![0.0; m.pow_len()];
    let mut out = vec![0.0; nm];
    for s in 0..k {
        let th = TAU * s as f64 / k as f64;
        let e = Complex64::from_polar(1.0, th);
        let mut vars: Vec<f64> = x.iter().map(|z| (z * e).re).collect();
        vars.extend(x.iter().map(|z| (Complex64::new(0.0, w) * z * e).re));
        vars.push((tone.pump * e * e).re);
        m.forces(&vars[..m.n_vars()], &mut pows, &mut out);
        for n in 0..nm {
            fund[n] += out[n] * e.conj() * (2.0 / k as f64);
        }
    }
    (0..nm)
        .map(|n| {
            let (wn, g) = (m.omega(n), m.gamma(n));
            Complex64::new(wn * wn - w * w, w * g) * x[n] + fund[n] - tone.force[n]
        })
        .collect()
}

#[test]
fn single_harmonic_expansion_equals_a_dft_of_the_equations() {
    // Cubic and quintic stiffness, a dispersive coupling, nonlinear damping, a velocity
    // coupling, a pump term and a quadratic term (no fundamental).
    let (_, _, m) = super::models::parse(
        "mode q1, f = 1 kHz, Q = 1000\nmode q2, f = 1.5 kHz, Q = 500\nparam a, b, g, e, h, l, k\n\
         eom q1 += a*q1^3 + b*q1^5 + g*q1*q2^2 + e*q1^2*d(q1) + l*pump*q1 + k*q1^2\n\
         eom q2 += g*q1^2*q2 + h*q2^2*d(q1) + l*pump*q2^3\n",
        "[parameters]\na = 1e12\nb = 3e20\ng = 2e12\ne = 1e5\nh = -2e4\nl = 0.7\nk = 1e9\n",
    );
    let tone = Tone {
        hz: 1003.0,
        force: vec![Complex64::new(2.0, 1.0), Complex64::new(-1.0, 0.5)],
        pump: Complex64::new(3e4, -2e4),
    };
    let x = [Complex64::new(3e-5, -1e-5), Complex64::new(-2e-5, 4e-5)];
    let got = harmonid_explore::residual(&m, &tone, &x).expect("expands");
    let want = dft_residual(&m, &tone, &x);
    for n in 0..2 {
        let scale = (TAU * 1e3).powi(2) * x[n].norm();
        let err = (got[n] - want[n]).norm() / scale;
        println!(
            "mode {n}: expansion {} vs DFT {} (relative {err:.1e})",
            got[n], want[n]
        );
        assert!(err < 1e-12, "{err:e}");
    }
    let _ = PI;
}

#[test]
fn phase_diagram_counts_agree_with_the_discriminant_on_200_by_200() {
    let (model, values, _) = duffing();
    let drive = Excitation::new(vec![1000.0], vec![vec![Complex64::new(1.0, 0.0)]]);
    let x = AxisRange {
        axis: Axis::Freq,
        from: 995.0,
        to: 1045.0,
        n: 200,
    };
    let y = AxisRange {
        axis: Axis::Force("q1".into()),
        from: 1.0,
        to: 150.0,
        n: 200,
    };
    let p = Problem {
        model: &model,
        values: &values,
        drive: &drive,
    };
    let t = std::time::Instant::now();
    let d = phase_diagram(&p, &x, &y, &PhaseSettings::default(), &|_| {}).expect("runs");
    let secs = t.elapsed().as_secs_f64();
    let (nx, ny) = (x.n, y.n);
    let want = |ix: usize, iy: usize| {
        if discriminant(d.x[ix], d.y[iy]) > 0.0 {
            2
        } else {
            1
        }
    };
    let (mut checked, mut bistable, mut skipped) = (0, 0, 0);
    for iy in 0..ny {
        for ix in 0..nx {
            let w = want(ix, iy);
            let near_boundary = (iy.saturating_sub(1)..(iy + 2).min(ny))
                .any(|j| (ix.saturating_sub(1)..(ix + 2).min(nx)).any(|i| want(i, j) != w));
            if near_boundary {
                skipped += 1;
                continue;
            }
            let c = d.counts[iy * nx + ix].expect("every row done");
            assert_eq!(
                c.stable, w,
                "stable states at {} Hz, {} N/kg",
                d.x[ix], d.y[iy]
            );
            assert_eq!(
                c.unstable,
                w - 1,
                "unstable states at {} Hz, {} N/kg",
                d.x[ix],
                d.y[iy]
            );
            checked += 1;
            bistable += (w == 2) as usize;
        }
    }
    println!(
        "{checked} points agree ({bistable} bistable), {skipped} within a cell of the boundary; {} full homotopies; generic count {}; {secs:.3} s",
        d.full_solves, d.generic_count
    );
    assert!(
        bistable > 2000 && checked - bistable > 2000,
        "both regions are on the grid"
    );
}
