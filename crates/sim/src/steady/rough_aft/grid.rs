//! Where the non-smooth terms are sampled: a grid on the torus of the drive's generators.
//!
//! A lattice line is a combination `Ω_r = Σ_i k_{r,i} ω_i` of the generators `ω_i` (the drive
//! tones and half of each pump, [`crate::Excitation::generators_hz`]). A signal on the lattice,
//! `x(t) = Σ_r Re(X_r e^{iΩ_r t})`, is the torus function `x(θ) = Σ_r Re(X_r e^{i k_r·θ})` read
//! along `θ = ω t`. For generators without a low-order rational relation the time average of
//! any function of the signals equals its average over the torus (Weyl), so the harmonic
//! coefficient `F_r` of a non-smooth force is its torus coefficient at `k_r`. The torus is
//! sampled on an `N_1 × … × N_d` grid (each `N_i` a power of two), `θ_{j,i} = 2π j_i / N_i`.
//!
//! When the lines are harmonics `k_r f_0` of one frequency with few enough samples (one tone,
//! or tones whose spacing divides them), the grid is one-dimensional over the common period
//! `1/f_0`: exact for commensurate tones, whose low-order relations the torus would miss. With
//! two generators or more the smaller of the two grids is taken (the one-dimensional one on a
//! tie); one tone always keeps its period's grid (at least [`ROUGH_MIN_SAMPLES`] samples).

use crate::lattice::{enumerate, LINE_TOL_HZ};

/// Fewest samples of the common period (one-dimensional grid) for terms with a jump (`sign`,
/// `tanh`), whose cell averages err like `N^{-2}` (2e-7 relative for Coulomb friction here).
pub const ROUGH_MIN_SAMPLES: usize = 4096;
/// Fewest samples of the common period for terms without a jump (`abs`): their aliasing falls
/// like `N^{-3}` (about `6/N³` relative on the fundamental of `|x|x`, 5e-8 here), and every
/// evaluation and Jacobian costs in proportion to the samples.
pub const ROUGH_MIN_SAMPLES_SMOOTH: usize = 512;
/// Fewest samples per period of the highest harmonic on a one-dimensional grid.
pub const ROUGH_SAMPLES_PER_HARMONIC: usize = 32;
/// Highest harmonic of the common frequency a lattice line may be (one-dimensional grid).
const MAX_HARMONIC: usize = 8192;
/// Most samples of a grid (the tables hold `samples × lines` sines and cosines).
pub(crate) const MAX_SAMPLES: usize = 1 << 17;
/// Samples per period of the highest multiple `max_r |k_{r,i}|` of a generator along its axis,
/// and fewest samples along an axis a line uses, tried in turn until the grid fits
/// [`MAX_SAMPLES`]: `|x|x` aliases like `N^{-3}` along each axis.
const TORUS_RESOLUTION: [(usize, usize); 3] = [(32, 128), (16, 64), (8, 32)];

/// The sampling grid of one lattice.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Samples along each axis (powers of two; 1 for a generator no line uses).
    pub dims: Vec<usize>,
    /// The integer vector of each line, `k[r·d + i]`.
    pub k: Vec<i64>,
}

impl Grid {
    /// Number of axes `d`.
    pub fn axes(&self) -> usize {
        self.dims.len()
    }

    /// Total number of samples `Π N_i`.
    pub fn samples(&self) -> usize {
        self.dims.iter().product()
    }

    /// The grid for `lattice` (Hz, sorted) under the drive's `generators` (Hz), or why there is
    /// none (a sentence naming the lines).
    pub fn choose(generators: &[f64], lattice: &[f64]) -> Result<Self, String> {
        Self::choose_with(generators, lattice, ROUGH_MIN_SAMPLES)
    }

    /// [`Grid::choose`] with at least `least` samples on a one-dimensional grid
    /// (`ROUGH_MIN_SAMPLES`, 4096, with a jump; `ROUGH_MIN_SAMPLES_SMOOTH`, 512, without).
    pub fn choose_with(generators: &[f64], lattice: &[f64], least: usize) -> Result<Self, String> {
        let harmonic = common_harmonics(lattice).map(|ks| {
            let kmax = ks.iter().copied().max().unwrap_or(1).max(1);
            let nt = (ROUGH_SAMPLES_PER_HARMONIC * kmax)
                .max(least)
                .next_power_of_two()
                .min(MAX_SAMPLES);
            Self {
                dims: vec![nt],
                k: ks.iter().map(|&k| k as i64).collect(),
            }
        });
        let torus = torus_grid(generators, lattice);
        match (harmonic, torus) {
            (Some(h), Ok(t)) if t.axes() > 1 && t.samples() < h.samples() => Ok(t),
            (Some(h), _) => Ok(h),
            (None, t) => t,
        }
    }

