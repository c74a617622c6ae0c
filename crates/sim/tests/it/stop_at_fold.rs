//! `HbSettings::stop_at_fold`: the ramp stops at the first fold (not converged, the fold named)
//! where the default follows the jump to the other branch.

use harmonid_sim::{
    Excitation, HbSettings, HbSolver, HbStatus, ModeValues, ModelValues, NumericModel,
};
use num_complex::Complex64;

#[test]
fn the_ramp_stops_at_the_first_fold_when_asked() {
    let model = harmonid_model::parse_str(
        "mode q1 at 207.58 kHz\nparam beta1\npotential: beta1/4*q1^4",
        "duffing.hb",
    )
    .expect("model");
    let mut v = ModelValues::default();
    v.modes.insert(
        "q1".into(),
        ModeValues {
            f_hz: Some(207_582.0),
            q: Some(116_232.0),
        },
    );
    v.parameters.insert("beta1".into(), 2.68e22);
    let num = NumericModel::from_model(&model, &v).expect("numeric model");
    // One tone 8 linewidths above resonance: a hardening Duffing driven up there jumps to the
    // large branch once the force passes the lower fold.
    let tone = 207_582.0 * (1.0 + 8.0 / 116_232.0);
    let mut jumped = 0;
    for force in [0.5, 2.0, 8.0, 32.0] {
        let drive = Excitation {
            pumps: Vec::new(),
            tones_hz: vec![tone],
            force: vec![vec![Complex64::new(force, 0.0)]],
        };
        let follow = HbSettings::default();
        let stop = HbSettings {
            stop_at_fold: true,
            ..HbSettings::default()
        };
        let mut solver = HbSolver::new(&num, &drive, &follow.lattice).expect("solver");
        let st = solver.solve(&follow);
        assert!(st.converged(), "force {force}: {:?}", st.status);
        let st_stop = solver.solve(&stop);
        if st.drive_jumps.is_empty() {
            assert!(st_stop.converged(), "force {force}: no fold, no stop");
            assert!(st_stop.drive_jumps.is_empty());
        } else {
            jumped += 1;
            let HbStatus::NotConverged { drive_fraction } = st_stop.status else {
                panic!(
                    "force {force}: the ramp went past the fold at {:?}",
                    st.drive_jumps
                );
            };
            assert_eq!(st_stop.drive_jumps, vec![drive_fraction]);
            assert!((drive_fraction - st.drive_jumps[0]).abs() < 1e-12);
        }
    }
    assert!(jumped > 0, "no force of the list drives past the fold");
}
