//! `harmonid mix MODEL --drives q1:207572,207592 --drives q2:415842`: for every term of every
//! equation, the lines it generates near each resonance and off resonance, with exact
//! coefficients in the tone amplitudes (Supplementary Note II, Table S1). A mode without a tone
//! responds at the lines its equation's terms force on it (amplitudes Z1, Z2, ...), and the
//! lines those responses make in turn are marked `second order, via <mode>`. Drive tones are
//! named Ω1, Ω2, ... (mode frequencies are f_n). Non-smooth terms (`abs(q1)*q1`, `sign(d(q1))`,
//! ...) have no exact table: their lines are listed with coefficients computed numerically at
//! given amplitudes ([`nonsmooth`]).

mod nonsmooth;

use harmonid_data::Manifest;
use harmonid_model::Model;
use harmonid_poly::PowerProduct;
use harmonid_spectral::{
    mixing_table, ComponentKind, Line, MixingTable, SpectralError, ToneAssignment, Window,
};
use miette::{miette, IntoDiagnostic, WrapErr};
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::PathBuf;

/// Arguments of `harmonid mix`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model file (`*.hb`), e.g. examples/nanostring_2mode/model.hb.
    pub model: PathBuf,
    /// Tones in a mode's motion, `MODE:HZ[,HZ...]`, e.g. `--drives q1:207572,207592
    /// --drives q2:415842`. Tones are numbered Ω1, Ω2, ... in the order given; tone d's real
    /// amplitude is the symbol Xd. A mode without a tone responds through the coupling
    /// (amplitudes Z1, Z2, ...).
    #[arg(long, value_name = "MODE:HZ,...", conflicts_with = "dataset")]
    pub drives: Vec<String>,
    /// Read the tones from a dataset folder's `dataset.toml` (with --measurement); each tone goes
    /// to the mode whose nominal resonance is closest.
    #[arg(long, value_name = "DIR", requires = "measurement")]
    pub dataset: Option<PathBuf>,
    /// The `[[measurement]]` of the dataset whose `drives_hz` to use.
    #[arg(long, value_name = "NAME", requires = "dataset")]
    pub measurement: Option<String>,
    /// Nominal resonance of a mode, `MODE=HZ` (wins over the dataset's and the model's).
    #[arg(long, value_name = "MODE=HZ")]
    pub nominal: Vec<String>,
    /// Let every mode with two or more tones carry its own sidebands up to this intermodulation
    /// order (3: ω1 ± 3δ; 5: also ω1 ± 5δ), each with its own amplitude Yj.
    #[arg(long, value_name = "ORDER")]
    pub sidebands: Option<u32>,
    /// A line counts as near a resonance within this many Hz of it (default: 1 % of the
    /// resonance frequency).
    #[arg(long, value_name = "HZ")]
    pub window: Option<f64>,
    /// Markdown tables.
    #[arg(long, conflicts_with_all = ["latex", "json"])]
    pub markdown: bool,
    /// LaTeX tables.
    #[arg(long, conflicts_with = "json")]
    pub latex: bool,
    /// JSON: one entry per equation and monomial, each line with `combination`, `freq_hz`,
    /// `coefficient`, `near`, `second_order` and `via`.
    #[arg(long)]
    pub json: bool,
    /// Amplitude of a component for the non-smooth terms' numerical lines, `SYMBOL=VALUE` in
    /// the model's units (e.g. `--amplitude X1=1e-9`); components not named have amplitude 1.
    /// Their coefficients are not polynomials in the amplitudes, so they are computed at these.
    #[arg(long, value_name = "SYMBOL=VALUE")]
    pub amplitude: Vec<String>,
    /// Highest intermodulation order of the non-smooth terms' lines (their spectra never end).
    #[arg(long, value_name = "ORDER", default_value_t = 5)]
    pub nonsmooth_order: u32,
    /// Write to this file (atomically) instead of standard output.
    #[arg(long, short, value_name = "FILE")]
    pub output: Option<PathBuf>,
}