    /// The neighbours of every sample one step back and one step on along the diagonal
    /// `(1, …, 1)` of the grid (every axis with more than one sample moves by one sample): a
    /// straight line on the torus, along which the cell averages of jumps are taken.
    pub fn neighbours(&self) -> (Vec<u32>, Vec<u32>) {
        let nt = self.samples();
        let mut prev = vec![0u32; nt];
        let mut next = vec![0u32; nt];
        let mut idx = vec![0usize; self.axes()];
        for j in 0..nt {
            let (mut p, mut n) = (0usize, 0usize);
            for (i, &len) in self.dims.iter().enumerate() {
                p = p * len + (idx[i] + len - 1) % len;
                n = n * len + (idx[i] + 1) % len;
            }
            prev[j] = p as u32;
            next[j] = n as u32;
            advance(&mut idx, &self.dims);
        }
        (prev, next)
    }
}

/// The next multi-index in row-major order (the last axis fastest), wrapping to zero.
fn advance(idx: &mut [usize], dims: &[usize]) {
    for i in (0..idx.len()).rev() {
        idx[i] += 1;
        if idx[i] < dims[i] {
            return;
        }
        idx[i] = 0;
    }
}

/// Highest intermodulation order searched for a line's integer vector, by number of generators
/// (about 10^4–10^5 candidate vectors).
fn search_order(d: usize) -> i64 {
    match d {
        0 | 1 => 4096,
        2 => 64,
        3 => 24,
        4 => 12,
        _ => 8,
    }
}

/// The torus grid: each line's lowest-order integer vector over the generators, and the
/// samples per axis from the largest multiple of each generator.
fn torus_grid(generators: &[f64], lattice: &[f64]) -> Result<Grid, String> {
    let d = generators.len();
    let k = line_vectors(generators, lattice)?;
    let kmax: Vec<usize> = (0..d)
        .map(|i| {
            (0..lattice.len())
                .map(|r| k[r * d + i].unsigned_abs() as usize)
                .max()
                .unwrap_or(0)
        })
        .collect();
    for &(per, least) in &TORUS_RESOLUTION {
        let dims: Vec<usize> = kmax
            .iter()
            .map(|&m| {
                if m == 0 {
                    1
                } else {
                    (per * m).max(least).next_power_of_two()
                }
            })
            .collect();
        if dims
            .iter()
            .try_fold(1usize, |a, &n| a.checked_mul(n))
            .is_some_and(|n| n <= MAX_SAMPLES)
        {
            return Ok(Grid { dims, k });
        }
    }
    let worst: Vec<String> = (0..lattice.len())
        .filter(|&r| (0..d).any(|i| k[r * d + i].unsigned_abs() as usize == kmax[i] && kmax[i] > 0))
        .take(6)
        .map(|r| {
            format!(
                "{} Hz = {}",
                lattice[r],
                combination(&k[r * d..(r + 1) * d])
            )
        })
        .collect();
    Err(format!(
        "sampling the torus of the {d} generators ({}) with at least 8 samples per period of the highest multiple of each ({}) needs more than {MAX_SAMPLES} samples; lower the lattice's order or drive fewer tones",
        hz_list(generators),
        worst.join(", ")
    ))
}

/// Each line's integer vector `k_r` over the generators with `Σ_i k_{r,i} g_i = f_r` (to the
/// line tolerance), the one of lowest order `Σ|k_i|` (first found among equals), `[r·d + i]`.
fn line_vectors(generators: &[f64], lattice: &[f64]) -> Result<Vec<i64>, String> {
    let d = generators.len();
    let tol = LINE_TOL_HZ.max(1e-12 * lattice.iter().copied().fold(0.0, f64::max));
    let mut best: Vec<Option<(i64, Vec<i64>)>> = vec![None; lattice.len()];
    let mut k = vec![0i64; d];
    enumerate(&mut k, 0, search_order(d), &mut |k| {
        let f: f64 = k.iter().zip(generators).map(|(&a, &b)| a as f64 * b).sum();
        if f < -tol {
            return;
        }
        let r = lattice.partition_point(|&x| x < f - tol);
        if lattice.get(r).is_none_or(|&x| (x - f).abs() > tol) {
            return;
        }
        let order: i64 = k.iter().map(|x| x.abs()).sum();
        if best[r].as_ref().is_none_or(|(o, _)| order < *o) {
            best[r] = Some((order, k.to_vec()));
        }
    });
    let missing: Vec<String> = lattice
        .iter()
        .zip(&best)
        .filter(|(_, b)| b.is_none())
        .take(6)
        .map(|(f, _)| format!("{f} Hz"))
        .collect();
    if !missing.is_empty() {
        return Err(format!(
            "the lines {} are not combinations of the drive's generators ({}) of order up to {}",
            missing.join(", "),
            hz_list(generators),
            search_order(d)
        ));
    }
    Ok(best.into_iter().flatten().flat_map(|(_, k)| k).collect())
}

/// `k·g` written out, e.g. `2 g1 − 1 g2`.
fn combination(k: &[i64]) -> String {
    let parts: Vec<String> = k
        .iter()
        .enumerate()
        .filter(|(_, &a)| a != 0)
        .map(|(i, &a)| format!("{a}·g{}", i + 1))
        .collect();
    if parts.is_empty() {
        "0".into()
    } else {
        parts.join(" + ")
    }
}

