//! A measurement background fitted with the resonator (`identify --background`, issue 36
//! item 3): a damped Duffing stepped sweep at four drive levels with a known complex
//! feedthrough `B·D`, slope `S·D·(f − f_ref)` and offset `C` added on every step's line. Fitted
//! with `drive,slope,constant`, the background and the resonator come back within their
//! standard errors; fitted without, the resonator's parameters are pulled far beyond theirs.
//! Bad input: drive terms without drive levels, unknown words, the linear estimator.

use harmonid::data::Dataset;
use harmonid::ident::{identify, Background, BackgroundTerm, Estimator, ForceModel, Settings};
use harmonid_testgen as gen;
use num_complex::Complex64;

const SHOTS: usize = 10;
/// Shot noise per quadrature of one sample, m.
const SIGMA: f64 = 3e-12;
/// The background put in: feedthrough (m per drive unit; the drive levels are 2 to 20 N/kg,
/// the peaks 1 to 10 nm, so about 20 % of each peak), slope (m per drive unit per Hz, the
/// sweep spans ±250 Hz) and offset (m).
const B: Complex64 = Complex64::new(1.0e-10, -0.6e-10);
const S: Complex64 = Complex64::new(-2.0e-13, 3.0e-13);
const C: Complex64 = Complex64::new(2.0e-10, 1.0e-10);
/// The model's nominal resonance (the slope's `f_ref`), Hz.
const F_REF: f64 = 1.0e6;

fn clean() -> (harmonid::model::Model, gen::Values, Dataset) {
    let model = harmonid::model::parse_str(gen::DAMPED_DUFFING, "stepped.hb").expect("model");
    let (v, d) = gen::stepped_sweep_plan();
    let clean = gen::simulate_clean(&model, &v, &d, &[1.0], SHOTS);
    (model, v, clean)
}

/// `ds` with the background added on every line at a drive tone (every shot).
fn with_background(ds: &Dataset) -> Dataset {
    let mut ds = ds.clone();
    for m in &mut ds.measurements {
        let (levels, phases) = m.spec.drive_levels_and_phases().expect("levels");
        let per = m.freqs_hz.len() * m.points.len();
        let add: Vec<Complex64> = m
            .freqs_hz
            .iter()
            .flat_map(|&f| {
                let tone = m.spec.drives_hz.iter().position(|&d| d == f);
                let bg = tone.map_or(Complex64::new(0.0, 0.0), |t| {
                    let d = Complex64::from_polar(levels[t], phases[t]);
                    B * d + S * d * (f - F_REF) + C
                });
                std::iter::repeat_n(bg, m.points.len())
            })
            .collect();
        for (i, x) in m.data.iter_mut().enumerate() {
            *x += add[i % per];
        }
    }
    ds
}

fn settings(background: &[BackgroundTerm]) -> Settings {
    Settings {
        force_model: ForceModel::GainPerMode,
        background: Background::of(background),
        jackknife: false,
        ..Settings::default()
    }
}

/// `(estimate − truth)/stderr` of f, Q, beta1, eta1, then (with a background) the real and
/// imaginary parts of B, S and C.
fn deviations(rep: &harmonid::ident::Report, v: &gen::Values) -> Vec<(String, f64)> {
    errors(rep, v)
        .into_iter()
        .map(|(name, e, s)| (name, e / s[0]))
        .collect()
}

const ALL: [BackgroundTerm; 3] = [
    BackgroundTerm::Drive,
    BackgroundTerm::Slope,
    BackgroundTerm::Constant,
];

