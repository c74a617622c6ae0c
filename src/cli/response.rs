//! `harmonid response MODEL --values V [--drives q1:HZ --force q1=F] [--pump HZ:LEVEL[:PHASE]]
//! --probe q1 --from HZ --to HZ`: the linear response of every mode to a weak probe tone about
//! the drive ramp's steady state (at rest without drives), its idler, and the noise spectrum
//! under white force noise, as CSV.

use super::simulate::numeric_model;
use harmonid_sim::{self as sim, Excitation, HbSettings, NumericModel, PumpTone, SteadyState};
use miette::{miette, IntoDiagnostic};
use num_complex::Complex64;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Most probe frequencies.
const MAX_POINTS: usize = 100_000;

/// Arguments of `harmonid response`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model file (`*.hb`).
    pub model: PathBuf,
    /// Parameter values (TOML or an identification result JSON), as for `harmonid simulate`.
    #[arg(long)]
    pub values: PathBuf,
    /// Drive tones on a mode, `MODE:HZ[,HZ...]`; repeat for several modes. Without drives the
    /// response is the one about rest.
    #[arg(long = "drives", value_name = "MODE:HZ[,HZ]")]
    pub drives: Vec<String>,
    /// Force of each of a mode's drive tones, N/kg (peak), as `MODE=AMPLITUDE`; one per mode
    /// named in --drives.
    #[arg(long = "force", value_name = "MODE=N_PER_KG")]
    pub force: Vec<String>,
    /// A pump tone (the model's `pump` signal), `HZ:LEVEL[:PHASE_RAD]`; repeat for several.
    #[arg(long = "pump", value_name = "HZ:LEVEL[:PHASE_RAD]")]
    pub pump: Vec<String>,
    /// The mode the probe tone drives.
    #[arg(long)]
    pub probe: String,
    /// Force of the probe tone, N/kg (peak): the amplitudes scale with it (the response is
    /// linear in it), the noise spectrum does not.
    #[arg(long = "probe-force", default_value_t = 1.0)]
    pub probe_force: f64,
    /// First probe frequency, Hz.
    #[arg(long)]
    pub from: f64,
    /// Last probe frequency, Hz (above --from).
    #[arg(long)]
    pub to: f64,
    /// Number of probe frequencies, evenly spaced.
    #[arg(long, default_value_t = 1000)]
    pub points: usize,
    /// One-sided PSD of a white force noise on every mode, (N/kg)²/Hz: adds each mode's
    /// displacement PSD at the probe frequency, m²/Hz.
    #[arg(long = "noise-psd", value_name = "S_F")]
    pub noise_psd: Option<f64>,
    /// Output CSV (stdout when absent).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let inputs = [args.model.as_path(), args.values.as_path()];
    if let Some(out) = &args.out {
        super::common::check_outputs(&[out.as_path()], &inputs)?;
    }
    check_range(&args)?;
    let model = numeric_model(&args.model, &args.values)?;
    let probe = mode_index(&model, &args.probe, "--probe")?;
    let pumps = args
        .pump
        .iter()
        .map(|p| super::sweep_pumped::parse_pump(p))
        .collect::<miette::Result<Vec<_>>>()?;
    let drive = excitation(&model, &args, &pumps)?;
    let state = match &drive {
        Some(d) => Some(driven_state(&model, d)?),
        None => {
            rest_note(&model, &pumps);
            None
        }
    };
    let n = args.points;
    let f: Vec<f64> = (0..n)
        .map(|i| args.from + (args.to - args.from) * i as f64 / (n - 1) as f64)
        .collect();
    let pb = super::progress::spinner("linear response");
    let r = sim::probe_response(
        &model,
        state.as_ref(),
        &pumps,
        probe,
        &f,
        Complex64::new(args.probe_force, 0.0),
        args.noise_psd.is_some(),
    );
    pb.finish_and_clear();
    let r = r.into_diagnostic()?;
    let csv = to_csv(
        &model,
        &r,
        idler_offset(drive.as_ref(), &pumps),
        args.noise_psd,
    );
    match &args.out {
        Some(p) => super::common::write_output(p, csv.as_bytes(), &inputs),
        None => {
            use std::io::Write;
            let _ = std::io::stdout().lock().write_all(csv.as_bytes());
            Ok(())
        }
    }
}

