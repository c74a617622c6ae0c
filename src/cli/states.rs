//! `harmonid states MODEL --values V --drive HZ --force q1=F [--pump HZ:LEVEL[:PHASE]]`: every
//! steady state at one point of parameters (`harmonid_explore::states`), each with its
//! amplitudes, stability, slow-flow eigenvalues and whether it continued onto the full lattice.

use super::simulate::numeric_model;
use harmonid_explore::{unstable_through_complex_pair, Continued, States, StatesSettings};
use harmonid_sim::{Excitation, NumericModel};
use miette::miette;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Arguments of `harmonid states`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model file (`*.hb`).
    pub model: PathBuf,
    /// Parameter values (TOML or an identification result JSON), as for `harmonid simulate`.
    #[arg(long)]
    pub values: PathBuf,
    /// The drive tone, its forces and a pump.
    #[command(flatten)]
    pub excitation: ExcitationArgs,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// The single-harmonic states only (no continuation onto the harmonic lattice).
    #[arg(long)]
    pub single_harmonic: bool,
}

/// The excitation arguments `harmonid states` and `harmonid phase-diagram` share: one drive
/// tone with its forces, and a pump. The help here is `states`' (`phase-diagram` rewords three
/// lines for its axes with `mut_arg`).
#[derive(Debug, clap::Args)]
pub struct ExcitationArgs {
    /// The drive tone, Hz (`--drives q1:HZ` is read the same, the mode before the colon
    /// ignored: the forces name the modes).
    #[arg(long = "drive", alias = "drives", value_name = "HZ")]
    pub drive: Option<String>,
    /// Force of the tone on a mode, N/kg (peak), as `mode=amplitude`; repeat for several modes.
    #[arg(long = "force", value_name = "MODE=N_PER_KG")]
    pub force: Vec<String>,
    /// A pump tone, `HZ:LEVEL[:PHASE_RAD]` (the model's `pump` signal); with a drive, at twice
    /// the drive tone.
    #[arg(long = "pump", value_name = "HZ:LEVEL[:PHASE_RAD]")]
    pub pump: Option<String>,
}

/// The excitation of `--drive`, `--force`, `--pump`: a tone with its forces (N/kg, peak), a
/// pump, or both.
pub fn excitation(model: &NumericModel, args: &ExcitationArgs) -> miette::Result<Excitation> {
    let (drive, pump) = (args.drive.as_deref(), args.pump.as_deref());
    let forces = super::common::forces(model, &args.force)?;
    let pumps = match pump {
        Some(p) => vec![super::sweep_pumped::parse_pump(p)?],
        None => Vec::new(),
    };
    if !pumps.is_empty() && !model.has_pump_terms() {
        return Err(miette!(
            help = "add the term the pump modulates (e.g. `eom q1 += lambda*pump*q1`), or leave out --pump",
            "--pump: the model has no pump terms, so the pump would act on nothing"
        ));
    }
    let hz = match drive {
        Some(d) => {
            let t = d.rsplit(':').next().unwrap_or(d).trim();
            let hz: f64 = t.parse().ok().filter(|f: &f64| f.is_finite() && *f > 0.0).ok_or_else(|| {
                miette!("--drive {d}: `{t}` is not a positive frequency in Hz (e.g. --drive 1003.5)")
            })?;
            Some(hz)
        }
        None => None,
    };
    match hz {
        Some(hz) => Ok(Excitation {
            tones_hz: vec![hz],
            force: forces.iter().map(|&f| vec![f]).collect(),
            pumps,
        }),
        None if !pumps.is_empty() => {
            if forces.iter().any(|f| f.norm() > 0.0) {
                return Err(miette!(
                    "--force without --drive: give the drive tone (--drive HZ)"
                ));
            }
            Ok(Excitation {
                tones_hz: vec![],
                force: vec![vec![]; model.n_modes()],
                pumps,
            })
        }
        None => Err(miette!(
            help = "give --drive HZ with --force MODE=N, or --pump HZ:LEVEL for a pumped model",
            "no excitation: a steady state needs a drive tone or a pump"
        )),
    }
}

/// Runs the subcommand.
pub fn run(args: Args) -> miette::Result<()> {
    let model = numeric_model(&args.model, &args.values)?;
    let drive = excitation(&model, &args.excitation)?;
    let settings = StatesSettings {
        lattice: !args.single_harmonic,
        ..StatesSettings::default()
    };
    let pb = super::progress::spinner("tracking every solution");
    let s = harmonid_explore::states(&model, &drive, &settings);
    pb.finish_and_clear();
    let s = s.map_err(miette::Report::new)?;
    let text = if args.json {
        json(&model, &s)
    } else {
        table(&model, &s)
    };
    super::common::print_out(format_args!("{text}"));
    Ok(())
}