#[test]
fn the_background_is_recovered_and_without_it_the_resonator_is_pulled() {
    let (model, v, clean) = clean();
    let ds = gen::add_noise(&with_background(&clean), SIGMA, 7);
    let t0 = std::time::Instant::now();
    let rep = identify(&model, &ds, &settings(&ALL)).expect("identify");
    println!("with background: {:.2} s", t0.elapsed().as_secs_f64());
    assert_eq!(rep.estimator, "ml", "{:?}", rep.warnings);
    let g = rep.goodness_of_fit.as_ref().expect("verdict");
    assert_eq!(g.fits, Some(true), "{}", g.one_line());
    let b = &rep.background["q1"];
    assert_eq!((b.unit.as_str(), b.f_ref_hz), ("m", F_REF));
    let devs = deviations(&rep, &v);
    println!("with background, (estimate - truth)/stderr: {devs:?}");
    assert_eq!(devs.len(), 4 + 6);
    for (name, d) in &devs {
        assert!(
            d.abs() < 4.0,
            "{name}: {d:.2} stderr from the truth ({devs:?})"
        );
    }
    // The summary shows it with its unit.
    let text = rep.summary(None);
    assert!(text.contains("measurement background"), "{text}");
    assert!(text.contains("q1 drive    re"), "{text}");
    // Without the background the same data pull the resonator far beyond its error bars.
    let t0 = std::time::Instant::now();
    let plain = identify(&model, &ds, &settings(&[])).expect("identify");
    println!("without background: {:.2} s", t0.elapsed().as_secs_f64());
    assert!(plain.background.is_empty());
    let devs = deviations(&plain, &v);
    println!("without background, (estimate - truth)/stderr: {devs:?}");
    let worst = devs.iter().map(|d| d.1.abs()).fold(0.0, f64::max);
    assert!(worst > 10.0, "the background should bias the fit: {devs:?}");
}

/// The standard errors carry the noise of the weights: every line's noise is its scatter over
/// the 10 shots (`ν = 18` degrees of freedom), and a quantity fixed by many lines then varies
/// up to `ν/(ν − 4)` times the inverse information at those weights
/// (`harmonid_ident::uncertainty::estimated_noise`): here each of the ten quantities rests on
/// many of the 160 lines (its leverage concentration `ĥ` is below 0.25; measured 1.109–1.131
/// for the ratio, `ĥ` 0.03–0.2), and its standard error is between `√((18 − 4·0.25)/14)` and
/// `√(18/14)` times the Fisher bound (times the χ² inflation); with the noise given as known,
/// equal to it. Before,
/// the standard error was the Fisher bound and ±1 / ±2 of it held the truth in 63–67 % /
/// 91–94 % of 1000 draws of this fit (`coverage_diagnostics`).
#[test]
fn the_standard_errors_carry_the_noise_of_the_weights() {
    let (model, _, clean) = clean();
    let ratios = |ds: &Dataset| {
        let rep = identify(&model, ds, &settings(&ALL)).expect("identify");
        // Every line at ν = 18 (pooling rejected no shot) where the noise is from the shots.
        assert!(rep.rejected_shots.is_empty(), "{:?}", rep.rejected_shots);
        let g = rep.goodness_of_fit.as_ref().expect("goodness");
        let mut all: Vec<&harmonid::data::result::Estimate> = vec![&rep.modes["q1"].f_hz];
        all.push(&rep.modes["q1"].q);
        all.extend(rep.parameters.values());
        for (_, _, c) in rep.background["q1"].terms() {
            all.extend([&c.re, &c.im]);
        }
        assert_eq!(all.len(), 10);
        all.iter()
            .map(|e| e.stderr / (e.crlb.expect("crlb") * g.stderr_inflation))
            .collect::<Vec<f64>>()
    };
    // A draw where pooling rejects no shot.
    let ds = (7..60)
        .map(|seed| gen::add_noise(&with_background(&clean), SIGMA, seed))
        .find(|ds| {
            harmonid::ident::pool(ds)
                .rejected
                .iter()
                .all(|r| r.is_empty())
        })
        .expect("a draw without rejected shots");
    let from_shots = ratios(&ds);
    println!("stderr / Fisher, noise from 10 shots: {from_shots:.4?}");
    for r in &from_shots {
        assert!(
            (((18.0 - 1.0) / 14.0f64).sqrt()..=(18.0f64 / 14.0).sqrt() + 1e-12).contains(r),
            "{from_shots:?}"
        );
    }
    let known = ratios(&with_known_noise(&ds, SIGMA));
    println!("stderr / Fisher, noise known: {known:.6?}");
    assert!(known.iter().all(|r| (r - 1.0).abs() < 1e-5), "{known:?}");
}

