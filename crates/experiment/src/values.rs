//! Parameter values for a simulation: a values file (TOML: `[modes.q1] f_hz, Q`, `[parameters]`,
//! optionally `[eom.q1]`; a `truth.toml` is accepted too) or an identification result
//! (`harmonid-result/1` JSON, read through its own types).
//!
//! A value of a mode or parameter may carry its uncertainty, for planning before the device is
//! known (`beta1 = { value = 6e23, factor = 2 }`, `Q = { value = 4.5e5, rel = 0.3 }`,
//! `f_hz = { value = 207600, abs_hz = 3 }`): [`read_guess`] keeps it as a [`Spread`], every
//! other reader takes the value.

use crate::ExperimentError;
use harmonid_data::result::Report;
use harmonid_sim::{ModeValues, ModelValues};
use std::collections::BTreeMap;
use std::path::Path;

/// How far the device's value may be from a guessed one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Spread {
    /// Between `value / k` and `value · k` (`k ≥ 1`).
    Factor(f64),
    /// Between `value (1 − r)` and `value (1 + r)` (`0 ≤ r < 1`).
    Rel(f64),
    /// Between `value − a` and `value + a` (`a ≥ 0`, in the quantity's unit).
    Abs(f64),
    /// Between two values, whatever the guess (a range narrowed by an identification).
    Ends(f64, f64),
}

impl Spread {
    /// The range's ends around `value`, lower first.
    pub fn ends(self, value: f64) -> (f64, f64) {
        let (a, b) = match self {
            Spread::Factor(k) => (value / k, value * k),
            Spread::Rel(r) => (value * (1.0 - r), value * (1.0 + r)),
            Spread::Abs(a) => (value - a, value + a),
            Spread::Ends(a, b) => (a, b),
        };
        (a.min(b), a.max(b))
    }

    /// As written in messages: `×/÷ 2`, `± 30 %`, `± 3`.
    pub fn describe(self) -> String {
        match self {
            Spread::Factor(k) => format!("×/÷ {k}"),
            Spread::Rel(r) => format!("± {} %", 100.0 * r),
            Spread::Abs(a) => format!("± {a:.4e}"),
            Spread::Ends(a, b) => format!("in [{a:.6e}, {b:.6e}]"),
        }
    }
}

/// Guessed values and the uncertainty of those that carry one, by quantity name: `f_hz:q1`,
/// `Q:q1` and parameter names (the names of a plan's bounds).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Guess {
    /// The guessed values.
    pub values: ModelValues,
    /// Uncertainties given with the values (none for a plain number).
    pub spread: BTreeMap<String, Spread>,
}

impl Guess {
    /// This guess updated by a later one (an identification's, [`guess_from_report`]): each
    /// value `later` gives replaces this one's, with `later`'s spread (none: the quantity's
    /// default); what `later` leaves out (an estimate it did not determine) keeps this guess's
    /// value and spread. `later`'s `[eom]` coefficients are not used.
    pub fn updated_by(mut self, later: &Guess) -> Guess {
        let mut set = |name: String, slot: &mut Option<f64>, x: Option<f64>| {
            if let Some(x) = x {
                *slot = Some(x);
                match later.spread.get(&name) {
                    Some(&s) => self.spread.insert(name, s),
                    None => self.spread.remove(&name),
                };
            }
        };
        for (mode, m) in &later.values.modes {
            let entry = self.values.modes.entry(mode.clone()).or_default();
            set(format!("f_hz:{mode}"), &mut entry.f_hz, m.f_hz);
            set(format!("Q:{mode}"), &mut entry.q, m.q);
        }
        for (name, &x) in &later.values.parameters {
            self.values.parameters.insert(name.clone(), x);
            match later.spread.get(name) {
                Some(&s) => self.spread.insert(name.clone(), s),
                None => self.spread.remove(name),
            };
        }
        self
    }
}

