//! The drive ramp must not step over a fold: a large step can converge past it onto another
//! branch, and the ramp would then report no jump where an experiment driving up jumps.
//! Reproducer: the two-mode nanostring (`examples/nanostring_2mode`), two tones on q1 at
//! 207579.5 and 207584.5 Hz (linewidth 1.8 Hz, resonance 207582 Hz). The hardening resonance
//! sweeps past the upper tone as the drive grows: the low branch ends at a fold near
//! 0.724 N/kg per tone, so every level above it must meet that fold, and jump there onto the
//! high branch.

use harmonid_sim::{
    Excitation, HbSettings, HbSolver, HbStatus, ModeValues, ModelValues, NumericModel, SteadyState,
};
use num_complex::Complex64;

const TONES: [f64; 2] = [207_579.5, 207_584.5];

fn nanostring() -> NumericModel {
    let root = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/nanostring_2mode"
    );
    let src = std::fs::read_to_string(format!("{root}/model.hb")).expect("model.hb");
    let model = harmonid_model::parse_str(&src, "model.hb").expect("model");
    // examples/nanostring_2mode/values.toml
    let mut v = ModelValues::default();
    for (name, f_hz, q) in [("q1", 207_582.0, 116_232.0), ("q2", 415_842.0, 599_173.0)] {
        let mode = ModeValues {
            f_hz: Some(f_hz),
            q: Some(q),
        };
        v.modes.insert(name.into(), mode);
    }
    for (name, value) in [("beta1", 2.68e22), ("beta2", 3.70e23), ("g12", 8.57e22)] {
        v.parameters.insert(name.into(), value);
    }
    NumericModel::from_model(&model, &v).expect("numeric model")
}

fn drive(force: f64) -> Excitation {
    let c = |x: f64| Complex64::new(x, 0.0);
    Excitation {
        pumps: Vec::new(),
        tones_hz: TONES.to_vec(),
        force: vec![vec![c(force), c(force)], vec![c(0.0), c(0.0)]],
    }
}

/// Where the ramp met the fold (drive fraction), asserting that it did and stopped there.
fn fold_at(st: &SteadyState) -> f64 {
    let HbStatus::NotConverged { drive_fraction } = st.status else {
        panic!("the ramp went past the fold: {:?}", st.status);
    };
    assert_eq!(st.drive_jumps.last(), Some(&drive_fraction), "{st:?}");
    drive_fraction
}

#[test]
fn every_level_past_the_fold_meets_it() {
    let num = nanostring();
    let fine = HbSettings {
        ramp_step: 1e-3,
        ramp_step_max: 1e-3,
        stop_at_fold: true,
        ..HbSettings::default()
    };
    let stop = HbSettings {
        stop_at_fold: true,
        ..HbSettings::default()
    };
    // The fold level (N/kg per tone) by a fine ramp at the strongest drive.
    let mut solver = HbSolver::new(&num, &drive(2.0), &fine.lattice).expect("solver");
    let fold = 2.0 * fold_at(&solver.solve(&fine));
    // The single-tone Duffing estimate puts it near 0.72 N/kg for these tones; the fine ramp
    // (the brute force) fixes it.
    assert!((fold - 0.7239).abs() < 2e-3, "fold at {fold} N/kg");
    for force in [0.8, 1.0, 1.5, 1.87, 1.95, 2.0] {
        let mut solver = HbSolver::new(&num, &drive(force), &fine.lattice).expect("solver");
        // Default settings: the ramp jumps at the fold, names it within the fine ramp's step,
        // and lands on the high branch, a stable state (a time-domain run from it at 2 N/kg
        // stays on it to 4e-6). Stopping at folds: it stops there.
        let st = solver.solve(&HbSettings::default());
        assert!(st.converged(), "force {force}: {}", st.status);
        let jump = force * st.drive_jumps.first().copied().expect("a jump");
        assert!(
            (jump - fold).abs() <= 1e-3 * force,
            "force {force}: jump at {jump} N/kg, fold {fold}"
        );
        assert!(solver.stability(&st).expect("stability").stable);
        for settings in [stop.clone(), fine.clone()] {
            let at = force * fold_at(&solver.solve(&settings));
            assert!(
                (at - fold).abs() <= 1e-3 * force,
                "force {force}: fold met at {at} N/kg, the fine ramp's at {fold}"
            );
        }
    }
    // Below the fold: converged, no jump, the same state as a fine ramp's.
    for force in [0.3, 0.6, 0.7] {
        let mut solver = HbSolver::new(&num, &drive(force), &fine.lattice).expect("solver");
        let st = solver.solve(&HbSettings::default());
        let st_fine = solver.solve(&fine);
        assert!(st.converged() && st_fine.converged(), "{:?}", st.status);
        assert!(st.drive_jumps.is_empty() && st_fine.drive_jumps.is_empty());
        for f in TONES {
            let (x, y) = (st.amplitude(0, f), st_fine.amplitude(0, f));
            assert!(
                (x - y).norm() < 1e-6 * x.norm(),
                "force {force}, {f} Hz: default ramp {x}, fine ramp {y}"
            );
        }
    }
}
