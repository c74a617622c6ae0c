//! A noise given with the data (the dataset's `std` and `samples` columns: each row an average
//! an instrument made, a lock-in sweeper's mean and standard deviation per point) weighs the
//! fit exactly as the same samples given as shots do, and its error bars cover the truth as
//! often as they say.

use harmonid::data::{Dataset, GivenNoise};
use harmonid::ident::{identify, pool, ForceModel, Settings};
use harmonid_testgen as gen;
use num_complex::Complex64;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

const SAMPLES: usize = 12;

/// The stepped sweep's first two levels (80 steps) with `SAMPLES` noisy samples per step, as
/// shots, and the same samples averaged with their noise given (of the shots pooling keeps, so
/// both hold the same information).
fn both(clean: &Dataset, sigma: f64, seed: u64) -> (Dataset, Dataset) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let normal = Normal::new(0.0, sigma).expect("normal");
    let mut shots = clean.clone();
    for ms in &mut shots.measurements {
        let per = ms.freqs_hz.len() * ms.points.len();
        let truth: Vec<Complex64> = ms.data[..per].to_vec();
        ms.data = (0..SAMPLES)
            .flat_map(|_| truth.clone())
            .map(|x| x + Complex64::new(normal.sample(&mut rng), normal.sample(&mut rng)))
            .collect();
        ms.n_shots = SAMPLES;
    }
    let pooled = pool(&shots);
    let mut given = pooled.mean.clone();
    for (mi, mg) in given.measurements.iter_mut().enumerate() {
        let sigma = pooled.sigma[mi].clone().expect("noise from the shots");
        let n = pooled.used[mi] as u32;
        mg.noise = Some(GivenNoise {
            samples: vec![n; sigma.len()],
            std: sigma,
        });
    }
    (shots, given)
}

fn setup() -> (harmonid::model::Model, gen::Values, Dataset) {
    let model = harmonid::model::parse_str(gen::DAMPED_DUFFING, "stepped.hb").expect("model");
    let (v, d) = gen::stepped_sweep_plan();
    let clean = gen::simulate_clean(&model, &v, &d[..80], &[1.0], 1);
    (model, v, clean)
}

fn settings() -> Settings {
    Settings {
        force_model: ForceModel::GainPerMode,
        ..Settings::default()
    }
}

#[test]
fn given_noise_weighs_as_the_shots_do_and_survives_the_folder() {
    let (model, _, clean) = setup();
    let (shots, given) = both(&clean, 3e-11, 5);
    let a = identify(&model, &shots, &settings()).expect("shots");
    let b = identify(&model, &given, &settings()).expect("given noise");
    for (name, ea) in &a.parameters {
        let eb = &b.parameters[name];
        assert!(
            (ea.value - eb.value).abs() <= 1e-7 * ea.value.abs(),
            "{name}: {} vs {}",
            ea.value,
            eb.value
        );
        assert!(
            (ea.stderr - eb.stderr).abs() <= 1e-5 * ea.stderr,
            "{name}: {} vs {}",
            ea.stderr,
            eb.stderr
        );
    }
    let ga = a.goodness_of_fit.as_ref().expect("gof");
    let gb = b.goodness_of_fit.as_ref().expect("gof");
    assert!((ga.chi2_per_dof - gb.chi2_per_dof).abs() <= 1e-6 * ga.chi2_per_dof);
    assert!(gb.p_value.is_some(), "judged against the given noise");
    // Written and read back: the std and samples columns keep it.
    let dir = tempfile::tempdir().expect("tempdir");
    given.write(dir.path().join("ds")).expect("write");
    let text = std::fs::read_to_string(dir.path().join("ds/l0_s00.csv")).expect("csv");
    assert!(
        text.starts_with("shot,freq_hz,point,re,im,std,samples\n"),
        "{text}"
    );
    let back = Dataset::load(dir.path().join("ds")).expect("read back");
    for (m, n) in given.measurements.iter().zip(&back.measurements) {
        let (g, h) = (
            m.noise.as_ref().expect("noise"),
            n.noise.as_ref().expect("noise"),
        );
        assert_eq!(g.samples, h.samples);
        for (x, y) in g.std.iter().zip(&h.std) {
            assert!((x - y).abs() <= 1e-15 * x);
        }
    }
}

#[test]
fn given_noise_error_bars_cover_the_truth() {
    let (model, v, clean) = setup();
    let truth = [("beta1", v.params["beta1"]), ("eta1", v.params["eta1"])];
    let (mut within1, mut within2, mut n) = (0, 0, 0);
    for seed in 0..60 {
        let (_, given) = both(&clean, 3e-11, 100 + seed);
        let r = identify(&model, &given, &settings()).expect("identify");
        let mut checks: Vec<(f64, f64, f64)> = truth
            .iter()
            .map(|(k, t)| (r.parameters[*k].value, r.parameters[*k].stderr, *t))
            .collect();
        let m = &r.modes["q1"];
        checks.push((m.f_hz.value, m.f_hz.stderr, v.f_hz[0]));
        checks.push((m.q.value, m.q.stderr, v.q[0]));
        for (value, stderr, t) in checks {
            let z = (value - t).abs() / stderr;
            n += 1;
            within1 += usize::from(z <= 1.0);
            within2 += usize::from(z <= 2.0);
        }
    }
    let (p1, p2) = (within1 as f64 / n as f64, within2 as f64 / n as f64);
    eprintln!("within 1 stderr: {p1:.3}, within 2: {p2:.3} of {n}");
    // 240 estimates: 68 % ± 3 %, 95 % ± 1.4 % one sigma of the binomial.
    assert!((0.60..=0.76).contains(&p1), "within 1 stderr: {p1}");
    assert!((0.91..=0.99).contains(&p2), "within 2 stderr: {p2}");
}
