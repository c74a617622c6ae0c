//! `harmonid import FORMAT INPUT… --out DIR`: instrument files into a dataset folder.

use clap::{Parser, ValueEnum};
use harmonid_data::import::{
    moku_csv, table, zi_csv, zi_hdf5, zi_sweeper, Amplitude, Conventions, ImportError, PhaseUnit,
    Quadrature, Response, Settle,
};
use miette::WrapErr;
use std::path::PathBuf;

/// The input formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// Any CSV/TSV/whitespace table or MATLAB v5/v7 file, with a mapping file (--map).
    Table,
    /// Zurich Instruments LabOne demodulator CSV (one file per demodulator, the drive's first).
    ZiCsv,
    /// Zurich Instruments LabOne HDF5 record (record groups 000, 001, … of demodulator samples).
    ZiHdf5,
    /// Zurich Instruments LabOne sweeper CSV (mean and standard deviation per point; one file
    /// per demodulator, the drive's first).
    ZiSweeper,
    /// Liquid Instruments Moku lock-in record converted to CSV (one file per frequency step).
    MokuCsv,
}

/// Import instrument files into a harmonid dataset folder.
#[derive(Debug, Parser)]
pub struct Args {
    /// The input format.
    #[arg(value_enum)]
    pub format: Format,
    /// Input files (table: one or more; zi-csv: one per demodulator, the drive's first;
    /// moku-csv: one per frequency step, in sweep order).
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// The dataset folder to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace --out even if it is a non-empty folder that is not a harmonid dataset (never a
    /// folder holding a model, values, plan or result file, or an input of this run).
    #[arg(long)]
    pub force: bool,
    /// table: the mapping file (columns, conventions, settling; docs/data-format.md).
    #[arg(long, value_name = "MAPPING.toml")]
    pub map: Option<PathBuf>,
    /// zi-csv, zi-hdf5, zi-sweeper, moku-csv: are the amplitudes peak or RMS? (not confirmed by the vendors: required)
    #[arg(long, value_enum)]
    pub amplitude: Option<AmplitudeArg>,
    /// zi-csv, zi-hdf5, zi-sweeper, moku-csv: x+iy (harmonid's convention) or x-iy (the file's phase rises through a
    /// resonance).
    #[arg(long, value_name = "x+iy|x-iy")]
    pub quadrature: Option<String>,
    /// zi-csv, zi-hdf5, zi-sweeper, moku-csv: what the sensor measured.
    #[arg(long, value_enum, default_value = "displacement")]
    pub response: ResponseArg,
    /// zi-csv, zi-hdf5, zi-sweeper, moku-csv: metres of displacement per volt; without it, --volts keeps volts.
    #[arg(long, value_name = "M_PER_V", conflicts_with = "volts")]
    pub metres_per_unit: Option<f64>,
    /// zi-csv, zi-hdf5, zi-sweeper, moku-csv: keep the instrument's volts (no sensor calibration; results in volts).
    #[arg(long)]
    pub volts: bool,
    /// zi-csv, zi-hdf5: device ticks per second (60e6 on the MFLI, 1.8e9 on the UHFLI).
    #[arg(long, value_name = "HZ")]
    pub clockbase_hz: Option<f64>,
    /// zi-csv, zi-hdf5, zi-sweeper, moku-csv: the drive's output level (V); without it, every step's force is free.
    #[arg(long, value_name = "V")]
    pub drive_level: Option<f64>,
    /// zi-csv, zi-hdf5, zi-sweeper, moku-csv: samples earlier than this after their step began are settling: dropped.
    #[arg(long, value_name = "S", conflicts_with = "settle_samples")]
    pub settle_s: Option<f64>,
    /// zi-csv, zi-hdf5, zi-sweeper, moku-csv: the first this many samples of each step are settling: dropped.
    #[arg(long, value_name = "N")]
    pub settle_samples: Option<usize>,
    /// zi-hdf5: the demodulators to read, the drive's first (default: every one, in number
    /// order).
    #[arg(long, value_name = "N,...", value_delimiter = ',')]
    pub demods: Vec<usize>,
    /// moku-csv: what channels 1 and 2 carry (the file does not say).
    #[arg(long, value_enum)]
    pub channels: Option<ChannelsArg>,
    /// moku-csv: the lock-in output gain (V per V; 1 for 0 dB), divided out.
    #[arg(long, value_name = "V_PER_V")]
    pub output_gain: Option<f64>,
    /// moku-csv: the lock-in output offset (V), subtracted.
    #[arg(long, value_name = "V", default_value_t = 0.0)]
    pub output_offset: f64,
    /// moku-csv: unit of a Theta channel (the Moku writes 1 V per cycle).
    #[arg(long, value_enum)]
    pub phase_unit: Option<PhaseUnitArg>,
    /// moku-csv: the demodulation frequency of each file, Hz, comma-separated (default: each
    /// file's `% ... demodulation ... Hz` header line).
    #[arg(long, value_name = "HZ,...", value_delimiter = ',')]
    pub demod_hz: Vec<f64>,
    /// table, zi-sweeper: also drop rows where nothing was measured (every value NaN) inside a
    /// sweep, each run counted in a warning. Without it only those at a sweep's end (a sweep
    /// stopped early) are dropped, and one inside is refused with its row.
    #[arg(long)]
    pub drop_nan_rows: bool,
}

