//! Honesty of the reported uncertainties on synthetic noise: the single-shot standard error
//! (from the fit's residuals) against the actual scatter of estimates over independent noise
//! realisations, and the multi-shot report against the truth.

use harmonid_testgen as gen;

use gen::{nanostring_2mode_plan, simulate, Design, Values};
use harmonid_ident::Unknown;
use harmonid_ident::{Problem, Settings};
use std::path::PathBuf;

fn nanostring() -> (harmonid_model::Model, Values, Vec<Design>) {
    let model = harmonid_model::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/nanostring_2mode/model.hb"),
    )
    .expect("model");
    let (v, d) = nanostring_2mode_plan();
    (model, v, d)
}

fn std(v: &[f64]) -> f64 {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
}

#[test]
fn single_shot_standard_errors_match_the_scatter() {
    let (model, v, d) = nanostring();
    let shots = 60;
    for sigma in [1e-12, 1e-11] {
        let ds = simulate(&model, &v, &d, &[0.309, 0.588], sigma, shots, 21);
        // Unweighted: every shot is fitted on its own, as a single-shot dataset would be.
        let settings = Settings {
            min_shots_for_weights: 0,
            ..Settings::default()
        };
        let p = Problem::new(&model, &ds, &settings).expect("problem");
        let fit = p.fit(&ds).expect("fit");
        let mut names = vec![];
        for u in [
            Unknown::OmegaSq(0),
            Unknown::Gamma(0),
            Unknown::OmegaSq(1),
            Unknown::Gamma(1),
            Unknown::Param(0),
            Unknown::Param(1),
            Unknown::Param(2),
        ] {
            let i = p.index_of(&u).expect("unknown");
            let est: Vec<f64> = fit.values.iter().map(|x| x[i]).collect();
            let scatter = std(&est);
            let mut se: Vec<f64> = fit.cov_diag.iter().map(|c| c[i].sqrt()).collect();
            se.sort_by(f64::total_cmp);
            let ratio = se[shots / 2] / scatter;
            println!(
                "sigma {sigma:.0e} {:<16} scatter {scatter:.3e}, median single-shot std {:.3e}, ratio {ratio:.2}",
                p.label(i),
                se[shots / 2]
            );
            names.push((p.label(i), ratio));
        }
        for (n, r) in names {
            assert!(
                (0.7..=1.3).contains(&r),
                "{n}: single-shot std / scatter = {r:.2}"
            );
        }
    }
}