fn hz_list(f: &[f64]) -> String {
    f.iter()
        .enumerate()
        .map(|(i, f)| format!("g{} = {f} Hz", i + 1))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The whole numbers `k_r` with `lattice[r] = k_r f_0` for one common frequency `f_0` (the
/// greatest common divisor of the lines, by Euclid's algorithm to the line tolerance), or
/// `None` when the lines are not harmonics of one frequency up to [`MAX_HARMONIC`].
pub(crate) fn common_harmonics(lattice: &[f64]) -> Option<Vec<usize>> {
    let tol = LINE_TOL_HZ.max(1e-9 * lattice.iter().copied().fold(0.0, f64::max));
    let mut f0 = 0.0f64;
    for &f in lattice.iter().filter(|&&f| f > tol) {
        f0 = if f0 == 0.0 { f } else { float_gcd(f0, f, tol) };
    }
    if f0 == 0.0 {
        return Some(vec![0; lattice.len()]);
    }
    if f0 <= tol {
        return None;
    }
    let mut ks = Vec::with_capacity(lattice.len());
    for &f in lattice {
        let k = (f / f0).round();
        if k > MAX_HARMONIC as f64 || (f - k * f0).abs() > tol {
            return None;
        }
        ks.push(k as usize);
    }
    Some(ks)
}

/// The greatest common divisor of two positive frequencies to within `tol` (Hz): Euclid's
/// algorithm, a remainder within `tol` of 0 or of the divisor counting as none.
fn float_gcd(a: f64, b: f64, tol: f64) -> f64 {
    let (mut a, mut b) = (a.max(b), a.min(b));
    for _ in 0..200 {
        if b <= tol {
            return a;
        }
        let mut r = a % b;
        if r <= tol || b - r <= tol {
            r = 0.0;
        }
        a = b;
        b = r;
    }
    0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn harmonics_of_a_common_frequency() {
        assert_eq!(common_harmonics(&[0.0, 100.0, 300.0]), Some(vec![0, 1, 3]));
        assert_eq!(common_harmonics(&[200.0, 300.0]), Some(vec![2, 3]));
        assert_eq!(common_harmonics(&[9990.0, 9995.0]), Some(vec![1998, 1999]));
        assert_eq!(common_harmonics(&[100.0, 100.0 * 2f64.sqrt()]), None);
    }

    #[test]
    fn two_tones_sample_the_torus() {
        let g = [10003.7, 10011.2];
        // 2 g1 − g2, g1, g2, 2 g2 − g1 and the static line.
        let lat = [0.0, 2.0 * g[0] - g[1], g[0], g[1], 2.0 * g[1] - g[0]];
        let grid = Grid::choose(&g, &lat).expect("a grid");
        assert_eq!(grid.k, vec![0, 0, 2, -1, 1, 0, 0, 1, -1, 2]);
        // Largest multiple 2 on both axes: 32·2 → 128 samples each.
        assert_eq!(grid.dims, vec![128, 128]);
        let sampler = super::super::GridSampler::new(&grid);
        let (mut c, mut s) = (vec![0.0; 128 * 128], vec![0.0; 128 * 128]);
        sampler.add_line(1, num_complex::Complex64::new(1.0, 0.0), &mut c, None);
        sampler.add_line(1, num_complex::Complex64::new(0.0, -1.0), &mut s, None);
        // Sample (j1, j2) = (3, 5): line 2 g1 − g2 has phase 2π(6 − 5)/128.
        let j = 3 * 128 + 5;
        let th = std::f64::consts::TAU / 128.0;
        assert!((c[j] - th.cos()).abs() < 1e-15);
        assert!((s[j] - th.sin()).abs() < 1e-15);
        let (prev, next) = grid.neighbours();
        assert_eq!(
            (prev[j], next[j]),
            ((2 * 128 + 4) as u32, (4 * 128 + 6) as u32)
        );
        assert_eq!((prev[0], next[128 * 128 - 1]), ((128 * 128 - 1) as u32, 0));
    }

    #[test]
    fn harmonic_lattices_keep_one_period() {
        let grid = Grid::choose(&[100.0, 200.0], &[100.0, 200.0, 300.0]).expect("a grid");
        assert_eq!(
            (grid.dims.clone(), grid.k.clone()),
            (vec![4096], vec![1, 2, 3])
        );
        // Harmonics ~2000 of 5 Hz: the torus has fewer samples.
        let g = [9990.0, 9995.0];
        let grid = Grid::choose(&g, &[9985.0, 9990.0, 9995.0, 10000.0]).expect("a grid");
        assert_eq!(grid.axes(), 2);
        let (a, b) = (100.0, 100.0 * 2f64.sqrt());
        let err = Grid::choose(&[a, b], &[a, b, 100.0 * 3f64.sqrt()]).expect_err("no grid");
        assert!(err.contains("173.2"), "{err}");
    }
}
