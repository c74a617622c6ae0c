//! `harmonid sweep MODEL --values V --from F0 --to F1 --force q1=F`: single-tone response curve
//! with continuation through folds, written as CSV (one row per curve point); with `--pump`,
//! the stepped sweep of a pumped model (`sweep_pumped`).

use super::simulate::numeric_model;
pub use super::sweep_args::Args;
use harmonid_sim::{self as sim, SweepSettings};
use miette::{miette, IntoDiagnostic};
use num_complex::Complex64;
use std::fmt::Write as _;

/// A curve is accepted when its highest harmonic stays below this fraction of the largest.
const TRUNCATION_TOL: f64 = 1e-3;
/// Harmonics are raised automatically (3, 7, 15, 31) up to this order.
const MAX_AUTO_HARMONICS: usize = 31;

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let inputs = [args.model.as_path(), args.values.as_path()];
    for out in [&args.out, &args.limit_cycles].into_iter().flatten() {
        super::common::check_outputs(&[out.as_path()], &inputs)?;
    }
    if let Some(p) = &args.plot {
        super::figure::check(p, &inputs)?;
    }
    let model = numeric_model(&args.model, &args.values)?;
    let force = super::common::forces(&model, &args.force)?;
    if !args.pump.is_empty() {
        let pumps = args
            .pump
            .iter()
            .map(|p| super::sweep_pumped::parse_pump(p))
            .collect::<miette::Result<Vec<_>>>()?;
        return super::sweep_pumped::run(&args, &model, force, pumps, &inputs);
    }
    if let Some(spacing) = args.two_tone {
        return two_tone(&args, &model, force, spacing, &inputs);
    }
    let s = SweepSettings {
        f_start_hz: args.from,
        f_stop_hz: args.to,
        points: args.points,
        harmonics: args.harmonics,
        ..SweepSettings::default()
    };
    let r = converged_sweep(&model, &force, s)?;
    let branches = match &args.limit_cycles {
        Some(_) => {
            super::limit_cycles::branches(&model, &force, &r, (args.from, args.to), args.points)
        }
        None => Vec::new(),
    };
    if let Some(path) = &args.plot {
        let n = harmonid_report::curves::driven_mode(&force);
        let mut fig = harmonid_report::curves::sweep_curve(&model, &r, n);
        let name = &model.mode_names[n];
        if !branches.is_empty() {
            fig.y_label = format!("|{name}| at f, and at f2 beside it (m)");
        }
        fig.branches
            .extend(super::limit_cycles::plot_branches(&branches, n, name));
        super::figure::save(&fig, path, &inputs)?;
        eprintln!("wrote {}", path.display());
    }
    if let Some(path) = &args.limit_cycles {
        let csv = super::limit_cycles::csv(&model, &branches);
        super::common::write_output(path, csv.as_bytes(), &inputs)?;
        eprintln!("wrote {}", path.display());
    }
    let csv = curve_csv(&model, &r);
    tell_curve(&r);
    match &args.out {
        Some(p) => super::common::write_output(p, csv.as_bytes(), &inputs),
        None => {
            use std::io::Write;
            let _ = std::io::stdout().lock().write_all(csv.as_bytes());
            Ok(())
        }
    }
}

/// The single-tone sweep with `s`, its harmonics raised (3, 7, 15, 31) until the highest kept
/// stays below [`TRUNCATION_TOL`] of the largest: otherwise the curve's amplitudes and
/// stability verdicts depend on the truncation.
fn converged_sweep(
    model: &sim::NumericModel,
    force: &[Complex64],
    mut s: SweepSettings,
) -> miette::Result<sim::SweepResult> {
    loop {
        let pb = super::progress::spinner("sweeping");
        let r = sim::sweep(model, force, &s);
        pb.finish_and_clear();
        let r = r.into_diagnostic()?;
        let (ratio, at_hz, h) = r.truncation();
        if ratio <= TRUNCATION_TOL {
            return Ok(r);
        }
        let next = (2 * s.harmonics + 1).min(MAX_AUTO_HARMONICS);
        if next <= s.harmonics {
            return Err(miette!(
                help = "lower the force (--force): the response is far beyond the weakly nonlinear regime the harmonic balance resolves",
                "harmonic {h} still reaches {ratio:.2e} of the largest harmonic at {at_hz:.6} Hz with {} harmonics (tolerance {TRUNCATION_TOL:e}): the curve is not converged",
                s.harmonics
            ));
        }
        eprintln!(
            "harmonic {h} reaches {ratio:.2e} of the largest harmonic at {at_hz:.6} Hz: recomputing with --harmonics {next}"
        );
        s.harmonics = next;
    }
}