/// Refuses a bad range, point count, probe force or noise PSD before any work.
fn check_range(args: &Args) -> miette::Result<()> {
    for (what, v) in [("--from", args.from), ("--to", args.to)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(miette!(
                "{what} {v}: expected a finite positive frequency in Hz"
            ));
        }
    }
    if args.from >= args.to {
        return Err(miette!(
            help = "give --from below --to, e.g. --from 990 --to 1010",
            "--from {} Hz is not below --to {} Hz",
            args.from,
            args.to
        ));
    }
    if !(2..=MAX_POINTS).contains(&args.points) {
        return Err(miette!(
            "--points {}: expected between 2 and {MAX_POINTS}",
            args.points
        ));
    }
    if !(args.probe_force.is_finite() && args.probe_force != 0.0) {
        return Err(miette!(
            "--probe-force {}: expected a finite non-zero force in N/kg",
            args.probe_force
        ));
    }
    if let Some(s) = args.noise_psd {
        if !(s.is_finite() && s > 0.0) {
            return Err(miette!(
                "--noise-psd {s}: expected a finite positive one-sided PSD in (N/kg)^2/Hz"
            ));
        }
    }
    Ok(())
}

/// Index of the mode `name`, or an error naming `option` and the model's modes.
fn mode_index(model: &NumericModel, name: &str, option: &str) -> miette::Result<usize> {
    model
        .mode_names
        .iter()
        .position(|m| m == name.trim())
        .ok_or_else(|| {
            miette!(
                "{option} {name}: `{}` is not a mode of the model ({})",
                name.trim(),
                model.mode_names.join(", ")
            )
        })
}

/// The drive of `--drives`/`--force` (and the pumps), `None` without drives.
fn excitation(
    model: &NumericModel,
    args: &Args,
    pumps: &[PumpTone],
) -> miette::Result<Option<Excitation>> {
    let nm = model.n_modes();
    let mut force = vec![None; nm];
    for s in &args.force {
        let (n, a) = super::common::force_entry(model, s)?;
        force[n] = Some(a);
    }
    let mut tones: Vec<f64> = Vec::new();
    let mut on: Vec<(usize, usize)> = Vec::new();
    for s in &args.drives {
        let (m, list) = s.split_once(':').ok_or_else(|| {
            miette!(
                help = "write MODE:HZ[,HZ...], e.g. --drives q1:1008",
                "cannot read --drives `{s}`"
            )
        })?;
        let n = mode_index(model, m, "--drives")?;
        if force[n].is_none() {
            return Err(miette!(
                help = format!("add --force {}=N_PER_KG", m.trim()),
                "--drives {s}: no --force on {}",
                m.trim()
            ));
        }
        for t in list.split(',') {
            let hz: f64 = t
                .trim()
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite() && *x > 0.0)
                .ok_or_else(|| miette!("--drives {s}: `{t}` is not a positive frequency in Hz"))?;
            let d = match tones.iter().position(|&x| (x - hz).abs() <= 1e-9 * hz) {
                Some(d) => d,
                None => {
                    tones.push(hz);
                    tones.len() - 1
                }
            };
            on.push((n, d));
        }
    }
    if tones.is_empty() {
        if !args.force.is_empty() {
            return Err(miette!(
                help = "add --drives MODE:HZ, e.g. --drives q1:1008",
                "--force given without --drives: at which frequency?"
            ));
        }
        return Ok(None);
    }
    let mut f = vec![vec![Complex64::new(0.0, 0.0); tones.len()]; nm];
    for (n, d) in on {
        f[n][d] = Complex64::new(force[n].unwrap_or(0.0), 0.0);
    }
    Ok(Some(Excitation {
        tones_hz: tones,
        force: f,
        pumps: pumps.to_vec(),
    }))
}

