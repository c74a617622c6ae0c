//! `harmonid sweep ... --pump HZ:LEVEL[:PHASE]`: the response of a parametrically pumped model
//! to one tone stepped up and then down through the range, as a stepped-sine experiment with
//! the pump on measures it (each step starts from the state before it, so the sweep stays on
//! its branch until that branch ends).

use super::sweep_args::Args;
use harmonid_plot::{Branch, Jump, ResponseCurve};
use harmonid_sim::{self as sim, Excitation, HbSettings, NumericModel, PumpTone};
use miette::{miette, IntoDiagnostic};
use num_complex::Complex64;
use std::fmt::Write as _;
use std::path::Path;

/// Most steps per direction.
const MAX_STEPS: usize = 4000;
/// Consecutive steps whose driven amplitude changes by more than this factor are a jump.
const JUMP_RATIO: f64 = 1.5;

/// `--pump 2000:4e4:0.3`: a pump tone at 2000 Hz, level 4e4 (the unit the model's pump
/// coefficients are per), phase 0.3 rad (default 0).
pub fn parse_pump(s: &str) -> miette::Result<PumpTone> {
    let bad = |why: &str| {
        miette!(
            help = "write HZ:LEVEL or HZ:LEVEL:PHASE_RAD, e.g. --pump 2000:4e4 (a pump at 2 kHz of level 4e4 in the unit of the model's pump coefficients)",
            "--pump {s}: {why}"
        )
    };
    let parts: Vec<&str> = s.split(':').map(str::trim).collect();
    if !(2..=3).contains(&parts.len()) {
        return Err(bad("expected two or three numbers separated by `:`"));
    }
    let num = |t: &str, what: &str| -> miette::Result<f64> {
        t.parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| bad(&format!("`{t}` is not a finite {what}")))
    };
    let hz = num(parts[0], "frequency in Hz")?;
    if hz <= 0.0 {
        return Err(bad("the pump frequency must be positive"));
    }
    let level = num(parts[1], "level")?;
    let phase = match parts.get(2) {
        Some(p) => num(p, "phase in rad")?,
        None => 0.0,
    };
    Ok(PumpTone {
        hz,
        amplitude: Complex64::from_polar(level, phase),
    })
}

/// One direction of the stepped sweep: per step the tone, the state's lines of each mode (the
/// tone, and each pump's idler `f_p − f`), stability and convergence.
struct Direction {
    up: bool,
    f_hz: Vec<f64>,
    /// `lines[step][mode][0]` at the tone, `[1 + 2k]` at pump `k`'s idler `f_p − f` and
    /// `[2 + 2k]` at its half `f_p/2` (where the oscillation it sustains above threshold is).
    lines: Vec<Vec<Vec<Complex64>>>,
    stable: Vec<bool>,
    converged: Vec<bool>,
}

/// Runs the pumped sweep (see the module documentation).
pub fn run(
    args: &Args,
    model: &NumericModel,
    force: Vec<Complex64>,
    pumps: Vec<PumpTone>,
    inputs: &[&Path],
) -> miette::Result<()> {
    check_args(args, model)?;
    let grid = step_grid(args);
    let pb = super::progress::spinner("stepped sweep with the pump on");
    let mut dirs = Vec::new();
    for up in [true, false] {
        dirs.push(sweep_direction(model, &force, &pumps, &grid, up)?);
    }
    pb.finish_and_clear();
    let driven = harmonid_report::curves::driven_mode(&force);
    let jumps: Vec<Jump> = dirs.iter().flat_map(|d| jumps_of(d, driven)).collect();
    if let Some(path) = &args.plot {
        save_plot(model, &dirs, &jumps, driven, path, inputs)?;
    }
    let mut csv = csv_header(model, pumps.len());
    for d in &dirs {
        push_rows(&mut csv, d);
        eprintln!("{}", summary(d, &jumps));
    }
    match &args.out {
        Some(p) => super::common::write_output(p, csv.as_bytes(), inputs),
        None => {
            use std::io::Write;
            let _ = std::io::stdout().lock().write_all(csv.as_bytes());
            Ok(())
        }
    }
}

/// The options a pumped sweep cannot run with: a model without pump terms, a two-tone sweep,
/// a range that is not two distinct positive frequencies.
fn check_args(args: &Args, model: &NumericModel) -> miette::Result<()> {
    if !model.has_pump_terms() {
        return Err(miette!(
            help = "add the term the pump modulates to the model (e.g. `eom q1 += lambda*pump*q1`), or leave out --pump",
            "--pump: the model has no pump terms, so the pump would act on nothing"
        ));
    }
    if args.two_tone.is_some() {
        return Err(miette!(
            help = "sweep one tone with the pump on (leave out --two-tone)",
            "--two-tone and --pump: the two-tone sweep does not take a pump yet"
        ));
    }
    if !(args.from.is_finite() && args.to.is_finite() && args.from > 0.0 && args.to > 0.0)
        || args.from == args.to
    {
        return Err(miette!(
            "--from {} --to {}: give two distinct positive frequencies in Hz",
            args.from,
            args.to
        ));
    }
    Ok(())
}

/// The tones, ascending: `--points` (2 to [`MAX_STEPS`]) evenly spaced over the range.
fn step_grid(args: &Args) -> Vec<f64> {
    let steps = args.points.clamp(2, MAX_STEPS);
    let (lo, hi) = (args.from.min(args.to), args.from.max(args.to));
    (0..steps)
        .map(|k| lo + (hi - lo) * k as f64 / (steps - 1) as f64)
        .collect()
}

