//! Stepped sweeps through strong folds: a stepped-sine measurement follows its branch up to the
//! fold where that branch ends and jumps there, as the device does.

use harmonid_sim::{
    stepped_sweep, Excitation, HbSettings, ModeValues, ModelValues, NumericModel, SteadyState,
};
use num_complex::Complex64;
use std::f64::consts::TAU;

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