/// The drive ramp's steady state (as `harmonid simulate` solves it), with a note when it is
/// unstable (its response then describes no state the resonator stays in).
fn driven_state(model: &NumericModel, drive: &Excitation) -> miette::Result<SteadyState> {
    let pb = super::progress::spinner("steady state");
    let st = sim::steady_state(model, drive, &HbSettings::default());
    pb.finish_and_clear();
    let st = st.into_diagnostic()?;
    if !st.converged() {
        return Err(miette!(
            help = "lower the force or move the drive off the fold",
            "the drive ramp found no steady state ({}): no state to probe",
            st.status
        ));
    }
    match sim::check_stability(model, drive, &st) {
        Ok(s) if !s.stable => eprintln!(
            "note: the steady state is unstable (growth rate {:.3e} 1/s): its response is that of a state the resonator leaves",
            s.growth_rate
        ),
        Ok(_) => {}
        Err(e) => eprintln!("note: no stability verdict for the steady state: {e}"),
    }
    Ok(st)
}

/// Says when rest is not a state the resonator stays in: a mode with non-positive net
/// damping (self-excited).
fn rest_note(model: &NumericModel, pumps: &[PumpTone]) {
    for n in 0..model.n_modes() {
        let g = model.net_linear_damping(n);
        if g <= 0.0 {
            eprintln!(
                "note: {} has a net linear damping of {g:.3e} 1/s: rest is unstable, its response is that of a state the resonator leaves",
                model.mode_names[n]
            );
        }
    }
    if !pumps.is_empty() && model.has_pump_terms() {
        eprintln!("note: the response about rest under the pump; above the parametric threshold rest is unstable (see harmonid sweep --pump)");
    }
}

/// Offset of the idler line reported beside the probe's, Hz: `−f_pump` under a pump (the idler
/// at `f_pump − f_p`), else `−2 f_d` of the first drive tone (at `2f_d − f_p`); `None` at rest.
fn idler_offset(drive: Option<&Excitation>, pumps: &[PumpTone]) -> Option<f64> {
    if let Some(p) = pumps.first() {
        return Some(-p.hz);
    }
    drive.and_then(|d| d.tones_hz.first()).map(|&f| -2.0 * f)
}

/// The CSV: `f_probe_hz`, `f_idler_hz` (with an idler), then per mode the signal's and the
/// idler's |X| (m) and phase (rad, of the physical line: an idler below zero conjugated), then
/// per mode the noise PSD (m²/Hz) when asked.
fn to_csv(
    model: &NumericModel,
    r: &sim::ProbeResponse,
    idler: Option<f64>,
    noise: Option<f64>,
) -> String {
    let j_idler = idler.and_then(|o| r.line(o));
    let mut csv = String::from("f_probe_hz");
    if j_idler.is_some() {
        csv.push_str(",f_idler_hz");
    }
    for n in &model.mode_names {
        let _ = write!(csv, ",{n}_signal_abs_m,{n}_signal_phase_rad");
        if j_idler.is_some() {
            let _ = write!(csv, ",{n}_idler_abs_m,{n}_idler_phase_rad");
        }
    }
    if noise.is_some() {
        for n in &model.mode_names {
            let _ = write!(csv, ",{n}_noise_psd_m2_per_hz");
        }
    }
    csv.push('\n');
    for (i, f) in r.probe_hz.iter().enumerate() {
        let _ = write!(csv, "{f:.9}");
        if let Some(j) = j_idler {
            let _ = write!(csv, ",{:.9}", r.physical(i, 0, j).0);
        }
        for n in 0..model.n_modes() {
            let x = r.amplitudes[i][n][0];
            let _ = write!(csv, ",{:e},{:.9}", x.norm(), x.arg());
            if let Some(j) = j_idler {
                let (_, y) = r.physical(i, n, j);
                let _ = write!(csv, ",{:e},{:.9}", y.norm(), y.arg());
            }
        }
        if let (Some(s), Some(psd)) = (noise, &r.noise_psd) {
            for v in &psd[i] {
                let _ = write!(csv, ",{:e}", v * s);
            }
        }
        csv.push('\n');
    }
    csv
}