/// Reads a values file with the uncertainties it gives: TOML (`{ value, factor | rel | abs }`
/// per value), or an identification result, whose standard errors give each estimate a
/// spread of [`RESULT_SPREAD_STDERR`] standard errors.
pub fn read_guess(path: &Path) -> Result<Guess, ExperimentError> {
    let origin = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| ExperimentError::Values {
        origin: origin.clone(),
        message: format!("cannot read the values file: {e}"),
    })?;
    if path.extension().is_some_and(|e| e == "json") {
        let r = report_from_json(&text, &origin)?;
        Ok(guess_from_report(&r))
    } else {
        guess_from_toml(&text, &origin)
    }
}

/// Standard errors of an estimate that make the spread of a guess read from a result: the
/// device is taken to be within 3 standard errors of the estimate.
pub const RESULT_SPREAD_STDERR: f64 = 3.0;

/// Reads a values file: an identification result when the name ends in `.json`, TOML otherwise
/// (the values of [`read_guess`], without their uncertainties).
pub fn read_values(path: &Path) -> Result<ModelValues, ExperimentError> {
    Ok(read_guess(path)?.values)
}

/// Values from TOML text (a value with an uncertainty gives its value). Keys of a
/// `truth.toml` other than modes, parameters and eom (`forces`, `noise`) are ignored; any other
/// table is refused.
pub fn values_from_toml(text: &str, origin: &str) -> Result<ModelValues, ExperimentError> {
    guess_from_toml(text, origin).map(|g| g.values)
}

/// Values and their uncertainties from TOML text: `[modes.<mode>]` `f_hz`/`Q` and
/// `[parameters]` entries are numbers or `{ value = .., factor | rel | abs = .. }` (`abs_hz`
/// for a frequency); `[eom.<mode>]` coefficients are numbers.
pub fn guess_from_toml(text: &str, origin: &str) -> Result<Guess, ExperimentError> {
    let err = |message: String| ExperimentError::Values {
        origin: origin.to_string(),
        message,
    };
    let v: toml::Table = toml::from_str(text).map_err(|e| {
        let at = e
            .span()
            .map(|s| format!(" ({})", harmonid_files::quote_line(text, s)))
            .unwrap_or_default();
        err(format!("not valid TOML: {}{at}", e.message().trim_end()))
    })?;
    if let Some(k) = v
        .keys()
        .find(|k| !["modes", "parameters", "eom", "forces", "noise"].contains(&k.as_str()))
    {
        return Err(err(format!(
            "unknown table `{k}` (a values file has [modes.<mode>], [parameters] and optionally [eom.<mode>])"
        )));
    }
    let spans = toml::from_str::<Spans>(text).ok();
    let mut spread = BTreeMap::new();
    let mut t = toml::Table::new();
    for key in ["modes", "parameters", "eom"] {
        if let Some(x) = v.get(key) {
            t.insert(key.into(), x.clone());
        }
    }
    // Uncertain values become their value, their spread kept by quantity name.
    let mut take = |slot: &mut toml::Value, label: String, name: String, span| {
        if let toml::Value::Table(u) = slot {
            let (value, s) = uncertain(u, &label, name.starts_with("f_hz:"))
                .map_err(|m| err(located(text, span, m)))?;
            *slot = toml::Value::Float(value);
            spread.insert(name, s);
        }
        Ok::<(), ExperimentError>(())
    };
    if let Some(toml::Value::Table(modes)) = t.get_mut("modes") {
        for (mode, entry) in modes.iter_mut() {
            if let toml::Value::Table(entry) = entry {
                for (key, slot) in entry.iter_mut() {
                    let span = spans.as_ref().and_then(|s| s.mode_span(mode, key));
                    let name = format!("{key}:{mode}");
                    take(slot, format!("modes.{mode}.{key}"), name, span)?;
                }
            }
        }
    }
    if let Some(toml::Value::Table(params)) = t.get_mut("parameters") {
        for (p, slot) in params.iter_mut() {
            let span = spans
                .as_ref()
                .and_then(|s| s.parameters.get(p).map(|v| v.span()));
            take(slot, format!("parameters.{p}"), p.clone(), span)?;
        }
    }
    let values = toml::Value::Table(t)
        .try_into::<ModelValues>()
        .map_err(|e| {
            err(format!(
                "expected [modes.<mode>] f_hz/Q, [parameters] name = value (or {{ value = .., factor = .. }}), [eom.<mode>]: {e}"
            ))
        })?;
    Ok(Guess { values, spread })
}

