//! Requests refused before any work, each saying why.

use super::models::{duffing, parametron};
use harmonid_explore::{phase_diagram, Axis, AxisRange, ExploreError, PhaseSettings, Problem};
use harmonid_sim::Excitation;
use num_complex::Complex64;

fn run(
    model: &harmonid_model::Model,
    values: &harmonid_sim::ModelValues,
    drive: &Excitation,
    x: AxisRange,
    y: AxisRange,
) -> Result<(), ExploreError> {
    let p = Problem {
        model,
        values,
        drive,
    };
    phase_diagram(&p, &x, &y, &PhaseSettings::default(), &|_| {
        panic!("no work")
    })
    .map(|_| ())
}

/// The error of a request that must be refused.
fn run_err(
    model: &harmonid_model::Model,
    values: &harmonid_sim::ModelValues,
    drive: &Excitation,
    x: AxisRange,
    y: AxisRange,
) -> ExploreError {
    match run(model, values, drive, x, y) {
        Err(e) => e,
        Ok(()) => panic!("accepted"),
    }
}

fn axis(axis: &str, from: f64, to: f64, n: usize) -> AxisRange {
    AxisRange {
        axis: axis.parse::<Axis>().unwrap_or(Axis::Freq),
        from,
        to,
        n,
    }
}

#[test]
fn bad_grids_and_axes_are_refused_by_name() {
    let (model, values, _) = duffing();
    let drive = Excitation::new(vec![1000.0], vec![vec![Complex64::new(1.0, 0.0)]]);
    let msg = |e: ExploreError| e.to_string();
    let e = run_err(
        &model,
        &values,
        &drive,
        axis("freq", 990.0, 1010.0, 1001),
        axis("force:q1", 1.0, 2.0, 1000),
    );
    assert!(msg(e).contains("1001000 points"), "over 10^6");
    let e = run_err(
        &model,
        &values,
        &drive,
        axis("freq", 990.0, 1010.0, 1),
        axis("force:q1", 1.0, 2.0, 10),
    );
    assert!(msg(e).contains("at least 2"));
    let e = run_err(
        &model,
        &values,
        &drive,
        axis("freq", 990.0, 1010.0, 10),
        axis("gamma", 1.0, 2.0, 10),
    );
    assert!(
        msg(e).contains("`gamma` names nothing in the model (parameters: beta)"),
        "unknown parameter"
    );
    let e = run_err(
        &model,
        &values,
        &drive,
        axis("freq", 990.0, 1010.0, 10),
        axis("force:q7", 1.0, 2.0, 10),
    );
    assert!(msg(e).contains("`q7` is not a mode"));
    let e = run_err(
        &model,
        &values,
        &drive,
        axis("freq", 990.0, 1010.0, 10),
        axis("pump_level", 1.0, 2.0, 10),
    );
    assert!(msg(e).contains("no pump terms"));
    let e = run_err(
        &model,
        &values,
        &drive,
        axis("freq", -5.0, 1010.0, 10),
        axis("beta", 1.0, 2.0, 10),
    );
    assert!(msg(e).contains("positive"));
    let e = run_err(
        &model,
        &values,
        &drive,
        axis("freq", f64::NAN, 1010.0, 10),
        axis("beta", 1.0, 2.0, 10),
    );
    assert!(msg(e).contains("finite"));
    let (pm, pv, _) = parametron();
    let pump_only = Excitation {
        tones_hz: vec![],
        force: vec![vec![]],
        pumps: vec![harmonid_sim::PumpTone {
            hz: 2000.0,
            amplitude: Complex64::new(1e5, 0.0),
        }],
    };
    let e = run_err(
        &pm,
        &pv,
        &pump_only,
        axis("freq", 990.0, 1010.0, 10),
        axis("pump_level", 1.0, 2.0, 10),
    );
    assert!(msg(e).contains("no drive tone"));
}

#[test]
fn non_smooth_terms_are_refused_by_name_not_dropped() {
    // The single-harmonic system of `abs(q1)*q1` is not polynomial: every state of it cannot be
    // promised, and dropping the term (as polynomial-only tools do) would be a silent lie.
    let (model, values, num) = super::models::parse(
        "mode q1, f = 1 kHz, Q = 1000\nparam beta, kappa\neom q1 += beta*q1^3 + kappa*abs(q1)*q1\n",
        "[parameters]\nbeta = 1e12\nkappa = 1e6\n",
    );
    let drive = Excitation::new(vec![1000.0], vec![vec![Complex64::new(10.0, 0.0)]]);
    let err = harmonid_explore::states(&num, &drive, &Default::default()).expect_err("refused");
    assert!(
        matches!(&err, ExploreError::NonSmooth { terms } if terms == "abs(q1)*q1"),
        "{err}"
    );
    let err = run_err(
        &model,
        &values,
        &drive,
        axis("freq", 990.0, 1010.0, 4),
        axis("force:q1", 1.0, 10.0, 4),
    );
    assert!(matches!(err, ExploreError::NonSmooth { .. }), "{err}");
}
