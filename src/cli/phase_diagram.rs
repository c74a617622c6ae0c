//! `harmonid phase-diagram MODEL --values V [--drive HZ --force q1=F] [--pump HZ:LEVEL] --x
//! AXIS:FROM:TO:N --y AXIS:FROM:TO:N --out map.csv`: the number of stable and unstable
//! single-harmonic steady states over a grid of two parameters (`harmonid_explore::phase_diagram`).

use super::states::{excitation, ExcitationArgs};
use harmonid_explore::{Axis, AxisRange, PhaseDiagram, PhaseSettings, Problem};
use harmonid_plot::PhaseMap;
use miette::miette;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Arguments of `harmonid phase-diagram`.
#[derive(Debug, clap::Args)]
#[command(
    mut_arg("drive", |a| a.help("The drive tone, Hz, where the axes do not move it (`--drives q1:HZ` read the same)")),
    mut_arg("force", |a| a.help("Force of the tone on a mode, N/kg, as `mode=amplitude`; repeat for several modes")),
    mut_arg("pump", |a| a.help("A pump tone, `HZ:LEVEL[:PHASE_RAD]`; with a drive, at twice the drive tone (the two move together on a freq or pump_hz axis)")),
)]
pub struct Args {
    /// The model file (`*.hb`).
    pub model: PathBuf,
    /// Parameter values (TOML or an identification result JSON).
    #[arg(long)]
    pub values: PathBuf,
    /// The drive tone, its forces and a pump (the help reworded above for the axes).
    #[command(flatten)]
    pub excitation: ExcitationArgs,
    /// The x axis, `AXIS:FROM:TO:N`, AXIS one of freq, force:MODE, pump_hz, pump_level or a
    /// parameter of the model.
    #[arg(long, value_name = "AXIS:FROM:TO:N")]
    pub x: String,
    /// The y axis, as `--x`.
    #[arg(long, value_name = "AXIS:FROM:TO:N")]
    pub y: String,
    /// Output CSV, columns `x,y,stable,unstable,oscillatory` (oscillatory: the unstable states
    /// that lose stability through a complex pair, Hopf type).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write every state: `x,y,state,stable` and each mode's `re,im,abs` (m).
    #[arg(long, value_name = "FILE.csv")]
    pub states: Option<PathBuf>,
    /// Also draw the map to this file, `.svg` or `.png`.
    #[arg(long, value_name = "FILE.svg|png")]
    pub plot: Option<PathBuf>,
    /// Stop starting new rows after this many seconds (the rows done are written).
    #[arg(long, value_name = "S")]
    pub time_budget: Option<f64>,
}

/// `force:q1:0:10:50` → the axis `force:q1` from 0 to 10 in 50 points (read from the right, so
/// an axis name may hold a colon).
pub fn parse_axis(opt: &str, s: &str) -> miette::Result<AxisRange> {
    let bad = |why: String| {
        miette!(
            help = "write AXIS:FROM:TO:N, e.g. --x freq:990:1010:100 or --y force:q1:0.1:50:100; AXIS is freq, force:MODE, pump_hz, pump_level or a parameter of the model",
            "{opt} {s}: {why}"
        )
    };
    let parts: Vec<&str> = s.rsplitn(4, ':').collect();
    if parts.len() != 4 {
        return Err(bad("expected four fields separated by `:`".into()));
    }
    let num = |t: &str| t.trim().parse::<f64>().ok().filter(|v| v.is_finite());
    let from =
        num(parts[2]).ok_or_else(|| bad(format!("`{}` is not a finite number", parts[2])))?;
    let to = num(parts[1]).ok_or_else(|| bad(format!("`{}` is not a finite number", parts[1])))?;
    let n: usize = parts[0]
        .trim()
        .parse()
        .map_err(|_| bad(format!("`{}` is not a whole number of points", parts[0])))?;
    let axis: Axis = parts[3]
        .parse()
        .map_err(|_| bad("unreadable axis".into()))?;
    Ok(AxisRange { axis, from, to, n })
}