/// One term of one equation with its table.
struct Term {
    equation: usize,
    monomial: PowerProduct,
    coefficient: harmonid_poly::Coeff,
    table: MixingTable,
}

/// Everything the printers need.
struct Report {
    model_path: String,
    mode_names: Vec<String>,
    /// Modes, then velocities (`d(q1)`): the names of a monomial's variables.
    var_names: Vec<String>,
    /// The same in LaTeX.
    var_latex: Vec<String>,
    param_names: Vec<String>,
    nominal: Vec<Option<f64>>,
    assignment: ToneAssignment,
    window: Option<f64>,
    terms: Vec<Term>,
    /// The non-smooth terms' numerical lines (`None`: the model has none).
    nonsmooth: Option<nonsmooth::NsReport>,
}

fn spectral_err(e: SpectralError) -> miette::Report {
    miette!(
        help = "check the --drives / --dataset tones and --sidebands order",
        "{e}"
    )
}

fn parse_drive(s: &str) -> miette::Result<(String, Vec<f64>)> {
    let usage = || {
        miette!(
            help = "write MODE:HZ[,HZ...], e.g. --drives q1:207572,207592",
            "cannot read --drives `{s}`"
        )
    };
    let (mode, list) = s.split_once(':').ok_or_else(usage)?;
    let mode = mode.trim();
    if mode.is_empty() {
        return Err(usage());
    }
    let mut hz = Vec::new();
    for part in list.split(',') {
        let v: f64 = part.trim().parse().map_err(|_| {
            miette!(
                help = "frequencies are plain numbers in Hz, e.g. 207572 or 2.07572e5",
                "--drives `{s}`: `{}` is not a frequency",
                part.trim()
            )
        })?;
        hz.push(v);
    }
    Ok((mode.to_string(), hz))
}

fn parse_nominal(s: &str) -> miette::Result<(String, f64)> {
    let bad = || {
        miette!(
            help = "write MODE=HZ, e.g. --nominal q1=207582",
            "cannot read --nominal `{s}`"
        )
    };
    let (m, v) = s.split_once('=').ok_or_else(bad)?;
    let v: f64 = v.trim().parse().map_err(|_| bad())?;
    if !(v.is_finite() && v > 0.0) {
        return Err(miette!("--nominal `{s}`: the frequency must be > 0 Hz"));
    }
    Ok((m.trim().to_string(), v))
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let manifest = args.dataset.as_ref().map(|dir| dir.join("dataset.toml"));
    let inputs: Vec<&std::path::Path> = [Some(&args.model), manifest.as_ref()]
        .into_iter()
        .flatten()
        .map(|p| p.as_path())
        .collect();
    if let Some(path) = &args.output {
        super::common::check_outputs(&[path.as_path()], &inputs)?;
    }
    let model = harmonid_model::load(&args.model).map_err(miette::Report::new)?;
    if model.has_pump_terms() {
        return Err(miette!(
            help = "leave the pump terms out of a copy of the model to list the other terms' lines; a pump term `lambda*pump*q` moves each line f of q to f_p − f and f_p + f",
            "{}: mix does not list the lines of pump terms (`pump`) yet",
            args.model.display()
        ));
    }
    let report = build(&args, &model)?;
    let text = if args.json {
        to_json(&report)
    } else if args.latex {
        to_latex(&report)
    } else if args.markdown {
        to_markdown(&report)
    } else {
        to_text(&report)
    };
    match &args.output {
        Some(path) => super::common::write_output(path, text.as_bytes(), &inputs),
        None => {
            let mut out = std::io::stdout().lock();
            let _ = out.write_all(text.as_bytes()).and_then(|()| out.flush());
            Ok(())
        }
    }
}