#[test]
fn a_background_that_cannot_be_fitted_is_refused_saying_what_to_do() {
    let (model, _, clean) = clean();
    // Drive terms without drive levels.
    let mut no_levels = clean.clone();
    for m in &mut no_levels.measurements {
        m.spec.drive_levels_v = None;
        m.spec.drive_phases_rad = None;
    }
    let s = Settings {
        force_model: ForceModel::Free,
        background: Background::of(&[BackgroundTerm::Drive, BackgroundTerm::Slope]),
        ..Settings::default()
    };
    let err = identify(&model, &no_levels, &s)
        .expect_err("no levels")
        .to_string();
    assert!(
        err.contains("--background drive,slope")
            && err.contains("records no drive_levels_v")
            && err.contains("--background constant"),
        "{err}"
    );
    // The linear estimator has no background.
    let s = Settings {
        estimator: Estimator::Linear,
        ..settings(&[BackgroundTerm::Constant])
    };
    let err = identify(&model, &clean, &s)
        .expect_err("linear")
        .to_string();
    assert!(err.contains("needs the output-error estimator"), "{err}");
    // An unknown word lists the valid ones.
    let err = "drive,offset"
        .parse::<Background>()
        .expect_err("word")
        .to_string();
    assert!(
        err.contains("\"offset\"") && err.contains("\"constant\""),
        "{err}"
    );
}

/// The command line: an unknown word is refused by the option's parser, listing the valid
/// ones; `report --result --background` is refused (the result carries its own); a dataset
/// fitted with `--background constant` writes `background` in the result.
#[test]
fn the_command_line_refuses_bad_backgrounds_and_writes_the_fitted_one() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let (model, data) = (
        root.join("examples/nanostring_2mode/model.hb"),
        root.join("examples/nanostring_2mode/data"),
    );
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("r.json");
    let harmonid = |args: &[&std::ffi::OsStr]| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_harmonid"))
            .args(args)
            .output()
            .expect("run");
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stderr).to_string(),
        )
    };
    let os = |s: &'static str| std::ffi::OsStr::new(s);
    let (ok, err) = harmonid(&[
        os("identify"),
        model.as_os_str(),
        data.as_os_str(),
        os("--background"),
        os("drive,feedthrough"),
    ]);
    assert!(
        !ok && err.contains("\"feedthrough\"") && err.contains("\"constant\""),
        "{err}"
    );
    let (ok, err) = harmonid(&[
        os("identify"),
        model.as_os_str(),
        data.as_os_str(),
        os("--background"),
        os("constant"),
        os("--out"),
        out.as_os_str(),
    ]);
    assert!(ok, "{err}");
    let rep = harmonid::ident::Report::from_json(&std::fs::read_to_string(&out).expect("read"))
        .expect("result");
    assert!(rep.background["q1"].constant.is_some() && rep.background["q1"].drive.is_none());
    let (ok, err) = harmonid(&[
        os("report"),
        model.as_os_str(),
        data.as_os_str(),
        os("--result"),
        out.as_os_str(),
        os("--background"),
        os("constant"),
        os("--out"),
        dir.path().join("rep").as_os_str(),
    ]);
    assert!(
        !ok && err.contains("carries the background it was fitted with"),
        "{err}"
    );
}

