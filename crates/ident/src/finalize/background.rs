//! The measurement background of the result ([`crate::background`]): per mode, each fitted
//! term's real and imaginary parts with their standard errors, judged as any quantity except
//! for the relative-error test (a background part near zero is a finding, not a failure).

use super::{JackknifeDisagreement, Judge};
use crate::background::{Background, BackgroundTerm};
use crate::layout::{Quantity, Unknown};
use harmonid_data::result::{BackgroundResult, ComplexEstimate, Estimate};
use harmonid_data::Dataset;
use std::collections::BTreeMap;

/// A quantity with no per-shot spread (the per-shot equation-error fits have no background).
fn blank() -> Estimate {
    Estimate {
        value: f64::NAN,
        std: f64::NAN,
        stderr: f64::NAN,
        crlb: None,
        jackknife: None,
        at_bound: false,
        identifiable: true,
        reason: None,
        outlier_shots: Vec::new(),
        single_shot_std: f64::NAN,
        per_shot: Vec::new(),
    }
}

/// The background per mode name from the reported `values` (layout of the problem's table,
/// whose background unknowns the output-error fit estimated, in the fit's unit: metres, or
/// volts), converted to the dataset's unit `unit` of `scale` metres each. Empty when the table
/// has none.
pub(super) fn table(
    judge: &Judge<'_>,
    values: &[f64],
    (unit, scale): (&str, f64),
    disagreements: &mut Vec<JackknifeDisagreement>,
) -> BTreeMap<String, BackgroundResult> {
    let prob = judge.prob;
    let mut out: BTreeMap<String, BackgroundResult> = BTreeMap::new();
    for u in prob.table.unknowns() {
        let Unknown::Background {
            mode,
            term,
            quad: 0,
        } = *u
        else {
            continue;
        };
        let part = |quad: u8, disagreements: &mut Vec<JackknifeDisagreement>| {
            let mut e = blank();
            let q = Quantity::Background { mode, term, quad };
            let v = prob
                .index_of(&Unknown::Background { mode, term, quad })
                .map_or(f64::NAN, |k| values[k]);
            judge.apply(q, &mut e, v, disagreements);
            if e.reason
                .as_deref()
                .is_some_and(|r| r.starts_with("relative standard error"))
            {
                e.identifiable = true;
                e.reason = None;
            }
            // In the dataset's unit (the jackknife compared above in the fit's).
            e.value /= scale;
            e.stderr /= scale;
            e.crlb = e.crlb.map(|c| c / scale);
            e.jackknife = e.jackknife.map(|j| j / scale);
            e
        };
        let c = ComplexEstimate {
            re: part(0, disagreements),
            im: part(1, disagreements),
        };
        let entry = out
            .entry(prob.mode_names[mode].clone())
            .or_insert_with(|| BackgroundResult {
                unit: unit.to_string(),
                f_ref_hz: prob.table.nominal_hz()[mode],
                drive: None,
                slope: None,
                constant: None,
            });
        match term {
            BackgroundTerm::Drive => entry.drive = Some(c),
            BackgroundTerm::Slope => entry.slope = Some(c),
            BackgroundTerm::Constant => entry.constant = Some(c),
        }
    }
    out
}

/// The background as the result reports it: [`table`] where the output-error fit estimated
/// it, none where the linear estimate is reported (it has no background).
pub(super) fn reported(
    judge: &Judge<'_>,
    values: &[f64],
    ds: &Dataset,
    disagreements: &mut Vec<JackknifeDisagreement>,
) -> BTreeMap<String, BackgroundResult> {
    if judge.fo.is_some() && judge.estimator.is_output_error() {
        let unit = &ds.manifest.displacement_unit;
        let scale = ds.manifest.unit_scale().unwrap_or(1.0);
        table(judge, values, (unit, scale), disagreements)
    } else {
        BTreeMap::new()
    }
}

/// The warning when the output-error fit failed with a background asked for: the linear
/// estimate reported has none.
pub(super) fn not_fitted(background: &Background) -> Option<String> {
    (!background.is_empty()).then(|| {
        format!(
            "the measurement background (--background {background}) was not fitted: the linear estimate reported has none, and a background in the data biases it"
        )
    })
}
