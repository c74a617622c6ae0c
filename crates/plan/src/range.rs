//! The range of devices a design must survive: each free quantity of the guess between two
//! ends (the uncertainty given with its value, or a default), the corners a candidate drive is
//! checked at, and the draws its bounds are reported over.

use crate::PlanError;
use harmonid_experiment::{Guess, Spread};
use harmonid_model::{Linear, Model, ParamKind};
use harmonid_sim::{ModelValues, NumericModel};
use rand::{Rng, SeedableRng};
use std::collections::BTreeMap;

/// Most frequency steps across one mode's range in the devices a drive is checked at.
const MAX_FREQUENCY_STEPS: usize = 16;

/// Default spread of a frequency, in linewidths `f/Q` of the guess.
pub const DEFAULT_F_LINEWIDTHS: f64 = 2.0;
/// Default relative spread of a quality factor.
pub const DEFAULT_Q_REL: f64 = 0.3;
/// Default factor of a parameter.
pub const DEFAULT_PARAM_FACTOR: f64 = 2.0;

/// What a quantity of the range is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Frequency(usize),
    Quality(usize),
    Parameter,
}

/// One uncertain quantity: its guess and spread.
#[derive(Debug, Clone, PartialEq)]
pub struct RangeEntry {
    /// Quantity name (`f_hz:q1`, `Q:q1`, `beta1`).
    pub name: String,
    /// The guessed value.
    pub guess: f64,
    /// How far the device's value may be from it.
    pub spread: Spread,
    /// Whether the spread was given with the values (else it is the default).
    pub given: bool,
    /// What narrowing it by an identification did, when worth saying (the estimate outside
    /// the guess's range).
    pub remark: Option<String>,
    kind: Kind,
}

impl RangeEntry {
    /// The ends, lower first.
    pub fn ends(&self) -> (f64, f64) {
        self.spread.ends(self.guess)
    }
}

/// The devices a plan is designed to survive: every free quantity of the model (a mode's f and
/// Q the model leaves unknown, its unknown parameters) between the ends of its spread.
#[derive(Debug, Clone, PartialEq)]
pub struct GuessRange {
    entries: Vec<RangeEntry>,
    /// The guess every device of the range modifies (its `[eom]` coefficients dropped: the
    /// parameters act).
    base: ModelValues,
    /// The model's mode names, in order.
    names: Vec<String>,
    /// Each mode's Q at the guess (a fixed Q, or the guessed one: the half-width of the
    /// frequency steps when Q has no range).
    q_guess: Vec<f64>,
}

impl GuessRange {
    /// The range of `values` with the `given` spreads (by quantity name), the others by the
    /// defaults: f ± [`DEFAULT_F_LINEWIDTHS`] linewidths, Q ± [`DEFAULT_Q_REL`], parameters
    /// ×/÷ [`DEFAULT_PARAM_FACTOR`]. Errors: a spread for a quantity the model does not leave
    /// free, a range that reaches a non-positive frequency or Q, values the simulation refuses.
    pub fn new(
        model: &Model,
        values: &ModelValues,
        given: &BTreeMap<String, Spread>,
    ) -> Result<Self, PlanError> {
        let num = NumericModel::from_model(model, values)?;
        let mut entries = Vec::new();
        for (n, m) in model.modes.iter().enumerate() {
            let f = num.f_hz[n];
            let q = num.q_factor[n];
            if m.f_hz == Linear::Unknown {
                entries.push((
                    format!("f_hz:{}", m.name),
                    f,
                    Spread::Abs(DEFAULT_F_LINEWIDTHS * f / q),
                    Kind::Frequency(n),
                ));
            }
            if m.q_factor == Linear::Unknown {
                entries.push((
                    format!("Q:{}", m.name),
                    q,
                    Spread::Rel(DEFAULT_Q_REL),
                    Kind::Quality(n),
                ));
            }
        }
        for p in &model.params {
            if p.kind == ParamKind::Unknown {
                let v = values.parameters.get(&p.name).copied().unwrap_or(f64::NAN);
                entries.push((
                    p.name.clone(),
                    v,
                    Spread::Factor(DEFAULT_PARAM_FACTOR),
                    Kind::Parameter,
                ));
            }
        }
        if let Some(k) = given.keys().find(|k| !entries.iter().any(|e| &e.0 == *k)) {
            let free: Vec<&str> = entries.iter().map(|e| e.0.as_str()).collect();
            return Err(PlanError::Range {
                quantity: k.clone(),
                message: format!(
                    "an uncertainty for a quantity the model does not leave free (free: {})",
                    free.join(", ")
                ),
            });
        }
        let entries: Vec<RangeEntry> = entries
            .into_iter()
            .map(|(name, guess, default, kind)| {
                let spread = given.get(&name).copied();
                RangeEntry {
                    guess,
                    spread: spread.unwrap_or(default),
                    given: spread.is_some(),
                    remark: None,
                    kind,
                    name,
                }
            })
            .collect();
        let mut base = values.clone();
        base.eom.clear();
        let range = Self {
            entries,
            base,
            names: num.mode_names.clone(),
            q_guess: num.q_factor.clone(),
        };
        range.check_positive()?;
        Ok(range)
    }

