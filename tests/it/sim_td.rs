//! Harmonic balance and time-domain lock-in emulation agree (issue 4: to 1e-3).

use harmonid::sim::{self, Excitation, HbSettings, NumericModel, Start, TdSettings, Term};
use num_complex::Complex64;

/// Two coupled Duffing modes, low Q so the test integrates few periods.
fn small_model() -> NumericModel {
    let t = |eq, coef, factors: Vec<(usize, u32)>| Term { eq, coef, factors };
    NumericModel::new(
        vec!["q1".into(), "q2".into()],
        vec![1000.0, 2110.0],
        vec![80.0, 120.0],
        vec![
            t(0, 4.0e13, vec![(0, 3)]),
            t(0, 3.0e13, vec![(0, 1), (1, 2)]),
            t(1, 3.0e13, vec![(0, 2), (1, 1)]),
            t(1, 9.0e13, vec![(1, 3)]),
        ],
    )
    .expect("model")
}

#[test]
fn hb_and_time_domain_agree() {
    let model = small_model();
    let drive = Excitation {
        pumps: Vec::new(),
        tones_hz: vec![995.0, 1005.0, 2105.0],
        force: vec![
            vec![
                Complex64::new(20.0, 0.0),
                Complex64::new(0.0, 20.0),
                Complex64::new(0.0, 0.0),
            ],
            vec![
                Complex64::new(0.0, 0.0),
                Complex64::new(0.0, 0.0),
                Complex64::new(60.0, 0.0),
            ],
        ],
    };
    let measure: Vec<f64> = (-3..=4)
        .map(|k| 995.0 + 10.0 * k as f64)
        .chain((-2..=2).map(|k| 2105.0 + 10.0 * k as f64))
        .collect();
    let mut hs = HbSettings::default();
    hs.lattice.extra_hz = measure.clone();
    hs.lattice.order = 11;
    hs.lattice.harmonics = true;
    hs.lattice.window_rel = 0.05;
    let st = sim::steady_state(&model, &drive, &hs).expect("hb");
    assert!(st.converged(), "{:?}", st.status);
    // Nonlinear enough to matter: sidebands at a few % of the drive response.
    let main = st.amplitude(0, 995.0).norm();
    let side = st.amplitude(0, 985.0).norm();
    assert!(side > 0.005 * main, "sideband {side:.3e} vs {main:.3e}");
    let shapes = vec![vec![0.3, 0.6]];
    for start in [Start::Rest, {
        let (q, v) = st.state_at(0.0);
        Start::State { q, v }
    }] {
        let r = sim::simulate_lockin(
            &model,
            &drive,
            &measure,
            &shapes,
            &start,
            &TdSettings::default(),
        )
        .expect("td");
        let biggest = measure
            .iter()
            .map(|&f| st.at_point(&shapes[0], f).norm())
            .fold(0.0, f64::max);
        let mut worst: f64 = 0.0;
        for (k, &f) in measure.iter().enumerate() {
            let hb = st.at_point(&shapes[0], f);
            if hb.norm() >= 0.01 * biggest {
                let rel = (r.points[0][k] - hb).norm() / hb.norm();
                worst = worst.max(rel);
                assert!(
                    rel < 1e-3,
                    "{f} Hz: td {} vs hb {hb} ({rel:.2e}), start {start:?}",
                    r.points[0][k]
                );
            }
        }
        eprintln!(
            "start {:?}: worst {worst:.2e}, {} steps, spp {}",
            matches!(start, Start::Rest),
            r.steps,
            r.steps_per_period
        );
    }
}