/// The curve as CSV: `f_hz, stable`, per mode and harmonic `re, im, abs` (m), `hopf_hz`.
fn curve_csv(model: &sim::NumericModel, r: &sim::SweepResult) -> String {
    let mut csv = String::from("f_hz,stable");
    for n in &model.mode_names {
        for &h in &r.harmonics {
            let _ = write!(csv, ",{n}_h{h}_re,{n}_h{h}_im,{n}_h{h}_abs");
        }
    }
    // A Hopf point between this point and the next: its frequency (empty on other rows).
    csv.push_str(",hopf_hz\n");
    for (i, p) in r.points.iter().enumerate() {
        let _ = write!(csv, "{:.9},{}", p.f_hz, p.stable as u8);
        for row in &p.amplitudes {
            for z in row {
                let _ = write!(csv, ",{:e},{:e},{:e}", z.re, z.im, z.norm());
            }
        }
        match r.hopf.iter().find(|h| h.index == i) {
            Some(h) => {
                let _ = writeln!(csv, ",{:.9}", h.f_hz);
            }
            None => csv.push_str(",\n"),
        }
    }
    csv
}

/// Says on stderr where the curve has Hopf points, how many points it has and where the up-
/// and down-sweeps jump.
fn tell_curve(r: &sim::SweepResult) {
    for h in &r.hopf {
        eprintln!(
            "Hopf point at {:.6} Hz: the state {} stability through a complex pair (a self-oscillation {:.4} Hz from the drive's lines {})",
            h.f_hz,
            if h.gains_stability { "gains" } else { "loses" },
            h.offset_hz,
            if h.gains_stability { "stops" } else { "starts" }
        );
    }
    let (up, down) = r.jumps();
    eprintln!(
        "{} points; folds: up-sweep jumps at [{}] Hz, down-sweep jumps at [{}] Hz{}",
        r.points.len(),
        hz_list(&up),
        hz_list(&down),
        if r.complete {
            ""
        } else {
            "; the curve stopped before the end of the range (Newton failed: try a smaller drive or more --harmonics)"
        }
    );
}

/// `207652.079, 207589.143` (for messages).
fn hz_list(v: &[f64]) -> String {
    v.iter()
        .map(|f| format!("{f:.3}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn two_tone(
    args: &Args,
    model: &sim::NumericModel,
    force: Vec<Complex64>,
    spacing: f64,
    inputs: &[&std::path::Path],
) -> miette::Result<()> {
    let s = sim::TwoToneSettings {
        c_start_hz: args.from,
        c_end_hz: args.to,
        spacing_hz: spacing,
        force_low: force.clone(),
        force_high: force.clone(),
        points: args.points,
        ..sim::TwoToneSettings::default()
    };
    let pb = super::progress::spinner("two-tone sweep");
    let r = sim::sweep_two_tone(model, &s);
    pb.finish_and_clear();
    let r = r.into_diagnostic()?;
    if let Some(path) = &args.plot {
        let n = harmonid_report::curves::driven_mode(&force);
        super::figure::save(
            &harmonid_report::curves::two_tone_curve(model, &r, n),
            path,
            inputs,
        )?;
        eprintln!("wrote {}", path.display());
    }
    // Each mode at its own lines: the pair's tones and sidebands for a mode near the pair, the
    // mixing products that reach it for any other mode.
    let mut csv = String::from("direction,centre_hz");
    for (n, lines) in model.mode_names.iter().zip(&r.mode_lines) {
        for l in lines {
            let _ = write!(csv, ",{n}_{}_abs,{n}_{}_phase_rad", l.label, l.label);
        }
    }
    csv.push_str(",stable\n");
    for c in [&r.up, &r.down] {
        let dir = if c.up { "up" } else { "down" };
        for p in &c.points {
            let _ = write!(csv, "{dir},{:.9}", p.centre_hz);
            for row in &p.amplitudes {
                for z in row {
                    let _ = write!(csv, ",{:e},{:.9}", z.norm(), z.arg());
                }
            }
            let _ = writeln!(csv, ",{}", p.stable as u8);
        }
        let jumps: Vec<String> = c
            .jumps
            .iter()
            .map(|j| format!("{:.4} -> {:.4} Hz", j.from_hz, j.to_hz))
            .collect();
        let status = match &c.status {
            sim::TwoToneStatus::Complete => String::new(),
            sim::TwoToneStatus::Stopped { at_hz, why } => format!("; stopped at {at_hz} Hz: {why}"),
        };
        eprintln!(
            "{dir}-sweep: {} points, jumps at [{}]{status}",
            c.points.len(),
            jumps.join(", ")
        );
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