    /// Refuses a range that reaches a non-positive frequency or quality factor.
    fn check_positive(&self) -> Result<(), PlanError> {
        for e in &self.entries {
            let (lo, _) = e.ends();
            if e.kind != Kind::Parameter && (lo.is_nan() || lo <= 0.0) {
                return Err(PlanError::Range {
                    quantity: e.name.clone(),
                    message: format!(
                        "{} {} reaches {lo:.4e}, and a {} must stay positive: narrow the uncertainty",
                        e.guess,
                        e.spread.describe(),
                        if matches!(e.kind, Kind::Frequency(_)) { "frequency" } else { "quality factor" }
                    ),
                });
            }
        }
        Ok(())
    }

    /// This range narrowed by what an identification of the device found (`later`, e.g.
    /// [`harmonid_experiment::guess_from_reports`]): a quantity `later` gives with a spread is
    /// where both ranges agree, its guess the estimate (moved into that interval if outside;
    /// [`RangeEntry::remark`] says so); when they do not overlap, the estimate's range alone
    /// (the data win over the guess). A
    /// quantity `later` gives without a spread takes its value and keeps its spread about it;
    /// the others are kept. Errors as [`Self::new`].
    pub fn narrowed(&self, model: &Model, later: &Guess) -> Result<Self, PlanError> {
        let mut out = self.clone();
        for e in &mut out.entries {
            let value = match e.kind {
                Kind::Frequency(n) => later
                    .values
                    .modes
                    .get(&model.modes[n].name)
                    .and_then(|m| m.f_hz),
                Kind::Quality(n) => later
                    .values
                    .modes
                    .get(&model.modes[n].name)
                    .and_then(|m| m.q),
                Kind::Parameter => later.values.parameters.get(&e.name).copied(),
            };
            let Some(v) = value.filter(|v| v.is_finite()) else {
                continue;
            };
            match later.spread.get(&e.name) {
                Some(s) => {
                    let (a, b) = e.ends();
                    let (c, d) = s.ends(v);
                    let overlap = a.max(c) <= b.min(d);
                    let (lo, hi) = if overlap {
                        (a.max(c), b.min(d))
                    } else {
                        (c, d)
                    };
                    if !(a..=b).contains(&v) {
                        e.remark = Some(format!(
                            "the estimate {v:.6e} is outside the guess's range [{a:.6e}, {b:.6e}]: {}",
                            if overlap {
                                "the range is where the two overlap; widen the guess's uncertainty if the device may be outside it"
                            } else {
                                "they do not overlap, so the estimate's range replaces the guess's"
                            }
                        ));
                    }
                    e.guess = v.clamp(lo, hi);
                    e.spread = Spread::Ends(lo, hi);
                    e.given = true;
                }
                None => e.guess = v,
            }
        }
        out.base = out.device(|e| e.guess);
        out.check_positive()?;
        Ok(out)
    }

