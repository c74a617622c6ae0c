//! Reads the shared datasets of `../shared/data` when they exist (skipped otherwise).

use harmonid_ident::Dataset;
use std::path::PathBuf;

fn shared(name: &str) -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data")
        .join(name);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipped: {} not found", p.display());
        None
    }
}

#[test]
fn reads_the_shared_nanostring_datasets() {
    let Some(dir) = shared("nanostring_ls50_2mode_noisy") else {
        return;
    };
    let ds = Dataset::load(&dir).expect("load noisy dataset");
    assert_eq!(ds.measurements.len(), 3);
    let m = ds.measurement("couple_q1_q2").expect("couple");
    assert_eq!(m.n_shots, 50);
    assert_eq!(m.freqs_hz.len(), 19);
    assert_eq!(m.points, vec![0]);
    let t = ds.truth.as_ref().expect("truth");
    assert_eq!(t.modes["q1"].q, 116232.0);
    assert_eq!(t.eom["q2"]["q2^3"], 3.7e23);
    assert_eq!(t.noise.as_ref().and_then(|n| n.shots), Some(50));
    let Some(dir) = shared("nanostring_ls50_2mode") else {
        return;
    };
    let ds = Dataset::load(&dir).expect("load noise-free dataset");
    let m = ds.measurement("single_q1").expect("single_q1");
    assert_eq!(m.n_shots, 1);
    assert_eq!(m.freqs_hz.len(), 10);
    assert_eq!(m.freqs_hz[0], 207492.5);
    assert!((m.amplitude(0, 0, 0).re - 6.523944823886086e-17).abs() < 1e-30);
}

#[test]
fn quick_look() {
    use harmonid_ident::problem::{Problem, Settings, Unknown, ForceModel};
    for name in ["nanostring_ls50_2mode", "nanostring_ls50_2mode_noisy"] {
    let Some(dir) = shared(name) else { return; };
    let ds = Dataset::load(&dir).expect("load");
    let model = harmonid_model::load(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/nanostring_2mode/model.hb")).expect("model");
    for fm in [ForceModel::Auto, ForceModel::Free] {
    let settings = Settings { force_model: fm, ..Settings::default() };
    let p = Problem::new(&model, &ds, &settings).expect("problem");
    for g in &p.groups { eprintln!("group stage {} meas {:?} unknowns {:?}", g.stage, g.measurements, g.unknowns.iter().map(|&u| p.label(u)).collect::<Vec<_>>()); }
    for n in &p.not_identifiable { eprintln!("NI {}: {}", p.label(n.unknown), n.reason); }
    let fit = p.fit(&ds, &settings);
    for g in &fit.groups { eprintln!("cond {:.3e} res {:.3e}", g.cond, g.rms_residual); }
    let ns = fit.values.len();
    for (i, u) in p.unknowns.iter().enumerate() {
        let mut v: Vec<f64> = fit.values.iter().map(|x| x[i]).collect();
        let vv = v.clone();
        v.sort_by(f64::total_cmp);
        let med = v[ns/2];
        let mean = vv.iter().sum::<f64>()/ns as f64;
        let sd = (vv.iter().map(|x| (x-mean).powi(2)).sum::<f64>()/(ns as f64 - 1.0).max(1.0)).sqrt();
        let extra = match u { Unknown::OmegaSq(_) => format!("f={:.6}", med.sqrt()/(2.0*std::f64::consts::PI)), _ => String::new() };
        eprintln!("{name} {fm:?} {:<40} median {:.6e} rel.sd {:.3e} single-shot sd {:.3e} {extra}", p.label(i), med, sd/med.abs(), fit.cov_diag[0][i].sqrt()/med.abs());
    }
    // Q
    for n in 0..2 {
        let iw = p.index_of(&Unknown::OmegaSq(n)).unwrap(); let ig = p.index_of(&Unknown::Gamma(n)).unwrap();
        let mut q: Vec<f64> = fit.values.iter().map(|x| x[iw].sqrt()/x[ig]).collect();
        let mut f: Vec<f64> = fit.values.iter().map(|x| x[iw].sqrt()/(2.0*std::f64::consts::PI)).collect();
        q.sort_by(f64::total_cmp); f.sort_by(f64::total_cmp);
        let iqr = |v: &Vec<f64>| (v[3*ns/4]-v[ns/4])/1.349;
        eprintln!("mode {n}: Q median {:.1} robust sd rel {:.3e}; f median {:.4} robust rel sd {:.3e}", q[ns/2], iqr(&q)/q[ns/2], f[ns/2], iqr(&f)/f[ns/2]);
    }
    }
    }
}
