//! Non-smooth terms on two-tone lattices (issue 36 item 2): the alternating frequency–time
//! sampled on the torus of the two tones, against the time domain and against the linearised
//! (incremental) describing function of `κ|q|q` for a small probe beside a large pump.

use harmonid_sim::{
    simulate_lockin, steady_state, Excitation, HbSettings, ModelValues, NumericModel, Start,
    TdSettings,
};
use num_complex::Complex64;
use std::f64::consts::{PI, TAU};

const F0: f64 = 10_000.0;
const Q: f64 = 1000.0;

fn model(terms: &str, params: &[(&str, f64)]) -> NumericModel {
    let names: Vec<&str> = params.iter().map(|(n, _)| *n).collect();
    let src = format!(
        "mode q1, f = 10 kHz, Q = 1000\nparam {}\neom q1 += {terms}\n",
        names.join(", ")
    );
    let m = harmonid_model::parse_str(&src, "test.hb").expect("parses");
    let mut v = ModelValues::default();
    for (n, x) in params {
        v.parameters.insert(n.to_string(), *x);
    }
    NumericModel::from_model(&m, &v).expect("numeric model")
}

fn two_tones(f: [f64; 2], force: [f64; 2]) -> Excitation {
    Excitation {
        pumps: Vec::new(),
        tones_hz: f.to_vec(),
        force: vec![force.iter().map(|&x| Complex64::new(x, 0.0)).collect()],
    }
}

/// The force of a linear peak amplitude of 1 µm at resonance.
fn force_um() -> f64 {
    1e-6 * (TAU * F0).powi(2) / Q
}

/// `κ` that softens the resonance by `linewidths` at 1 µm (`8κa/(3π)` a stiffness).
fn kappa(linewidths: f64) -> f64 {
    let w = TAU * F0;
    -linewidths * w * w / Q / 1e-6 * 3.0 * PI / 8.0
}

#[test]
fn two_tones_on_abs_q_q_agree_with_the_time_domain() {
    // 10000 and 10002.5 Hz: harmonics 4000 and 4001 of 2.5 Hz, so the time domain has a common
    // period (0.4 s) to demodulate over, while the lattice is sampled on the 2-torus (fewer
    // samples than the common period; the torus misses only the relation of order 8001).
    let m = model("kappa1*abs(q1)*q1", &[("kappa1", kappa(1.0))]);
    let (d, f) = (2.5, [F0, F0 + 2.5]);
    let dr = two_tones(f, [0.6 * force_um(), 0.4 * force_um()]);
    let mut s = HbSettings {
        ramp: false,
        ..HbSettings::default()
    };
    s.lattice.order = 15;
    // The lines near 3f the non-smooth force drives off resonance (they move the tones' lines
    // by ~1e-6 of the first).
    s.lattice.extra_hz = (-5..=8).map(|m| 3.0 * F0 + d * m as f64).collect();
    let t0 = std::time::Instant::now();
    let st = steady_state(&m, &dr, &s).expect("solves");
    let t_hb = t0.elapsed();
    assert!(
        st.converged(),
        "{:?}, residual {:e}",
        st.status,
        st.residual
    );
    println!("status {:?}, ramp steps {}", st.status, st.ramp_steps);
    let (q0, v0) = st.state_at(0.0);
    let measure: Vec<f64> = (-3..=4).map(|k| F0 + d * k as f64).collect();
    let t0 = std::time::Instant::now();
    let td = simulate_lockin(
        &m,
        &dr,
        &measure,
        &[vec![1.0]],
        &Start::State { q: q0, v: v0 },
        &TdSettings {
            rtol: 1e-11,
            settle_tau: Some(1.0),
            settle_tol: 1e-9,
            ..TdSettings::default()
        },
    )
    .expect("time domain runs");
    let big = st.amplitude(0, f[0]).norm();
    let mut worst: f64 = 0.0;
    for (k, &fk) in measure.iter().enumerate() {
        let (hb, t) = (st.amplitude(0, fk), td.modal[0][k]);
        let rel = (hb - t).norm() / big;
        println!(
            "{fk} Hz: HB {:.6e}, time domain {:.6e}, {rel:.2e} of the first tone's line",
            hb.norm(),
            t.norm()
        );
        worst = worst.max(rel);
    }
    println!(
        "{} lines, HB {t_hb:?}, time domain {:?}; worst {worst:.2e}",
        st.lattice_hz.len(),
        t0.elapsed()
    );
    assert!(worst < 1e-6, "worst {worst:e}");
    // Intermodulation lines to compare: the third-order ones are a few % of the tones.
    assert!(st.amplitude(0, F0 - d).norm() > 1e-2 * big);
}