    /// The guess at the range's centre (without `[eom]` coefficients: its parameters act).
    pub fn guess(&self) -> &ModelValues {
        &self.base
    }

    /// The quantities of device `values` that bear on measurement `pm`, against the guess:
    /// its driven modes' frequencies (offset in Hz) and Q, and the parameters of terms in
    /// their equations (ratio), e.g. `f_hz:q2 +3.1 Hz, Q:q2 ×1.27, beta2 ×1.8`.
    pub fn describe_device(
        &self,
        model: &Model,
        values: &ModelValues,
        pm: &harmonid_experiment::PlanMeasurement,
    ) -> String {
        let driven: Vec<usize> = model
            .modes
            .iter()
            .enumerate()
            .filter(|(_, m)| {
                pm.force
                    .get(&m.name)
                    .is_some_and(|f| f.iter().any(|&x| x != 0.0))
            })
            .map(|(k, _)| k)
            .collect();
        let mut out = Vec::new();
        for e in &self.entries {
            let (relevant, x) = match e.kind {
                Kind::Frequency(n) => (
                    driven.contains(&n),
                    values.modes.get(&model.modes[n].name).and_then(|m| m.f_hz),
                ),
                Kind::Quality(n) => (
                    driven.contains(&n),
                    values.modes.get(&model.modes[n].name).and_then(|m| m.q),
                ),
                Kind::Parameter => {
                    let p = model.params.iter().position(|p| p.name == e.name);
                    let touches = p.is_some_and(|p| {
                        crate::terms::param_modes(model, p)
                            .iter()
                            .any(|n| driven.contains(n))
                    });
                    (touches, values.parameters.get(&e.name).copied())
                }
            };
            let Some(x) = x.filter(|_| relevant) else {
                continue;
            };
            out.push(match e.kind {
                Kind::Frequency(_) => format!("{} {:+.3} Hz", e.name, x - e.guess),
                _ => format!("{} ×{:.3}", e.name, x / e.guess),
            });
        }
        out.join(", ")
    }

    /// The quantities of the range.
    pub fn entries(&self) -> &[RangeEntry] {
        &self.entries
    }

    /// One line per quantity: `f_hz:q1  207582 ± 3.57 Hz (default: 2 linewidths)`.
    pub fn describe(&self) -> Vec<String> {
        self.entries
            .iter()
            .map(|e| {
                let (lo, hi) = e.ends();
                let why = if matches!(e.spread, Spread::Ends(..)) {
                    "narrowed by the results".to_string()
                } else if e.given {
                    "given".to_string()
                } else {
                    match e.kind {
                        Kind::Frequency(_) => format!("default: {DEFAULT_F_LINEWIDTHS} linewidths"),
                        Kind::Quality(_) => format!("default: ± {} %", 100.0 * DEFAULT_Q_REL),
                        Kind::Parameter => format!("default: ×/÷ {DEFAULT_PARAM_FACTOR}"),
                    }
                };
                let remark = e
                    .remark
                    .as_ref()
                    .map_or(String::new(), |r| format!("; {r}"));
                format!(
                    "{} = {:.6e} {} ({why}): {lo:.6e} … {hi:.6e}{remark}",
                    e.name,
                    e.guess,
                    e.spread.describe()
                )
            })
            .collect()
    }

    /// The values of one device of the range: each quantity at `pick(entry)`.
    fn device(&self, mut pick: impl FnMut(&RangeEntry) -> f64) -> ModelValues {
        let names = &self.names;
        let mut v = self.base.clone();
        for e in &self.entries {
            let x = pick(e);
            match e.kind {
                Kind::Frequency(n) => v.modes.entry(names[n].clone()).or_default().f_hz = Some(x),
                Kind::Quality(n) => v.modes.entry(names[n].clone()).or_default().q = Some(x),
                Kind::Parameter => {
                    v.parameters.insert(e.name.clone(), x);
                }
            }
        }
        v
    }

