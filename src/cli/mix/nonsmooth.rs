//! The lines of a model's non-smooth terms (`abs(q1)*q1`, `abs(d(q1))*d(q1)`, `sign(d(q1))`,
//! `tanh(d(q1)/c)`) for `harmonid mix` (issue 36).
//!
//! Their spectra never end and their coefficients are not polynomials in the amplitudes, so
//! there is no exact table: each line's complex amplitude `C` (the line being
//! `Re[C e^{i2πft}]`, DC its value) is computed numerically at given amplitudes. The motion is
//! sampled on the torus of the tones (one angle `θ_d` per tone, each component
//! `X cos(k·θ)`, a velocity `−X·Ω sin(k·θ)` with `Ω = 2π k·f`): the average over the torus is
//! the time average when the tones are incommensurate, and it is what the polynomial tables
//! assume too (every combination its own line). The sampling is the simulator's
//! ([`harmonid_sim::GridSampler`], the one sampler of harmonic balance and identification too):
//! a jump (`sign`) or near-jump (`tanh`) is averaged over each sample's cell along the grid's
//! diagonal (the variable linear across the cell; the flow `θ = ω t` of tones near one
//! frequency), so the error falls like the square of the cell; `abs` is sampled pointwise. Each coefficient carries an error estimate: its
//! difference from the same projection on a grid of half the samples per axis.

use harmonid_model::{Model, NonSmooth};
use harmonid_sim::{Grid, GridSampler};
use harmonid_spectral::{nearest_mode, Combination, ToneAssignment, Window};
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Samples of one period with one tone (the error of a jump falls like the square of the cell:
/// about 1e-7 relative on the 3rd harmonic of `sign`).
const ONE_TONE_SAMPLES: usize = 16384;
/// Most samples of the torus grid (per term, two grids: this one and half per axis).
const MAX_SAMPLES: usize = 1 << 18;
/// Lines whose |C| is below this fraction of the term's largest line are left out (zeros of
/// the symmetry, e.g. the even harmonics of `abs(q)*q`, land at rounding level).
pub(super) const DROP_BELOW: f64 = 1e-9;

/// One line of a non-smooth term.
pub(super) struct NsLine {
    /// The combination of the tones (canonical: ≥ 0 Hz).
    pub combination: Combination,
    /// Frequency, Hz.
    pub hz: f64,
    /// Complex amplitude: the line is `Re[C e^{i2πft}]` (the value itself at DC).
    pub value: Complex64,
    /// `|C − C_half|`, `C_half` from half the samples per axis (`None` when that grid is too
    /// coarse for the order).
    pub error: Option<f64>,
    /// The mode this line is near (within the window), if any.
    pub near: Option<usize>,
}

/// One non-smooth term with its lines.
pub(super) struct NsTerm {
    pub equation: usize,
    /// Canonical name, `abs(q1)*q1`.
    pub monomial: String,
    /// The term's coefficient as text (`kappa1`).
    pub coefficient: String,
    /// `p` such that every line scales as amplitude^p (all amplitudes scaled together); `None`
    /// with a `tanh` factor (not homogeneous).
    pub power: Option<u32>,
    pub lines: Vec<NsLine>,
    /// Every line is zero at the given amplitudes but not at amplitude 1: their powers
    /// underflow (the term is listed without lines).
    pub underflow: bool,
}

/// The non-smooth part of a mix report.
pub(super) struct NsReport {
    /// Samples per axis of the torus (one axis per tone).
    pub samples_per_axis: usize,
    /// Highest intermodulation order listed.
    pub order: u32,
    /// Amplitude of each component of the assignment (same order).
    pub amplitudes: Vec<f64>,
    pub terms: Vec<NsTerm>,
}

/// One component of a mode's motion, for sampling.
struct Comp {
    k: Vec<i32>,
    amplitude: f64,
    /// Angular frequency, rad/s (signed: `2π k·f`).
    omega: f64,
}

/// The motion of every mode as lines on the torus of the tones.
struct Motion {
    n_modes: usize,
    comps: Vec<Vec<Comp>>,
    /// Number of tones (axes of the torus).
    axes: usize,
}

/// A term split for sampling.
struct Sampled {
    poly: Vec<(usize, u32)>,
    factors: Vec<(NonSmooth, u32)>,
}

/// Samples per axis for `axes` tones: [`ONE_TONE_SAMPLES`] for one, else the largest even number whose power
/// stays within [`MAX_SAMPLES`].
fn samples_per_axis(axes: usize) -> usize {
    if axes <= 1 {
        return ONE_TONE_SAMPLES;
    }
    let mut m = (MAX_SAMPLES as f64).powf(1.0 / axes as f64).floor() as usize;
    while m.checked_pow(axes as u32).is_none_or(|s| s > MAX_SAMPLES) {
        m -= 1;
    }
    m - m % 2
}

/// Every canonical combination of `axes` tones of order ≤ `order` (≥ 0 Hz), by frequency.
fn combinations(tones_hz: &[f64], order: u32) -> Vec<(Combination, f64)> {
    let d = tones_hz.len();
    let o = order as i32;
    let tol = 1e-9 * tones_hz.iter().fold(0.0_f64, |a, f| a.max(f.abs()));
    let mut out = Vec::new();
    let mut k = vec![-o; d];
    loop {
        let c = Combination::from_coeffs(&k);
        if c.order() <= order {
            let hz: f64 = k
                .iter()
                .zip(tones_hz)
                .map(|(&k, &f)| f64::from(k) * f)
                .sum();
            if hz > tol || (hz.abs() <= tol && c.is_canonical()) {
                out.push((c, hz.max(0.0)));
            }
        }
        // Next vector in [−o, o]^d.
        let mut i = 0;
        while i < d && k[i] == o {
            k[i] = -o;
            i += 1;
        }
        if i == d {
            break;
        }
        k[i] += 1;
    }
    out.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.order().cmp(&b.0.order())));
    out
}

