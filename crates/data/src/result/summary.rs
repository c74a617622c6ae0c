//! The result as people read it: a summary table and the per-shot CSV.

use super::{Estimate, Estimator, Report};
use crate::dataset::Truth;
use crate::text::index_list;
use std::fmt::Write as _;

impl Report {
    /// Every estimate with its key, in the result's order: `f_hz:<mode>` and `Q:<mode>` per
    /// mode, then the parameters by name.
    pub fn estimates(&self) -> Vec<(String, &Estimate)> {
        let mut out: Vec<(String, &Estimate)> = Vec::new();
        for (n, m) in &self.modes {
            out.push((format!("f_hz:{n}"), &m.f_hz));
            out.push((format!("Q:{n}"), &m.q));
        }
        for (p, e) in &self.parameters {
            out.push((p.clone(), e));
        }
        out
    }

    /// Every shot's estimates as CSV: `shot`, `f_hz:<mode>`, `Q:<mode>`, parameters, `outlier`.
    pub fn per_shot_csv(&self) -> String {
        let cols = self.estimates();
        let mut s = String::from("shot");
        for (c, _) in &cols {
            s.push(',');
            s.push_str(c);
        }
        s.push_str(",outlier\n");
        let fitted = if self.shot_index.is_empty() {
            (0..self.shots).collect()
        } else {
            self.shot_index.clone()
        };
        for (k, shot) in fitted.into_iter().enumerate() {
            let _ = write!(s, "{shot}");
            for (_, e) in &cols {
                let _ = write!(s, ",{:e}", e.per_shot.get(k).copied().unwrap_or(f64::NAN));
            }
            let _ = writeln!(s, ",{}", u8::from(self.outlier_shots.contains(&shot)));
        }
        s
    }

    /// A readable summary: value ± std per quantity (with truth, when the dataset has it), the
    /// fits per stage with residuals and conditioning, warnings.
    pub fn summary(&self, truth: Option<&Truth>) -> String {
        let mut s = String::new();
        let verdict = self.goodness_of_fit.as_ref().and_then(|g| g.headline());
        if let Some(v) = &verdict {
            let _ = writeln!(s, "{v}\n");
        }
        self.write_head(&mut s);
        let with_crlb = self
            .modes
            .values()
            .flat_map(|m| [&m.f_hz, &m.q])
            .chain(self.parameters.values())
            .any(|e| e.crlb.is_some());
        let _ = write!(
            s,
            "\n{:<14} {:>18} {:>11} {:>9} {:>11}",
            "quantity", "value", "± stderr", "rel.", "std"
        );
        if with_crlb {
            let _ = write!(s, " {:>11}", "crlb");
        }
        let _ = writeln!(s, " {:>18} {:>10}", "truth", "dev/stderr");
        let mut line = |name: String, e: &Estimate, t: Option<f64>| {
            let rel = e.stderr / e.value.abs();
            let (tt, dev) = match t {
                Some(t) => (
                    format!("{t:.10e}"),
                    format!("{:+.2}", (e.value - t) / e.stderr),
                ),
                None => (String::new(), String::new()),
            };
            let flag = if e.at_bound {
                "  AT BOUND"
            } else if e.identifiable {
                ""
            } else {
                "  NOT DETERMINED"
            };
            let _ = write!(
                s,
                "{name:<14} {:>18.10e} {:>11.3e} {:>9.2e} {:>11.3e}",
                e.value, e.stderr, rel, e.std
            );
            if with_crlb {
                match e.crlb {
                    Some(c) => {
                        let _ = write!(s, " {c:>11.3e}");
                    }
                    None => {
                        let _ = write!(s, " {:>11}", "");
                    }
                }
            }
            let _ = writeln!(s, " {tt:>18} {dev:>10}{flag}");
        };
        for (n, m) in &self.modes {
            let tm = truth.and_then(|t| t.modes.get(n));
            line(format!("f_{n} [Hz]"), &m.f_hz, tm.map(|t| t.f_hz));
            line(format!("Q_{n}"), &m.q, tm.map(|t| t.q));
        }
        for (p, e) in &self.parameters {
            // Truth of a parameter: the truth coefficient of a monomial it alone sets.
            let t = truth.and_then(|t| self.truth_of_param(p, t));
            line(p.clone(), e, t);
        }
        let _ = writeln!(s, "\nfits:");
        for f in &self.fits {
            let _ = writeln!(
                s,
                "  stage {} [{}]: {} unknowns, {} rows, cond {:.2e}, rel. residual {:.2e}{}",
                f.stage,
                crate::text::first_and_more(f.measurements.clone(), 8).join(", "),
                f.unknowns.len(),
                f.rows,
                f.condition_number,
                f.relative_residual,
                match (f.weighted, f.noise_from_shots) {
                    (true, true) => ", GLS, noise from shot scatter",
                    (true, false) => ", GLS with equal amplitude noise",
                    _ => ", unweighted",
                }
            );
        }
        if !self.gains.is_empty() {
            let _ = writeln!(s, "\nactuator gains (N/kg per drive unit):");
            for (m, g) in &self.gains {
                for (n, x) in g {
                    let _ = writeln!(
                        s,
                        "  {m} {n}: |G| = {:.6e}, arg G = {:+.4} rad",
                        x.amplitude, x.phase_rad
                    );
                }
            }
        }
        self.write_background(&mut s);
        for n in &self.notes {
            let _ = writeln!(s, "note: {n}");
        }
        for g in &self.unfit {
            let _ = writeln!(s, "not fitted: {}", g.line());
        }
        if !self.outlier_shots.is_empty() {
            let _ = writeln!(
                s,
                "\noutlier shots of the per-shot fits (outside the IQR fences for some quantity): {}",
                index_list(&self.outlier_shots)
            );
        }
        for w in self
            .warnings
            .iter()
            .filter(|w| Some(*w) != verdict.as_ref())
        {
            let _ = writeln!(s, "warning: {w}");
        }
        s
    }

