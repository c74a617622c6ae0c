//! Harder stand-ins for the held-back lock-in measurement of issue 36 (12 drive levels, up and
//! down sweeps, a VELOCITY response), beside the kind one of `examples/nonsmooth_beam`, which
//! has no model error, no fold and no drift. Each is written as the lock-in exports it (the
//! columns and conventions of `examples/nonsmooth_beam/lockin.toml`: `sweep, drive_v, freq_hz,
//! x_v, y_v`, RMS volts of a vibrometer at 0.1 m/s per V, the drive in V at 10 N/kg per V):
//!
//! - `fold.csv`: `kappa1` four times the example's, so the strongest levels soften by about
//!   three linewidths and fold: the up and down sweeps follow different branches and jump;
//! - `model_error.csv`: the truth has a quintic stiffness `eps1*q1^5` the fitted model lacks
//!   (a hardening of 0.3 linewidth at 10 nm), and every step carries a 1 % complex gain
//!   scatter its own four samples do not show (the noise model under-states the scatter: the
//!   error floor has to take it);
//! - `drift.csv`: the resonance drifts by 0.1 linewidth over the measurement (a temperature
//!   drift: linear in the sweep's index, sweeps measured `up_l00, dn_l00, up_l01, ...`);
//! - `messy.csv`: the example's resonator on an uneven frequency grid (denser near the
//!   resonance, jittered), one step measured twice in a row, one row duplicated, one sample
//!   whose X and Y are `NaN`;
//! - `drag_only.csv`: a tenth of the linear damping (Q = 2e5) and three times the drag: the
//!   damping almost all quadratic drag, as the MFLI beam's fit finds.
//!
//! Written by `HELD_BACK_DIR=/tmp/held_back cargo test --release -p harmonid --test it --
//! held_back::write_harder_stand_ins --ignored` (1 s of simulation; not in CI). The
//! numbers they give (import, identify, `--holdout up_l11,dn_l11`) are in
//! `examples/nonsmooth_beam/README.md`.

use harmonid::data::Dataset;
use harmonid_testgen as gen;
use num_complex::Complex64;
use std::fmt::Write as _;

const MODEL: &str = include_str!("../../examples/nonsmooth_beam/model.hb");
/// The vibrometer's sensitivity (m/s per V) and the actuator's (N/kg per V), as in the example.
const METRES_PER_VOLT: f64 = 0.1;
const NEWTON_PER_KG_PER_VOLT: f64 = 10.0;

/// A seeded standard normal (SplitMix64 and Box–Muller: no dependency, reproducible).
struct Normal(u64);

