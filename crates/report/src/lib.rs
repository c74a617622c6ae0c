//! `harmonid report`: one self-contained HTML page about an identification.
//!
//! [`build`] identifies the model from the dataset (or takes a result already written by
//! `harmonid identify`), reconstructs every measured spectrum by harmonic balance from the
//! identified model, and draws the figures of the method's paper with [`harmonid_plot`]:
//! per measurement the measured spectrum with the reconstruction and the residuals; per
//! identified quantity the histogram of per-shot estimates; the potential matrix when the
//! model couples modes. [`Page::write`] writes `DIR/index.html` (figures inline as SVG, no
//! network) and every figure as SVG and PNG in `DIR/figures/`, through a staging folder renamed
//! into place, and never over a folder that is not a harmonid report.

#![warn(missing_docs)]

pub mod curves;
mod html;
pub mod plan;
pub mod potential;
pub mod response;
pub mod result;
pub mod spectra;

/// The file that marks a folder as a harmonid report (an existing `--out` folder is replaced
/// only when it holds this file, or is empty).
pub const MARKER: &str = ".harmonid-report";

use harmonid_data::Dataset;
use harmonid_ident::{Report, Settings};
use harmonid_model::Model;
use harmonid_plot::{Figure, FrequencyResponse, Histogram, PlotError, PotentialMatrix, Spectrum};
use harmonid_sim::NumericModel;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Errors of building or writing a report, each a diagnostic with a stable code.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
#[non_exhaustive]
pub enum ReportError {
    /// The identification could not be set up.
    #[error(transparent)]
    #[diagnostic(transparent)]
    Ident(#[from] harmonid_ident::IdentError),
    /// Writing the report (or refusing to write it there) failed.
    #[error(transparent)]
    #[diagnostic(transparent)]
    File(#[from] harmonid_files::FileError),
    /// A figure could not be drawn.
    #[error(transparent)]
    #[diagnostic(transparent)]
    Plot(#[from] PlotError),
    /// The output folder exists and is not a harmonid report.
    #[error("{} exists and is not a harmonid report (no {MARKER} in it); choose another --out or remove it yourself", path.display())]
    #[diagnostic(code(harmonid::report::clobber))]
    Clobber {
        /// The folder.
        path: PathBuf,
    },
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    #[diagnostic(code(harmonid::report::io))]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// Where the identified values come from.
#[derive(Debug, Clone)]
pub enum Source {
    /// Identify now with these settings (`harmonid_ident::identify`, as `harmonid identify`).
    Identify(Settings),
    /// A result already written by `harmonid identify` (its path, for the page), read with
    /// [`Report::from_json`]; it holds no per-shot estimates, so no histograms.
    Result(PathBuf, Box<Report>),
}

/// Any figure of the report.
#[derive(Debug, Clone)]
pub enum AnyFigure {
    /// A spectrum.
    Spectrum(Spectrum),
    /// A histogram.
    Histogram(Histogram),
    /// The potential matrix.
    Potential(PotentialMatrix),
    /// A stepped-sine frequency response.
    Response(FrequencyResponse),
}

impl Figure for AnyFigure {
    fn size(&self) -> (u32, u32) {
        match self {
            AnyFigure::Spectrum(f) => f.size(),
            AnyFigure::Histogram(f) => f.size(),
            AnyFigure::Potential(f) => f.size(),
            AnyFigure::Response(f) => f.size(),
        }
    }

    fn draw<DB: harmonid_plot::plotters::prelude::DrawingBackend>(
        &self,
        root: &harmonid_plot::plotters::prelude::DrawingArea<
            DB,
            harmonid_plot::plotters::coord::Shift,
        >,
    ) -> Result<(), PlotError> {
        match self {
            AnyFigure::Spectrum(f) => f.draw(root),
            AnyFigure::Histogram(f) => f.draw(root),
            AnyFigure::Potential(f) => f.draw(root),
            AnyFigure::Response(f) => f.draw(root),
        }
    }
}

/// One figure of the page: its file stem, caption, the figure and its SVG.
#[derive(Debug, Clone)]
pub struct PageFigure {
    /// File stem in `figures/` (`spectrum_single_q1_p0`).
    pub stem: String,
    /// Caption.
    pub caption: String,
    /// The figure (for the PNG).
    pub figure: AnyFigure,
    /// The SVG, as inlined in the page.
    pub svg: String,
}

/// A built report.
#[derive(Debug, Clone)]
pub struct Page {
    /// The HTML page.
    pub html: String,
    /// Its figures.
    pub figures: Vec<PageFigure>,
    /// Warnings (also on the page).
    pub warnings: Vec<String>,
}

/// A file-name-safe stem.
fn stem(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The largest measured modal amplitude of each mode (|median X| / shape near its resonance),
/// the scale of the potential maps, m.
fn amplitude_scale(ds: &Dataset, names: &[String], f_hz: &[f64]) -> Vec<f64> {
    names
        .iter()
        .zip(f_hz)
        .map(|(n, &fnn)| {
            let mut a: f64 = 0.0;
            for m in &ds.measurements {
                for (fi, &f) in m.freqs_hz.iter().enumerate() {
                    if (f - fnn).abs() > 0.01 * fnn {
                        continue;
                    }
                    for (p, &pi) in m.points.iter().enumerate() {
                        let shape = ds.manifest.points.get(pi).map_or(1.0, |pt| pt.shape_of(n));
                        if shape.abs() > 1e-3 {
                            a = a.max(m.amplitude(0, fi, p).norm() / shape.abs());
                        }
                    }
                }
            }
            if a > 0.0 {
                a
            } else {
                1e-9
            }
        })
        .collect()
}

/// A figure with its file stem and caption, before it is drawn.
type Captioned = (String, String, AnyFigure);

/// A quantity with per-shot estimates: name, unit, estimate, and the truth when known.
type Quantity<'a> = (String, String, &'a harmonid_ident::Estimate, Option<f64>);

/// Builds the report of `model` (read from `model_path`) on `ds`.
pub fn build(
    model_path: &Path,
    model: &Model,
    ds: &Dataset,
    source: Source,
) -> Result<Page, ReportError> {
    let (result, result_from) = result_of(model_path, model, ds, source)?;
    let mut warnings = result.warnings.clone();
    let names: Vec<String> = model.mode_names().iter().map(|s| s.to_string()).collect();
    let identified = match NumericModel::from_values(&names, &result::model_values(&result)) {
        Ok(m) => Some(m),
        Err(e) => {
            warnings.push(format!(
                "no reconstruction: the identified model is incomplete ({e})"
            ));
            None
        }
    };
    let truth_model = truth_model(ds, &names);
    let mut figs = response_figures(ds, identified.as_ref(), &result, &mut warnings);
    figs.extend(spectrum_figures(
        ds,
        identified.as_ref(),
        &result,
        &mut warnings,
    ));
    let quantities = quantities(&result, ds);
    let no_shots = histogram_figures(&quantities, &mut figs);
    if !no_shots.is_empty() && result_from.is_some() {
        warnings.push(format!(
            "no histograms for {}: the result file holds no per-shot estimates (run the report without --result to identify and draw them)",
            no_shots.join(", ")
        ));
    }
    if let Some(idm) = identified.as_ref().filter(|m| potential::has_couplings(m)) {
        let q_max = amplitude_scale(ds, &names, &idm.f_hz);
        figs.push((
            "potential".into(),
            "The nonlinear potential U_nl over each pair of modal coordinates, the others at rest (the method's Fig. 5c): lower triangle identified, upper triangle the truth when truth.toml is present; the diagonal shows U_nl along one coordinate. Each coordinate spans ± its largest measured modal amplitude.".into(),
            AnyFigure::Potential(potential::matrix(idm, truth_model.as_ref(), &q_max)),
        ));
    }
    let figures = draw(figs)?;
    let html = html::page(&html::PageInputs {
        model_path,
        model,
        ds,
        result: &result,
        result_from: result_from.as_deref(),
        truth: ds.truth.as_ref(),
        figures: &figures,
        warnings: &warnings,
    });
    Ok(Page {
        html,
        figures,
        warnings,
    })
}

/// The result the report shows: identified now (named after `model_path`), or read from a
/// file (its path returned for the page).
fn result_of(
    model_path: &Path,
    model: &Model,
    ds: &Dataset,
    source: Source,
) -> Result<(Report, Option<PathBuf>), ReportError> {
    Ok(match source {
        Source::Identify(settings) => {
            let mut rep = harmonid_ident::identify(model, ds, &settings)?;
            rep.model = model_path.display().to_string();
            (rep, None)
        }
        Source::Result(path, rep) => (*rep, Some(path)),
    })
}

/// The model at the dataset's true values (`truth.toml`), when it has them and they make a
/// complete model: the potential map's upper triangle.
fn truth_model(ds: &Dataset, names: &[String]) -> Option<NumericModel> {
    ds.truth.as_ref().and_then(|t| {
        let mut v = harmonid_sim::ModelValues::default();
        for (n, m) in &t.modes {
            v.modes.insert(
                n.clone(),
                harmonid_sim::ModeValues {
                    f_hz: Some(m.f_hz),
                    q: Some(m.q),
                },
            );
        }
        v.eom.clone_from(&t.eom);
        NumericModel::from_values(names, &v).ok()
    })
}

/// Whether `m` is a step of a frequency sweep (drawn in a frequency-response figure, not as a
/// spectrum of its own).
fn in_frequency_sweep(ds: &Dataset, m: &harmonid_data::Measurement) -> bool {
    m.spec.sweep.as_ref().is_some_and(|st| {
        ds.manifest
            .sweeps
            .iter()
            .any(|s| s.name == st.sweep && response::is_frequency_sweep(s))
    })
}

/// The caption of a family's figure: what is drawn, and how well the model meets the steps.
fn response_caption(r: &response::FamilyResponse) -> String {
    let (mut num2, mut den2) = (0.0, 0.0);
    for s in &r.sweeps {
        if let Some(mx) = &s.model {
            num2 +=
                s.x.iter()
                    .zip(mx)
                    .map(|(a, b)| (a - b).norm_sqr())
                    .sum::<f64>();
            den2 += s.x.iter().map(|a| a.norm_sqr()).sum::<f64>();
        }
    }
    let fit = if den2 > 0.0 {
        format!(
            " The model's steady state at each step (followed from step to step as the sweep was) differs from the measured X by {} % RMS of |X|.",
            harmonid_plot::style::num(100.0 * (num2 / den2).sqrt(), 2)
        )
    } else {
        String::new()
    };
    let model = match &r.model {
        Some(m) => format!(
            " Lines: the identified model's response at this drive by harmonic balance (harmonics of the drive up to {}, as the identification's lattice keeps them), continued through its folds: solid where stable, dashed where unstable; its force on the driven mode is {} N/kg (the identification's force of these steps: actuator gain × drive level, or the fitted force).",
            m.harmonics,
            harmonid_plot::style::num(m.force.iter().map(|z| z.norm()).fold(0.0, f64::max), 4)
        ),
        None => " No model curve.".into(),
    };
    let notes = if r.notes.is_empty() {
        String::new()
    } else {
        format!(" Note: {}.", r.notes.join("; "))
    };
    format!(
        "{}: the measured response at the drive frequency at {} (median over each step's shots; ▲ up-sweep, ▽ down-sweep, ● other order), in {}: amplitude |X| against the drive frequency (top left), phase of X against the step's identified force (bottom left: 0° far below a resonance, −90° at it), and the Nyquist view Re X against Im X (right).{model}{fit}{notes}",
        r.family.label, r.point, r.unit
    )
}

/// The frequency-response figures of the dataset's frequency sweeps: with more than one
/// family, an overview of every family first; then one figure per family. Families are
/// computed in parallel; a family without its model curve adds a warning.
fn response_figures(
    ds: &Dataset,
    identified: Option<&NumericModel>,
    result: &Report,
    warnings: &mut Vec<String>,
) -> Vec<Captioned> {
    let fams = response::families(ds);
    let rs: Vec<response::FamilyResponse> = fams
        .par_iter()
        .map(|f| response::family_response(identified, result, ds, f))
        .filter(|r| !r.sweeps.is_empty())
        .collect();
    let mut figs: Vec<Captioned> = Vec::new();
    if rs.len() > 1 {
        figs.push((
            "response_all".into(),
            format!(
                "Every drive level in one figure, one colour per level (dark: lowest), as in the per-level figures below: measured points (▲ up-sweep, ▽ down-sweep, ● other order) and the identified model's curves (solid stable, dashed unstable), in {}.",
                rs[0].unit
            ),
            AnyFigure::Response(response::overview(&rs)),
        ));
    }
    for r in &rs {
        if identified.is_some() && r.model.is_none() {
            warnings.extend(r.notes.iter().cloned());
        }
        figs.push((
            stem(&format!("response_{}", r.family.label)),
            response_caption(r),
            AnyFigure::Response(response::figure(r)),
        ));
    }
    figs
}

/// The spectrum figures, one per measurement and point, except the steps of frequency sweeps
/// (their figures are the frequency responses): one harmonic-balance solve per measurement,
/// in parallel; their warnings are added to `warnings` in measurement order.
fn spectrum_figures(
    ds: &Dataset,
    identified: Option<&NumericModel>,
    result: &Report,
    warnings: &mut Vec<String>,
) -> Vec<Captioned> {
    let shown: Vec<&harmonid_data::Measurement> = ds
        .measurements
        .iter()
        .filter(|m| !in_frequency_sweep(ds, m))
        .collect();
    let per_meas: Vec<(Vec<Spectrum>, Option<String>)> = shown
        .par_iter()
        .map(|m| spectra::spectra(identified, result, ds, m))
        .collect();
    let mut figs: Vec<Captioned> = Vec::new();
    for (m, (specs, warn)) in shown.iter().zip(per_meas) {
        warnings.extend(warn);
        for (k, s) in specs.into_iter().enumerate() {
            let point = m
                .points
                .get(k)
                .and_then(|&p| ds.manifest.points.get(p))
                .map_or("modal".to_string(), |p| p.name.clone());
            let below = if s.residual_in_sigmas {
                "the fit's residual of every line in its own noise, |X̄ − X_HB|/σ, below (dashed: √2, a correct model's typical value)"
            } else {
                "the complex residual |X − X_HB| below"
            };
            figs.push((
                stem(&format!("spectrum_{}_{point}", m.spec.name)),
                format!(
                    "Measurement {}, {point}: |X| of every measured line (median over shots; filled dots), the spectrum the identified model gives by harmonic balance (open circles), and {below}. Drives: {}.",
                    m.spec.name,
                    m.spec.drives_hz.iter().enumerate().map(|(d, f)| format!("f{} = {} Hz", d + 1, harmonid_plot::style::hz(*f))).collect::<Vec<_>>().join(", ")
                ),
                AnyFigure::Spectrum(s),
            ));
        }
    }
    figs
}

/// Every quantity of the result that may have per-shot estimates: each mode's `f` and `Q`,
/// then the parameters, with the dataset's truth where it has one.
fn quantities<'a>(result: &'a Report, ds: &Dataset) -> Vec<Quantity<'a>> {
    let truth = ds.truth.as_ref();
    let mut quantities: Vec<Quantity<'a>> = Vec::new();
    for (n, m) in &result.modes {
        let tm = truth.and_then(|t| t.modes.get(n));
        quantities.push((format!("f_{n}"), "Hz".into(), &m.f_hz, tm.map(|t| t.f_hz)));
        quantities.push((format!("Q_{n}"), String::new(), &m.q, tm.map(|t| t.q)));
    }
    for (p, e) in &result.parameters {
        quantities.push((
            p.clone(),
            String::new(),
            e,
            truth.and_then(|t| result::truth_of_param(result, p, t)),
        ));
    }
    quantities
}

/// Adds a histogram to `figs` for every quantity with at least two per-shot estimates;
/// returns the names of those without.
fn histogram_figures(quantities: &[Quantity<'_>], figs: &mut Vec<Captioned>) -> Vec<String> {
    let mut no_shots = Vec::new();
    for (name, unit, e, t) in quantities {
        if e.per_shot.len() < 2 {
            no_shots.push(name.clone());
            continue;
        }
        figs.push((
            stem(&format!("hist_{name}")),
            format!(
                "{name}: estimates of the {} shots (bars), the normal distribution with the mean and std of the shots kept (curve), outliers by the interquartile rule (triangles), the reported value ± stderr (line and band){}.",
                e.per_shot.len(),
                if t.is_some() { " and the truth (dashed)" } else { "" }
            ),
            AnyFigure::Histogram(Histogram {
                name: name.clone(),
                unit: unit.clone(),
                values: e.per_shot.clone(),
                outliers: e.outlier_shots.clone(),
                value: e.value,
                stderr: e.stderr,
                std: e.std,
                truth: *t,
            }),
        ));
    }
    no_shots
}

/// Draws every figure as SVG, in parallel, keeping their order.
fn draw(figs: Vec<Captioned>) -> Result<Vec<PageFigure>, PlotError> {
    figs.into_par_iter()
        .map(|(stem, caption, figure)| {
            let svg = harmonid_plot::to_svg(&figure)?;
            Ok(PageFigure {
                stem,
                caption,
                figure,
                svg,
            })
        })
        .collect()
}

impl Page {
    /// Writes `out/index.html` and `out/figures/*.{svg,png}` (see the crate docs) through
    /// `harmonid_files`: the folder is filled as a staging folder beside `out` and swapped in
    /// when complete; an existing `out` is replaced only when it is empty or a harmonid report
    /// (it holds [`MARKER`]) and holds none of `inputs`.
    pub fn write(&self, out: &Path, inputs: &[&Path]) -> Result<(), ReportError> {
        let foreign = out.is_dir()
            && !out.join(MARKER).is_file()
            && std::fs::read_dir(out).map_or(true, |mut d| d.next().is_some());
        if foreign || (out.exists() && !out.is_dir()) {
            return Err(ReportError::Clobber {
                path: out.to_path_buf(),
            });
        }
        let opts = harmonid_files::DirWrite {
            // Not a dataset folder: the report's own marker was checked above.
            force: true,
            inputs,
        };
        harmonid_files::replace_dir(out, opts, |dir| -> Result<(), ReportError> {
            let figs = dir.join("figures");
            std::fs::create_dir(&figs).map_err(|source| ReportError::Io {
                path: figs.clone(),
                source,
            })?;
            let write = |path: &Path, bytes: &[u8]| harmonid_files::write_file(path, bytes, &[]);
            write(&dir.join("index.html"), self.html.as_bytes())?;
            self.figures.par_iter().try_for_each(|f| {
                write(&figs.join(format!("{}.svg", f.stem)), f.svg.as_bytes())?;
                let png = harmonid_plot::to_png(&f.figure)?;
                write(&figs.join(format!("{}.png", f.stem)), &png)?;
                Ok::<(), ReportError>(())
            })?;
            write(&dir.join(MARKER), b"written by harmonid report\n")?;
            Ok(())
        })
    }
}