/// Coverage of the background and the resonator over many noise draws (run with
/// `cargo test --release -p harmonid --test it -- background::coverage_over --ignored
/// --nocapture`; 200 draws of the fit above with 50 shots and 500 with 10, the noise of the
/// mean the same, a few minutes): the truth within 1 / 2 standard errors in 68 ± 8 % /
/// 95 ± 4 % of the draws for every quantity, asserted. The same draws without a background in
/// the data nor in the fit, and the standard errors as the Fisher bound alone gives them
/// (before the noise of the weights was accounted for), are printed beside. Seeds 70000 on
/// (the diagnostics that found the defect used 1000 and 20000 on, the withdrawn widening
/// 40000 on). Measured: docs/identification.md.
#[test]
#[ignore]
fn coverage_over_many_draws() {
    let model = harmonid::model::parse_str(gen::DAMPED_DUFFING, "stepped.hb").expect("model");
    let (v, d) = gen::stepped_sweep_plan();
    let mut bad = Vec::new();
    for (shots, runs) in [(50, 200u64), (10, 500)] {
        let clean = gen::simulate_clean(&model, &v, &d, &[1.0], shots);
        let biased = with_background(&clean);
        let sigma = SIGMA * (shots as f64 / SHOTS as f64).sqrt();
        let count = |data: &Dataset, terms: &[BackgroundTerm]| {
            let mut c: [Coverage; 3] = Default::default();
            let mut infl = Vec::new();
            for seed in 0..runs {
                let ds = gen::add_noise(data, sigma, 70_000 + seed);
                let rep = identify(&model, &ds, &settings(terms)).expect("identify");
                Coverage::add_all(&mut c, &errors(&rep, &v));
                infl.push(inflations(&rep));
            }
            (c, infl)
        };
        let t0 = std::time::Instant::now();
        count(&clean, &[]).0[0].print(&format!("{shots} shots, no background"));
        let ([c, fisher, beyond], infl) = count(&biased, &ALL);
        println!("{shots} shots: {:.0} s", t0.elapsed().as_secs_f64());
        c.print(&format!("{shots} shots, background fitted"));
        fisher.print(&format!(
            "{shots} shots, background fitted, Fisher bound (as before)"
        ));
        beyond.print(&format!(
            "{shots} shots, background fitted, inflated whenever chi2/dof > expected"
        ));
        print_inflations(&format!("{shots} shots"), &infl);
        for (name, a, b, _, _) in c.table() {
            if (a - 0.68).abs() > 0.08 || (b - 0.95).abs() > 0.04 {
                bad.push(format!("{name} at {shots} shots: {a:.3} / {b:.3}"));
            }
        }
    }
    assert!(bad.is_empty(), "miscalibrated: {bad:?}");
}

/// Per quantity over Monte-Carlo draws: the truth within 1 and 2 stderr, the mean of
/// `(estimate − truth)/stderr` (bias in stderr units) and the spread of the estimate over the
/// mean reported stderr (1 for an honest stderr).
#[derive(Default)]
pub(crate) struct Coverage {
    rows: Vec<(String, Vec<(f64, f64)>)>,
}

impl Coverage {
    /// Adds one draw: `(name, estimate − truth, stderr)` per quantity.
    pub(crate) fn add(&mut self, draw: impl IntoIterator<Item = (String, f64, f64)>) {
        for (name, err, se) in draw {
            match self.rows.iter_mut().find(|r| r.0 == name) {
                Some(r) => r.1.push((err, se)),
                None => self.rows.push((name, vec![(err, se)])),
            }
        }
    }

    /// Adds one draw of `(name, error, [stderr, Fisher stderr, stderr inflated whenever χ²/dof
    /// exceeds its expectation])` (a [`Draw`]) to the three tallies, column by column.
    pub(crate) fn add_all(c: &mut [Self; 3], draw: &[Draw]) {
        for (k, t) in c.iter_mut().enumerate() {
            t.add(draw.iter().map(|x| (x.0.clone(), x.1, x.2[k])));
        }
    }

