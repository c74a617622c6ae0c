//! Pooling the shots of each measurement: robust rejection of disturbed shots, the coherent
//! mean spectrum, and the noise of every measured line from the shot scatter.
//!
//! Shots of one measurement observe the same steady state, so their complex amplitudes are
//! averaged line by line (per frequency and point). Before that, a shot is rejected as disturbed
//! when its spectrum is too far from the others' for the noise they show. For one line `o` of a
//! shot among `m`, the internally studentised deviation
//! `r_o = m/(m − 1) · |x_o − x̄_o|² / Σ_t |x_{t,o} − x̄_o|²` has, for circular Gaussian noise
//! (the same σ in both quadratures, the fit's noise model), the exact tail
//! `P(r_o > ρ) = (1 − ρ)^{m−2}` whatever σ and the mean: it is the leave-one-out statistic
//! `F(2, 2(m − 2))` written without the shot's own scatter. The lines' p-values are combined by
//! Fisher's method (`−2 Σ_o ln p_o ~ χ²_{2L}` over the `L` lines that scatter), so a shot off
//! on one line or a little off on many is found alike, and lines of very different noise count
//! by their own. The test runs as Rosner's generalised ESD: the least likely shot is set aside,
//! the rest tested again, up to `⌊(n − 1)/2⌋` shots while three remain (ten stages, then on
//! only while they find), and the shots up to the last stage whose p-value is below the level
//! are rejected, so that shots disturbed alike (a jump of the state during the measurement)
//! do not hide each other.
//!
//! **Level.** A dataset of `N` shots tested in all (the shots of every measurement without a
//! given noise) is tested at `p < α/(N·S)`, `α` = [`REJECTION_ALPHA`] = 1 %, `S` the stages the
//! search runs on clean data (`⌊(n − 1)/2⌋`, 1 to 10): a dataset whose shots are all clean
//! loses any in at most about 1 % of datasets, whatever its numbers of measurements, shots and
//! lines (Bonferroni over exact p-values; measured 0.0–1.4 ± 0.4 % for 2–50 shots and 10–2000
//! steps, `tests/it/disturbed_shots_mc.rs`). The rule before this one (`d²/median(d²)` with
//! robust MAD scales, a threshold `k(L)(1 + 4/n)` set for a per-shot rate) rejected 7 shots of
//! every clean 480-step sweep of 4 shots on average, each a warning. What it costs: at 4 shots a
//! step the scale of a line is known from three others only; in a 480-step sweep of one line a
//! shot displaced by 50 σ is caught in 63 % of cases, by 100 σ always; at 10 shots by 10 σ in
//! 65 %, by 20 σ always; at 30 shots by 10 σ in 99.8 % (σ per quadrature). Two shots are never
//! rejected (nothing tells which is off), three only when wildly so. Non-finite shots are
//! always rejected.
//!
//! The noise of a line is the sample standard deviation per quadrature of the kept shots,
//! `σ_o² = Σ_s |x_{s,o} − x̄_o|² / (2(n − 1))` (m); the mean's is `σ_o/√n`. A measurement whose
//! rows are averages with their noise given (an instrument's sweeper: the dataset's `std` and
//! `samples` columns) is its own mean, with that noise.

use harmonid_data::Dataset;
use num_complex::Complex64;

/// The pooled dataset and what pooling found.
#[derive(Debug, Clone)]
pub struct Pooled {
    /// The dataset with one shot per measurement: the mean of its kept shots.
    pub mean: Dataset,
    /// Per measurement, the shots rejected as disturbed (ascending).
    pub rejected: Vec<Vec<usize>>,
    /// Per measurement, the number of shots averaged.
    pub used: Vec<usize>,
    /// Per measurement, the noise per quadrature of one shot at every (frequency, point), m,
    /// in the order of a shot's data; `None` when the measurement has fewer than 2 kept shots
    /// or a line does not scatter (noise-free data).
    pub sigma: Vec<Option<Vec<f64>>>,
}