/// The projections `C_k` of `term` onto `lines` from an `m`-per-axis grid of the torus, by the
/// simulator's sampler ([`harmonid_sim::GridSampler`]: the grid's lines are the components,
/// then `lines`).
fn project(
    term: &Sampled,
    motion: &Motion,
    lines: &[(Combination, f64)],
    m: usize,
) -> Vec<Complex64> {
    let d = motion.axes;
    let mut k: Vec<i64> = Vec::new();
    for c in motion.comps.iter().flatten() {
        k.extend(c.k.iter().map(|&x| i64::from(x)));
    }
    let n_in = k.len() / d.max(1);
    for (c, _) in lines {
        k.extend(c.coeffs().iter().map(|&x| i64::from(x)));
    }
    let sampler = GridSampler::new(&Grid {
        dims: vec![m; d],
        k,
    });
    let nt = sampler.samples();
    let nm = motion.n_modes;
    let top = term
        .poly
        .iter()
        .map(|&(v, _)| v)
        .chain(term.factors.iter().map(|(f, _)| f.var().index()))
        .max()
        .unwrap_or(0);
    // Modes, velocities, and any further variable (the pump) left at zero.
    let mut xs = vec![0.0; nt * (2 * nm).max(top + 1)];
    let (q, v) = xs.split_at_mut(nm * nt);
    let mut line = 0;
    for (n, comps) in motion.comps.iter().enumerate() {
        for c in comps {
            let (qn, vn) = (&mut q[n * nt..(n + 1) * nt], &mut v[n * nt..(n + 1) * nt]);
            sampler.add_line(
                line,
                Complex64::new(c.amplitude, 0.0),
                qn,
                Some((c.omega, vn)),
            );
            line += 1;
        }
    }
    let mut g = vec![0.0; nt];
    sampler.add_term(1.0, &term.poly, &term.factors, &xs, &mut g);
    (0..lines.len())
        .map(|i| sampler.coefficient(n_in + i, &g))
        .collect()
}

/// Whether `distance_hz` from a resonance at `nominal_hz` is within `window`.
fn within(window: Window, distance_hz: f64, nominal_hz: f64) -> bool {
    match window {
        Window::Hz(w) => distance_hz.abs() <= w,
        Window::Relative(r) => distance_hz.abs() <= r * nominal_hz.abs(),
    }
}

