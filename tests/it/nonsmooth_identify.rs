//! Identification with non-smooth terms (issue 36, items 2 and 3): a one-mode resonator that
//! softens like `|q| q` and whose damping grows like `|q̇| q̇` (plus Duffing and `q² q̇`),
//! measured as stepped sweeps up and down at several drive levels (the simulator follows each
//! sweep's branch, the non-smooth terms by alternating frequency–time).
//!
//! - The forward model's Jacobian (the implicit derivative through the steady state, and the
//!   non-smooth terms' coefficients as columns) equals central differences of its predictions.
//! - The fit recovers `kappa1` and `drag1` within their standard errors.
//! - `#[ignore]`d: the coverage of `kappa1`, `drag1` and a drive feedthrough over many seeds.

use harmonid::data::Dataset;
use harmonid::ident::{
    identify, Background, BackgroundTerm, ForceModel, ForwardModel, ForwardSettings, Settings,
};
use harmonid_testgen as gen;
use num_complex::Complex64;

/// The resonator: 1 MHz, Q 2e4; at 10 nm `kappa1` softens it by about 0.8 linewidth,
/// `drag1` and `eta1` each add about 0.4 linewidth of damping, `beta1` hardens by 0.2.
pub(crate) const MODEL: &str = "
    mode q1 at 1 MHz
    param beta1, eta1, kappa1, drag1
    potential: beta1/4*q1^4
    eom q1 += eta1*q1^2*d(q1) + kappa1*abs(q1)*q1 + drag1*abs(d(q1))*d(q1)
";

pub(crate) fn values() -> gen::Values {
    gen::Values {
        f_hz: vec![1.0e6],
        q: vec![2.0e4],
        params: [
            ("beta1", 1.0e25),
            ("eta1", 5.0e18),
            ("kappa1", -4.0e17),
            ("drag1", 2.0e3),
        ]
        .iter()
        .map(|(k, x)| (k.to_string(), *x))
        .collect(),
    }
}

/// Up and down sweeps at `levels` drive levels (linear peak response 1 to 10 nm), `steps`
/// steps each over ±5 linewidths.
pub(crate) fn sweeps(v: &gen::Values, levels: usize, steps: usize) -> Vec<gen::SteppedSweep> {
    let (f, q) = (v.f_hz[0], v.q[0]);
    let w = std::f64::consts::TAU * f;
    let lw = f / q;
    let mut out = Vec::new();
    for l in 0..levels {
        let x = 1e-9 + 9e-9 * l as f64 / (levels.max(2) - 1) as f64;
        let force = x * w * w / q;
        let up: Vec<(f64, f64)> = (0..steps)
            .map(|s| (f + lw * (10.0 * s as f64 / (steps - 1) as f64 - 5.0), force))
            .collect();
        let down = up.iter().rev().copied().collect();
        out.push(gen::SteppedSweep {
            name: format!("up_l{l:02}"),
            direction: harmonid::data::Direction::Up,
            steps: up,
        });
        out.push(gen::SteppedSweep {
            name: format!("dn_l{l:02}"),
            direction: harmonid::data::Direction::Down,
            steps: down,
        });
    }
    out
}

fn model() -> harmonid::model::Model {
    harmonid::model::parse_str(MODEL, "nonsmooth.hb").expect("model")
}

/// The drive feedthrough put in for the coverage run: m per unit of drive level (the levels
/// are N/kg here, 2e3 to 2e4; about 5 % of each peak).
const B: Complex64 = Complex64::new(2.5e-14, -1.5e-14);