/// Where the modes' and parameters' values are in the text, for messages.
#[derive(serde::Deserialize)]
struct Spans {
    #[serde(default)]
    modes: BTreeMap<String, BTreeMap<String, toml::Spanned<toml::Value>>>,
    #[serde(default)]
    parameters: BTreeMap<String, toml::Spanned<toml::Value>>,
}

impl Spans {
    fn mode_span(&self, mode: &str, key: &str) -> Option<std::ops::Range<usize>> {
        self.modes.get(mode)?.get(key).map(|v| v.span())
    }
}

/// `message`, with the line of `span` quoted when known.
fn located(text: &str, span: Option<std::ops::Range<usize>>, message: String) -> String {
    match span {
        Some(s) => format!("{message} ({})", harmonid_files::quote_line(text, s)),
        None => message,
    }
}

/// The value and spread of an uncertain value `{ value = .., factor | rel | abs = .. }`
/// (`abs_hz` too for a frequency) written at `label`.
fn uncertain(t: &toml::Table, label: &str, frequency: bool) -> Result<(f64, Spread), String> {
    let kinds: &[&str] = if frequency {
        &["factor", "rel", "abs", "abs_hz"]
    } else {
        &["factor", "rel", "abs"]
    };
    let expected = format!("`value` and one of {}", kinds.join(", "));
    if let Some(k) = t
        .keys()
        .find(|k| k.as_str() != "value" && !kinds.contains(&k.as_str()))
    {
        return Err(format!(
            "{label}: unknown key `{k}` in an uncertain value (expected {expected})"
        ));
    }
    let number = |k: &str| -> Result<Option<f64>, String> {
        match t.get(k) {
            None => Ok(None),
            Some(toml::Value::Float(x)) if x.is_finite() => Ok(Some(*x)),
            Some(toml::Value::Integer(i)) => Ok(Some(*i as f64)),
            Some(v) => Err(format!("{label}.{k}: expected a finite number, found {v}")),
        }
    };
    let value = number("value")?.ok_or_else(|| {
        format!("{label}: an uncertain value needs `value` (expected {expected})")
    })?;
    let given: Vec<(&str, f64)> = kinds
        .iter()
        .filter_map(|&k| number(k).transpose().map(|x| x.map(|x| (k, x))))
        .collect::<Result<_, _>>()?;
    let [(kind, x)] = given[..] else {
        return Err(format!(
            "{label}: give exactly one uncertainty ({}), or write the plain number",
            kinds.join(", ")
        ));
    };
    let spread = match kind {
        "factor" if x >= 1.0 => Spread::Factor(x),
        "factor" => return Err(format!("{label}.factor = {x}: a factor must be at least 1 (2 means ×/÷ 2)")),
        "rel" if (0.0..1.0).contains(&x) => Spread::Rel(x),
        "rel" => return Err(format!("{label}.rel = {x}: a relative uncertainty must be in [0, 1) (0.3 means ± 30 %); use factor for a wider range")),
        _ if x >= 0.0 => Spread::Abs(x),
        _ => return Err(format!("{label}.{kind} = {x}: an absolute uncertainty must not be negative")),
    };
    Ok((value, spread))
}

/// Values from an identification result (`harmonid-result/1`).
pub fn values_from_json(text: &str, origin: &str) -> Result<ModelValues, ExperimentError> {
    Ok(values_from_report(&report_from_json(text, origin)?))
}

/// Reads an identification result (`harmonid-result/1` JSON).
pub fn read_result(path: &Path) -> Result<Report, ExperimentError> {
    let origin = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| ExperimentError::Values {
        origin: origin.clone(),
        message: format!("cannot read the result: {e}"),
    })?;
    report_from_json(&text, &origin)
}