/// One direction of the sweep over `grid` (reversed when not `up`), each step starting from
/// the state before it; per step the lines of every mode, stability and convergence.
fn sweep_direction(
    model: &NumericModel,
    force: &[Complex64],
    pumps: &[PumpTone],
    grid: &[f64],
    up: bool,
) -> miette::Result<Direction> {
    let steps = grid.len();
    let f_hz: Vec<f64> = if up {
        grid.to_vec()
    } else {
        grid.iter().rev().copied().collect()
    };
    let drives: Vec<Excitation> = f_hz
        .iter()
        .map(|&f| Excitation {
            tones_hz: vec![f],
            force: force.iter().map(|&z| vec![z]).collect(),
            pumps: pumps.to_vec(),
        })
        .collect();
    let states = sim::stepped_sweep(model, &drives, &HbSettings::default()).into_diagnostic()?;
    let mut d = Direction {
        up,
        f_hz: f_hz.clone(),
        lines: Vec::with_capacity(steps),
        stable: Vec::with_capacity(steps),
        converged: Vec::with_capacity(steps),
    };
    for ((st, drive), &f) in states.iter().zip(&drives).zip(&f_hz) {
        let at = |n: usize| {
            std::iter::once(st.amplitude(n, f))
                .chain(pumps.iter().flat_map(|p| {
                    [
                        st.amplitude(n, (p.hz - f).abs()),
                        st.amplitude(n, 0.5 * p.hz),
                    ]
                }))
                .collect()
        };
        d.lines.push((0..model.n_modes()).map(at).collect());
        d.converged.push(st.converged());
        d.stable
            .push(st.converged() && sim::check_stability(model, drive, st).is_ok_and(|s| s.stable));
    }
    Ok(d)
}

/// Draws the driven mode's response at the tone, both directions with their jumps, to `path`.
fn save_plot(
    model: &NumericModel,
    dirs: &[Direction],
    jumps: &[Jump],
    driven: usize,
    path: &Path,
    inputs: &[&Path],
) -> miette::Result<()> {
    let name = &model.mode_names[driven];
    let curve = ResponseCurve {
        title: format!("response of {name} to one tone, pumped (stepped up and down)"),
        y_label: format!("|{name}| at f (m)"),
        branches: dirs
            .iter()
            .map(|d| Branch {
                label: format!("{name}, {}-sweep", if d.up { "up" } else { "down" }),
                f_hz: d.f_hz.clone(),
                amp: d.lines.iter().map(|l| l[driven][0].norm()).collect(),
                stable: d.stable.clone(),
            })
            .collect(),
        jumps: jumps.to_vec(),
        backbone: Vec::new(),
        measured: Vec::new(),
    };
    super::figure::save(&curve, path, inputs)?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// The CSV's header: per mode its tone's line, then per pump its idler and half lines.
fn csv_header(model: &NumericModel, n_pumps: usize) -> String {
    let mut csv = String::from("direction,f_hz");
    for n in &model.mode_names {
        let _ = write!(csv, ",{n}_f_abs,{n}_f_phase_rad");
        for k in 1..=n_pumps {
            let _ = write!(
                csv,
                ",{n}_idler{k}_abs,{n}_idler{k}_phase_rad,{n}_half{k}_abs,{n}_half{k}_phase_rad"
            );
        }
    }
    csv.push_str(",stable,converged\n");
    csv
}

/// Appends one CSV row per step of `d`.
fn push_rows(csv: &mut String, d: &Direction) {
    let dir = if d.up { "up" } else { "down" };
    for (k, &f) in d.f_hz.iter().enumerate() {
        let _ = write!(csv, "{dir},{f:.9}");
        for mode in &d.lines[k] {
            for z in mode {
                let _ = write!(csv, ",{:e},{:.9}", z.norm(), z.arg());
            }
        }
        let _ = writeln!(csv, ",{},{}", d.stable[k] as u8, d.converged[k] as u8);
    }
}

/// The one-line summary of direction `d`: its steps, its jumps, the steps that did not settle.
fn summary(d: &Direction, jumps: &[Jump]) -> String {
    let dir = if d.up { "up" } else { "down" };
    let failed = d.converged.iter().filter(|c| !**c).count();
    let at: Vec<String> = jumps
        .iter()
        .filter(|j| j.up == d.up)
        .map(|j| format!("{:.3}", j.f_hz))
        .collect();
    format!(
        "{dir}-sweep: {} steps, jumps at [{}] Hz{}",
        d.f_hz.len(),
        at.join(", "),
        if failed > 0 {
            format!("; {failed} steps did not settle on a steady state (converged = 0 in the CSV)")
        } else {
            String::new()
        }
    )
}

/// Where the driven mode's amplitude at the tone changes by more than [`JUMP_RATIO`] between
/// consecutive converged steps: the state left its branch.
fn jumps_of(d: &Direction, n: usize) -> Vec<Jump> {
    let amp: Vec<f64> = d.lines.iter().map(|l| l[n][0].norm()).collect();
    (1..amp.len())
        .filter(|&k| d.converged[k] && d.converged[k - 1])
        .filter(|&k| {
            let (a, b) = (amp[k - 1], amp[k]);
            a.max(b) > JUMP_RATIO * a.min(b).max(f64::MIN_POSITIVE)
        })
        .map(|k| Jump {
            f_hz: d.f_hz[k - 1],
            from: amp[k - 1],
            to: amp[k],
            up: d.up,
        })
        .collect()
}