/// The lines of every non-smooth term of `model` under `assignment` at `amplitudes` (one per
/// component), up to intermodulation order `order`. Errors (as text): too many tones for a
/// grid that resolves that order.
pub(super) fn build(
    model: &Model,
    assignment: &ToneAssignment,
    amplitudes: Vec<f64>,
    nominal: &[Option<f64>],
    window: Window,
    order: u32,
) -> Result<NsReport, String> {
    let tones_hz = assignment.tones().hz().to_vec();
    let axes = tones_hz.len();
    let m = samples_per_axis(axes);
    if m <= 2 * order as usize {
        return Err(format!(
            "{axes} tones leave {m} samples per axis of the torus, too few for the non-smooth terms' lines up to order {order} (at least {})",
            2 * order + 2
        ));
    }
    let n_modes = model.modes.len();
    let mut comps: Vec<Vec<Comp>> = (0..n_modes).map(|_| Vec::new()).collect();
    for (c, &a) in assignment.components().iter().zip(&amplitudes) {
        comps[c.mode].push(Comp {
            k: c.combination.coeffs().to_vec(),
            amplitude: a,
            omega: TAU * c.combination.hz(assignment.tones()),
        });
    }
    // The same motion at amplitude 1, to tell a term whose lines underflow from one that
    // vanishes (a mode without motion).
    let unit = Motion {
        n_modes,
        comps: comps
            .iter()
            .map(|cs| {
                cs.iter()
                    .map(|c| Comp {
                        k: c.k.clone(),
                        amplitude: 1.0,
                        omega: c.omega,
                    })
                    .collect()
            })
            .collect(),
        axes,
    };
    let motion = Motion {
        n_modes,
        comps,
        axes,
    };
    let lines = combinations(&tones_hz, order);
    let params: Vec<String> = model.params.iter().map(|p| p.name.clone()).collect();
    let mut terms = Vec::new();
    for (n, eq) in model.nonsmooth.iter().enumerate() {
        for (mono, coeff) in eq.terms() {
            let (pp, fs) = model.split_nonsmooth(mono);
            let sampled = Sampled {
                poly: pp.factors().iter().map(|&(v, e)| (v.index(), e)).collect(),
                factors: fs
                    .iter()
                    .filter_map(|&(k, e)| model.nonsmooth_factors.get(k).map(|&f| (f, e)))
                    .collect(),
            };
            let fine = project(&sampled, &motion, &lines, m);
            let coarse = (m / 2 > 2 * order as usize)
                .then(|| project(&sampled, &motion, &lines, m / 2 - (m / 2) % 2));
            let largest = fine.iter().fold(0.0_f64, |a, c| a.max(c.norm()));
            let mut out = Vec::new();
            for (i, ((c, hz), v)) in lines.iter().zip(&fine).enumerate() {
                if v.norm() <= DROP_BELOW * largest || largest == 0.0 {
                    continue;
                }
                let near = nearest_mode(*hz, nominal).and_then(|(k, dist)| {
                    nominal[k].filter(|&f| within(window, dist, f)).map(|_| k)
                });
                out.push(NsLine {
                    combination: c.clone(),
                    hz: *hz,
                    value: *v,
                    error: coarse.as_ref().map(|cs| (cs[i] - v).norm()),
                    near,
                });
            }
            let tanh = sampled
                .factors
                .iter()
                .any(|(f, _)| matches!(f, NonSmooth::Tanh(..)));
            let abs: u32 = sampled
                .factors
                .iter()
                .filter(|(f, _)| matches!(f, NonSmooth::Abs(_)))
                .map(|&(_, e)| e)
                .sum();
            let underflow = largest == 0.0
                && project(&sampled, &unit, &lines, m)
                    .iter()
                    .any(|c| c.norm() > 0.0);
            terms.push(NsTerm {
                equation: n,
                monomial: model.monomial_name(mono),
                coefficient: coeff.to_string_with(&params),
                power: (!tanh).then_some(pp.degree() + abs),
                lines: out,
                underflow,
            });
        }
    }
    Ok(NsReport {
        samples_per_axis: m,
        order,
        amplitudes,
        terms,
    })
}