fn build(args: &Args, model: &Model) -> miette::Result<Report> {
    let mode_names: Vec<String> = model.modes.iter().map(|m| m.name.clone()).collect();
    // Nominal resonances: model, then dataset, then command line.
    let mut nominal: Vec<Option<f64>> = model
        .modes
        .iter()
        .map(|m| {
            m.nominal_hz.or(match m.f_hz {
                harmonid_model::Linear::Fixed(f) => Some(f),
                harmonid_model::Linear::Unknown => None,
            })
        })
        .collect();
    let set_nominal =
        |nominal: &mut Vec<Option<f64>>, name: &str, hz: f64, source: &str| match mode_names
            .iter()
            .position(|m| m == name)
        {
            Some(n) => {
                nominal[n] = Some(hz);
                Ok(())
            }
            None => Err(miette!(
                help = format!("the model declares: {}", mode_names.join(", ")),
                "{source} gives a nominal frequency for `{name}`, which the model does not declare"
            )),
        };
    let mut drives: Vec<(String, Vec<f64>)> = Vec::new();
    if let (Some(dir), Some(name)) = (&args.dataset, &args.measurement) {
        let path = dir.join("dataset.toml");
        let text = std::fs::read_to_string(&path)
            .into_diagnostic()
            .wrap_err_with(|| format!("cannot read {}", path.display()))?;
        let manifest: Manifest = toml::from_str(&text).map_err(|e| {
            let at = e
                .span()
                .map(|s| harmonid_files::quote_line(&text, s))
                .unwrap_or_default();
            miette!("{}: {} ({at})", path.display(), e.message().trim_end())
        })?;
        for (m, &hz) in &manifest.nominal_hz {
            set_nominal(&mut nominal, m, hz, &path.display().to_string())?;
        }
        for s in &args.nominal {
            let (m, hz) = parse_nominal(s)?;
            set_nominal(&mut nominal, &m, hz, "--nominal")?;
        }
        let spec = manifest
            .measurements
            .iter()
            .find(|m| &m.name == name)
            .ok_or_else(|| {
                let names: Vec<&str> = manifest
                    .measurements
                    .iter()
                    .map(|m| m.name.as_str())
                    .collect();
                miette!(
                    help = format!("its measurements are: {}", names.join(", ")),
                    "{} has no [[measurement]] named `{name}`",
                    path.display()
                )
            })?;
        for (d, &hz) in spec.drives_hz.iter().enumerate() {
            let near = harmonid_spectral::nearest_mode(hz, &nominal).ok_or_else(|| {
                miette!(
                    help = "give nominal frequencies in the model, the dataset's [nominal_hz] or --nominal MODE=HZ",
                    "cannot attribute drive tone #{d} ({hz} Hz) to a mode: no mode has a nominal frequency"
                )
            })?;
            let mode = &mode_names[near.0];
            match drives.iter_mut().find(|(m, _)| m == mode) {
                Some((_, v)) => v.push(hz),
                None => drives.push((mode.clone(), vec![hz])),
            }
        }
    } else {
        for s in &args.nominal {
            let (m, hz) = parse_nominal(s)?;
            set_nominal(&mut nominal, &m, hz, "--nominal")?;
        }
        for s in &args.drives {
            drives.push(parse_drive(s)?);
        }
    }
    if drives.is_empty() {
        return Err(miette!(
            help = "e.g. --drives q1:207572,207592 --drives q2:415842, or --dataset DIR --measurement NAME",
            "no tones given"
        ));
    }
    let mut assignment = ToneAssignment::from_drives(&mode_names, &drives).map_err(spectral_err)?;
    if let Some(order) = args.sidebands {
        if order > 15 {
            return Err(miette!(
                help = "orders 3, 5, 7 give ω ± 3δ, ± 5δ, ± 7δ",
                "--sidebands {order} is too high (at most 15)"
            ));
        }
        assignment.add_own_sidebands(order).map_err(spectral_err)?;
    }
    // A mode without a nominal frequency sits at the mean of its own tones.
    assignment.fill_nominal_from_drives(&mut nominal);
    // A mode without a tone moves at the lines its equation's other terms force on it.
    let equations: Vec<Vec<PowerProduct>> = model
        .eom
        .iter()
        .map(|eq| eq.terms().map(|(m, _)| m.clone()).collect())
        .collect();
    assignment.add_responses(&equations).map_err(spectral_err)?;
    let window = match args.window {
        Some(w) if w.is_finite() && w >= 0.0 => Window::Hz(w),
        Some(w) => return Err(miette!("--window {w}: the window must be a number ≥ 0 Hz")),
        None => Window::default(),
    };
    let nonsmooth = nonsmooth_lines(args, model, &assignment, &nominal, window)?;
    let param_names: Vec<String> = model.params.iter().map(|p| p.name.clone()).collect();
    let mut terms = Vec::new();
    for (n, eq) in model.eom.iter().enumerate() {
        for (m, c) in eq.terms() {
            let table = mixing_table(m, &assignment, &nominal, window).map_err(spectral_err)?;
            terms.push(Term {
                equation: n,
                monomial: m.clone(),
                coefficient: c.clone(),
                table,
            });
        }
    }
    Ok(Report {
        model_path: args.model.display().to_string(),
        var_names: model.variable_names(),
        var_latex: model.variable_latex_names(),
        mode_names,
        param_names,
        nominal,
        assignment,
        window: args.window,
        terms,
        nonsmooth,
    })
}