/// The lattice column: `yes`, `yes (stable)`, `same as 2`, `no: why`.
fn lattice_text(c: &Continued) -> String {
    match c {
        Continued::NotAsked => "-".into(),
        Continued::Yes { same_as: Some(k), .. } => format!("same lattice state as {}", k + 1),
        Continued::Yes { stable, growth_rate, shift, state, .. } => format!(
            "yes ({} lines), {}, growth {growth_rate:.3e} /s, the tone's line moved by {shift:.1e} of itself",
            state.lattice_hz.len(),
            if *stable { "stable" } else { "unstable" }
        ),
        Continued::No { why } => format!("NOT continued: {why}"),
    }
}

fn table(model: &NumericModel, s: &States) -> String {
    let mut t = String::new();
    let _ = writeln!(
        t,
        "{} steady states at {} Hz ({} stable); {} paths tracked, {} finite complex solutions, {} at infinity, {} failed",
        s.states.len(),
        s.tone_hz,
        s.states.iter().filter(|x| x.stable).count(),
        s.paths,
        s.complex_solutions,
        s.at_infinity,
        s.failed
    );
    for (i, st) in s.states.iter().enumerate() {
        let verdict = if st.stable {
            "stable"
        } else if unstable_through_complex_pair(model, &st.eigenvalues) {
            "UNSTABLE through a complex pair (oscillatory, Hopf type: a self-oscillation grows beside the drive)"
        } else {
            "UNSTABLE through a real eigenvalue (a saddle)"
        };
        let _ = writeln!(t, "state {}: {verdict}", i + 1);
        for (n, x) in st.amplitudes.iter().enumerate() {
            let _ = writeln!(
                t,
                "  {}: |X| = {:.6e} m, phase {:.6} rad",
                model.mode_names[n],
                x.norm(),
                x.arg()
            );
        }
        let eig: Vec<String> = st
            .eigenvalues
            .iter()
            .map(|z| format!("{:.4e}{:+.4e}i", z.re, z.im))
            .collect();
        let _ = writeln!(t, "  slow-flow eigenvalues (1/s): {}", eig.join(", "));
        let _ = writeln!(t, "  on the lattice: {}", lattice_text(&st.lattice));
        if let Continued::Yes {
            eigenvalues,
            same_as: None,
            ..
        } = &st.lattice
        {
            let eig: Vec<String> = eigenvalues
                .iter()
                .map(|z| format!("{:.4e}{:+.4e}i", z.re, z.im))
                .collect();
            let _ = writeln!(
                t,
                "  slow-flow eigenvalues on the lattice (1/s): {}",
                eig.join(", ")
            );
        }
    }
    t
}

fn json(model: &NumericModel, s: &States) -> String {
    use serde_json::json;
    let states: Vec<_> = s
        .states
        .iter()
        .map(|st| {
            let amps: serde_json::Map<String, serde_json::Value> = st
                .amplitudes
                .iter()
                .enumerate()
                .map(|(n, x)| (model.mode_names[n].clone(), json!({"re": x.re, "im": x.im, "abs": x.norm(), "phase_rad": x.arg()})))
                .collect();
            let lattice = match &st.lattice {
                Continued::NotAsked => json!(null),
                Continued::Yes { stable, growth_rate, eigenvalues, shift, same_as, .. } => {
                    let eig: Vec<[f64; 2]> = eigenvalues.iter().map(|z| [z.re, z.im]).collect();
                    json!({"continued": true, "stable": stable, "growth_rate": growth_rate, "eigenvalues": eig, "shift": shift, "same_as": same_as})
                }
                Continued::No { why } => json!({"continued": false, "why": why}),
            };
            json!({
                "amplitudes": amps,
                "stable": st.stable,
                "oscillatory": unstable_through_complex_pair(model, &st.eigenvalues),
                "eigenvalues": st.eigenvalues.iter().map(|z| [z.re, z.im]).collect::<Vec<_>>(),
                "lattice": lattice,
            })
        })
        .collect();
    let v = json!({
        "tone_hz": s.tone_hz,
        "paths": s.paths,
        "complex_solutions": s.complex_solutions,
        "at_infinity": s.at_infinity,
        "failed": s.failed,
        "states": states,
    });
    serde_json::to_string_pretty(&v).unwrap_or_default() + "\n"
}