/// `C` as text: real, `i·b`, or `a + i·b` (a part below 1e-12 of |C| is left out).
pub(super) fn complex_text(c: Complex64) -> String {
    let tiny = 1e-12 * c.norm();
    if c.im.abs() <= tiny {
        format!("{:.6e}", c.re)
    } else if c.re.abs() <= tiny {
        format!("{}i·{:.6e}", if c.im < 0.0 { "−" } else { "" }, c.im.abs())
    } else {
        let sign = if c.im < 0.0 { "−" } else { "+" };
        format!("{:.6e} {sign} i·{:.6e}", c.re, c.im.abs())
    }
}

/// How the lines scale with the amplitudes, in words.
pub(super) fn scaling_text(t: &NsTerm) -> String {
    match t.power {
        Some(0) => "lines independent of the amplitudes (amplitude⁰)".into(),
        Some(1) => "lines scale as amplitude¹".into(),
        Some(2) => "lines scale as amplitude²".into(),
        Some(3) => "lines scale as amplitude³".into(),
        Some(p) => format!("lines scale as amplitude^{p}"),
        None => "tanh is not homogeneous: these values hold at these amplitudes only".into(),
    }
}

/// The sentence that says how the coefficients were computed.
pub(super) fn method_text(r: &NsReport, symbols: &[String], axes: usize) -> String {
    let at: Vec<String> = symbols
        .iter()
        .zip(&r.amplitudes)
        .map(|(s, &a)| {
            if a == 0.0 || (1e-3..1e4).contains(&a.abs()) {
                format!("|{s}| = {a}")
            } else {
                format!("|{s}| = {a:e}")
            }
        })
        .collect();
    let grid = if axes == 1 {
        format!("{} samples of one period", r.samples_per_axis)
    } else {
        format!(
            "{}^{axes} samples of the torus of the {axes} tones (tones taken as incommensurate, every combination its own line)",
            r.samples_per_axis
        )
    };
    format!(
        "non-smooth terms: coefficients numerical, by sampling in time ({grid}) at {} (--amplitude SYMBOL=VALUE; default 1); lines up to intermodulation order {} (--nonsmooth-order); each line's complex amplitude C (the line is Re[C e^(i2π f t)]), ± its change from half the samples per axis; lines below {DROP_BELOW:e} of the term's largest left out; for abs(q)*q the lines scale as amplitude², for sign as amplitude⁰",
        at.join(", "),
        r.order
    )
}

/// What the printers need besides the report.
pub(super) struct Context<'a> {
    pub mode_names: &'a [String],
    pub nominal: &'a [Option<f64>],
    /// Tone labels for names (`Ω1`, ...).
    pub labels: &'a [String],
    /// Component symbols (`X1`, `Y1`, `Z1`, ...).
    pub symbols: &'a [String],
    pub axes: usize,
}

/// The lines near each mode (in mode order), then off resonance, with a title.
fn groups<'a>(cx: &Context, t: &'a NsTerm) -> Vec<(String, Vec<&'a NsLine>)> {
    let mut out = Vec::new();
    for (n, name) in cx.mode_names.iter().enumerate() {
        let lines: Vec<&NsLine> = t.lines.iter().filter(|l| l.near == Some(n)).collect();
        if !lines.is_empty() {
            let at = cx.nominal[n].map_or(String::new(), |f| format!(" ({f} Hz)"));
            out.push((format!("near {name}{at}"), lines));
        }
    }
    let off: Vec<&NsLine> = t.lines.iter().filter(|l| l.near.is_none()).collect();
    if !off.is_empty() {
        out.push(("off resonance".to_string(), off));
    }
    out
}

fn error_text(l: &NsLine) -> String {
    l.error
        .map_or("(no error estimate)".into(), |e| format!("± {e:.1e}"))
}

