//! What the import tests share: the conventions of their small files (RMS volts, x + iy), a
//! file writer and a LabOne demodulator record of given drive frequencies and responses.

use harmonid_data::import::{Amplitude, Conventions, Quadrature, Response};
use num_complex::Complex64;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// RMS volts, `x + iy`, a displacement response in the lock-in's unit.
pub fn conv() -> Conventions {
    Conventions {
        amplitude: Amplitude::Rms,
        quadrature: Quadrature::XPlusIY,
        response: Response::Displacement,
        metres_per_unit: None,
        displacement_unit: "V".into(),
        phase_unit: None,
        frequency_scale: None,
    }
}

/// `text` written to `dir/name`; its path.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p
}

/// A LabOne demodulator record (`;`-separated, one sample a row, 60 clock ticks apart) of the
/// drive frequencies `drives`, row `k`'s response `value(k)`.
pub fn zi_csv_record(drives: &[f64], value: impl Fn(usize) -> Complex64) -> String {
    let mut s = String::from("chunk;timestamp;x;y;freq;phase;dio;trigger;auxin0;auxin1\n");
    for (k, &f) in drives.iter().enumerate() {
        let z = value(k);
        let _ = writeln!(
            s,
            "0;{};{:e};{:e};{f:?};0;0;0;0;0",
            1000 + 60 * k,
            z.re,
            z.im
        );
    }
    s
}