/// `ds` with the feedthrough `B·D` added on every step's drive line.
fn with_feedthrough(ds: &Dataset) -> Dataset {
    let mut ds = ds.clone();
    for m in &mut ds.measurements {
        let (levels, phases) = m.spec.drive_levels_and_phases().expect("levels");
        let d = Complex64::from_polar(levels[0], phases[0]);
        for x in &mut m.data {
            *x += B * d;
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

/// `(estimate − truth)/stderr` of f, Q, every parameter and (when fitted) the feedthrough.
fn deviations(rep: &harmonid::ident::Report, v: &gen::Values) -> Vec<(String, f64)> {
    errors(rep, v)
        .into_iter()
        .map(|(name, e, s)| (name, e / s[0]))
        .collect()
}

#[test]
fn the_forward_jacobian_of_non_smooth_terms_matches_differences() {
    let (model, v) = (model(), values());
    let ds = gen::simulate_sweeps_clean(&model, &v, &sweeps(&v, 2, 5), &[1.0], 1);
    let mut fwd = ForwardModel::new(
        &model,
        &ds,
        ForceModel::GainPerMode,
        &ForwardSettings::default(),
    )
    .expect("forward");
    let forces: Vec<Vec<Vec<Complex64>>> = ds
        .measurements
        .iter()
        .map(|m| {
            let (l, _) = m.spec.drive_levels_and_phases().expect("levels");
            vec![vec![Complex64::new(l[0], 0.0)]]
        })
        .collect();
    let theta = fwd
        .theta_from(&gen::model_values(&model, &v), &forces)
        .expect("theta");
    let (no, nk) = (fwd.n_observations(), fwd.unknowns().len());
    let mut x = vec![Complex64::new(0.0, 0.0); no];
    let mut jac = vec![Complex64::new(0.0, 0.0); no * nk];
    fwd.evaluate(&theta, &mut x, Some(&mut jac))
        .expect("evaluate");
    // At the truth the prediction is the simulated data.
    for (mi, m) in ds.measurements.iter().enumerate() {
        let o = fwd.observations_of(mi).start;
        assert!(
            (x[o] - m.data[0]).norm() <= 1e-9 * m.data[0].norm(),
            "{}",
            m.spec.name
        );
    }
    let mut worst: f64 = 0.0;
    for k in fwd.free() {
        let col: Vec<Complex64> = (0..no).map(|o| jac[o * nk + k]).collect();
        let dmax = col.iter().map(|z| z.norm()).fold(0.0, f64::max);
        assert!(dmax > 0.0, "{}: a zero column", fwd.label(k));
        // A step that moves the predictions by about 1e-4 of themselves.
        let h = (0..no)
            .filter(|&o| col[o].norm() > 1e-3 * dmax)
            .map(|o| 1e-4 * x[o].norm() / col[o].norm())
            .fold(f64::INFINITY, f64::min);
        let mut eval = |d: f64| {
            let mut t = theta.clone();
            t[k] += d;
            let mut y = vec![Complex64::new(0.0, 0.0); no];
            fwd.evaluate(&t, &mut y, None).expect("evaluate");
            y
        };
        let (xp, xm) = (eval(h), eval(-h));
        let err = (0..no)
            .map(|o| ((xp[o] - xm[o]) / (2.0 * h) - col[o]).norm())
            .fold(0.0, f64::max)
            / dmax;
        println!("{}: relative error {err:.2e}", fwd.label(k));
        worst = worst.max(err);
    }
    assert!(worst < 1e-5, "worst relative Jacobian error {worst:e}");
}

#[test]
fn kappa_and_drag_are_recovered_within_their_errors() {
    let (model, v) = (model(), values());
    let clean = gen::simulate_sweeps_clean(&model, &v, &sweeps(&v, 4, 15), &[1.0], 10);
    let ds = gen::add_noise(&clean, 2e-11, 3);
    let t0 = std::time::Instant::now();
    let rep = identify(&model, &ds, &settings(&[])).expect("identify");
    println!("identify: {:.2} s", t0.elapsed().as_secs_f64());
    assert_eq!(rep.estimator, "ml", "{:?}", rep.warnings);
    let devs = deviations(&rep, &v);
    println!("(estimate - truth)/stderr: {devs:?}");
    for (name, d) in &devs {
        assert!(d.abs() < 4.0, "{name}: {d:.2} stderr ({devs:?})");
    }
    let rel = |p: &str| rep.parameters[p].stderr / v.params[p].abs();
    println!(
        "relative stderr: kappa1 {:.2e}, drag1 {:.2e}",
        rel("kappa1"),
        rel("drag1")
    );
    assert!(rel("kappa1") < 0.05 && rel("drag1") < 0.1);
    // The eom table names the terms canonically.
    let eom = &rep.eom["q1"];
    assert!(
        eom.contains_key("abs(q1)*q1") && eom.contains_key("abs(d(q1))*d(q1)"),
        "{eom:?}"
    );
}

/// Coverage over many noise draws (run with `cargo test --release -p harmonid --test it --
/// nonsmooth_identify::coverage_over --ignored --nocapture`, about 15 min; `HARMONID_MC_SHOTS=10`
/// runs only the 10-shot half): 4 levels up and down, 25 steps each, a drive feedthrough `B·D`
/// in the data and fitted (`--background drive`), 200 draws with 50 shots and 200 with 10 (the
/// noise of the mean the same); the truth of f, Q, every parameter and the feedthrough within
/// 1 / 2 stderr in 68 ± 8 % / 95 ± 4 % of the draws, asserted. The standard errors as the
/// Fisher bound alone gives them (before the noise of the weights was accounted for) are
/// printed beside. Seeds 60000 on, as for the withdrawn uniform widening (the diagnostics used
/// 30000 on). Measured: docs/identification.md.
#[test]
#[ignore]
fn coverage_over_many_draws() {
    use crate::background::{inflations, print_inflations, Coverage};
    let (model, v) = (model(), values());
    let runs = 200u64;
    let t0 = std::time::Instant::now();
    let mut bad = Vec::new();
    let which = std::env::var("HARMONID_MC_SHOTS").unwrap_or_else(|_| "50,10".into());
    for shots in which
        .split(',')
        .filter_map(|s| s.trim().parse::<usize>().ok())
    {
        let clean = gen::simulate_sweeps_clean(&model, &v, &sweeps(&v, 4, 25), &[1.0], shots);
        let data = with_feedthrough(&clean);
        let sigma = 2e-11 * (shots as f64 / 10.0).sqrt();
        let mut c: [Coverage; 3] = Default::default();
        let mut infl = Vec::new();
        for seed in 0..runs {
            let ds = gen::add_noise(&data, sigma, 60_000 + seed);
            let rep = identify(&model, &ds, &settings(&[BackgroundTerm::Drive])).expect("identify");
            Coverage::add_all(&mut c, &errors(&rep, &v));
            infl.push(inflations(&rep));
        }
        println!("{shots} shots: {:.0} s so far", t0.elapsed().as_secs_f64());
        c[0].print(&format!("{shots} shots"));
        c[1].print(&format!("{shots} shots, Fisher bound (as before)"));
        c[2].print(&format!(
            "{shots} shots, inflated whenever chi2/dof > expected"
        ));
        print_inflations(&format!("{shots} shots"), &infl);
        for (a, b) in [
            ("Q", "drive im"),
            ("Q", "drive re"),
            ("f", "drive im"),
            ("f", "drive re"),
        ] {
            println!(
                "correlation of the errors of {a} and {b}: {:+.3}",
                c[0].correlation(a, b)
            );
        }
        for (name, a, b, _, _) in c[0].table() {
            if (a - 0.68).abs() > 0.08 || (b - 0.95).abs() > 0.04 {
                bad.push(format!("{name} at {shots} shots: {a:.3} / {b:.3}"));
            }
        }
    }
    assert!(bad.is_empty(), "miscalibrated: {bad:?}");
}

/// Fit all levels and predict the strongest; `(misfit of all levels, misfit per level,
/// prediction of the held-out sweeps)`, relative RMS.
fn fit_and_hold_out(model: &str, ds: &Dataset, held: &[String]) -> (f64, Vec<f64>, f64) {
    let model = harmonid::model::parse_str(model, "m.hb").expect("model");
    let s = Settings {
        error_floor: true,
        ..settings(&[BackgroundTerm::Drive])
    };
    let all = identify(&model, ds, &s).expect("identify");
    let g = all.goodness_of_fit.as_ref().expect("goodness");
    let per: Vec<f64> = g.sweeps.iter().map(|w| w.relative_rms).collect();
    let rep = harmonid::ident::identify_with_holdout(&model, ds, held, &s).expect("holdout");
    let (mut miss, mut meas) = (0.0, 0.0);
    for h in rep.holdout.iter().filter(|h| h.steps.is_some()) {
        let m = ds.measurements.iter().filter(|m| {
            m.spec
                .sweep
                .as_ref()
                .is_some_and(|w| w.sweep == h.measurement)
        });
        let a2: f64 = m
            .map(|m| m.data.iter().map(|x| x.norm_sqr()).sum::<f64>() / m.n_shots as f64)
            .sum();
        miss += (h.relative_rms.powi(2)) * a2;
        meas += a2;
    }
    (g.relative_rms, per, (miss / meas).sqrt())
}

/// The held-back lock-in measurement's synthetic stand-in (issue 36; `examples/nonsmooth_beam`):
/// 12 drive levels (linear peak response 1 to 10 nm), a sweep up and one down at each, 20 steps
/// over ±5 linewidths, 4 shots of 3e-11 m per quadrature, a drive feedthrough `B·D` on every
/// line. Fitted with `--background drive --error-floor`, with and without the non-smooth
/// terms, and the strongest level (both sweeps) predicted from the other eleven. Run with
/// `cargo test --release -p harmonid --test it -- nonsmooth_identify::held_back_stand_in
/// --ignored --nocapture` (numbers in docs/judging-a-model.md).
#[test]
#[ignore]
fn held_back_stand_in() {
    let model = harmonid::model::parse_str(
        include_str!("../../examples/nonsmooth_beam/model.hb"),
        "model.hb",
    )
    .expect("model");
    let v = gen::example_values("nonsmooth_beam", &["q1".to_string()]);
    let t0 = std::time::Instant::now();
    let clean = gen::simulate_sweeps_clean(&model, &v, &sweeps(&v, 12, 20), &[1.0], 4);
    let ds = gen::add_noise(&with_feedthrough(&clean), 3e-11, 11);
    println!(
        "simulated {} steps in {:.1} s",
        ds.measurements.len(),
        t0.elapsed().as_secs_f64()
    );
    let held = vec!["up_l11".to_string(), "dn_l11".to_string()];
    let without =
        "mode q1 at 1 MHz\nparam beta1, eta1\npotential: beta1/4*q1^4\neom q1 += eta1*q1^2*d(q1)\n";
    let mut out = Vec::new();
    for (name, text) in [
        (
            "with |q|q, |q'|q'",
            include_str!("../../examples/nonsmooth_beam/model.hb"),
        ),
        ("Duffing + q^2 q' only", without),
    ] {
        let t0 = std::time::Instant::now();
        let (all, per, pred) = fit_and_hold_out(text, &ds, &held);
        let per: Vec<String> = per.iter().map(|x| format!("{:.2}", 100.0 * x)).collect();
        println!(
            "{name}: all levels {:.2} % (per sweep {}), strongest level predicted to {:.2} % ({:.1} s)",
            100.0 * all,
            per.join(" "),
            100.0 * pred,
            t0.elapsed().as_secs_f64()
        );
        out.push((all, pred));
    }
    assert!(out[0].0 <= 0.08 && out[0].1 <= 0.06, "{out:?}");
    assert!(out[1].0 > out[0].0 && out[1].1 > out[0].1, "{out:?}");
}

/// [`crate::background::Draw`]s of the quantities [`deviations`] names.
fn errors(rep: &harmonid::ident::Report, v: &gen::Values) -> Vec<crate::background::Draw> {
    let mut out = Vec::new();
    let (inflation, always) = crate::background::inflations(rep);
    let mut dev = |name: &str, e: &harmonid::data::result::Estimate, t: f64| {
        let fisher = e.crlb.map_or(f64::NAN, |c| c * always);
        let se = [e.stderr, fisher, e.stderr / inflation * always];
        out.push((name.to_string(), e.value - t, se));
    };
    dev("f", &rep.modes["q1"].f_hz, v.f_hz[0]);
    dev("Q", &rep.modes["q1"].q, v.q[0]);
    for (p, &t) in &v.params {
        dev(p, &rep.parameters[p], t);
    }
    if let Some(b) = rep.background.get("q1") {
        for (term, _, c) in b.terms() {
            if term == "drive" {
                dev("drive re", &c.re, B.re);
                dev("drive im", &c.im, B.im);
            }
        }
    }
    out
}

/// Diagnostics: shots and draws from `HARMONID_MC_SHOTS`, `HARMONID_MC_RUNS`, seeds from
/// `HARMONID_MC_SEED`; the noise estimated from the shots and given as known.
#[test]
#[ignore]
fn coverage_diagnostics() {
    use crate::background::{mc_env, with_known_noise, Coverage};
    let (shots, runs, seed0) = (
        mc_env("HARMONID_MC_SHOTS", 10) as usize,
        mc_env("HARMONID_MC_RUNS", 100),
        mc_env("HARMONID_MC_SEED", 5000),
    );
    let known_too = mc_env("HARMONID_MC_KNOWN", 1) == 1;
    let (model, v) = (model(), values());
    let clean = gen::simulate_sweeps_clean(&model, &v, &sweeps(&v, 4, 25), &[1.0], shots);
    let data = with_feedthrough(&clean);
    let sigma = 2e-11 * (shots as f64 / 10.0).sqrt();
    let (mut c, mut k): ([Coverage; 3], Coverage) = Default::default();
    let t0 = std::time::Instant::now();
    for seed in 0..runs {
        let ds = gen::add_noise(&data, sigma, seed0 + seed);
        let s = settings(&[BackgroundTerm::Drive]);
        let rep = identify(&model, &ds, &s).expect("identify");
        Coverage::add_all(&mut c, &errors(&rep, &v));
        if known_too {
            let rep = identify(&model, &with_known_noise(&ds, sigma), &s).expect("identify");
            k.add(errors(&rep, &v).into_iter().map(|x| (x.0, x.1, x.2[0])));
        }
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
