//! Writing a measurement's or a sweep's CSV text.

use super::*;

pub(super) fn csv_text(m: &Measurement, manifest: &Manifest, scale: f64) -> String {
    let mut s = header(false, m.noise.is_some(), manifest);
    rows(&mut s, None, m, manifest, scale);
    s
}

/// A sweep's CSV text: its steps' rows, with the `step` column.
pub(super) fn sweep_csv_text(steps: &[&Measurement], manifest: &Manifest, scale: f64) -> String {
    let mut s = header(true, steps.iter().any(|m| m.noise.is_some()), manifest);
    for (k, m) in steps.iter().enumerate() {
        rows(&mut s, Some(k), m, manifest, scale);
    }
    s
}

/// The header row: `step` for a sweep, `point` when the manifest declares points, `std` and
/// `samples` when the noise came with the data.
fn header(step: bool, noise: bool, manifest: &Manifest) -> String {
    let point = if manifest.points.is_empty() {
        ""
    } else {
        "point,"
    };
    let step = if step { "step," } else { "" };
    let noise = if noise { ",std,samples" } else { "" };
    format!("{step}shot,freq_hz,{point}re,im{noise}\n")
}

/// Appends `m`'s rows (amplitudes divided by `scale`), each led by `step` when given.
fn rows(s: &mut String, step: Option<usize>, m: &Measurement, manifest: &Manifest, scale: f64) {
    let with_point = !manifest.points.is_empty();
    for shot in 0..m.n_shots {
        for (f, hz) in m.freqs_hz.iter().enumerate() {
            for (p, &pi) in m.points.iter().enumerate() {
                let x = m.amplitude(shot, f, p) / scale;
                if let Some(k) = step {
                    let _ = write!(s, "{k},");
                }
                if with_point {
                    let _ = write!(
                        s,
                        "{shot},{hz:?},{},{:e},{:e}",
                        manifest.points[pi].name, x.re, x.im
                    );
                } else {
                    let _ = write!(s, "{shot},{hz:?},{:e},{:e}", x.re, x.im);
                }
                if let Some(n) = &m.noise {
                    let i = f * m.points.len() + p;
                    let _ = write!(s, ",{:e},{}", n.std[i] / scale, n.samples[i]);
                }
                s.push('\n');
            }
        }
    }
}