/// The label of an axis, with its unit.
fn label(a: &Axis) -> String {
    match a {
        Axis::Freq => "drive frequency (Hz)".into(),
        Axis::Force(m) => format!("force on {m} (N/kg)"),
        Axis::PumpHz => "pump frequency (Hz)".into(),
        Axis::PumpLevel => "pump level".into(),
        Axis::Param(p) => p.clone(),
    }
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let inputs = [args.model.as_path(), args.values.as_path()];
    let mut outs = vec![args.out.as_path()];
    outs.extend(args.states.as_deref());
    super::common::check_outputs(&outs, &inputs)?;
    if let Some(p) = &args.plot {
        super::figure::check(p, &inputs)?;
    }
    if let Some(b) = args.time_budget {
        if !(b.is_finite() && b > 0.0) {
            return Err(miette!(
                "--time-budget {b}: give a positive number of seconds"
            ));
        }
    }
    let x = parse_axis("--x", &args.x)?;
    let y = parse_axis("--y", &args.y)?;
    let model = harmonid_model::load(&args.model).map_err(miette::Report::new)?;
    let values = super::simulate::read_values(&args.values)?;
    let num = super::simulate::numeric_model(&args.model, &args.values)?;
    let drive = excitation(&num, &args.excitation)?;
    let problem = Problem {
        model: &model,
        values: &values,
        drive: &drive,
    };
    let settings = PhaseSettings {
        time_budget_s: args.time_budget,
        keep_states: args.states.is_some(),
    };
    let pb = super::progress::bar(y.n as u64, "rows", false);
    let t0 = std::time::Instant::now();
    let d = harmonid_explore::phase_diagram(&problem, &x, &y, &settings, &|done| {
        pb.set_position(done as u64)
    });
    pb.finish_and_clear();
    let d = d.map_err(miette::Report::new)?;
    eprintln!(
        "{} × {} points in {:.2} s: {} full homotopies, {} parameter homotopies, the rest continued by Newton; generic count {} complex solutions{}",
        x.n,
        y.n,
        t0.elapsed().as_secs_f64(),
        d.full_solves,
        d.parameter_homotopies,
        d.generic_count,
        if d.complete { "" } else { "; the time budget ran out: rows not done are left out of the files" }
    );
    super::common::write_output(&args.out, map_csv(&d).as_bytes(), &inputs)?;
    eprintln!("wrote {}", args.out.display());
    if let Some(p) = &args.states {
        super::common::write_output(p, states_csv(&num.mode_names, &d).as_bytes(), &inputs)?;
        eprintln!("wrote {}", p.display());
    }
    if let Some(p) = &args.plot {
        let map = PhaseMap {
            title: format!("{}: stable and unstable states", model_name(&args.model)),
            x_label: label(&x.axis),
            y_label: label(&y.axis),
            x: d.x.clone(),
            y: d.y.clone(),
            counts: d
                .counts
                .iter()
                .map(|c| c.map(|c| (c.stable, c.unstable)))
                .collect(),
        };
        super::figure::save(&map, p, &inputs)?;
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}

/// The model's name for a title: the file's stem, or its folder's name for a `model.hb`.
fn model_name(path: &std::path::Path) -> String {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    match path.parent().and_then(|p| p.file_name()) {
        Some(dir) if stem == "model" => dir.to_string_lossy().to_string(),
        _ => stem,
    }
}

fn map_csv(d: &PhaseDiagram) -> String {
    let mut s = String::from("x,y,stable,unstable,oscillatory\n");
    let nx = d.x.len();
    for (i, c) in d.counts.iter().enumerate() {
        if let Some(c) = c {
            let _ = writeln!(
                s,
                "{},{},{},{},{}",
                d.x[i % nx],
                d.y[i / nx],
                c.stable,
                c.unstable,
                c.oscillatory
            );
        }
    }
    s
}

fn states_csv(modes: &[String], d: &PhaseDiagram) -> String {
    let mut s = String::from("x,y,state,stable,oscillatory");
    for m in modes {
        let _ = write!(s, ",{m}_re,{m}_im,{m}_abs");
    }
    s.push('\n');
    let nx = d.x.len();
    for (i, pts) in d.states.iter().enumerate() {
        if d.counts[i].is_none() {
            continue;
        }
        for (k, p) in pts.iter().enumerate() {
            let (x, y) = (d.x[i % nx], d.y[i / nx]);
            let _ = write!(s, "{x},{y},{k},{},{}", p.stable as u8, p.oscillatory as u8);
            for z in &p.amplitudes {
                let _ = write!(s, ",{:e},{:e},{:e}", z.re, z.im, z.norm());
            }
            s.push('\n');
        }
    }
    s
}