/// `--channels`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ChannelsArg {
    /// Channel 1 = X, channel 2 = Y.
    #[value(name = "x,y")]
    XY,
    /// Channel 1 = R, channel 2 = Theta.
    #[value(name = "r,theta")]
    RTheta,
}

/// `--phase-unit`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PhaseUnitArg {
    /// Radians.
    Rad,
    /// Degrees.
    Deg,
    /// Cycles.
    Cycles,
}

/// `--amplitude`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AmplitudeArg {
    /// Peak amplitudes.
    Peak,
    /// RMS amplitudes (multiplied by √2).
    Rms,
}

/// `--response`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ResponseArg {
    /// Displacement.
    Displacement,
    /// Velocity (divided by i·2πf).
    Velocity,
    /// Acceleration (divided by −(2πf)²).
    Acceleration,
}

/// The conventions the zi-csv flags give; a missing one is an error naming its flag.
fn conventions(args: &Args) -> Result<Conventions, ImportError> {
    let missing = |flag: &str, what: &str| ImportError::Convention {
        origin: flag.to_string(),
        message: format!("{what} is not in the file and is never guessed: give {flag}"),
    };
    let amplitude = match args
        .amplitude
        .ok_or_else(|| missing("--amplitude", "peak or RMS"))?
    {
        AmplitudeArg::Peak => Amplitude::Peak,
        AmplitudeArg::Rms => Amplitude::Rms,
    };
    let quadrature = args
        .quadrature
        .as_deref()
        .ok_or_else(|| missing("--quadrature", "the quadrature sign"))?
        .parse::<Quadrature>()
        .map_err(|message| ImportError::Convention {
            origin: "--quadrature".into(),
            message,
        })?;
    if args.metres_per_unit.is_none() && !args.volts {
        return Err(missing(
            "--metres-per-unit (or --volts)",
            "the sensor's volts-to-metres factor",
        ));
    }
    let conv = Conventions {
        amplitude,
        quadrature,
        response: match args.response {
            ResponseArg::Displacement => Response::Displacement,
            ResponseArg::Velocity => Response::Velocity,
            ResponseArg::Acceleration => Response::Acceleration,
        },
        metres_per_unit: args.metres_per_unit,
        displacement_unit: if args.volts { "V" } else { "m" }.into(),
        phase_unit: Some(PhaseUnit::Rad),
        frequency_scale: None,
    };
    conv.check("the options")?;
    Ok(conv)
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let mut inputs: Vec<&std::path::Path> = args.inputs.iter().map(|p| p.as_path()).collect();
    if let Some(m) = &args.map {
        inputs.push(m);
    }
    let opts = harmonid_files::DirWrite {
        force: args.force,
        inputs: &inputs,
    };
    harmonid_files::check_output_dir(&args.out, opts).map_err(miette::Report::new)?;
    let settle = Settle {
        settle_s: args.settle_s,
        settle_samples: args.settle_samples,
    };
    if args.drop_nan_rows && !matches!(args.format, Format::Table | Format::ZiSweeper) {
        return Err(miette::Report::new(ImportError::Convention {
            origin: "--drop-nan-rows".into(),
            message: "applies to table and zi-sweeper (a sweeper writes the points it never reached as NaN); a demodulator record or a Moku file with a NaN sample is refused with its row".into(),
        }));
    }
    let (ds, note) = match args.format {
        Format::Table => {
            let map = args.map.as_ref().ok_or_else(|| {
                miette::miette!("import table needs --map MAPPING.toml (the columns and conventions; docs/data-format.md)")
            })?;
            let mut mapping = table::Mapping::load(map).map_err(miette::Report::new)?;
            mapping.drop_nan_rows |= args.drop_nan_rows;
            table::import(&args.inputs, &mapping, &args.out)
        }
        Format::ZiCsv => conventions(&args).and_then(|conv| {
            let opts = zi_csv::Options {
                clockbase_hz: args.clockbase_hz.unwrap_or(f64::NAN),
                drive_level: args.drive_level,
                drive_phase_rad: None,
            };
            zi_csv::import(&args.inputs, &conv, settle, &opts, &args.out)
        }),
        Format::ZiHdf5 => conventions(&args).and_then(|conv| {
            let opts = zi_hdf5::Options {
                clockbase_hz: args.clockbase_hz.unwrap_or(f64::NAN),
                demods: args.demods.clone(),
                drive_level: args.drive_level,
            };
            zi_hdf5::import(&args.inputs, &conv, settle, &opts, &args.out)
        }),
        Format::ZiSweeper => conventions(&args).and_then(|conv| {
            if settle.settle_s.is_some() || settle.settle_samples.is_some() {
                return Err(ImportError::Convention {
                    origin: "--settle-s/--settle-samples".into(),
                    message: "the sweeper settles before it averages (its settling time is a sweeper setting): no samples to drop".into(),
                });
            }
            let opts = zi_sweeper::Options {
                drive_level: args.drive_level,
                drop_nan_rows: args.drop_nan_rows,
            };
            zi_sweeper::import(&args.inputs, &conv, &opts, &args.out)
        }),
        Format::MokuCsv => conventions(&args).and_then(|mut conv| {
            let missing = |flag: &str, what: &str| ImportError::Convention {
                origin: flag.into(),
                message: format!("{what} is not in the file and is never guessed: give {flag}"),
            };
            let opts = moku_csv::Options {
                channels: match args
                    .channels
                    .ok_or_else(|| missing("--channels", "what channels 1 and 2 carry"))?
                {
                    ChannelsArg::XY => moku_csv::Channels::XY,
                    ChannelsArg::RTheta => moku_csv::Channels::RTheta,
                },
                output_gain: args
                    .output_gain
                    .ok_or_else(|| missing("--output-gain", "the lock-in's output gain"))?,
                output_offset_v: args.output_offset,
                phase_unit: args.phase_unit.map(|u| match u {
                    PhaseUnitArg::Rad => PhaseUnit::Rad,
                    PhaseUnitArg::Deg => PhaseUnit::Deg,
                    PhaseUnitArg::Cycles => PhaseUnit::Cycles,
                }),
                demod_hz: args.demod_hz.clone(),
                drive_level: args.drive_level,
            };
            conv.phase_unit = opts.phase_unit;
            moku_csv::import(&args.inputs, &conv, settle, &opts, &args.out)
        }),
    }
    .map_err(miette::Report::new)?;
    ds.write_with(&args.out, opts)
        .map_err(miette::Report::new)
        .wrap_err_with(|| format!("cannot write the dataset {}", args.out.display()))?;
    // One line per run of rows dropped because nothing was measured there.
    for warning in &ds.notes {
        eprintln!("warning: {warning}");
    }
    eprintln!("note: {note}");
    eprintln!(
        "wrote {} ({} steps in {} sweeps)",
        args.out.display(),
        ds.measurements.len(),
        ds.manifest.sweeps.len()
    );
    Ok(())
}