impl Pooled {
    /// Per measurement of `ds` (the dataset that was pooled), the shots kept in the mean.
    pub fn kept(&self, ds: &Dataset) -> Vec<Vec<usize>> {
        ds.measurements
            .iter()
            .zip(&self.rejected)
            .map(|(m, bad)| (0..m.n_shots).filter(|s| !bad.contains(s)).collect())
            .collect()
    }

    /// Whether every measurement has a noise estimate from the shot scatter.
    pub fn noise_from_shots(&self) -> bool {
        self.sigma.iter().all(Option::is_some)
    }
}

/// Family-wise false-alarm probability of the rejection: the chance that a dataset whose shots
/// are all undisturbed (Gaussian, circular noise per line) loses any shot, whatever its numbers
/// of measurements, shots and lines (an upper bound: Bonferroni over exact p-values).
pub const REJECTION_ALPHA: f64 = 0.01;

/// Stages of the outlier search run even when they find nothing (a shot hidden by up to this
/// many others is found); beyond them it goes on only while it finds.
const MASKING_STAGES: usize = 10;

/// The shots of one measurement (`data[shot][line]`) that pooling rejects as disturbed, for a
/// dataset of `family_shots` shots tested in all (at least `data.len()`; the per-shot level is
/// [`REJECTION_ALPHA`]` / family_shots`); see the module documentation. Shots with a value that
/// is not finite are rejected whatever the others.
pub fn disturbed_shots(data: &[&[Complex64]], family_shots: usize) -> Vec<usize> {
    let n = data.len();
    let lines = data.first().map_or(0, |d| d.len());
    if lines == 0 || data.iter().any(|d| d.len() != lines) {
        return Vec::new();
    }
    let finite = |d: &[Complex64]| d.iter().all(|z| z.re.is_finite() && z.im.is_finite());
    let mut bad: Vec<usize> = (0..n).filter(|&s| !finite(data[s])).collect();
    let mut kept: Vec<usize> = (0..n).filter(|s| !bad.contains(s)).collect();
    // Generalised ESD (Rosner): the most outlying shot is set aside stage by stage, at most
    // `⌊(n − 1)/2⌋` of them (more than half are kept) while 3 remain; every stage's p-value is
    // that of its own sample; the shots up to the last stage below the level are rejected, so a
    // disturbed shot hidden by another (masking) is still found.
    let most = kept.len().saturating_sub(1) / 2;
    // Each stage that runs on clean data is a chance of a false alarm: the level is shared
    // between them (one stage alone at the level lost any shot of clean 10-shot sets in 2 %
    // of 1 000 ten-step datasets, not 1 %).
    let stages = most.clamp(1, MASKING_STAGES);
    let ln_level = (REJECTION_ALPHA / (family_shots.max(n).max(1) * stages) as f64).ln();
    let mut order = Vec::new();
    let mut last_significant = 0;
    while order.len() < most && kept.len() >= 3 {
        let Some((pos, ln_p)) = most_outlying(data, &kept) else {
            break;
        };
        order.push(kept.remove(pos));
        if ln_p < ln_level {
            last_significant = order.len();
        } else if order.len() >= MASKING_STAGES {
            // A long record: masking by more shots than this is not looked for.
            break;
        }
    }
    bad.extend(&order[..last_significant]);
    bad.sort_unstable();
    bad
}

