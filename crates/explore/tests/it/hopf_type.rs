//! How a state loses stability: through a complex pair of its slow flow (oscillatory, Hopf
//! type) or through a real eigenvalue (a saddle).

use super::models::{duffing, parse};
use harmonid_explore::{
    phase_diagram, states, unstable_through_complex_pair, Axis, AxisRange, PhaseSettings, Problem,
    StatesSettings,
};
use harmonid_model::Model;
use harmonid_sim::Excitation;
use harmonid_sim::{ModelValues, NumericModel};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// The driven van der Pol–Duffing of examples/vdp_duffing.
fn vdp() -> (Model, ModelValues, NumericModel) {
    let read = |f: &str| {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/vdp_duffing/");
        std::fs::read_to_string(format!("{dir}{f}")).expect("the example")
    };
    parse(&read("model.hb"), &read("values.toml"))
}

#[test]
fn the_middle_duffing_state_is_a_saddle() {
    // Bistable point of the Duffing (the closed-form check is in duffing.rs): the middle
    // state is unstable through one real eigenvalue.
    let (_, _, m) = duffing();
    let drive = Excitation::new(vec![1010.0], vec![vec![Complex64::new(60.0, 0.0)]]);
    let s = states(&m, &drive, &StatesSettings::default()).expect("solves");
    assert_eq!(s.states.len(), 3);
    let kinds: Vec<(bool, bool)> = s
        .states
        .iter()
        .map(|st| {
            (
                st.stable,
                unstable_through_complex_pair(&m, &st.eigenvalues),
            )
        })
        .collect();
    assert_eq!(kinds, [(true, false), (false, false), (true, false)]);
}

#[test]
fn a_van_der_pol_driven_off_resonance_is_unstable_through_a_complex_pair() {
    // The example's driven van der Pol–Duffing (examples/vdp_duffing): net linear damping
    // −ω0/Q, so the weakly driven state 15 Hz off resonance keeps growing at its own
    // frequency: a complex pair with Re λ > 0 and Im λ ≈ ±2π·15 Hz in the frame of the tone
    // (linear slow flow: λ ≈ i(ω0² − Ω²)/2Ω − γ_net/2, the drive's amplitude damping it a
    // little through eta q² q̇).
    let (_, _, m) = vdp();
    let (f0, tone) = (1000.0, 985.0);
    let drive = Excitation::new(vec![tone], vec![vec![Complex64::new(0.446, 0.0)]]);
    let s = states(&m, &drive, &StatesSettings::default()).expect("solves");
    let small = s
        .states
        .iter()
        .min_by(|a, b| a.amplitudes[0].norm().total_cmp(&b.amplitudes[0].norm()))
        .expect("a state");
    assert!(!small.stable);
    assert!(unstable_through_complex_pair(&m, &small.eigenvalues));
    let offset = TAU * (f0 - tone);
    let top = small
        .eigenvalues
        .iter()
        .max_by(|a, b| a.re.total_cmp(&b.re))
        .expect("eigenvalues");
    assert!(top.re > 0.0, "{top}");
    let ratio = top.im.abs() / offset;
    assert!((0.8..1.2).contains(&ratio), "Im λ / 2π·15 Hz = {ratio}");
}

#[test]
fn the_phase_diagram_counts_oscillatory_states_up_to_the_hopf_point() {
    // The same van der Pol–Duffing over the drive frequency: the driven state is oscillatory
    // (unstable through a complex pair) farther than the Hopf point from the resonance and
    // quenched nearer. Averaging puts that Hopf point at 992 Hz for 0.446 N/kg
    // (docs/exploring.md, crates/sim's quasi-periodic tests); one-cell tolerance.
    let (model, values, _) = vdp();
    let drive = Excitation::new(vec![990.0], vec![vec![Complex64::new(0.446, 0.0)]]);
    let p = Problem {
        model: &model,
        values: &values,
        drive: &drive,
    };
    let x = AxisRange {
        axis: Axis::Freq,
        from: 984.0,
        to: 1000.0,
        n: 17,
    };
    let y = AxisRange {
        axis: Axis::Force("q1".into()),
        from: 0.446,
        to: 0.4461,
        n: 2,
    };
    let d = phase_diagram(&p, &x, &y, &PhaseSettings::default(), &|_| {}).expect("runs");
    for (i, c) in d.counts.iter().take(17).enumerate() {
        let c = c.expect("done");
        let f = d.x[i];
        if f <= 991.0 {
            assert!(c.oscillatory >= 1, "{f} Hz: {c:?}");
        } else if f >= 993.0 {
            assert_eq!(c.oscillatory, 0, "{f} Hz: {c:?}");
        }
        assert!(c.oscillatory <= c.unstable);
    }
}