/// The non-smooth terms' lines at the `--amplitude` values (1 where not given).
fn nonsmooth_lines(
    args: &Args,
    model: &Model,
    assignment: &ToneAssignment,
    nominal: &[Option<f64>],
    window: Window,
) -> miette::Result<Option<nonsmooth::NsReport>> {
    let symbols = assignment.symbols();
    let mut amplitudes = vec![1.0; symbols.len()];
    for s in &args.amplitude {
        let bad = |why: String| {
            miette!(
                help = format!(
                    "write SYMBOL=VALUE with a symbol of the listed components ({}), e.g. --amplitude {}=1e-9",
                    symbols.join(", "),
                    symbols.first().map_or("X1", String::as_str)
                ),
                "--amplitude `{s}`: {why}"
            )
        };
        let (name, value) = s
            .split_once('=')
            .ok_or_else(|| bad("expected SYMBOL=VALUE".into()))?;
        let i = symbols
            .iter()
            .position(|x| x == name.trim())
            .ok_or_else(|| bad(format!("no component is named `{}`", name.trim())))?;
        amplitudes[i] = value
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| bad(format!("`{}` is not a finite number", value.trim())))?;
        if amplitudes[i] <= 0.0 {
            return Err(bad(format!(
                "an amplitude is the size of a component, so it must be positive, not {}",
                value.trim()
            )));
        }
    }
    if !model.has_nonsmooth() {
        if !args.amplitude.is_empty() {
            eprintln!(
                "note: --amplitude is used only for non-smooth terms, and {} has none: the polynomial lines are exact in the symbols",
                args.model.display()
            );
        }
        return Ok(None);
    }
    if args.nonsmooth_order == 0 || args.nonsmooth_order > 15 {
        return Err(miette!(
            help = "orders 3 to 7 are usual; the default is 5",
            "--nonsmooth-order {}: expected an order from 1 to 15",
            args.nonsmooth_order
        ));
    }
    let report = nonsmooth::build(
        model,
        assignment,
        amplitudes,
        nominal,
        window,
        args.nonsmooth_order,
    )
    .map_err(|why| {
        miette!(
            help = "lower --nonsmooth-order, or list fewer tones",
            "{}: cannot list the non-smooth terms' lines ({}): {why}",
            args.model.display(),
            model.nonsmooth_term_names().join(", ")
        )
    })?;
    check_nonsmooth_finite(args, model, &report)?;
    Ok(Some(report))
}