/// The position in `kept` of the shot whose spectrum is least likely under the others and the
/// logarithm of its p-value; `None` when no line scatters (noise-free data). Per line `o` the
/// internally studentised deviation `r = m/(m − 1) · |x_o − x̄_o|² / Σ_t |x_{t,o} − x̄_o|²` of a
/// shot among the `m` kept has, for circular Gaussian noise, the exact tail
/// `P(r > ρ) = (1 − ρ)^{m−2}` (Beta(1, m − 2): its leave-one-out form is `F(2, 2(m − 2))`);
/// the lines' p-values are combined by Fisher's method, `−2 Σ_o ln p_o ~ χ²_{2L}`.
fn most_outlying(data: &[&[Complex64]], kept: &[usize]) -> Option<(usize, f64)> {
    let m = kept.len();
    let mf = m as f64;
    let lines = data[kept[0]].len();
    let mut x2 = vec![0.0; m];
    let mut used = 0;
    // `o` indexes a line within every kept shot (`data[s][o]`), not `data` itself.
    #[allow(clippy::needless_range_loop)]
    for o in 0..lines {
        let mean = kept.iter().map(|&s| data[s][o]).sum::<Complex64>() / mf;
        let ss: f64 = kept.iter().map(|&s| (data[s][o] - mean).norm_sqr()).sum();
        if !(ss > 0.0 && ss.is_finite()) {
            continue;
        }
        used += 1;
        for (x, &s) in x2.iter_mut().zip(kept) {
            let r = mf / (mf - 1.0) * (data[s][o] - mean).norm_sqr() / ss;
            // −2 ln p_o = −2 (m − 2) ln(1 − r); r = 1 (the others identical) is p = 0.
            *x += if r < 1.0 {
                -2.0 * (mf - 2.0) * (-r).ln_1p()
            } else {
                f64::INFINITY
            };
        }
    }
    if used == 0 {
        return None;
    }
    let (pos, &worst) = x2.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
    Some((pos, ln_chi2_even_survival(worst, used)))
}

/// `ln P(χ²_{2l} > x)` for even degrees of freedom: `ln(e^{−x/2} Σ_{k<l} (x/2)^k / k!)`, summed
/// in logarithms so that a large `x` (a shot far off) or `l` (many lines) neither underflows
/// nor overflows; `−∞` for `x = ∞`.
pub(crate) fn ln_chi2_even_survival(x: f64, l: usize) -> f64 {
    if x.is_infinite() {
        return f64::NEG_INFINITY;
    }
    let h = 0.5 * x.max(0.0);
    if h == 0.0 {
        return 0.0;
    }
    let lh = h.ln();
    let (mut term, mut top, mut terms) = (0.0_f64, f64::NEG_INFINITY, Vec::with_capacity(l));
    for k in 0..l {
        if k > 0 {
            term += lh - (k as f64).ln();
        }
        terms.push(term);
        top = top.max(term);
    }
    let sum: f64 = terms.iter().map(|t| (t - top).exp()).sum();
    (-h + top + sum.ln()).min(0.0)
}

