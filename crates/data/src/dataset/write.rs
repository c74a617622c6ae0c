//! Writing a measurement's CSV text.

use super::*;

pub(super) fn csv_text(m: &Measurement, manifest: &Manifest, scale: f64) -> String {
    let with_point = !manifest.points.is_empty();
    let mut s = String::new();
    s.push_str(if with_point {
        "shot,freq_hz,point,re,im\n"
    } else {
        "shot,freq_hz,re,im\n"
    });
    for shot in 0..m.n_shots {
        for (f, hz) in m.freqs_hz.iter().enumerate() {
            for (p, &pi) in m.points.iter().enumerate() {
                let x = m.amplitude(shot, f, p) / scale;
                if with_point {
                    let _ = writeln!(
                        s,
                        "{shot},{hz:?},{},{:e},{:e}",
                        manifest.points[pi].name, x.re, x.im
                    );
                } else {
                    let _ = writeln!(s, "{shot},{hz:?},{:e},{:e}", x.re, x.im);
                }
            }
        }
    }
    s
}

/// A sweep's CSV text: its steps' rows, with the `step` column.
pub(super) fn sweep_csv_text(steps: &[&Measurement], manifest: &Manifest, scale: f64) -> String {
    let with_point = !manifest.points.is_empty();
    let mut s = String::new();
    s.push_str(if with_point {
        "step,shot,freq_hz,point,re,im\n"
    } else {
        "step,shot,freq_hz,re,im\n"
    });
    for (k, m) in steps.iter().enumerate() {
        for shot in 0..m.n_shots {
            for (f, hz) in m.freqs_hz.iter().enumerate() {
                for (p, &pi) in m.points.iter().enumerate() {
                    let x = m.amplitude(shot, f, p) / scale;
                    if with_point {
                        let _ = writeln!(
                            s,
                            "{k},{shot},{hz:?},{},{:e},{:e}",
                            manifest.points[pi].name, x.re, x.im
                        );
                    } else {
                        let _ = writeln!(s, "{k},{shot},{hz:?},{:e},{:e}", x.re, x.im);
                    }
                }
            }
        }
    }
    s
}