fn report_from_json(text: &str, origin: &str) -> Result<Report, ExperimentError> {
    Report::from_json(text).map_err(|e| ExperimentError::Values {
        origin: origin.to_string(),
        message: format!("not an identification result (harmonid-result/1): {e}"),
    })
}

/// The guess of an identification result: its values ([`values_from_report`]), each estimate
/// with a finite positive standard error spread by [`RESULT_SPREAD_STDERR`] of them.
pub fn guess_from_report(r: &Report) -> Guess {
    guess_from_reports(std::slice::from_ref(r))
}

/// The guess of several identification results of one device, each from its own data (the
/// rounds of a lab loop): per quantity, the estimates with a finite positive standard error
/// combined by inverse-variance weights (`Σ(x/σ²)/Σ(1/σ²)`, standard error `(Σ 1/σ²)^(−1/2)`;
/// correlations between quantities are not used), spread by [`RESULT_SPREAD_STDERR`] combined
/// standard errors. A quantity with no standard error in any result keeps the last result's
/// value, without a spread. No results: an empty guess.
pub fn guess_from_reports(reports: &[Report]) -> Guess {
    let Some(last) = reports.last() else {
        return Guess::default();
    };
    let mut values = values_from_report(last);
    let mut spread = BTreeMap::new();
    // (value, stderr) of every estimate of each quantity, by name.
    let mut estimates: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    for r in reports {
        let mut put = |name: String, e: &harmonid_data::result::Estimate| {
            if e.value.is_finite() && e.stderr.is_finite() && e.stderr > 0.0 {
                estimates.entry(name).or_default().push((e.value, e.stderr));
            }
        };
        for (k, m) in &r.modes {
            put(format!("f_hz:{k}"), &m.f_hz);
            put(format!("Q:{k}"), &m.q);
        }
        for (k, e) in &r.parameters {
            put(k.clone(), e);
        }
    }
    for (name, list) in estimates {
        // One estimate is taken as it is (the weighted mean would round its last digit).
        let (value, stderr) = match list[..] {
            [one] => one,
            _ => {
                let weight: f64 = list.iter().map(|(_, s)| s.powi(-2)).sum();
                let mean = list.iter().map(|(x, s)| x * s.powi(-2)).sum::<f64>() / weight;
                (mean, weight.powf(-0.5))
            }
        };
        match name.split_once(':') {
            Some(("f_hz", m)) => values.modes.entry(m.to_string()).or_default().f_hz = Some(value),
            Some(("Q", m)) => values.modes.entry(m.to_string()).or_default().q = Some(value),
            _ => {
                values.parameters.insert(name.clone(), value);
            }
        }
        spread.insert(name, Spread::Abs(RESULT_SPREAD_STDERR * stderr));
    }
    Guess { values, spread }
}

