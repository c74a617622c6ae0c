//! Response-curve figures from harmonid_sim's sweeps (`harmonid sweep --plot`).

use harmonid_plot::{Branch, Jump, ResponseCurve};
use harmonid_sim::{NumericModel, SweepResult, TwoToneSweep};

/// The mode driven hardest (largest |force|), the one whose response a figure shows.
pub fn driven_mode(force: &[num_complex::Complex64]) -> usize {
    force
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.norm().total_cmp(&b.1.norm()))
        .map_or(0, |(n, _)| n)
}

/// Amplitude where the stable part of the curve away from `skip` crosses `f`, the farthest
/// from `a0` (the branch a sweep lands on after a jump at `f`).
fn landing(
    f_hz: &[f64],
    amp: &[f64],
    stable: &[bool],
    skip: usize,
    f: f64,
    a0: f64,
) -> Option<f64> {
    let mut best: Option<f64> = None;
    for i in 0..f_hz.len().saturating_sub(1) {
        if i.abs_diff(skip) <= 2 || !(stable[i] && stable[i + 1]) {
            continue;
        }
        let (f0, f1) = (f_hz[i], f_hz[i + 1]);
        if (f0 - f) * (f1 - f) > 0.0 || f0 == f1 {
            continue;
        }
        let t = (f - f0) / (f1 - f0);
        let a = amp[i] + t * (amp[i + 1] - amp[i]);
        if best.is_none_or(|b| (a - a0).abs() > (b - a0).abs()) {
            best = Some(a);
        }
    }
    best
}

/// The response curve of mode `n` at the fundamental of a single-tone sweep: stability per
/// point, the jumps at the folds (up-sweep at the upper folds, down-sweep at the lower ones),
/// and the backbone of mode `n` up to the largest amplitude (points where it fails are left out).
pub fn sweep_curve(model: &NumericModel, r: &SweepResult, n: usize) -> ResponseCurve {
    let h1 = r.harmonics.iter().position(|&h| h == 1).unwrap_or(0);
    let f_hz: Vec<f64> = r.points.iter().map(|p| p.f_hz).collect();
    let amp: Vec<f64> = r
        .points
        .iter()
        .map(|p| {
            p.amplitudes
                .get(n)
                .and_then(|row| row.get(h1))
                .map_or(f64::NAN, |z| z.norm())
        })
        .collect();
    let stable: Vec<bool> = r.points.iter().map(|p| p.stable).collect();
    let jumps = r
        .folds
        .iter()
        .filter_map(|fold| {
            let from = *amp.get(fold.index)?;
            let to = landing(&f_hz, &amp, &stable, fold.index, fold.f_hz, from)?;
            Some(Jump {
                f_hz: fold.f_hz,
                from,
                to,
                up: fold.upper,
            })
        })
        .collect();
    let a_max = amp
        .iter()
        .copied()
        .filter(|a| a.is_finite())
        .fold(0.0, f64::max);
    let amps: Vec<f64> = (1..=40).map(|k| a_max * k as f64 / 40.0).collect();
    // The backbone with the sweep's highest harmonic (not the count of harmonics kept: an odd
    // model keeps only 1, 3, ...).
    let h_max = r.harmonics.iter().copied().max().unwrap_or(1).max(1);
    let backbone: Vec<(f64, f64)> = harmonid_sim::backbone(model, n, &amps, h_max)
        .map(|fs| {
            amps.iter()
                .zip(fs)
                .filter_map(|(&a, f)| f.map(|f| (f, a)))
                .collect()
        })
        .unwrap_or_default();
    let name = &model.mode_names[n];
    // Where Newton fails (far beyond the weakly nonlinear regime), say how far the backbone goes.
    let bb_top = backbone.iter().map(|p| p.1).fold(0.0, f64::max);
    let note = if model.has_velocity_terms() {
        // A free oscillation with motion-dependent damping decays: no backbone.
        " (no backbone: the damping depends on the motion)".to_string()
    } else if model.has_nonsmooth() {
        // harmonid_sim::backbone refuses abs/sign/tanh terms: say so, not "found up to 0 m".
        " (no backbone: computed for polynomial terms only)".to_string()
    } else if bb_top < 0.999 * a_max {
        format!(
            " (backbone found only up to {} m)",
            harmonid_plot::style::tick(bb_top)
        )
    } else {
        String::new()
    };
    ResponseCurve {
        title: format!("response of {name} to one tone{note}"),
        y_label: format!("|{name}| at f (m)"),
        branches: vec![Branch {
            label: name.clone(),
            f_hz,
            amp,
            stable,
        }],
        jumps,
        backbone,
        measured: Vec::new(),
    }
}

/// The two-tone sweep's response of mode `n` at the two tones (`fa`, `fb`; for a mode away from
/// the pair its first two lines) against the pair's centre, up- and down-sweeps, with the jumps
/// of the first of them.
pub fn two_tone_curve(model: &NumericModel, r: &TwoToneSweep, n: usize) -> ResponseCurve {
    let lines = r.mode_lines.get(n).map(Vec::as_slice).unwrap_or(&[]);
    let mut shown: Vec<usize> = (0..lines.len())
        .filter(|&l| lines[l].label == "fa" || lines[l].label == "fb")
        .collect();
    if shown.is_empty() {
        shown = (0..lines.len().min(2)).collect();
    }
    let mut branches = Vec::new();
    let mut jumps = Vec::new();
    for c in [&r.up, &r.down] {
        let dir = if c.up { "↑" } else { "↓" };
        for (k, &l) in shown.iter().enumerate() {
            let amp: Vec<f64> = c
                .points
                .iter()
                .map(|p| {
                    p.amplitudes
                        .get(n)
                        .and_then(|row| row.get(l))
                        .map_or(f64::NAN, |z| z.norm())
                })
                .collect();
            if k == 0 {
                for j in &c.jumps {
                    if let (Some(&to), Some(&from)) =
                        (amp.get(j.index), amp.get(j.index.saturating_sub(1)))
                    {
                        jumps.push(Jump {
                            f_hz: j.from_hz,
                            from,
                            to,
                            up: c.up,
                        });
                    }
                }
            }
            branches.push(Branch {
                label: format!("{} {dir}", lines[l].label),
                f_hz: c.points.iter().map(|p| p.centre_hz).collect(),
                amp,
                stable: c.points.iter().map(|p| p.stable).collect(),
            });
        }
    }
    let name = &model.mode_names[n];
    ResponseCurve {
        title: format!("two-tone response of {name} (↑ up-sweep, ↓ down-sweep)"),
        y_label: format!("|{name}| (m)"),
        branches,
        jumps,
        backbone: Vec::new(),
        measured: Vec::new(),
    }
}
