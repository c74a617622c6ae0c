//! `harmonid plan` on a model with non-smooth terms (issue 36, item 2, plan evaluation):
//! examples/nonsmooth (`|q| q` stiffness, quadratic drag `|q̇| q̇`, Duffing) designed at the
//! guess (`plan --nominal`), written, read back and simulated with the default checks. The
//! drag removes the fold the level search stops at; its damping caps the drive (three
//! linewidths added, `|drag| a ω = 3γ`), where the lattice settles at a low order.
//!
//!     cargo test --release --test it -- plan_nonsmooth:: --nocapture

use harmonid_experiment::{Plan, Settings};
use harmonid_plan::{design, DesignSettings};

#[test]
fn a_nonsmooth_plan_is_designed_and_simulated() {
    let t0 = std::time::Instant::now();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/nonsmooth");
    let model = harmonid_model::load(&root.join("model.hb")).expect("model");
    let values = harmonid_experiment::read_values(&root.join("values.toml")).expect("values");
    let settings = DesignSettings {
        sigma_m: 1e-10,
        shots: 30,
        draws: 0,
        ..DesignSettings::default()
    };
    let (plan, ev) = design(&model, &values, &settings).expect("designs");
    assert_eq!(plan.measurements.len(), 1, "{:?}", plan.measurements);
    // Every unknown bounded (f, Q, kappa1, drag1, beta1), none worse than 2 %.
    assert!(
        ev.bounds.unidentifiable.is_empty(),
        "{:?}",
        ev.bounds.unidentifiable
    );
    assert_eq!(ev.bounds.quantities.len(), 5);
    for b in &ev.bounds.quantities {
        assert!(b.rel.is_finite() && b.rel < 0.02, "{}: {:e}", b.name, b.rel);
    }
    // The drive is at most the drag's cap: the force whose linear peak response is the
    // amplitude a = 3γ/(drag1 ω) (2.5 um), rounded to three digits.
    let (w, q, drag) = (std::f64::consts::TAU * 1e4, 2000.0, 5.9e2);
    let cap = 3.0 * (w / q) / (drag * w) * w * w / q;
    let force = plan.measurements[0].force["q1"][0];
    assert!(
        force > 0.0 && force <= cap * 1.001,
        "{force} N/kg over the cap {cap}"
    );
    // `simulate --plan` accepts it: the default truncation and stability checks pass.
    let text = plan.to_toml();
    let back = Plan::from_toml(&text, "plan.toml").expect("the written plan reads back");
    let sim = back
        .simulate(&model, &values, &Settings::default())
        .expect("simulate accepts the plan");
    let r = &sim.reports[0];
    let change = r.truncation_change.expect("checked");
    assert!(change < 1e-6, "truncation change {change:e}");
    let big = sim.dataset.measurements[0]
        .data
        .iter()
        .map(|x| x.norm())
        .fold(0.0, f64::max);
    assert!(big > 1e-7 && big < 1e-5, "largest line {big:e} m");
    println!(
        "force {force} N/kg (cap {cap:.3}), order {} ({} lines), change {change:.1e}, largest line {big:.3e} m, {:.2} s",
        r.order,
        r.lattice_lines,
        t0.elapsed().as_secs_f64()
    );
}
