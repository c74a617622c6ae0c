//! The HTML page: one file, figures inline as SVG, a small style sheet, no script and no
//! network.

use crate::PageFigure;
use harmonid_data::result::FitReport as FitView;
use harmonid_data::result::{Estimate, Report};
use harmonid_data::{Dataset, Truth};
use harmonid_model::Model;
use harmonid_plot::style::num;
use std::fmt::Write as _;
use std::path::Path;

/// What the page shows.
pub struct PageInputs<'a> {
    pub model_path: &'a Path,
    pub model: &'a Model,
    pub ds: &'a Dataset,
    pub result: &'a Report,
    pub result_from: Option<&'a Path>,
    pub truth: Option<&'a Truth>,
    pub figures: &'a [PageFigure],
    pub warnings: &'a [String],
}

/// Escapes text for HTML.
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

const CSS: &str = "body{font-family:'DejaVu Sans',Helvetica,Arial,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#111;line-height:1.4}
h1{font-size:1.6em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:2em}
table{border-collapse:collapse;font-size:.9em}td,th{border:1px solid #ccc;padding:.25em .6em;text-align:right}
th{background:#f2f2f2}td.l,th.l{text-align:left}tr.bad td{background:#fde8df}
figure{margin:1.5em 0}figure svg{max-width:100%;height:auto;border:1px solid #eee}
figcaption{font-size:.9em;color:#333;max-width:60em}pre{background:#f7f7f7;padding:.8em;overflow-x:auto}
.warn{background:#fff4d6;border-left:4px solid #e69f00;padding:.5em 1em}.verdict{background:#fde8df;border-left:6px solid #d55e00;padding:.6em 1em}nav a{margin-right:1em}";

/// The stage and condition number of the fit that identified `unknown` (its name as the fit
/// lists it, e.g. `beta1` or `of q1` for a mode's linear parameters).
fn fit_of<'a>(fits: &'a [FitView], unknown: &str) -> Option<&'a FitView> {
    fits.iter().find(|f| {
        f.unknowns
            .iter()
            .any(|u| u == unknown || (unknown.starts_with("of ") && u.ends_with(unknown)))
    })
}

/// The measurements of a fit in few words: a sweep's steps by the sweep's name (once), the
/// others by their own; more than six names as `first…last`; the count of steps when there
/// are any (`level_0.1, level_0.2 (80 steps)`, `up_l00…dn_l11 (24 sweeps, 1152 steps)`).
pub fn measurement_list(ds: &Dataset, names: &[String]) -> String {
    let sweep_of = |n: &str| -> Option<String> {
        let (base, k) = n.strip_suffix(']')?.rsplit_once('[')?;
        (k.parse::<usize>().is_ok() && ds.manifest.sweeps.iter().any(|s| s.name == base))
            .then(|| base.to_string())
    };
    let mut items: Vec<String> = Vec::new();
    let (mut steps, mut sweeps, mut plain) = (0usize, 0usize, 0usize);
    for n in names {
        match sweep_of(n) {
            Some(sw) => {
                steps += 1;
                if !items.contains(&sw) {
                    sweeps += 1;
                    items.push(sw);
                }
            }
            None => {
                plain += 1;
                items.push(n.clone());
            }
        }
    }
    let mut out = if items.len() > 6 {
        format!("{}…{}", items[0], items[items.len() - 1])
    } else {
        items.join(", ")
    };
    if steps > 0 {
        let mut count = Vec::new();
        if items.len() > 6 {
            count.push(format!("{sweeps} sweeps"));
        }
        count.push(format!("{steps} steps"));
        if plain > 0 && items.len() > 6 {
            count.push(format!("{plain} measurements"));
        }
        out += &format!(" ({})", count.join(", "));
    } else if items.len() > 6 {
        out += &format!(" ({plain} measurements)");
    }
    out
}

/// An optional column of the parameter table.
#[derive(Clone, Copy)]
struct Extra {
    title: &'static str,
    get: fn(&Estimate) -> Option<f64>,
}

/// The optional columns: estimator diagnostics the result holds for some estimates.
const EXTRA: [Extra; 2] = [
    Extra {
        title: "Cramér–Rao bound",
        get: |e| e.crlb,
    },
    Extra {
        title: "jackknife stderr",
        get: |e| e.jackknife,
    },
];

#[allow(clippy::too_many_arguments)] // one table row: each argument is one column
fn row(
    out: &mut String,
    ds: &Dataset,
    name: &str,
    unit: &str,
    e: &Estimate,
    bound: &str,
    fit: Option<&FitView>,
    truth: Option<f64>,
    extra: &[Extra],
) {
    let cls = if e.identifiable { "" } else { " class=\"bad\"" };
    let _ = write!(
        out,
        "<tr{cls}><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td><td>{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td>",
        esc(name),
        num(e.value, 8),
        num(e.stderr, 2),
        num(e.std, 2),
        esc(unit),
        esc(bound),
        if e.identifiable {
            "yes".to_string()
        } else {
            format!("no: {}", esc(e.reason.as_deref().unwrap_or("")))
        },
        fit.map_or("–".into(), |f| format!("{} ({})", f.stage, esc(&measurement_list(ds, &f.measurements)))),
        fit.map_or("–".into(), |f| num(f.condition_number, 3)),
        truth.map_or("–".into(), |t| num(t, 8)),
    );
    for x in extra {
        let v = (x.get)(e);
        let _ = write!(out, "<td>{}</td>", v.map_or("–".into(), |v| num(v, 3)));
    }
    out.push_str("</tr>\n");
}

/// The page.
pub fn page(p: &PageInputs) -> String {
    let mut s = String::with_capacity(1 << 20);
    write_head(p, &mut s);
    write_parameters(p, &mut s);
    write_equations(p, &mut s);
    let section = |s: &mut String, id: &str, title: &str, pick: &dyn Fn(&PageFigure) -> bool| {
        let _ = writeln!(s, "<h2 id=\"{id}\">{title}</h2>");
        for f in p.figures.iter().filter(|f| pick(f)) {
            let _ = writeln!(
                s,
                "<figure id=\"fig-{}\">{}<figcaption>{} <a href=\"figures/{}.svg\">SVG</a> · <a href=\"figures/{}.png\">PNG</a></figcaption></figure>",
                f.stem,
                f.svg,
                esc(&f.caption),
                f.stem,
                f.stem
            );
        }
    };
    if p.figures.iter().any(|f| f.stem.starts_with("response_")) {
        section(&mut s, "responses", "Frequency responses", &|f| {
            f.stem.starts_with("response_")
        });
    }
    section(
        &mut s,
        "spectra",
        "Spectra and their reconstruction",
        &|f| f.stem.starts_with("spectrum_"),
    );
    section(&mut s, "histograms", "Per-shot estimates", &|f| {
        f.stem.starts_with("hist_")
    });
    if p.figures.iter().any(|f| f.stem == "potential") {
        section(&mut s, "potential", "Potential matrix", &|f| {
            f.stem == "potential"
        });
    }
    s.push_str("<p><small>Written by harmonid report.</small></p>\n</body></html>\n");
    s
}

/// The title, the verdict on the fit (first: values of a model that does not fit are the best
/// it can do, not the device's), the dataset line, the navigation and the warnings.
fn write_head(p: &PageInputs, s: &mut String) {
    let r = p.result;
    let title = format!("harmonid report: {}", p.model_path.display());
    let _ = write!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title><style>{CSS}</style></head><body>\n<h1>{}</h1>\n",
        esc(&title),
        esc(&title)
    );
    // The verdict first: values of a model that does not fit are the best it can do, not the
    // device's, and their error bars say less than they seem to.
    let verdict = r.goodness_of_fit.as_ref().and_then(|g| g.headline());
    if let Some(g) = &r.goodness_of_fit {
        match &verdict {
            Some(v) => {
                let _ = writeln!(
                    s,
                    "<div class=\"verdict\"><strong>{}</strong></div>",
                    esc(v)
                );
            }
            None => {
                let _ = writeln!(s, "<p>Goodness of fit: {}.</p>", esc(&g.one_line()));
            }
        }
    }
    let _ = writeln!(
        s,
        "<p>Dataset <code>{}</code> ({}), {} shot(s), {} measurement(s); force model: {}. {}</p>",
        esc(&p.ds.dir.display().to_string()),
        esc(&p.ds.manifest.description),
        r.shots,
        p.ds.measurements.len(),
        esc(&r.force_model),
        match p.result_from {
            Some(f) => format!("Values from the result <code>{}</code>.", esc(&f.display().to_string())),
            None => "Identified by this report with the default settings of <code>harmonid identify</code>.".into(),
        }
    );
    s.push_str("<nav><a href=\"#parameters\">parameters</a><a href=\"#equations\">equations</a>");
    if p.figures.iter().any(|f| f.stem.starts_with("response_")) {
        s.push_str("<a href=\"#responses\">frequency responses</a>");
    }
    s.push_str("<a href=\"#spectra\">spectra</a><a href=\"#histograms\">histograms</a>");
    if p.figures.iter().any(|f| f.stem == "potential") {
        s.push_str("<a href=\"#potential\">potential</a>");
    }
    s.push_str("</nav>\n");
    // The verdict is the first warning too: not twice on the page.
    let listed: Vec<&String> = p
        .warnings
        .iter()
        .filter(|w| Some(*w) != verdict.as_ref())
        .collect();
    if !listed.is_empty() {
        s.push_str("<h2 id=\"warnings\">Warnings</h2>\n<div class=\"warn\"><ul>\n");
        for w in listed {
            let _ = writeln!(s, "<li>{}</li>", esc(w));
        }
        s.push_str("</ul></div>\n");
    }
    write_unfit(p.result, s);
}

/// The groups of unknowns the identification could not fit (the result's `unfit`): a table of
/// why, which quantities, in which measurements, and what measurement would help.
fn write_unfit(r: &Report, s: &mut String) {
    if r.unfit.is_empty() {
        return;
    }
    s.push_str("<h2 id=\"unfit\">Not fitted</h2>\n<table><tr><th class=\"l\">why</th><th class=\"l\">quantities</th><th class=\"l\">measurements</th><th>χ²/dof</th><th class=\"l\">detail</th><th class=\"l\">would help</th></tr>\n");
    for g in &r.unfit {
        let chi2 = match g.chi2_per_dof {
            Some(c) if c.is_finite() => num(c, 3),
            Some(_) => "no fit".into(),
            None => String::new(),
        };
        let _ = writeln!(
            s,
            "<tr class=\"bad\"><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td></tr>",
            esc(g.why.text()),
            esc(&g.unknowns.join(", ")),
            esc(&g.measurements.join(", ")),
            esc(&chi2),
            esc(&g.detail),
            esc(&g.advice)
        );
    }
    s.push_str("</table>\n");
}

/// The parameter table and the fits.
fn write_parameters(p: &PageInputs, s: &mut String) {
    let r = p.result;
    // Parameter table.
    // Optional columns, shown when any estimate has them.
    let extra: Vec<Extra> = EXTRA
        .iter()
        .filter(|x| {
            r.modes
                .values()
                .flat_map(|m| [&m.f_hz, &m.q])
                .chain(r.parameters.values())
                .any(|e| (x.get)(e).is_some())
        })
        .copied()
        .collect();
    s.push_str("<h2 id=\"parameters\">Parameters</h2>\n<table><tr><th class=\"l\">quantity</th><th>value</th><th>stderr</th><th>std (one shot)</th><th>unit</th><th class=\"l\">bound</th><th>identifiable</th><th class=\"l\">stage (measurements)</th><th>condition number</th><th>truth</th>");
    for x in &extra {
        let _ = write!(s, "<th>{}</th>", esc(x.title));
    }
    s.push_str("</tr>\n");
    for (n, m) in &r.modes {
        let tm = p.truth.and_then(|t| t.modes.get(n));
        let fit = fit_of(&r.fits, &format!("of {n}"));
        row(
            s,
            p.ds,
            &format!("f_{n}"),
            "Hz",
            &m.f_hz,
            "",
            fit,
            tm.map(|t| t.f_hz),
            &extra,
        );
        row(
            s,
            p.ds,
            &format!("Q_{n}"),
            "",
            &m.q,
            "> 0",
            fit,
            tm.map(|t| t.q),
            &extra,
        );
    }
    for (name, e) in &r.parameters {
        let bound = p
            .model
            .params
            .iter()
            .find(|q| &q.name == name)
            .map(|q| match (q.bounds.lower, q.bounds.upper) {
                (Some(a), Some(b)) => format!("[{}, {}]", num(a, 3), num(b, 3)),
                (Some(a), None) => format!("≥ {}", num(a, 3)),
                (None, Some(b)) => format!("≤ {}", num(b, 3)),
                (None, None) => String::new(),
            })
            .unwrap_or_default();
        let truth = p
            .truth
            .and_then(|t| crate::result::truth_of_param(r, name, t));
        row(
            s,
            p.ds,
            name,
            "",
            e,
            &bound,
            fit_of(&r.fits, name),
            truth,
            &extra,
        );
    }
    s.push_str("</table>\n<p>value: median over shots; stderr: uncertainty of the value; std: spread of one shot after rejecting outliers by the interquartile rule; condition number of the column-equilibrated fit.</p>\n");
    // Fits.
    s.push_str("<h3>Fits</h3>\n<table><tr><th>stage</th><th class=\"l\">measurements</th><th>unknowns</th><th>condition number</th><th>relative residual</th></tr>\n");
    for f in &r.fits {
        let _ = writeln!(
            s,
            "<tr><td>{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            f.stage,
            esc(&measurement_list(p.ds, &f.measurements)),
            f.unknowns.len(),
            num(f.condition_number, 3),
            num(f.relative_residual, 3)
        );
    }
    s.push_str("</table>\n");
}

/// The equations of motion and the identified coefficients.
fn write_equations(p: &PageInputs, s: &mut String) {
    let r = p.result;
    // Equations.
    let _ = write!(
        s,
        "<h2 id=\"equations\">Equations of motion</h2>\n<pre>{}</pre>\n<h3>Identified coefficients</h3>\n<table><tr><th class=\"l\">equation</th><th class=\"l\">monomial</th><th>coefficient</th></tr>\n",
        esc(&p.model.to_text())
    );
    for (mode, terms) in &r.eom {
        for (mono, c) in terms {
            let _ = writeln!(
                s,
                "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td></tr>",
                esc(mode),
                esc(mono),
                c.map_or("not identified".into(), |c| num(c, 6))
            );
        }
    }
    s.push_str("</table>\n");
}

#[cfg(test)]
mod tests {
    use super::*;
    use harmonid_data::{Direction, Manifest, SweepSpec};

    #[test]
    fn unfit_groups_are_a_table_with_the_advice() {
        let json = r#"{"format": "harmonid-result/1", "model": "m.hb", "dataset": "d",
            "modes": {}, "parameters": {}, "unfit": [{"why": "group_not_fitted",
            "unknowns": ["f_hz:q6", "g6_7"], "measurements": ["couple_q6_q7"],
            "chi2_per_dof": 320.0, "detail": "its own fit missed", "advice": "q6 & q7 alone"}]}"#;
        let r = Report::from_json(json).expect("result");
        let mut s = String::new();
        write_unfit(&r, &mut s);
        assert!(s.starts_with("<h2 id=\"unfit\">Not fitted</h2>"), "{s}");
        assert!(
            s.contains("<td class=\"l\">group not fitted</td><td class=\"l\">f_hz:q6, g6_7</td><td class=\"l\">couple_q6_q7</td><td>320</td>")
                && s.contains("<td class=\"l\">q6 &amp; q7 alone</td>"),
            "{s}"
        );
        let mut none = String::new();
        write_unfit(
            &Report::from_json(&json.replace("\"unfit\"", "\"other\"")).expect("result"),
            &mut none,
        );
        assert!(none.is_empty());
    }

    #[test]
    fn fits_name_sweeps_not_steps() {
        let mut m = Manifest::new("t");
        for n in ["up_l00", "dn_l00", "up_l01", "dn_l01"] {
            m.sweeps
                .push(SweepSpec::new(n, Direction::Up, vec![vec![1.0]; 300]));
        }
        let ds = Dataset {
            dir: Default::default(),
            manifest: m,
            measurements: Vec::new(),
            truth: None,
            notes: Vec::new(),
        };
        fn steps(sw: &str) -> Vec<String> {
            (0..300).map(|k| format!("{sw}[{k}]")).collect()
        }
        let two: Vec<String> = [steps("up_l00"), steps("dn_l00")].concat();
        assert_eq!(measurement_list(&ds, &two), "up_l00, dn_l00 (600 steps)");
        let mut all: Vec<String> = ["up_l00", "dn_l00", "up_l01", "dn_l01"]
            .iter()
            .flat_map(|s| steps(s))
            .collect();
        all.extend(["a", "b", "c"].map(String::from));
        assert_eq!(
            measurement_list(&ds, &all),
            "up_l00…c (4 sweeps, 1200 steps, 3 measurements)"
        );
        let plain: Vec<String> = ["single_q1", "couple[x]"].map(String::from).to_vec();
        assert_eq!(measurement_list(&ds, &plain), "single_q1, couple[x]");
    }
}