#[test]
fn a_small_probe_sees_the_incremental_describing_function() {
    // Pump A at f_p, probe at f_s = f_p + δ: to first order in the probe, `κ|q|q` acts on the
    // probe through `2κ|q_p(t)|`, whose mean is `G0 = 4κa/π` and whose second harmonic is
    // `G2 = (8κa/(3π)) e^{2i arg A}`; the latter couples the probe to its idler at
    // `2f_p − f_s` through the conjugate: L_s Y_s + G0 Y_s + (G2/2) conj(Y_i) = F_s,
    // L_i Y_i + G0 Y_i + (G2/2) conj(Y_s) = 0.
    let k = kappa(2.0);
    let m = model("kappa1*abs(q1)*q1", &[("kappa1", k)]);
    let (fp, fs) = (F0 - 3.1, F0 + 1.7);
    let w = TAU * F0;
    let g = w / Q;
    let lin = |f: f64| {
        let o = TAU * f;
        Complex64::new(w * w - o * o, o * g)
    };
    let mut errs = Vec::new();
    for probe in [1e-3, 1e-4] {
        let fsig = probe * force_um();
        let dr = two_tones([fp, fs], [force_um(), fsig]);
        let s = HbSettings {
            ramp: false,
            ..HbSettings::default()
        };
        let st = steady_state(&m, &dr, &s).expect("solves");
        assert!(st.converged(), "{:?}", st.status);
        let a_c = st.amplitude(0, fp);
        let a = a_c.norm();
        let g0 = 4.0 * k * a / PI;
        let g2 = 8.0 * k * a / (3.0 * PI) * (2.0 * Complex64::new(0.0, a_c.arg())).exp();
        // Unknowns (Y_s, conj Y_i): [L_s + G0, G2/2; conj(G2)/2, conj(L_i + G0)].
        let fi = 2.0 * fp - fs;
        let (p, qq) = (lin(fs) + g0, 0.5 * g2);
        let (r, t) = (0.5 * g2.conj(), (lin(fi) + g0).conj());
        let det = p * t - qq * r;
        let ys = t * fsig / det;
        let yi = (-r * fsig / det).conj();
        let (hs, hi) = (st.amplitude(0, fs), st.amplitude(0, fi));
        let es = (hs - ys).norm() / ys.norm();
        let ei = (hi - yi).norm() / yi.norm();
        println!(
            "probe {probe:e}: Y_s {hs:.6e} vs {ys:.6e} ({es:.2e}), idler {hi:.6e} vs {yi:.6e} ({ei:.2e})"
        );
        errs.push(es.max(ei));
    }
    // What is left is not the linearisation (it is the same at a tenth of the probe) but the
    // aliasing of `2|q_p|`, a kink, on 256 samples per axis (`O(N^{-2})`: 4.6e-5 for Y_s,
    // 1.5e-4 for the idler; 7e-6 and 2.3e-5 at 512).
    assert!(errs[1] < 3e-4, "{errs:?}");
    assert!((errs[1] - errs[0]).abs() < 0.05 * errs[1], "{errs:?}");
}
