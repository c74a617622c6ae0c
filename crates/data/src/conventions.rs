//! The conventions an import applies to an instrument's numbers and the manifest's `[import]`
//! table that records them. Both the dataset (which reads and writes that table) and
//! `import` (which applies the conventions) use these types; they live here, below both, so
//! neither module has to import the other's.

use num_complex::Complex64;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// One spelling per convention value, the manifest's (serde) one: `name()` and `FromStr`, so
/// the command line, Python and the `[import]` table read and write the same words.
macro_rules! spellings {
    ($t:ty { $($v:ident => $n:literal),+ $(,)? }) => {
        impl $t {
            /// The value's spelling, as the manifest writes it.
            pub fn name(self) -> &'static str {
                match self {
                    $(Self::$v => $n,)+
                }
            }
        }

        impl std::str::FromStr for $t {
            /// What was expected, for a message that names the option.
            type Err = String;

            fn from_str(s: &str) -> Result<Self, String> {
                match s {
                    $($n => Ok(Self::$v),)+
                    _ => Err(format!(
                        "\"{s}\": expected {}",
                        [$(concat!("\"", $n, "\"")),+].join(" or ")
                    )),
                }
            }
        }
    };
}

/// Peak or RMS amplitudes in the file. harmonid's amplitudes are peak.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Amplitude {
    /// The file's X, Y (or R) are peak amplitudes.
    Peak,
    /// RMS: multiplied by √2.
    Rms,
}

/// The sign of the file's quadrature against harmonid's `Re[X e^{+i2πft}]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Quadrature {
    /// `X = x + i·y` (a weakly driven mode's phase falls through −π/2 going up in frequency).
    #[serde(rename = "x+iy")]
    XPlusIY,
    /// `X = x − i·y` (the file's phase rises through a resonance).
    #[serde(rename = "x-iy")]
    XMinusIY,
}

/// What the sensor measured; harmonid wants displacement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Response {
    /// Displacement (or a signal proportional to it).
    Displacement,
    /// Velocity: divided by `i·2πf`.
    Velocity,
    /// Acceleration: divided by `−(2πf)²` (so its phase shifts by π).
    Acceleration,
}

/// The unit of an angle in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PhaseUnit {
    /// Radians.
    Rad,
    /// Degrees.
    Deg,
    /// Cycles (Moku's "1 V per cycle").
    Cycles,
}

spellings!(Amplitude { Peak => "peak", Rms => "rms" });
spellings!(Quadrature { XPlusIY => "x+iy", XMinusIY => "x-iy" });
spellings!(Response {
    Displacement => "displacement",
    Velocity => "velocity",
    Acceleration => "acceleration",
});
spellings!(PhaseUnit { Rad => "rad", Deg => "deg", Cycles => "cycles" });

impl PhaseUnit {
    /// `x` in this unit, in radians.
    pub fn to_rad(self, x: f64) -> f64 {
        match self {
            PhaseUnit::Rad => x,
            PhaseUnit::Deg => x.to_radians(),
            PhaseUnit::Cycles => 2.0 * PI * x,
        }
    }
}

/// Every convention that turns a file's numbers into harmonid's: none has a default, so a
/// missing one is an error naming its option.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Conventions {
    /// Peak or RMS.
    pub amplitude: Amplitude,
    /// `x+iy` or `x-iy`.
    pub quadrature: Quadrature,
    /// What was sensed (default displacement).
    #[serde(default = "displacement")]
    pub response: Response,
    /// Metres of displacement per unit of the file (after the response conversion), or absent
    /// with `displacement_unit = "V"`: the dataset keeps the instrument's unit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metres_per_unit: Option<f64>,
    /// `"m"` (with `metres_per_unit`) or `"V"` (no sensor calibration: every result in volts).
    pub displacement_unit: String,
    /// Unit of the file's phase columns (required when there are any).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub phase_unit: Option<PhaseUnit>,
    /// Hz per unit of the file's frequency column (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frequency_scale: Option<f64>,
}

fn displacement() -> Response {
    Response::Displacement
}

impl Conventions {
    /// The file's complex amplitude `z` at `f_hz` as harmonid's peak displacement in the
    /// dataset's unit.
    pub fn apply(&self, z: Complex64, f_hz: f64) -> Complex64 {
        let mut x = match self.quadrature {
            Quadrature::XPlusIY => z,
            Quadrature::XMinusIY => z.conj(),
        };
        if self.amplitude == Amplitude::Rms {
            x *= std::f64::consts::SQRT_2;
        }
        let w = 2.0 * PI * f_hz;
        x = match self.response {
            Response::Displacement => x,
            Response::Velocity => x / Complex64::new(0.0, w),
            Response::Acceleration => x / -(w * w),
        };
        x * self.metres_per_unit.unwrap_or(1.0)
    }
}

/// Which samples of a step are the response settling after the step: dropped.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Settle {
    /// Samples less than this many seconds after the step's first sample.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settle_s: Option<f64>,
    /// The first this many samples of each step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settle_samples: Option<usize>,
}

/// What `harmonid import` assumed, as the manifest's `[import]` table records it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImportRecord {
    /// The format name (`table`, `zi-csv`, ...).
    pub format: String,
    /// The input files, as given.
    pub inputs: Vec<String>,
    /// The conventions applied.
    pub conventions: Conventions,
    /// The settling rule applied.
    #[serde(default)]
    pub settle: Settle,
    /// Samples dropped as settling, of all read.
    pub settling_dropped: usize,
    /// Samples read.
    pub samples_read: usize,
    /// The format's own settings that were applied (a Moku's channel assignment, output gain
    /// and offset, where the demodulation frequency came from; a LabOne clock base).
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub instrument: std::collections::BTreeMap<String, String>,
}
