//! What the report needs from an identification result ([`harmonid_ident::Report`], read with
//! the same type that writes it: `Report::from_json`).

use harmonid_data::Truth;
use harmonid_ident::Report;

/// The numbers a simulation needs: `[modes]` and `[eom]` (terms reported as null dropped).
pub fn model_values(r: &Report) -> harmonid_sim::ModelValues {
    let mut v = harmonid_sim::ModelValues::default();
    for (n, m) in &r.modes {
        v.modes.insert(
            n.clone(),
            harmonid_sim::ModeValues {
                f_hz: Some(m.f_hz.value),
                q: Some(m.q.value),
            },
        );
    }
    for (n, terms) in &r.eom {
        v.eom.insert(
            n.clone(),
            terms
                .iter()
                .filter_map(|(k, c)| c.filter(|c| c.is_finite()).map(|c| (k.clone(), c)))
                .collect(),
        );
    }
    v
}

/// The truth of parameter `p`: the truth coefficient of a monomial whose identified
/// coefficient equals the parameter's value (a monomial it alone sets).
pub fn truth_of_param(r: &Report, p: &str, truth: &Truth) -> Option<f64> {
    let e = r.parameters.get(p)?;
    r.eom.iter().find_map(|(mode, row)| {
        row.iter().find_map(|(mono, v)| {
            let v = (*v)?;
            ((v - e.value).abs() <= 1e-12 * e.value.abs())
                .then(|| truth.eom.get(mode).and_then(|r| r.get(mono)).copied())
                .flatten()
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_of_a_result_read_back() {
        let text = r#"{"format": "harmonid-result/1", "model": "m.hb", "dataset": "d",
            "modes": {"q1": {"f_hz": {"value": 1000.0, "std": 0.1, "stderr": 0.01},
                             "Q": {"value": 500.0, "std": null, "stderr": 1.0}}},
            "parameters": {"b": {"value": 2.0, "std": 0.3, "stderr": 0.1}},
            "eom": {"q1": {"q1^3": 2.0, "q1^5": null}}}"#;
        let r = Report::from_json(text).expect("reads");
        assert!(r.modes["q1"].q.std.is_nan());
        let v = model_values(&r);
        assert_eq!(v.modes["q1"].f_hz, Some(1000.0));
        assert_eq!(v.eom["q1"].len(), 1, "the null coefficient is dropped");
        let mut truth = Truth::default();
        truth
            .eom
            .entry("q1".into())
            .or_default()
            .insert("q1^3".into(), 2.1);
        assert_eq!(truth_of_param(&r, "b", &truth), Some(2.1));
    }
}