    /// The devices a drive is checked at, each with a label. `tones` are the drive's tones
    /// (Hz) with the mode each drives; every device has every Q at its upper end (less damping:
    /// a larger response, an earlier fold). Then:
    /// - the corners: each driven mode's frequency at either end, every parameter at the end
    ///   of larger magnitude (a stronger stiffening);
    /// - per driven mode, its frequency stepped across its range by one half-width `f/2Q`
    ///   (at most 16 steps), the other modes at their guesses,
    ///   parameters at the larger end: a tone folds at the weakest force when the resonance
    ///   sits a cusp detuning (`√3` half-widths for one Duffing tone, moved by the other
    ///   modes' dispersive shifts) from it, which can be anywhere inside the range;
    /// - the guess's frequencies with every parameter at the end of smaller magnitude (a
    ///   weaker nonlinear damping, a weaker term that competes with another).
    ///
    /// A set, not a proof: the checks sample the range where drives fail most, and the plan's
    /// [`crate::Robustness`] reports devices drawn at random from it.
    pub fn corners(
        &self,
        model: &Model,
        tones: &[(f64, usize)],
    ) -> Result<Vec<(String, NumericModel)>, PlanError> {
        let f_entries: Vec<(usize, &RangeEntry)> = self
            .entries
            .iter()
            .filter_map(|e| match e.kind {
                Kind::Frequency(n) if tones.iter().any(|t| t.1 == n) => Some((n, e)),
                _ => None,
            })
            .collect();
        let q_hi = |n: usize| -> f64 {
            self.entries
                .iter()
                .find(|e| e.kind == Kind::Quality(n))
                .map_or(self.q_guess[n], |e| e.ends().1)
        };
        // (label, frequency per uncertain driven mode, parameters at the larger end)
        let mut devices: Vec<(String, Vec<f64>, bool)> = Vec::new();
        for bits in 0..(1usize << f_entries.len()) {
            let f: Vec<f64> = f_entries
                .iter()
                .enumerate()
                .map(|(k, (_, e))| {
                    if bits >> k & 1 == 1 {
                        e.ends().1
                    } else {
                        e.ends().0
                    }
                })
                .collect();
            let label: Vec<String> = f_entries
                .iter()
                .enumerate()
                .map(|(k, (_, e))| {
                    format!(
                        "{} {}",
                        e.name,
                        if bits >> k & 1 == 1 { "high" } else { "low" }
                    )
                })
                .collect();
            devices.push((label.join(", "), f, true));
        }
        let guesses: Vec<f64> = f_entries.iter().map(|(_, e)| e.guess).collect();
        for (k, &(n, e)) in f_entries.iter().enumerate() {
            let (lo, hi) = e.ends();
            // A step of one half-width at the upper Q: a tone's fold detuning (√3 half-widths
            // for one Duffing tone, moved by the other modes' dispersive shifts) is never more
            // than half a step from a point.
            let h = e.guess / (2.0 * q_hi(n));
            let steps = ((hi - lo) / h)
                .ceil()
                .clamp(1.0, MAX_FREQUENCY_STEPS as f64) as usize;
            for j in 1..steps {
                let f = lo + (hi - lo) * j as f64 / steps as f64;
                let mut fs = guesses.clone();
                fs[k] = f;
                devices.push((format!("{} {:+.3} Hz", e.name, f - e.guess), fs, true));
            }
        }
        devices.push(("frequencies at the guess".into(), guesses, false));
        let mut out = Vec::with_capacity(devices.len());
        for (label, fs, large) in devices {
            let values = self.device(|e| {
                let (lo, hi) = e.ends();
                match e.kind {
                    Kind::Frequency(n) => f_entries
                        .iter()
                        .position(|(m, _)| *m == n)
                        .map_or(e.guess, |k| fs[k]),
                    Kind::Quality(_) => hi,
                    Kind::Parameter => {
                        let (small, big) = if lo.abs() <= hi.abs() {
                            (lo, hi)
                        } else {
                            (hi, lo)
                        };
                        if large {
                            big
                        } else {
                            small
                        }
                    }
                }
            });
            let label = format!(
                "{label}, every Q high, parameters at their {} magnitude",
                if large { "larger" } else { "smaller" }
            );
            out.push((label, NumericModel::from_model(model, &values)?));
        }
        Ok(out)
    }