/// Pools every measurement of `ds`; see the module documentation.
pub fn pool(ds: &Dataset) -> Pooled {
    let mut mean = ds.clone();
    let mut rejected = Vec::with_capacity(ds.measurements.len());
    let mut used = Vec::with_capacity(ds.measurements.len());
    let mut sigma = Vec::with_capacity(ds.measurements.len());
    // Every shot the rejection tests is one chance of a false alarm: the level is shared.
    let family_shots = ds
        .measurements
        .iter()
        .filter(|m| m.noise.is_none())
        .map(|m| m.n_shots)
        .sum::<usize>();
    for m in &mut mean.measurements {
        if let Some(g) = &m.noise {
            // The instrument averaged each row and measured its noise (one shot): the mean as
            // given, each line's noise of the mean `std/√samples`, expressed per shot of the
            // fewest samples averaged (`used`), so `σ/√used` is that noise.
            let n = g.samples.iter().copied().min().unwrap_or(2).max(2);
            sigma.push(Some(
                g.std
                    .iter()
                    .zip(&g.samples)
                    .map(|(s, &k)| s * (f64::from(n) / f64::from(k)).sqrt())
                    .collect(),
            ));
            used.push(n as usize);
            rejected.push(Vec::new());
            continue;
        }
        let per = m.freqs_hz.len() * m.points.len();
        let shots: Vec<&[Complex64]> = (0..m.n_shots)
            .map(|s| &m.data[s * per..(s + 1) * per])
            .collect();
        let bad = disturbed_shots(&shots, family_shots);
        let kept: Vec<&[Complex64]> = shots
            .iter()
            .enumerate()
            .filter(|(s, _)| !bad.contains(s))
            .map(|(_, d)| *d)
            .collect();
        let n = kept.len();
        let mut avg = vec![Complex64::new(0.0, 0.0); per];
        for d in &kept {
            for (a, x) in avg.iter_mut().zip(d.iter()) {
                *a += x / n as f64;
            }
        }
        let sig = (n >= 2)
            .then(|| {
                (0..per)
                    .map(|o| {
                        let ss: f64 = kept.iter().map(|d| (d[o] - avg[o]).norm_sqr()).sum();
                        (ss / (2.0 * (n as f64 - 1.0))).sqrt()
                    })
                    .collect::<Vec<f64>>()
            })
            .filter(|s| s.iter().all(|&x| x > 0.0 && x.is_finite()));
        m.data = avg;
        m.n_shots = 1;
        rejected.push(bad);
        used.push(n);
        sigma.push(sig);
    }
    Pooled {
        mean,
        rejected,
        used,
        sigma,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn shots(n: usize, lines: usize, sigma: f64, seed: u64) -> Vec<Vec<Complex64>> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let d = Normal::new(0.0, sigma).expect("normal");
        (0..n)
            .map(|_| {
                (0..lines)
                    .map(|o| {
                        Complex64::new(o as f64, 1.0)
                            + Complex64::new(d.sample(&mut rng), d.sample(&mut rng))
                    })
                    .collect()
            })
            .collect()
    }

    fn refs(s: &[Vec<Complex64>]) -> Vec<&[Complex64]> {
        s.iter().map(Vec::as_slice).collect()
    }

    #[test]
    fn the_chi2_survival_matches_its_closed_forms() {
        // Two degrees of freedom: e^{−x/2}; four: e^{−x/2}(1 + x/2); six at x = 10:
        // e^{−5}(1 + 5 + 12.5) = 0.124652 (scipy's chi2.sf(10, 6)).
        for x in [0.1, 3.0, 40.0, 3000.0] {
            assert!((ln_chi2_even_survival(x, 1) + x / 2.0).abs() < 1e-12);
            let want = -x / 2.0 + (1.0 + x / 2.0).ln();
            assert!((ln_chi2_even_survival(x, 2) - want).abs() < 1e-12);
        }
        assert!((ln_chi2_even_survival(10.0, 3).exp() - 0.124_652).abs() < 1e-6);
        // Far in the tail and with many lines: finite logarithms, no underflow.
        let far = ln_chi2_even_survival(1e5, 500);
        assert!(far.is_finite() && far < -4e4, "{far}");
        // The median of χ²_{2000} is about 1999.3: p ≈ 0.5.
        let mid = ln_chi2_even_survival(1999.33, 1000).exp();
        assert!((mid - 0.5).abs() < 2e-3, "{mid}");
        assert_eq!(ln_chi2_even_survival(0.0, 4), 0.0);
        assert_eq!(ln_chi2_even_survival(f64::INFINITY, 4), f64::NEG_INFINITY);
    }

    /// Rejections among `sets` clean sets of `n` shots on `lines` lines, each set its own family.
    fn clean_rejections(n: usize, lines: usize, sets: u64, seed: u64) -> usize {
        (0..sets)
            .filter(|k| {
                let s = shots(n, lines, 1.0, seed + k);
                !disturbed_shots(&refs(&s), n).is_empty()
            })
            .count()
    }

    #[test]
    fn clean_sets_lose_a_shot_at_the_family_rate() {
        // The p-values are exact (Beta tails) and the Bonferroni bound nearly tight: a set of 3
        // or 4 shots (one stage) that is its own family loses any shot in just under 1 % of
        // sets, for any number of lines (4 000 sets: 40 ± 6.3). More shots run more stages,
        // each at its share of the level: at most 1 %.
        for (n, lines) in [(3, 1), (4, 1), (4, 3), (10, 1), (10, 4), (30, 3)] {
            let k = clean_rejections(n, lines, 4000, 50_000 + 7919 * n as u64);
            let low = if n <= 4 { 20 } else { 0 };
            assert!(
                (low..=60).contains(&k),
                "{n} shots, {lines} lines: {k} of 4000"
            );
        }
    }

    #[test]
    fn disturbed_shots_are_rejected_and_clean_ones_kept() {
        for (seed, lines) in [(1, 1), (2, 5), (3, 40)] {
            let mut s = shots(30, lines, 0.1, seed);
            assert!(disturbed_shots(&refs(&s), 30).is_empty(), "lines {lines}");
            for k in [4, 17, 22] {
                for (o, x) in s[k].iter_mut().enumerate() {
                    *x += Complex64::new(3.0 * (o as f64 + 1.0).sin(), -3.0);
                }
            }
            // Three shots moved together, each hiding the others from a one-at-a-time test.
            assert_eq!(
                disturbed_shots(&refs(&s), 30),
                vec![4, 17, 22],
                "lines {lines}"
            );
        }
    }

    #[test]
    fn a_shot_far_off_and_a_jump_are_caught_in_a_long_sweep() {
        // A 480-step sweep of 10 shots on one line (family 4 800 shots): one shot 15 σ off
        // (per quadrature, along a diagonal) is caught in each of 50 seeds; a step whose
        // state jumps before its last three shots (20 σ) loses exactly those.
        for seed in 0..50 {
            let mut s = shots(10, 1, 1.0, 700 + seed);
            s[6][0] += Complex64::new(15.0, 15.0) / 2_f64.sqrt();
            assert_eq!(disturbed_shots(&refs(&s), 4800), vec![6], "seed {seed}");
            let mut s = shots(10, 1, 1.0, 900 + seed);
            for x in &mut s[7..] {
                x[0] += Complex64::new(0.0, 20.0);
            }
            assert_eq!(
                disturbed_shots(&refs(&s), 4800),
                vec![7, 8, 9],
                "seed {seed}"
            );
        }
    }

    #[test]
    fn noise_free_or_two_shots_reject_nothing_and_non_finite_shots_go() {
        let s = shots(10, 4, 0.0, 1);
        assert!(disturbed_shots(&refs(&s), 10).is_empty());
        let mut s = shots(2, 4, 1.0, 1);
        s[1][0] += Complex64::new(1e6, 0.0);
        assert!(disturbed_shots(&refs(&s), 2).is_empty());
        let mut s = shots(5, 2, 1.0, 1);
        s[3][1] = Complex64::new(f64::NAN, 0.0);
        assert_eq!(disturbed_shots(&refs(&s), 5), vec![3]);
    }

    #[test]
    fn pooling_averages_kept_shots_and_measures_their_noise() {
        use harmonid_data::{Manifest, Measurement, MeasurementSpec};
        let spec = MeasurementSpec::new("m", vec![10.0]);
        let s = shots(400, 3, 0.2, 9);
        let mut m = Measurement::zeros(spec.clone(), vec![10.0, 11.0, 12.0], vec![], 400);
        for (k, shot) in s.iter().enumerate() {
            for (o, &x) in shot.iter().enumerate() {
                *m.amplitude_mut(k, o, 0) = x;
            }
        }
        // One disturbed shot.
        *m.amplitude_mut(7, 1, 0) += Complex64::new(50.0, 0.0);
        let mut manifest = Manifest::new("t");
        manifest.measurements.push(spec);
        let ds = Dataset {
            dir: "t".into(),
            manifest,
            measurements: vec![m],
            truth: None,
            notes: Vec::new(),
        };
        let p = pool(&ds);
        assert_eq!(p.rejected, vec![vec![7]]);
        assert_eq!(p.used, vec![399]);
        assert!(p.noise_from_shots());
        let sig = p.sigma[0].as_ref().expect("sigma");
        for &x in sig {
            assert!((x / 0.2 - 1.0).abs() < 0.1, "{x}");
        }
        let mean = p.mean.measurements[0].amplitude(0, 1, 0);
        assert!(
            (mean - Complex64::new(1.0, 1.0)).norm() < 4.0 * 0.2 / 20.0,
            "{mean}"
        );
        assert_eq!(p.mean.measurements[0].n_shots, 1);
    }
}