/// Refuses non-smooth lines that overflow or all underflow at the `--amplitude` values (a
/// power of a huge or tiny amplitude), rather than print `NaN` or nothing; warns, naming it,
/// of a term whose lines all underflow while others' do not (it is listed without lines).
fn check_nonsmooth_finite(
    args: &Args,
    model: &Model,
    report: &nonsmooth::NsReport,
) -> miette::Result<()> {
    let given = if args.amplitude.is_empty() {
        "the default amplitude 1".to_string()
    } else {
        format!("--amplitude {}", args.amplitude.join(" --amplitude "))
    };
    let help = "give the components' amplitudes in the model's units (metres for a mode: e.g. --amplitude X1=1e-9)";
    for t in &report.terms {
        let finite = |l: &nonsmooth::NsLine| {
            l.hz.is_finite()
                && l.value.re.is_finite()
                && l.value.im.is_finite()
                && l.error.is_none_or(f64::is_finite)
        };
        if !t.lines.iter().all(finite) {
            return Err(miette!(
                help = help,
                "{}: the lines of {} overflow (not finite) at {given}",
                args.model.display(),
                t.monomial
            ));
        }
    }
    if report.terms.iter().all(|t| t.lines.is_empty()) {
        return Err(miette!(
            help = help,
            "{}: every line of the non-smooth terms ({}) is zero at {given} (the amplitudes' powers underflow)",
            args.model.display(),
            report
                .terms
                .iter()
                .map(|t| t.monomial.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    for t in report.terms.iter().filter(|t| t.underflow) {
        let scaling = match t.power {
            Some(p) => format!("its lines scale as amplitude^{p}, "),
            None => String::new(),
        };
        eprintln!(
            "warning: {}: every line of {} (equation of {}) underflows to zero at {given}: {scaling}below the smallest number a double holds, so it is listed without lines; {help}",
            args.model.display(),
            t.monomial,
            model.modes.get(t.equation).map_or("?", |m| m.name.as_str()),
        );
    }
    Ok(())
}

/// What the non-smooth printers need.
fn ns_context<'a>(
    r: &'a Report,
    labels: &'a [String],
    symbols: &'a [String],
) -> nonsmooth::Context<'a> {
    nonsmooth::Context {
        mode_names: &r.mode_names,
        nominal: &r.nominal,
        labels,
        symbols,
        axes: r.assignment.tones().len(),
    }
}

/// Group title and lines: near each mode (in mode order), then off resonance.
fn groups<'a>(r: &'a Report, t: &'a MixingTable) -> Vec<(String, Vec<&'a Line>)> {
    let mut out = Vec::new();
    for (n, name) in r.mode_names.iter().enumerate() {
        let lines: Vec<&Line> = t.near(n).collect();
        if !lines.is_empty() {
            let at = r.nominal[n].map_or(String::new(), |f| format!(" ({f} Hz)"));
            out.push((format!("near {name}{at}"), lines));
        }
    }
    let off: Vec<&Line> = t.off_resonance().collect();
    if !off.is_empty() {
        out.push(("off resonance".to_string(), off));
    }
    out
}

fn window_text(r: &Report) -> String {
    match r.window {
        Some(w) => format!("within {w} Hz of a resonance"),
        None => "within 1 % of a resonance (--window HZ to change)".to_string(),
    }
}

/// Drive tones are `Ω1, Ω2, ...` in the text and Markdown tables (mode frequencies are `f_n`).
fn tone_labels(r: &Report) -> Vec<String> {
    (1..=r.assignment.tones().len())
        .map(|d| format!("Ω{d}"))
        .collect()
}

/// The modes whose response (no tone of their own) a line goes through, by name.
fn via(r: &Report, l: &Line) -> Vec<String> {
    r.assignment
        .responses_in(&l.coefficient)
        .into_iter()
        .map(|n| r.mode_names[n].clone())
        .collect()
}

/// `"second order, via q3"` for a line through a response, else empty.
fn order_mark(r: &Report, l: &Line) -> String {
    let v = via(r, l);
    if v.is_empty() {
        String::new()
    } else {
        format!("second order, via {}", v.join(", "))
    }
}

fn component_kind(r: &Report, kind: &ComponentKind, mode: usize) -> String {
    match kind {
        ComponentKind::Drive(_) => "tone".into(),
        ComponentKind::Sideband => "sideband".into(),
        ComponentKind::Response => format!(
            "response: {} has no tone, its equation's terms force this line",
            r.mode_names[mode]
        ),
    }
}

fn tone_lines(r: &Report) -> Vec<String> {
    let a = &r.assignment;
    let labels = tone_labels(r);
    a.components()
        .iter()
        .map(|c| {
            let hz = c.combination.hz(a.tones());
            format!(
                "{} = {} = {} Hz in {} ({})",
                c.symbol,
                c.combination.display_with(&labels),
                hz,
                r.mode_names[c.mode],
                component_kind(r, &c.kind, c.mode)
            )
        })
        .collect()
}

/// Why a term has no lines: the modes of its factors that do not move.
fn at_rest(r: &Report, t: &Term) -> String {
    let mut still: Vec<usize> = t
        .monomial
        .factors()
        .iter()
        .map(|&(v, _)| v.index() % r.mode_names.len())
        .filter(|&n| !r.assignment.components().iter().any(|c| c.mode == n))
        .collect();
    still.sort_unstable();
    still.dedup();
    let still: Vec<&str> = still.iter().map(|&n| r.mode_names[n].as_str()).collect();
    format!(
        "no lines ({} at rest: no tone, and no term of its equation without it is forced)",
        still.join(", ")
    )
}

fn to_text(r: &Report) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "harmonid mix {}", r.model_path);
    let _ = writeln!(s, "amplitudes (each component is X·cos(2π f t)):");
    for l in tone_lines(r) {
        let _ = writeln!(s, "  {l}");
    }
    let _ = writeln!(s, "near: {}", window_text(r));
    let _ = writeln!(
        s,
        "each line: combination, frequency, amplitude of cos(2π f t) in the monomial (DC value at 0 Hz)"
    );
    if r.terms.iter().any(|t| t.table.velocity_factors > 0) {
        let _ = writeln!(
            s,
            "velocity terms (d(q)): the line's complex amplitude C, the line being Re[C e^(i2π f t)] (i·c: −c·sin(2π f t)); ω(X) = 2π × the frequency of component X"
        );
    }
    let labels = tone_labels(r);
    let symbols = r.assignment.symbols_with_frequencies();
    let mut last_eq = usize::MAX;
    for t in &r.terms {
        if t.equation != last_eq {
            let _ = writeln!(s, "\nequation of {}", r.mode_names[t.equation]);
            last_eq = t.equation;
        }
        let _ = writeln!(
            s,
            "  ({}) · {}",
            t.coefficient.to_string_with(&r.param_names),
            t.monomial.name(&r.var_names)
        );
        let gs = groups(r, &t.table);
        if gs.is_empty() {
            let _ = writeln!(s, "    {}", at_rest(r, t));
        }
        for (title, lines) in gs {
            let _ = writeln!(s, "    {title}:");
            for l in lines {
                let mark = order_mark(r, l);
                let _ = writeln!(
                    s,
                    "      {:<24} {:>16.3} Hz   {}{}{mark}",
                    l.combination.display_with(&labels),
                    l.hz,
                    t.table.coefficient_text(l, &symbols),
                    if mark.is_empty() { "" } else { "   " },
                );
            }
        }
    }
    if let Some(ns) = &r.nonsmooth {
        s.push_str(&nonsmooth::to_text(
            ns,
            &ns_context(r, &labels, &r.assignment.symbols()),
        ));
    }
    s
}