    /// The summary's head: what was fitted, by which estimator, the verdict on the fit and
    /// the held-out predictions.
    fn write_head(&self, s: &mut String) {
        let _ = writeln!(
            s,
            "harmonid identify: {} shot(s), force model: {}",
            self.shots, self.force_model
        );
        let _ = writeln!(
            s,
            "  estimator: {}; value ± stderr{}; std = spread of per-shot estimates (diagnostic){}",
            match self.estimator.parse::<Estimator>() {
                Ok(e) => e.description(),
                Err(_) => self.estimator.as_str(),
            },
            if self
                .estimator
                .parse::<Estimator>()
                .is_ok_and(Estimator::is_output_error)
            {
                " (Fisher information at the estimate)"
            } else {
                ""
            },
            if self.shots <= 1 {
                " (single shot: the fit's standard error)"
            } else {
                ""
            }
        );
        if let Some(g) = &self.goodness_of_fit {
            let _ = writeln!(s, "  goodness of fit: {}", g.one_line());
            let _ = writeln!(s, "  {}", g.misfit_line());
        }
        for h in self.holdout.iter().filter(|h| h.sweep.is_none()) {
            let _ = writeln!(
                s,
                "  held out \"{}\" ({}{} lines, not fitted): predicted to {:.3} % RMS of its amplitudes{}{}",
                h.measurement,
                h.steps.map_or(String::new(), |k| format!("sweep of {k} steps, ")),
                h.lines,
                100.0 * h.relative_rms,
                h.rms_sigma_floor
                    .map_or(String::new(), |r| format!(", {r:.3} sigmas RMS with the error floor")),
                h.rms_sigma
                    .map_or(String::new(), |r| format!(", {r:.3} shot-noise sigmas RMS")),
            );
        }
    }

    /// The measurement background, one line per mode and term: the real and imaginary parts
    /// with their standard errors, and the unit.
    fn write_background(&self, s: &mut String) {
        if self.background.is_empty() {
            return;
        }
        let _ = writeln!(
            s,
            "\nmeasurement background (added to the model on each measured drive line: B·D + S·D·(f − f_ref) + C, D the drive level):"
        );
        for (mode, b) in &self.background {
            for (term, unit, c) in b.terms() {
                let part = |e: &Estimate| {
                    let flag = if e.identifiable {
                        ""
                    } else {
                        " (not determined)"
                    };
                    format!("{:+.6e} ± {:.3e}{flag}", e.value, e.stderr)
                };
                let _ = writeln!(
                    s,
                    "  {mode} {term:<8} re {}, im {} [{unit}]{}",
                    part(&c.re),
                    part(&c.im),
                    if term == "slope" {
                        format!(", f_ref {} Hz", b.f_ref_hz)
                    } else {
                        String::new()
                    }
                );
            }
        }
    }

    /// The truth value of parameter `p`: found through the `eom` table, as the coefficient of a
    /// monomial whose identified coefficient equals the parameter (single-parameter terms).
    fn truth_of_param(&self, p: &str, t: &Truth) -> Option<f64> {
        let e = self.parameters.get(p)?;
        for (mode, row) in &self.eom {
            for (mono, v) in row {
                let v = (*v)?;
                if (v - e.value).abs() <= 1e-12 * e.value.abs() {
                    return t.eom.get(mode).and_then(|r| r.get(mono)).copied();
                }
            }
        }
        None
    }
}
