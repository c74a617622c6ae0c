//! Modes a steady state leaves uncoupled (undriven, forced by nothing) are factorised and
//! analysed apart (`DenseLu`'s parts, the stability's blocks). The same problem with a
//! negligible drive on every mode couples them all into one block; both ways must give the
//! same steady state and the same stability verdict and growth rate.

use harmonid_sim::{Excitation, HbSettings, HbSolver, ModeValues, ModelValues, NumericModel};
use num_complex::Complex64;

fn numeric(source: &str, modes: &[(f64, f64)], params: &[(&str, f64)]) -> NumericModel {
    let model = harmonid_model::parse_str(source, "test.hb").expect("model");
    let mut v = ModelValues::default();
    for (m, &(f, q)) in model.modes.iter().zip(modes) {
        v.modes.insert(
            m.name.clone(),
            ModeValues {
                f_hz: Some(f),
                q: Some(q),
            },
        );
    }
    for &(p, x) in params {
        v.parameters.insert(p.into(), x);
    }
    NumericModel::from_model(&model, &v).expect("numeric model")
}

/// Steady state and stability with `force` on mode 0 at `tones`, and the same with `tiny` on
/// every other mode at the same tones (which couples every block of the Jacobian).
fn compare(num: &NumericModel, tones: &[f64], force: f64, tiny: f64) {
    let nm = num.n_modes();
    let drive = |other: f64| Excitation {
        pumps: Vec::new(),
        tones_hz: tones.to_vec(),
        force: (0..nm)
            .map(|n| vec![Complex64::new(if n == 0 { force } else { other }, 0.0); tones.len()])
            .collect(),
    };
    let settings = HbSettings::default();
    let run = |other: f64| {
        let mut solver =
            HbSolver::new(num, &drive(other), &settings.lattice).expect("solver set-up");
        let state = solver.solve(&settings);
        assert!(state.converged(), "{:?}", state.status);
        let stab = solver.stability(&state).expect("stability");
        (state, stab)
    };
    let (apart, stab_apart) = run(0.0);
    let (joint, stab_joint) = run(tiny);
    assert!(
        apart.amplitudes[1..]
            .iter()
            .flatten()
            .all(|z| z.norm() == 0.0),
        "the undriven modes stay at rest"
    );
    let scale = apart.amplitudes[0]
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max);
    for (a, b) in apart.amplitudes[0].iter().zip(&joint.amplitudes[0]) {
        assert!((a - b).norm() <= 1e-9 * scale, "{a} vs {b}");
    }
    assert_eq!(stab_apart.stable, stab_joint.stable);
    let rel = (stab_apart.growth_rate - stab_joint.growth_rate).abs()
        / stab_joint
            .growth_rate
            .abs()
            .max(stab_joint.linear_decay_rate);
    assert!(
        rel < 1e-6,
        "growth rate {:e} (blocks apart) vs {:e} (one block)",
        stab_apart.growth_rate,
        stab_joint.growth_rate
    );
}

#[test]
fn dispersive_nanostring_driven_on_one_mode() {
    let num = numeric(
        "mode q1 at 207.58 kHz
         mode q2 at 415.84 kHz
         param beta1, beta2, g12
         potential: beta1/4*q1^4 + beta2/4*q2^4 + g12/2*q1^2*q2^2",
        &[(207_582.0, 116_232.0), (415_842.0, 99_173.0)],
        &[("beta1", 2.68e22), ("beta2", 3.7e23), ("g12", 8.57e22)],
    );
    let kappa = 207_582.0 / 116_232.0;
    compare(
        &num,
        &[207_582.0 - 5.5 * kappa, 207_582.0 + 5.5 * kappa],
        3.5,
        1e-14,
    );
}

#[test]
fn three_wave_driven_on_one_mode() {
    // q1 alone driven: κ q1 couples q2 and q3 to each other (one block), q1 is alone.
    let num = numeric(
        "mode q1 at 1.0 MHz
         mode q2 at 1.6 MHz
         mode q3 at 2.6 MHz
         param kappa
         for i in 1..3: param beta[i]
         potential: kappa * q1*q2*q3
         for i in 1..3: potential: beta[i]/4 * q[i]^4",
        &[(1.0e6, 2.0e4), (1.6e6, 2.5e4), (2.6e6, 3.0e4)],
        &[
            ("kappa", 2.0e17),
            ("beta1", 2.6e25),
            ("beta2", 5.4e25),
            ("beta3", 1.2e26),
        ],
    );
    compare(&num, &[1.0e6 - 150.0, 1.0e6 + 150.0], 20.0, 1e-16);
}