fn to_markdown(r: &Report) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Mixing table: `{}`\n", r.model_path);
    for l in tone_lines(r) {
        let _ = writeln!(s, "- {l}");
    }
    let _ = writeln!(
        s,
        "\nNear means {}. Coefficients are amplitudes of cos(2π f t); with velocities (d(q)) the line's complex amplitude C (the line is Re[C e^(i2π f t)]), ω(X) being 2π times component X's frequency.",
        window_text(r)
    );
    let labels = tone_labels(r);
    let symbols = r.assignment.symbols_with_frequencies();
    for t in &r.terms {
        let _ = writeln!(
            s,
            "\n## Equation of {}: `({}) * {}`\n",
            r.mode_names[t.equation],
            t.coefficient.to_string_with(&r.param_names),
            t.monomial.name(&r.var_names)
        );
        let _ = writeln!(s, "| where | combination | frequency (Hz) | coefficient |");
        let _ = writeln!(s, "|---|---|---:|---|");
        for (title, lines) in groups(r, &t.table) {
            for l in lines {
                let mark = order_mark(r, l);
                let _ = writeln!(
                    s,
                    "| {title}{}{mark} | {} | {:.3} | `{}` |",
                    if mark.is_empty() { "" } else { ", " },
                    l.combination.display_with(&labels),
                    l.hz,
                    t.table.coefficient_text(l, &symbols)
                );
            }
        }
    }
    if let Some(ns) = &r.nonsmooth {
        let plain = r.assignment.symbols();
        s.push_str(&nonsmooth::to_markdown(ns, &ns_context(r, &labels, &plain)));
    }
    s
}

