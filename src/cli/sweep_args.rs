//! The arguments of `harmonid sweep`, read by both of its runs: the curve with continuation
//! (`sweep`) and the stepped sweep of a pumped model (`sweep_pumped`). They live here, below
//! both, so that `sweep` (which hands a pumped sweep over) is the only one that names the other.

use std::path::PathBuf;

/// Arguments of `harmonid sweep`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model file (`*.hb`).
    pub model: PathBuf,
    /// Parameter values (TOML or an identification result JSON), as for `harmonid simulate`.
    #[arg(long)]
    pub values: PathBuf,
    /// Start of the sweep, Hz.
    #[arg(long)]
    pub from: f64,
    /// End of the sweep, Hz (below `--from` for a curve followed downwards).
    #[arg(long)]
    pub to: f64,
    /// Force of the tone on a mode, N/kg (peak), as `mode=amplitude`; repeat for several modes.
    #[arg(long = "force", value_name = "MODE=N_PER_KG", required = true)]
    pub force: Vec<String>,
    /// Resolution of the curve: consecutive points are at most `(to − from)/POINTS` apart in
    /// frequency, so the curve gets at least about POINTS + 1 points, more on steep flanks and
    /// around folds (at most 8 × POINTS). Two-tone mode: grid steps of the centre each way;
    /// with a pump: steps each way.
    #[arg(long, default_value_t = 2000)]
    pub points: usize,
    /// Highest harmonic of the tone kept.
    #[arg(long, default_value_t = 3)]
    pub harmonics: usize,
    /// Two-tone mode: sweep the centre of a tone pair `c ± SPACING_HZ/2` from `--from` to `--to`
    /// (each `--force` then applies to each tone `fa`, `fb`), up and down, with continuation; CSV
    /// columns `direction, centre_hz`, |X| and phase of each mode at its own lines, `stable`: a
    /// mode near the pair at `2fa-fb, fa, fb, 2fb-fa`, any other mode at the mixing products
    /// that reach its resonance (e.g. `2fa`, `fa+fb`, `2fb`).
    #[arg(long = "two-tone", value_name = "SPACING_HZ")]
    pub two_tone: Option<f64>,
    /// A pump tone (parametric pumping: the model's `pump` signal), as
    /// `HZ:LEVEL[:PHASE_RAD]`, level in the unit the model's pump coefficients are per; repeat
    /// for several. With a pump the tone is stepped up and then down through the range as a
    /// stepped-sine experiment does (`--points` steps each way); CSV columns `direction, f_hz`,
    /// |X| and phase of each mode at the tone `f`, at each pump's idler `f_p − f` and at its
    /// half `f_p/2` (the oscillation a pump above threshold sustains), `stable`, `converged`.
    #[arg(long = "pump", value_name = "HZ:LEVEL[:PHASE_RAD]")]
    pub pump: Vec<String>,
    /// From every Hopf point of the curve, continue the quasi-periodic branch (the drive plus
    /// a self-oscillation at a second base frequency `f2`, on the lines `k1 f + k2 f2`) in the
    /// drive frequency over the range, and write it to this CSV: `hopf, f_hz, f2_hz,
    /// offset_hz`, each mode's |X| at `f2`, `f` and `2f-f2` (m), `stable` (empty where not
    /// judged), `growth_per_s`.
    /// With `--plot` the branches are drawn too.
    #[arg(long = "limit-cycles", value_name = "FILE.csv")]
    pub limit_cycles: Option<PathBuf>,
    /// Output CSV (stdout when absent).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Also draw the response curve of the most strongly driven mode (stable solid, unstable
    /// dashed, jumps, backbone) to this file, `.svg` or `.png`.
    #[arg(long, value_name = "FILE.svg|png")]
    pub plot: Option<PathBuf>,
}