impl Normal {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn next(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

fn model(src: &str) -> harmonid::model::Model {
    harmonid::model::parse_str(src, "stand_in.hb").expect("model")
}

fn values() -> gen::Values {
    gen::example_values("nonsmooth_beam", &["q1".to_string()])
}

/// Up and down sweeps at 12 levels (linear peak response 1 to 10 nm), 20 steps each over ±5
/// linewidths at the offsets `grid` (in linewidths, ascending).
fn sweeps(v: &gen::Values, grid: &[f64]) -> Vec<gen::SteppedSweep> {
    let (f, q) = (v.f_hz[0], v.q[0]);
    let w = std::f64::consts::TAU * f;
    let lw = f / q;
    let mut out = Vec::new();
    for l in 0..12 {
        let x = 1e-9 + 9e-9 * l as f64 / 11.0;
        let force = x * w * w / q;
        let up: Vec<(f64, f64)> = grid.iter().map(|g| (f + lw * g, force)).collect();
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

fn even_grid() -> Vec<f64> {
    (0..20).map(|s| 10.0 * s as f64 / 19.0 - 5.0).collect()
}

/// The example's noise and feedthrough on a clean simulation (4 samples per step; in metres).
fn noisy(clean: &Dataset, seed: u64) -> Dataset {
    let mut ds = clean.clone();
    let b = Complex64::new(2.5e-14, -1.5e-14);
    for m in &mut ds.measurements {
        let (levels, _) = m.spec.drive_levels_and_phases().expect("levels");
        for x in &mut m.data {
            *x += b * levels[0];
        }
    }
    gen::add_noise(&ds, 3e-11, seed)
}

/// The rows of `ds` as the lock-in writes them: (sweep, drive V, frequency Hz, X V, Y V).
fn rows(ds: &Dataset) -> Vec<(String, f64, f64, f64, f64)> {
    let mut out = Vec::new();
    for m in &ds.measurements {
        let sweep = &m.spec.sweep.as_ref().expect("a sweep step").sweep;
        let (levels, _) = m.spec.drive_levels_and_phases().expect("levels");
        let f = m.freqs_hz[0];
        let iw = Complex64::new(0.0, std::f64::consts::TAU * f);
        for x in &m.data {
            let z = iw * x / METRES_PER_VOLT / std::f64::consts::SQRT_2;
            out.push((
                sweep.clone(),
                levels[0] / NEWTON_PER_KG_PER_VOLT,
                f,
                z.re,
                z.im,
            ));
        }
    }
    out
}

fn write(dir: &std::path::Path, name: &str, rows: &[(String, f64, f64, f64, f64)]) {
    let mut out = String::from("sweep,drive_v,freq_hz,x_v,y_v\n");
    for (s, d, f, x, y) in rows {
        let _ = writeln!(out, "{s},{d:.6},{f:.6},{x:.9e},{y:.9e}");
    }
    std::fs::write(dir.join(name), out).expect("write");
}

/// The largest relative difference between a level's up and down sweep at the same frequency:
/// about 1 when they sit on different branches of a fold, the noise's otherwise.
fn hysteresis(ds: &Dataset, level: usize) -> f64 {
    let mean = |name: &str| -> Vec<(f64, Complex64)> {
        ds.measurements
            .iter()
            .filter(|m| m.spec.sweep.as_ref().is_some_and(|s| s.sweep == name))
            .map(|m| {
                let n = m.data.len() as f64;
                (m.freqs_hz[0], m.data.iter().sum::<Complex64>() / n)
            })
            .collect()
    };
    let up = mean(&format!("up_l{level:02}"));
    let dn = mean(&format!("dn_l{level:02}"));
    let peak = up.iter().map(|(_, x)| x.norm()).fold(0.0, f64::max);
    up.iter()
        .map(|(f, x)| {
            let y = dn.iter().find(|(g, _)| g == f).expect("same grid").1;
            (x - y).norm() / peak
        })
        .fold(0.0, f64::max)
}

/// Where the largest response of a sweep sits, in linewidths from the linear resonance.
fn peak_lw(ds: &Dataset, name: &str, v: &gen::Values) -> f64 {
    let (f, _) = ds
        .measurements
        .iter()
        .filter(|m| m.spec.sweep.as_ref().is_some_and(|s| s.sweep == name))
        .map(|m| (m.freqs_hz[0], m.data[0].norm()))
        .fold((0.0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
    (f - v.f_hz[0]) / (v.f_hz[0] / v.q[0])
}

/// The fold stand-in's values: the example's with `kappa1` and the damping `drag1`, `eta1`
/// scaled by `damping`.
fn fold_values(kappa1: f64, damping: f64) -> gen::Values {
    let mut v = values();
    v.params.insert("kappa1".into(), kappa1);
    for p in ["drag1", "eta1"] {
        *v.params.get_mut(p).expect(p) *= damping;
    }
    v
}

/// The fold stand-in (kappa1 = -2e18, half the damping: levels 10 and 11 fold, 2.4-2.9
/// linewidths of softening). FOLD_SCAN="kappa1:damping,..." first prints each candidate's
/// hysteresis (how the values were chosen; "-2.4e18:0.25" stops in the simulator: a step of
/// dn_l06 "stopped at 100.0 % of the drive").
fn fold(dir: &std::path::Path) {
    let scan = std::env::var("FOLD_SCAN").unwrap_or_default();
    for c in scan.split(',').filter(|c| !c.is_empty()) {
        let (k, d) = c.split_once(':').expect("kappa1:damping");
        let (k, d): (f64, f64) = (k.parse().expect("kappa1"), d.parse().expect("damping"));
        let v = fold_values(k, d);
        let clean =
            gen::simulate_sweeps_clean(&model(MODEL), &v, &sweeps(&v, &even_grid()), &[1.0], 1);
        for l in [4, 6, 8, 10, 11] {
            println!(
                "fold scan kappa1 {k:e} damping x{d}: level {l}: up/down differ by {:.3} of the peak; peaks at {:.2} (up), {:.2} (down) linewidths",
                hysteresis(&clean, l),
                peak_lw(&clean, &format!("up_l{l:02}"), &v),
                peak_lw(&clean, &format!("dn_l{l:02}"), &v)
            );
        }
    }
    // FOLD_VALUES="kappa1:damping" writes another fold instead (a stronger one, say).
    let (k, d) = std::env::var("FOLD_VALUES")
        .ok()
        .and_then(|c| {
            let (k, d) = c.split_once(':')?;
            Some((k.parse().ok()?, d.parse().ok()?))
        })
        .unwrap_or((-2.0e18, 0.5));
    let v = fold_values(k, d);
    let clean = gen::simulate_sweeps_clean(&model(MODEL), &v, &sweeps(&v, &even_grid()), &[1.0], 4);
    write(dir, "fold.csv", &rows(&noisy(&clean, 21)));
}

fn model_error(dir: &std::path::Path) {
    let mut v = values();
    v.params.insert("eps1".into(), 1.9e41);
    let src = MODEL.replace("eom q1 += ", "param eps1\neom q1 += eps1*q1^5 + ");
    let clean = gen::simulate_sweeps_clean(&model(&src), &v, &sweeps(&v, &even_grid()), &[1.0], 4);
    let mut ds = noisy(&clean, 22);
    let mut n = Normal(23);
    for m in &mut ds.measurements {
        let g = Complex64::new(1.0 + 0.01 * n.next(), 0.01 * n.next());
        for x in &mut m.data {
            *x *= g;
        }
    }
    write(dir, "model_error.csv", &rows(&ds));
}

fn drift(dir: &std::path::Path) {
    let v0 = values();
    let all = sweeps(&v0, &even_grid());
    let lw = v0.f_hz[0] / v0.q[0];
    let mut out = Vec::new();
    for (k, sw) in all.iter().enumerate() {
        let mut v = v0.clone();
        v.f_hz[0] += 0.1 * lw * k as f64 / (all.len() - 1) as f64;
        let clean =
            gen::simulate_sweeps_clean(&model(MODEL), &v, std::slice::from_ref(sw), &[1.0], 4);
        out.extend(rows(&noisy(&clean, 100 + k as u64)));
    }
    write(dir, "drift.csv", &out);
}

fn messy(dir: &std::path::Path) {
    let v = values();
    let mut n = Normal(31);
    // Denser near the resonance (|t|^1.5 of an even grid), jittered by up to 0.05 linewidth.
    let mut grid: Vec<f64> = (0..20)
        .map(|s| {
            let t = 2.0 * s as f64 / 19.0 - 1.0;
            5.0 * t.signum() * t.abs().powf(1.5) + 0.05 * (2.0 * n.uniform() - 1.0)
        })
        .collect();
    grid.sort_by(f64::total_cmp);
    let clean = gen::simulate_sweeps_clean(&model(MODEL), &v, &sweeps(&v, &grid), &[1.0], 4);
    let mut rows = rows(&noisy(&clean, 32));
    // up_l05's 8th step measured twice in a row (4 more samples at its frequency).
    let i = rows.iter().position(|r| r.0 == "up_l05").expect("up_l05") + 4 * 7;
    let again: Vec<_> = rows[i..i + 4].to_vec();
    rows.splice(i + 4..i + 4, again);
    // A row of dn_l03 written twice; a sample of up_l09 lost (nan).
    let j = rows.iter().position(|r| r.0 == "dn_l03").expect("dn_l03") + 10;
    rows.insert(j, rows[j].clone());
    let k = rows.iter().position(|r| r.0 == "up_l09").expect("up_l09") + 41;
    rows[k].3 = f64::NAN;
    rows[k].4 = f64::NAN;
    write(dir, "messy.csv", &rows);
}

/// Damping from drag alone: the linear damping a tenth of the example's (Q = 2e5), `drag1`
/// three times the example's (the response's width grows from 0.1 to about 1 linewidth of the
/// example's over the levels), `kappa1` halved; the example's forces (its Q), ±3 linewidths.
fn drag_only(dir: &std::path::Path) {
    let forces = values();
    let mut v = forces.clone();
    v.q[0] = 2.0e5;
    v.params.insert("drag1".into(), 6.0e3);
    v.params.insert("kappa1".into(), -2.0e17);
    let grid: Vec<f64> = (0..20).map(|s| 6.0 * s as f64 / 19.0 - 3.0).collect();
    let clean = gen::simulate_sweeps_clean(&model(MODEL), &v, &sweeps(&forces, &grid), &[1.0], 4);
    write(dir, "drag_only.csv", &rows(&noisy(&clean, 41)));
}

#[test]
#[ignore]
fn write_harder_stand_ins() {
    let dir = std::path::PathBuf::from(
        std::env::var("HELD_BACK_DIR").unwrap_or_else(|_| "/tmp/held_back".into()),
    );
    std::fs::create_dir_all(&dir).expect("mkdir");
    fold(&dir);
    model_error(&dir);
    drift(&dir);
    messy(&dir);
    drag_only(&dir);
}