/// A line's coefficient in LaTeX, with the table's `i^k` in front when the term has velocity
/// factors (as [`MixingTable::coefficient_text`]).
fn latex_coefficient(t: &MixingTable, l: &Line, symbols: &[String]) -> String {
    let c = l.coefficient.to_latex_with(symbols);
    match t.velocity_factors % 4 {
        0 => c,
        1 => format!("i\\left({c}\\right)"),
        2 => format!("-\\left({c}\\right)"),
        _ => format!("-i\\left({c}\\right)"),
    }
}

/// `X1 → X_{1}`, `X3_q2 → X_{3,q2}`, `Y1 → Y_{1}`.
fn latex_symbol(s: &str) -> String {
    let (head, rest) = s.split_at(1);
    format!("{head}_{{{}}}", rest.replace('_', ","))
}

fn to_latex(r: &Report) -> String {
    let mut s = String::new();
    let labels: Vec<String> = (1..=r.assignment.tones().len())
        .map(|d| format!("\\Omega_{{{d}}}"))
        .collect();
    let amplitudes: Vec<String> = r
        .assignment
        .symbols()
        .iter()
        .map(|x| latex_symbol(x))
        .collect();
    let frequencies: Vec<String> = amplitudes
        .iter()
        .map(|x| format!("\\omega_{{{x}}}"))
        .collect();
    let symbols = [amplitudes, frequencies].concat();
    let params: Vec<String> = r
        .param_names
        .iter()
        .map(|p| harmonid_model::latex_name(p))
        .collect();
    let _ = writeln!(s, "% harmonid mix {}", r.model_path);
    for c in r.assignment.components() {
        let _ = writeln!(
            s,
            "% {} = {} ({} Hz) in {} ({})",
            c.symbol,
            c.combination.display_with(&tone_labels(r)),
            c.combination.hz(r.assignment.tones()),
            r.mode_names[c.mode],
            component_kind(r, &c.kind, c.mode)
        );
    }
    for t in &r.terms {
        let coeff = t.coefficient.to_latex_with(&params);
        let _ = writeln!(
            s,
            "\n% equation of {}\n\\begin{{tabular}}{{llrl}}\n\\multicolumn{{4}}{{l}}{{$({coeff})\\,{}$}} \\\\\n\\hline",
            r.mode_names[t.equation],
            t.monomial.join(&r.var_latex, " ", |k| format!("^{{{k}}}"))
        );
        for (title, lines) in groups(r, &t.table) {
            for l in lines {
                let mark = order_mark(r, l);
                let _ = writeln!(
                    s,
                    "{title}{}{mark} & ${}$ & {:.3} Hz & ${}$ \\\\",
                    if mark.is_empty() { "" } else { ", " },
                    l.combination.latex_with(&labels),
                    l.hz,
                    latex_coefficient(&t.table, l, &symbols)
                );
            }
        }
        let _ = writeln!(s, "\\end{{tabular}}");
    }
    if let Some(ns) = &r.nonsmooth {
        let (omega, plain) = (tone_labels(r), r.assignment.symbols());
        s.push_str(&nonsmooth::to_latex(
            ns,
            &ns_context(r, &omega, &plain),
            &labels,
        ));
    }
    s
}