    /// Per quantity: `(name, within 1, within 2, mean z, sd(error)/mean(stderr))`.
    pub(crate) fn table(&self) -> Vec<(String, f64, f64, f64, f64)> {
        self.rows
            .iter()
            .map(|(name, v)| {
                let n = v.len() as f64;
                let z: Vec<f64> = v.iter().map(|(e, s)| e / s).collect();
                let within = |k: f64| z.iter().filter(|z| z.abs() <= k).count() as f64 / n;
                let mean_err = v.iter().map(|x| x.0).sum::<f64>() / n;
                let sd =
                    (v.iter().map(|x| (x.0 - mean_err).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
                let se = v.iter().map(|x| x.1).sum::<f64>() / n;
                let mz = z.iter().sum::<f64>() / n;
                (name.clone(), within(1.0), within(2.0), mz, sd / se)
            })
            .collect()
    }

    /// The correlation coefficient of the errors of quantities `a` and `b` over the draws.
    pub(crate) fn correlation(&self, a: &str, b: &str) -> f64 {
        let get = |n: &str| self.rows.iter().find(|r| r.0 == n).map(|r| &r.1);
        let (Some(x), Some(y)) = (get(a), get(b)) else {
            return f64::NAN;
        };
        let n = x.len().min(y.len()) as f64;
        let mx = x.iter().map(|p| p.0).sum::<f64>() / n;
        let my = y.iter().map(|p| p.0).sum::<f64>() / n;
        let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
        for (p, q) in x.iter().zip(y) {
            sxy += (p.0 - mx) * (q.0 - my);
            sxx += (p.0 - mx).powi(2);
            syy += (q.0 - my).powi(2);
        }
        sxy / (sxx * syy).sqrt()
    }

    /// Prints [`Coverage::table`] under `title`.
    pub(crate) fn print(&self, title: &str) {
        println!("{title}: quantity, within 1 / 2 stderr, mean z, sd(error)/mean(stderr)");
        for (name, a, b, mz, r) in self.table() {
            println!(
                "  {name:10} {:5.1} % {:5.1} %  {mz:+.3}  {r:.3}",
                100.0 * a,
                100.0 * b
            );
        }
    }
}

/// `ds` with each measurement's shots replaced by their mean and the noise given as known
/// (`sigma` per quadrature of one shot), as an instrument's average of a million samples
/// gives it: the fit's weights are then exact.
pub(crate) fn with_known_noise(ds: &Dataset, sigma: f64) -> Dataset {
    let mut ds = ds.clone();
    for m in &mut ds.measurements {
        let per = m.freqs_hz.len() * m.points.len();
        let n = m.n_shots;
        let mut mean = vec![Complex64::new(0.0, 0.0); per];
        for (i, x) in m.data.iter().enumerate() {
            mean[i % per] += x / n as f64;
        }
        m.data = mean;
        m.n_shots = 1;
        let k = 1_000_000u32;
        m.noise = Some(harmonid::data::GivenNoise {
            std: vec![sigma * (f64::from(k) / n as f64).sqrt(); per],
            samples: vec![k; per],
        });
    }
    ds
}

/// One quantity of one draw: `(name, estimate − truth, [stderr, Fisher bound × inflation,
/// stderr with the inflation whenever χ²/dof exceeds its expectation])` (the last two: the
/// standard errors before the weights' own noise, and before the inflation's spread, were
/// accounted for).
pub(crate) type Draw = (String, f64, [f64; 3]);

/// `(inflation as reported, inflation whenever χ²/dof exceeds its expectation)` of a fit: the
/// first is `√max(1, (χ²/dof − spread)/expected)`, which leaves a correct model's standard
/// errors alone unless its `χ²/dof` exceeds the expectation by more than one spread; the
/// second `√max(1, (χ²/dof)/expected)`, as before.
pub(crate) fn inflations(rep: &harmonid::ident::Report) -> (f64, f64) {
    rep.goodness_of_fit
        .as_ref()
        .map_or((f64::NAN, f64::NAN), |g| {
            let always = g.chi2_per_dof / g.expected_chi2_per_dof;
            (g.stderr_inflation, always.max(1.0).sqrt())
        })
}

/// Prints how often and by how much the inflations of [`inflations`] fired over draws.
pub(crate) fn print_inflations(title: &str, v: &[(f64, f64)]) {
    let n = v.len() as f64;
    let fired = |k: usize| v.iter().filter(|x| [x.0, x.1][k] > 1.0).count() as f64 / n;
    let mean = |k: usize| v.iter().map(|x| [x.0, x.1][k]).sum::<f64>() / n;
    println!(
        "{title}: chi2 inflation (beyond the spread) fired in {:.1} % of the draws (mean {:.4}); whenever above the expectation: {:.1} % (mean {:.4})",
        100.0 * fired(0),
        mean(0),
        100.0 * fired(1),
        mean(1)
    );
}

/// [`Draw`]s of the quantities [`deviations`] names (the Fisher column: the standard error
/// before the weights' own noise was accounted for).
fn errors(rep: &harmonid::ident::Report, v: &gen::Values) -> Vec<Draw> {
    let mut out = Vec::new();
    let (inflation, always) = inflations(rep);
    let mut dev = |name: &str, e: &harmonid::data::result::Estimate, t: f64| {
        let fisher = e.crlb.map_or(f64::NAN, |c| c * always);
        let se = [e.stderr, fisher, e.stderr / inflation * always];
        out.push((name.to_string(), e.value - t, se));
    };
    dev("f", &rep.modes["q1"].f_hz, v.f_hz[0]);
    dev("Q", &rep.modes["q1"].q, v.q[0]);
    dev("beta1", &rep.parameters["beta1"], v.params["beta1"]);
    dev("eta1", &rep.parameters["eta1"], v.params["eta1"]);
    if let Some(b) = rep.background.get("q1") {
        for (term, _, c) in b.terms() {
            let t = match term {
                "drive" => B,
                "slope" => S,
                _ => C,
            };
            dev(&format!("{term} re"), &c.re, t.re);
            dev(&format!("{term} im"), &c.im, t.im);
        }
    }
    out
}

/// A Monte-Carlo diagnostic's setting `k` from the environment, `d` when unset or unreadable.
pub(crate) fn mc_env(k: &str, d: u64) -> u64 {
    std::env::var(k)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(d)
}

/// Diagnostics: shots and draws from `HARMONID_MC_SHOTS`, `HARMONID_MC_RUNS`, seeds from
/// `HARMONID_MC_SEED`; the noise estimated from the shots and given as known.
#[test]
#[ignore]
fn coverage_diagnostics() {
    let (shots, runs, seed0) = (
        mc_env("HARMONID_MC_SHOTS", 10) as usize,
        mc_env("HARMONID_MC_RUNS", 100),
        mc_env("HARMONID_MC_SEED", 1000),
    );
    let model = harmonid::model::parse_str(gen::DAMPED_DUFFING, "stepped.hb").expect("model");
    let (v, d) = gen::stepped_sweep_plan();
    let clean = with_background(&gen::simulate_clean(&model, &v, &d, &[1.0], shots));
    let sigma = SIGMA * (shots as f64 / SHOTS as f64).sqrt();
    let (mut c, mut k): ([Coverage; 3], Coverage) = Default::default();
    let t0 = std::time::Instant::now();
    for seed in 0..runs {
        let ds = gen::add_noise(&clean, sigma, seed0 + seed);
        let rep = identify(&model, &ds, &settings(&ALL)).expect("identify");
        Coverage::add_all(&mut c, &errors(&rep, &v));
        let rep = identify(&model, &with_known_noise(&ds, sigma), &settings(&ALL)).expect("id");
        k.add(errors(&rep, &v).into_iter().map(|x| (x.0, x.1, x.2[0])));
    }
    println!(
        "{runs} draws, {shots} shots, {:.0} s",
        t0.elapsed().as_secs_f64()
    );
    c[0].print("noise from the shots, stderr");
    c[1].print("noise from the shots, Fisher bound, inflated whenever chi2/dof > expected");
    c[2].print("noise from the shots, inflated whenever chi2/dof > expected");
    k.print("noise known");
}