/// The values of an identification result: each mode's f and Q, each parameter's value (an
/// undetermined, NaN value is left out); when the result has no parameters, its `eom`
/// coefficients.
pub fn values_from_report(r: &Report) -> ModelValues {
    let finite = |x: f64| x.is_finite().then_some(x);
    let mut out = ModelValues::default();
    for (k, m) in &r.modes {
        out.modes.insert(
            k.clone(),
            ModeValues {
                f_hz: finite(m.f_hz.value),
                q: finite(m.q.value),
            },
        );
    }
    for (k, e) in &r.parameters {
        if let Some(x) = finite(e.value) {
            out.parameters.insert(k.clone(), x);
        }
    }
    if out.parameters.is_empty() {
        for (mode, terms) in &r.eom {
            let map = terms
                .iter()
                .filter_map(|(k, x)| x.map(|x| (k.clone(), x)))
                .collect();
            out.eom.insert(mode.clone(), map);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const GUESS: &str = r#"
[modes.q1]
f_hz = { value = 207600.0, abs_hz = 3 }
Q = { value = 4.5e5, rel = 0.3 }

[modes.q2]
f_hz = 415849.0
Q = 99173

[parameters]
beta1 = { value = 6e23, factor = 2 }
g12 = 2.9e22
"#;

    #[test]
    fn uncertain_values_give_their_value_and_spread() {
        let g = guess_from_toml(GUESS, "guess.toml").expect("a guess");
        assert_eq!(g.values.modes["q1"].f_hz, Some(207600.0));
        assert_eq!(g.values.modes["q1"].q, Some(4.5e5));
        assert_eq!(g.values.modes["q2"].q, Some(99173.0));
        assert_eq!(g.values.parameters["beta1"], 6e23);
        assert_eq!(g.values.parameters["g12"], 2.9e22);
        let want: BTreeMap<String, Spread> = [
            ("f_hz:q1".to_string(), Spread::Abs(3.0)),
            ("Q:q1".to_string(), Spread::Rel(0.3)),
            ("beta1".to_string(), Spread::Factor(2.0)),
        ]
        .into_iter()
        .collect();
        assert_eq!(g.spread, want);
        // The plain reader takes the values.
        assert_eq!(
            values_from_toml(GUESS, "guess.toml").expect("values"),
            g.values
        );
        assert_eq!(Spread::Factor(2.0).ends(-6.0), (-12.0, -3.0));
        assert_eq!(Spread::Rel(0.5).ends(4.0), (2.0, 6.0));
        assert_eq!(Spread::Abs(3.0).ends(10.0), (7.0, 13.0));
    }

    #[test]
    fn a_later_guess_replaces_what_it_gives_and_keeps_the_rest() {
        let first = guess_from_toml(GUESS, "guess.toml").expect("a guess");
        let later = guess_from_toml(
            "[modes.q1]\nQ = { value = 5.1e5, abs = 900 }\n[modes.q2]\nf_hz = 415850.5\n\
             [parameters]\nbeta1 = { value = 5e23, abs = 4e22 }\n",
            "result",
        )
        .expect("later");
        let g = first.clone().updated_by(&later);
        assert_eq!(g.values.modes["q1"].q, Some(5.1e5));
        assert_eq!(g.spread["Q:q1"], Spread::Abs(900.0));
        // Not given later: kept, value and spread.
        assert_eq!(g.values.modes["q1"].f_hz, Some(207600.0));
        assert_eq!(g.spread["f_hz:q1"], Spread::Abs(3.0));
        assert_eq!(g.values.parameters["g12"], 2.9e22);
        // Given later without a spread: its default applies.
        assert_eq!(g.values.modes["q2"].f_hz, Some(415850.5));
        assert!(!g.spread.contains_key("f_hz:q2"));
        assert_eq!(g.values.parameters["beta1"], 5e23);
        assert_eq!(g.spread["beta1"], Spread::Abs(4e22));
    }

    #[test]
    fn a_malformed_uncertainty_is_located_and_explained() {
        let cases = [
            ("beta1 = { value = 6e23, factor = 0.5 }", "at least 1"),
            ("beta1 = { value = 6e23, rel = 1.5 }", "[0, 1)"),
            ("beta1 = { value = 6e23, abs = -1 }", "must not be negative"),
            ("beta1 = { value = 6e23 }", "exactly one uncertainty"),
            (
                "beta1 = { value = 6e23, rel = 0.1, factor = 2 }",
                "exactly one",
            ),
            ("beta1 = { factor = 2 }", "needs `value`"),
            (
                "beta1 = { value = 6e23, spread = 2 }",
                "unknown key `spread`",
            ),
            (
                "beta1 = { value = 6e23, abs_hz = 2 }",
                "unknown key `abs_hz`",
            ),
            ("beta1 = { value = \"big\", factor = 2 }", "finite number"),
        ];
        for (line, want) in cases {
            let text = format!("[parameters]\n{line}\n");
            let e = guess_from_toml(&text, "g.toml")
                .expect_err(line)
                .to_string();
            assert!(e.contains(want), "{line}: {e}");
            assert!(e.contains("g.toml") && e.contains("line 2"), "{line}: {e}");
            assert!(e.contains("parameters.beta1"), "{line}: {e}");
        }
    }
}