/// The plain-text section.
pub(super) fn to_text(r: &NsReport, cx: &Context) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(s, "\n{}", method_text(r, cx.symbols, cx.axes));
    let mut last_eq = usize::MAX;
    for t in &r.terms {
        if t.equation != last_eq {
            let _ = writeln!(
                s,
                "\nequation of {} (non-smooth terms)",
                cx.mode_names[t.equation]
            );
            last_eq = t.equation;
        }
        let _ = writeln!(
            s,
            "  ({}) · {}   [numerical; {}]",
            t.coefficient,
            t.monomial,
            scaling_text(t)
        );
        for (title, lines) in groups(cx, t) {
            let _ = writeln!(s, "    {title}:");
            for l in lines {
                let _ = writeln!(
                    s,
                    "      {:<24} {:>16.3} Hz   {}   {}",
                    l.combination.display_with(cx.labels),
                    l.hz,
                    complex_text(l.value),
                    error_text(l)
                );
            }
        }
    }
    s
}

/// The Markdown section.
pub(super) fn to_markdown(r: &NsReport, cx: &Context) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\n## Non-smooth terms\n\n{}.",
        method_text(r, cx.symbols, cx.axes)
    );
    for t in &r.terms {
        let _ = writeln!(
            s,
            "\n### Equation of {}: `({}) * {}` (numerical; {})\n",
            cx.mode_names[t.equation],
            t.coefficient,
            t.monomial,
            scaling_text(t)
        );
        let _ = writeln!(s, "| where | combination | frequency (Hz) | C | error |");
        let _ = writeln!(s, "|---|---|---:|---|---|");
        for (title, lines) in groups(cx, t) {
            for l in lines {
                let _ = writeln!(
                    s,
                    "| {title} | {} | {:.3} | `{}` | {} |",
                    l.combination.display_with(cx.labels),
                    l.hz,
                    complex_text(l.value),
                    error_text(l)
                );
            }
        }
    }
    s
}

/// The LaTeX section (comments and one tabular per term).
pub(super) fn to_latex(r: &NsReport, cx: &Context, latex_labels: &[String]) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(s, "\n% {}", method_text(r, cx.symbols, cx.axes));
    for t in &r.terms {
        let _ = writeln!(
            s,
            "\n% equation of {}: ({}) * {} (numerical; {})\n\\begin{{tabular}}{{llrll}}\n\\hline",
            cx.mode_names[t.equation],
            t.coefficient,
            t.monomial,
            scaling_text(t)
        );
        for (title, lines) in groups(cx, t) {
            for l in lines {
                let _ = writeln!(
                    s,
                    "{title} & ${}$ & {:.3} Hz & {} & {} \\\\",
                    l.combination.latex_with(latex_labels),
                    l.hz,
                    complex_text(l.value).replace('·', "").replace('−', "-"),
                    error_text(l).replace('±', "$\\pm$")
                );
            }
        }
        let _ = writeln!(s, "\\end{{tabular}}");
    }
    s
}

/// The JSON value (`"nonsmooth"` of format harmonid-mix/1).
pub(super) fn to_json(r: &NsReport, cx: &Context, json_labels: &[String]) -> serde_json::Value {
    use serde_json::json;
    let amplitudes: serde_json::Map<String, serde_json::Value> = cx
        .symbols
        .iter()
        .zip(&r.amplitudes)
        .map(|(s, a)| (s.clone(), json!(a)))
        .collect();
    let terms: Vec<serde_json::Value> = r
        .terms
        .iter()
        .map(|t| {
            let lines: Vec<serde_json::Value> = t
                .lines
                .iter()
                .map(|l| {
                    json!({
                        "combination": l.combination.coeffs(),
                        "label": l.combination.display_with(json_labels),
                        "name": l.combination.display_with(cx.labels),
                        "freq_hz": l.hz,
                        "re": l.value.re,
                        "im": l.value.im,
                        "error": l.error,
                        "near": l.near.map(|n| cx.mode_names[n].clone()),
                    })
                })
                .collect();
            json!({
                "equation": cx.mode_names[t.equation],
                "monomial": t.monomial,
                "term_coefficient": t.coefficient,
                "amplitude_power": t.power,
                "lines": lines,
            })
        })
        .collect();
    json!({
        "method": method_text(r, cx.symbols, cx.axes),
        "numerical": true,
        "amplitudes": amplitudes,
        "order": r.order,
        "samples_per_axis": r.samples_per_axis,
        "terms": terms,
    })
}