    /// `n` devices drawn from the range with seed `seed`: each quantity uniform between its
    /// ends (log-uniform for a factor spread).
    pub fn draws(&self, n: usize, seed: u64) -> Vec<ModelValues> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                self.device(|e| {
                    let u: f64 = rng.random();
                    match e.spread {
                        Spread::Factor(k) => e.guess * k.powf(2.0 * u - 1.0),
                        _ => {
                            let (lo, hi) = e.ends();
                            lo + u * (hi - lo)
                        }
                    }
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> Model {
        harmonid_model::parse_str(
            "mode q1\nmode q2\nparam beta1, eta1\npotential: beta1/4*q1^4\neom q1 += eta1*q1^2*d(q1)\n",
            "m.hb",
        )
        .expect("model")
    }

    fn values() -> ModelValues {
        harmonid_experiment::values_from_toml(
            "[modes.q1]\nf_hz = 1000.0\nQ = 500.0\n[modes.q2]\nf_hz = 3000.0\nQ = 1000.0\n\
             [parameters]\nbeta1 = -4e12\neta1 = 2e6\n",
            "v.toml",
        )
        .expect("values")
    }

    #[test]
    fn defaults_fill_what_the_guess_does_not_give() {
        let given = [("Q:q1".to_string(), Spread::Abs(100.0))]
            .into_iter()
            .collect();
        let r = GuessRange::new(&model(), &values(), &given).expect("range");
        let ends: BTreeMap<&str, ((f64, f64), bool)> = r
            .entries()
            .iter()
            .map(|e| (e.name.as_str(), (e.ends(), e.given)))
            .collect();
        assert_eq!(ends["f_hz:q1"], ((996.0, 1004.0), false));
        assert_eq!(ends["Q:q1"], ((400.0, 600.0), true));
        let (lo, hi) = ends["Q:q2"].0;
        assert!((lo - 700.0).abs() < 1e-9 && (hi - 1300.0).abs() < 1e-9);
        assert_eq!(ends["beta1"], ((-8e12, -2e12), false));
        assert_eq!(r.describe().len(), 6);
    }

    #[test]
    fn the_checked_devices_are_the_corners_the_frequency_steps_and_the_weak_end() {
        let m = model();
        let r = GuessRange::new(&m, &values(), &BTreeMap::new()).expect("range");
        // A pair 2 Hz apart on q1 (linewidth 2 Hz, range ± 4 Hz; at Q 650 the half-width is
        // 1000/1300 Hz, so 11 steps across the 8 Hz).
        let c = r.corners(&m, &[(999.0, 0), (1001.0, 0)]).expect("corners");
        let mut want = vec![996.0, 1004.0];
        want.extend((1..11).map(|j| 996.0 + 8.0 * j as f64 / 11.0));
        want.push(1000.0);
        let got: Vec<f64> = c.iter().map(|(_, num)| num.f_hz[0]).collect();
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            assert!((g - w).abs() < 1e-9, "{got:?} vs {want:?}");
        }
        // No two frequencies more than a half-width apart: a cusp detuning is never more than
        // half a step from a checked one.
        let mut sorted = got.clone();
        sorted.sort_by(f64::total_cmp);
        assert!(sorted
            .windows(2)
            .all(|w| w[1] - w[0] <= 1000.0 / 1300.0 + 1e-12));
        for (k, (label, num)) in c.iter().enumerate() {
            // Q at the upper end, the undriven mode at its guess.
            assert!((num.q_factor[0] - 650.0).abs() < 1e-9, "{label}");
            assert!((num.f_hz[1] - 3000.0).abs() < 1e-12, "{label}");
            let beta = num
                .eq_terms(0)
                .iter()
                .find(|t| t.factors == [(0, 3)])
                .expect("beta")
                .coef;
            let large = k + 1 < c.len();
            assert_eq!(label.contains("larger"), large, "{label}");
            assert_eq!(beta.abs(), if large { 8e12 } else { 2e12 }, "{label}");
        }
        // Two driven modes: 4 corners, 10 inner steps of each (q2: ± 6 Hz, half-width
        // 3000/2600 Hz), the guess.
        let c = r.corners(&m, &[(999.0, 0), (3000.0, 1)]).expect("corners");
        assert_eq!(c.len(), 4 + 10 + 10 + 1);
    }

    #[test]
    fn draws_stay_inside_the_range() {
        let m = model();
        let r = GuessRange::new(&m, &values(), &BTreeMap::new()).expect("range");
        let d = r.draws(200, 1);
        assert_eq!(d, r.draws(200, 1), "deterministic");
        let (mut below, mut above) = (0, 0);
        for v in &d {
            let b = v.parameters["beta1"];
            assert!((-8e12..=-2e12).contains(&b));
            if b.abs() < 4e12 {
                below += 1
            } else {
                above += 1
            }
            let q = v.modes["q1"].q.expect("Q");
            assert!((350.0..=650.0).contains(&q));
        }
        // Log-uniform: as many below the guess as above.
        assert!(below > 70 && above > 70, "{below} {above}");
    }

    #[test]
    fn a_result_narrows_the_range_where_both_agree() {
        let m = model();
        let r = GuessRange::new(&m, &values(), &BTreeMap::new()).expect("range");
        let later = harmonid_experiment::guess_from_toml(
            "[modes.q1]\nf_hz = { value = 1001.0, abs = 0.01 }\nQ = { value = 700, abs = 100 }\n\
             [parameters]\nbeta1 = { value = -3e12, abs = 2e12 }\neta1 = { value = 9e6, abs = 1e6 }\n",
            "result",
        )
        .expect("later");
        let n = r.narrowed(&m, &later).expect("narrowed");
        let get = |name: &str| {
            n.entries()
                .iter()
                .find(|e| e.name == name)
                .expect(name)
                .clone()
        };
        // Inside the guess's range: the estimate's range.
        let f = get("f_hz:q1");
        assert_eq!((f.guess, f.ends()), (1001.0, (1000.99, 1001.01)));
        assert!(f.remark.is_none());
        // Overlapping: where both agree; the estimate outside is moved in, with a remark.
        let q = get("Q:q1");
        assert_eq!((q.guess, q.ends()), (650.0, (600.0, 650.0)));
        assert!(q.remark.as_deref().is_some_and(|r| r.contains("overlap")));
        let b = get("beta1");
        assert_eq!((b.guess, b.ends()), (-3e12, (-5e12, -2e12)));
        // No overlap (eta1 ×/÷ 2 of 2e6 against 9e6 ± 1e6): the data's.
        let eta = get("eta1");
        assert_eq!((eta.guess, eta.ends()), (9e6, (8e6, 1e7)));
        assert!(eta
            .remark
            .as_deref()
            .is_some_and(|r| r.contains("replaces")));
        // Untouched, and the guess the range's centre.
        assert_eq!(
            get("Q:q2").ends(),
            r.entries()
                .iter()
                .find(|e| e.name == "Q:q2")
                .expect("Q2")
                .ends()
        );
        assert_eq!(n.guess().parameters["eta1"], 9e6);
        assert_eq!(n.guess().modes["q1"].q, Some(650.0));
    }

    #[test]
    fn a_spread_for_a_fixed_quantity_or_one_reaching_zero_is_refused() {
        let m = model();
        let e = GuessRange::new(
            &m,
            &values(),
            &[("gamma".to_string(), Spread::Rel(0.1))]
                .into_iter()
                .collect(),
        )
        .expect_err("unknown");
        assert!(
            e.to_string().contains("gamma") && e.to_string().contains("beta1"),
            "{e}"
        );
        let e = GuessRange::new(
            &m,
            &values(),
            &[("Q:q1".to_string(), Spread::Abs(600.0))]
                .into_iter()
                .collect(),
        )
        .expect_err("non-positive Q");
        assert!(
            e.to_string().contains("Q:q1") && e.to_string().contains("positive"),
            "{e}"
        );
    }
}
