//! `harmonid sweep ... --limit-cycles branches.csv`: from every Hopf point of the response
//! curve, the quasi-periodic branch (the drive plus a self-oscillation at a second base
//! frequency `f2`) continued in the drive frequency over the sweep's range
//! ([`harmonid_sim::quasi_periodic_branch`]).

use harmonid_plot::Branch;
use harmonid_sim::{self as sim, QuasiPeriodicBranch, QuasiPeriodicSettings};
use num_complex::Complex64;
use std::fmt::Write as _;

/// The branches from every Hopf point of `r`, with [`QuasiPeriodicSettings::for_sweep`]. A
/// branch that cannot start is reported on stderr and left out.
pub fn branches(
    model: &sim::NumericModel,
    force: &[Complex64],
    r: &sim::SweepResult,
    (from, to): (f64, f64),
    points: usize,
) -> Vec<QuasiPeriodicBranch> {
    let s = QuasiPeriodicSettings::for_sweep(r, (from, to), points);
    let mut out = Vec::new();
    for (i, h) in r.hopf.iter().enumerate() {
        match sim::quasi_periodic_branch(model, force, r, i, &s) {
            Ok(b) => {
                report(&b);
                out.push(b);
            }
            Err(e) => eprintln!(
                "no limit-cycle branch from the Hopf point at {:.6} Hz: {e}",
                h.f_hz
            ),
        }
    }
    if r.hopf.is_empty() {
        eprintln!("no Hopf point on the curve: the limit-cycle file holds its header only");
    }
    out
}

/// One line on stderr per branch: where it goes and why it ends.
fn report(b: &QuasiPeriodicBranch) {
    let (Some(first), Some(last)) = (b.points.first(), b.points.last()) else {
        return;
    };
    let end = b.end;
    eprintln!(
        "limit-cycle branch from the Hopf point at {:.6} Hz: {} points, drive {:.6} -> {:.6} Hz, f2 {:.6} -> {:.6} Hz; ends at {end}",
        b.hopf.f_hz,
        b.points.len(),
        first.f_hz,
        last.f_hz,
        first.f2_hz,
        last.f2_hz
    );
}

/// The CSV: one row per branch point, columns `hopf` (1-based, the order of the curve's Hopf
/// points), `f_hz` (drive), `f2_hz`, `offset_hz` (`f2 − f`), per mode `|X|` (m, peak) on the
/// self-oscillation's line `f2`, the drive's line `f` and the sideband `2f − f2`, then
/// `stable` (1, 0; empty where not judged: a growth rate within the slow flow's own error of
/// zero, as near the Hopf point, or lines that coincide) and
/// `growth_per_s` (the slow flow's largest growth rate less the free phase's zero).
pub fn csv(model: &sim::NumericModel, branches: &[QuasiPeriodicBranch]) -> String {
    let mut csv = String::from("hopf,f_hz,f2_hz,offset_hz");
    for n in &model.mode_names {
        let _ = write!(csv, ",{n}_f2_abs,{n}_f_abs,{n}_2f-f2_abs");
    }
    csv.push_str(",stable,growth_per_s\n");
    for (h, b) in branches.iter().enumerate() {
        let lines = [b.line((0, 1)), b.line((1, 0)), b.line((-2, 1))];
        for p in &b.points {
            let _ = write!(
                csv,
                "{},{:.9},{:.9},{:.9}",
                h + 1,
                p.f_hz,
                p.f2_hz,
                p.f2_hz - p.f_hz
            );
            for row in &p.amplitudes {
                for l in lines {
                    match l {
                        Some(l) => {
                            let _ = write!(csv, ",{:e}", row[l].norm());
                        }
                        None => csv.push(','),
                    }
                }
            }
            match p.stability {
                Some(s) => {
                    let _ = writeln!(csv, ",{},{:e}", s.stable as u8, s.growth_rate);
                }
                None => csv.push_str(",,\n"),
            }
        }
    }
    csv
}

/// The branches of mode `n` for the sweep's figure: its amplitude at `f2` and at the drive
/// along each branch (a point not judged drawn as stable), labelled by the branch's number
/// (the CSV's `hopf`).
pub fn plot_branches(branches: &[QuasiPeriodicBranch], n: usize, name: &str) -> Vec<Branch> {
    let mut out = Vec::new();
    for (i, b) in branches.iter().enumerate() {
        let stable: Vec<bool> = b
            .points
            .iter()
            .map(|p| p.stability.is_none_or(|s| s.stable))
            .collect();
        let f_hz: Vec<f64> = b.points.iter().map(|p| p.f_hz).collect();
        for (k, what) in [((0, 1), "f2"), ((1, 0), "f")] {
            if let Some(l) = b.line(k) {
                out.push(Branch {
                    label: format!("{name} at {what} ({})", i + 1),
                    f_hz: f_hz.clone(),
                    amp: b.points.iter().map(|p| p.amplitudes[n][l].norm()).collect(),
                    stable: stable.clone(),
                });
            }
        }
    }
    out
}
