//! Hopf points of a single-tone sweep (issue 38, item 3) against the closed form of the
//! weakly nonlinear limit: a driven van der Pol–Duffing oscillator
//! `q̈ + (γ₀ + μ) q̇ + ω₀² q + α q³ + η q² q̇ = F cos Ωt` with net linear damping
//! `γ = γ₀ + μ < 0`.
//!
//! Averaging (`q = Re[A e^{iΩt}]`, `A` slow; `[q³]₁ = ¾|A|²A`, `[q²q̇]₁ = iΩ|A|²A/4`):
//! `2iΩ Ȧ = −(D + iΩΓ) A + F` with `D = ω₀² − Ω² + ¾αa²`, `Γ = γ + ηa²/4`, `a = |A|`. The
//! Jacobian of `Ȧ = (iσ − g) A + …` (`σ = D/2Ω`, `g = Γ/2`, `σ' = 3α/8Ω`, `g' = η/8` their
//! derivatives in `a²`) has trace `−2(g + g'a²) = −(γ + ηa²/2)` and determinant
//! `(g + g'a²)² + (σ + σ'a²)² − (g'² + σ'²)a⁴`. Hopf: trace 0, i.e. `a_H² = −2γ/η`, with
//! det > 0; on the response curve `F² = a_H² (D² + Ω²γ²/4)` (`Γ = γ/2` there) gives `Ω`.

use harmonid_sim::{sweep, NumericModel, SweepSettings, Term};
use num_complex::Complex64;
use std::f64::consts::TAU;

const F0: f64 = 1000.0;
const Q: f64 = 1e4;
const A_H: f64 = 1e-6;

struct Vdp {
    w0: f64,
    gamma: f64,
    alpha: f64,
    eta: f64,
    force: f64,
}

fn vdp() -> Vdp {
    let w0 = TAU * F0;
    let g0 = w0 / Q;
    let gamma = -g0;
    Vdp {
        w0,
        gamma,
        alpha: 8.0 * w0 * g0 / (3.0 * A_H * A_H),
        eta: -2.0 * gamma / (A_H * A_H),
        force: A_H * 2.0 * w0 * 3.0 * g0,
    }
}

fn model(p: &Vdp) -> NumericModel {
    let g0 = p.w0 / Q;
    let terms = vec![
        Term {
            eq: 0,
            // μ q̇ (variable 1 of a one-mode model is its velocity).
            coef: p.gamma - g0,
            factors: vec![(1, 1)],
        },
        Term {
            eq: 0,
            coef: p.alpha,
            factors: vec![(0, 3)],
        },
        Term {
            eq: 0,
            coef: p.eta,
            factors: vec![(0, 2), (1, 1)],
        },
    ];
    NumericModel::new(vec!["q1".into()], vec![F0], vec![Q], terms).expect("model")
}

/// The closed-form Hopf frequencies (Hz), ascending: both roots of `D = ±√(F²/a_H² − Ω²γ²/4)`
/// with det > 0.
fn closed_form(p: &Vdp) -> Vec<f64> {
    let a2 = A_H * A_H;
    let mut out = Vec::new();
    for sign in [1.0, -1.0] {
        let mut w = p.w0;
        for _ in 0..50 {
            let root = (p.force * p.force / a2 - w * w * p.gamma * p.gamma / 4.0).sqrt();
            w = (p.w0 * p.w0 + 0.75 * p.alpha * a2 - sign * root).sqrt();
        }
        let d = p.w0 * p.w0 - w * w + 0.75 * p.alpha * a2;
        let (sigma, ds, dg) = (d / (2.0 * w), 3.0 * p.alpha / (8.0 * w), p.eta / 8.0);
        let det = (sigma + ds * a2).powi(2) - (dg * dg + ds * ds) * a2 * a2;
        if det > 0.0 {
            out.push(w / TAU);
        }
    }
    out.sort_by(f64::total_cmp);
    out
}

#[test]
fn a_driven_van_der_pol_duffing_has_its_hopf_points_at_the_closed_form() {
    let p = vdp();
    let m = model(&p);
    let want = closed_form(&p);
    assert_eq!(want.len(), 2, "{want:?}");
    let settings = SweepSettings {
        f_start_hz: F0 - 2.0,
        f_stop_hz: F0 + 2.0,
        points: 400,
        harmonics: 3,
        ..SweepSettings::default()
    };
    let t = std::time::Instant::now();
    let r = sweep(&m, &[Complex64::new(p.force, 0.0)], &settings).expect("sweep");
    eprintln!("sweep of {} points in {:?}", r.points.len(), t.elapsed());
    assert!(r.complete);
    let got: Vec<f64> = r.hopf.iter().map(|h| h.f_hz).collect();
    let linewidth = p.w0 / Q / TAU;
    eprintln!(
        "Hopf at {:?} Hz, closed form {:?} Hz; offsets {:?} Hz; errors {:?} linewidths",
        got,
        want,
        r.hopf.iter().map(|h| h.offset_hz).collect::<Vec<_>>(),
        got.iter()
            .zip(&want)
            .map(|(g, w)| (g - w) / linewidth)
            .collect::<Vec<_>>()
    );
    assert_eq!(got.len(), 2, "{:?}", r.hopf);
    for (g, w) in got.iter().zip(&want) {
        assert!(
            (g - w).abs() < 0.01 * linewidth,
            "Hopf at {g} Hz, closed form {w} Hz"
        );
    }
    // Up the curve: unstable (self-oscillating beside the drive) below the first, stable
    // (entrained) between them, unstable above the second.
    assert!(r.hopf[0].gains_stability && !r.hopf[1].gains_stability);
    assert!(!r.points[0].stable && !r.points.last().expect("points").stable);
    let mid = r.hopf[0].index + 2;
    assert!(r.points[mid].stable);
}