fn to_json(r: &Report) -> String {
    use serde_json::{json, Value};
    let a = &r.assignment;
    let components: Vec<Value> = a
        .components()
        .iter()
        .map(|c| {
            json!({
                "symbol": c.symbol,
                "mode": r.mode_names[c.mode],
                "combination": c.combination.coeffs(),
                "freq_hz": c.combination.hz(a.tones()),
                "kind": match c.kind { ComponentKind::Drive(_) => "tone", ComponentKind::Sideband => "sideband", ComponentKind::Response => "response" },
                "name": c.combination.display_with(&tone_labels(r)),
            })
        })
        .collect();
    let symbols = a.symbols_with_frequencies();
    // `label` keeps format harmonid-mix/1's names f1, f2, ... (the Python records' `combination`);
    // `name` is the same combination with the tones as Ω1, Ω2, ...
    let labels = a.tones().labels();
    let omega = tone_labels(r);
    let terms: Vec<Value> = r
        .terms
        .iter()
        .map(|t| {
            let lines: Vec<Value> = t
                .table
                .lines
                .iter()
                .map(|l| {
                    json!({
                        "combination": l.combination.coeffs(),
                        "label": l.combination.display_with(labels),
                        "freq_hz": l.hz,
                        "coefficient": t.table.coefficient_text(l, &symbols),
                        "near": l.near_mode().map(|n| r.mode_names[n].clone()),
                        "name": l.combination.display_with(&omega),
                        "second_order": !via(r, l).is_empty(),
                        "via": via(r, l),
                    })
                })
                .collect();
            json!({
                "equation": r.mode_names[t.equation],
                "monomial": t.monomial.name(&r.var_names),
                "term_coefficient": t.coefficient.to_string_with(&r.param_names),
                "velocity_factors": t.table.velocity_factors,
                "lines": lines,
            })
        })
        .collect();
    let nominal: serde_json::Map<String, Value> = r
        .mode_names
        .iter()
        .zip(&r.nominal)
        .map(|(m, f)| (m.clone(), json!(f)))
        .collect();
    let plain = a.symbols();
    let nonsmooth = r
        .nonsmooth
        .as_ref()
        .map(|ns| nonsmooth::to_json(ns, &ns_context(r, &omega, &plain), labels));
    let mut v = json!({
        "format": "harmonid-mix/1",
        "model": r.model_path,
        "tones_hz": a.tones().hz(),
        "components": components,
        "nominal_hz": nominal,
        "window_hz": r.window,
        "terms": terms,
    });
    if let (Some(ns), Some(map)) = (nonsmooth, v.as_object_mut()) {
        map.insert("nonsmooth".into(), ns);
    }
    let mut s = serde_json::to_string_pretty(&v).unwrap_or_default();
    s.push('\n');
    s
}
