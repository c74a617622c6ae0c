//! Combination frequencies as exact lattice points `Σ_d k_d f_d` over a set of drive tones.
//!
//! A [`Combination`] keeps the integer vector `k` (not only the float), so coincident
//! combinations are recognised exactly and tables print `f1 + 2·f3 − f2`.

use crate::{SpectralError, FREQ_TOLERANCE_HZ};
use smallvec::SmallVec;
use std::fmt;

/// Most tones a [`ToneSet`] may hold.
pub const MAX_TONES: usize = 64;
/// Most points [`ToneSet::lattice`] may enumerate (memory bound).
pub const MAX_LATTICE_POINTS: usize = 1 << 20;

/// The drive tones (Hz, all > 0 and distinct) that span a frequency lattice, with labels used
/// when printing combinations (`f1`, `f2`, ... by default).
#[derive(Debug, Clone, PartialEq)]
pub struct ToneSet {
    hz: Vec<f64>,
    labels: Vec<String>,
}

impl ToneSet {
    /// Tones at `hz` (Hz), labelled `f1`, `f2`, ... in order.
    ///
    /// Errors: a tone ≤ 0 Hz or not finite, two tones within [`FREQ_TOLERANCE_HZ`], more than
    /// [`MAX_TONES`] tones.
    pub fn new(hz: &[f64]) -> Result<Self, SpectralError> {
        let labels = (1..=hz.len()).map(|d| format!("f{d}")).collect();
        Self::with_labels(hz, labels)
    }

    /// Tones with custom labels (one per tone).
    pub fn with_labels(hz: &[f64], labels: Vec<String>) -> Result<Self, SpectralError> {
        if hz.len() > MAX_TONES {
            return Err(SpectralError::TooManyTones {
                count: hz.len(),
                limit: MAX_TONES,
            });
        }
        if labels.len() != hz.len() {
            return Err(SpectralError::Invalid(format!(
                "{} tones but {} labels",
                hz.len(),
                labels.len()
            )));
        }
        for (index, &f) in hz.iter().enumerate() {
            if !(f.is_finite() && f > 0.0) {
                return Err(SpectralError::NonPositiveFrequency {
                    what: "tone",
                    index,
                    hz: f,
                });
            }
        }
        for i in 0..hz.len() {
            for j in i + 1..hz.len() {
                if (hz[i] - hz[j]).abs() <= FREQ_TOLERANCE_HZ {
                    return Err(SpectralError::CoincidentFrequencies {
                        what: "tone",
                        first: i,
                        second: j,
                        hz: hz[i],
                    });
                }
            }
        }
        Ok(Self {
            hz: hz.to_vec(),
            labels,
        })
    }

    /// Number of tones.
    pub fn len(&self) -> usize {
        self.hz.len()
    }

    /// Whether there are no tones.
    pub fn is_empty(&self) -> bool {
        self.hz.is_empty()
    }

    /// The tone frequencies, Hz.
    pub fn hz(&self) -> &[f64] {
        &self.hz
    }

    /// The labels used when printing.
    pub fn labels(&self) -> &[String] {
        &self.labels
    }

    /// The combination that is tone `d` itself.
    pub fn unit(&self, d: usize) -> Combination {
        let mut k = Combination::zero(self.len());
        if let Some(x) = k.0.get_mut(d) {
            *x = 1;
        }
        k
    }

    /// A combination from an integer vector over the tones (length must be [`ToneSet::len`]).
    pub fn combination(&self, k: &[i32]) -> Result<Combination, SpectralError> {
        if k.len() != self.len() {
            return Err(SpectralError::Invalid(format!(
                "combination has {} coefficients, the tone set has {} tones",
                k.len(),
                self.len()
            )));
        }
        Ok(Combination(k.iter().copied().collect()))
    }

    /// Every lattice point `Σ k_d f_d ≥ 0` of intermodulation order `Σ|k_d| ≤ max_order`, sorted
    /// by frequency. Combinations that land on the same frequency (within
    /// [`FREQ_TOLERANCE_HZ`]) are one point, represented by the lowest-order one. The zero
    /// combination (DC) is included.
    ///
    /// Errors: more than [`MAX_LATTICE_POINTS`] points would be enumerated.
    pub fn lattice(&self, max_order: u32) -> Result<Vec<LatticePoint>, SpectralError> {
        let needed = lattice_count(self.len(), max_order);
        if needed > MAX_LATTICE_POINTS {
            return Err(SpectralError::TooLarge {
                what: "the tone lattice",
                needed,
                limit: MAX_LATTICE_POINTS,
            });
        }
        let mut all = Vec::with_capacity(needed);
        let mut k = vec![0i32; self.len()];
        enumerate(&mut k, 0, max_order as i32, &mut all);
        let mut points: Vec<LatticePoint> = all
            .into_iter()
            .map(|k| {
                let c = Combination(k.into_iter().collect());
                let hz = c.hz(self);
                LatticePoint { combination: c, hz }
            })
            .filter(|p| {
                p.hz > FREQ_TOLERANCE_HZ
                    || (p.hz.abs() <= FREQ_TOLERANCE_HZ && p.combination.is_canonical())
            })
            .collect();
        points.sort_by(|a, b| {
            a.hz.total_cmp(&b.hz)
                .then(a.combination.order().cmp(&b.combination.order()))
        });
        let mut out: Vec<LatticePoint> = Vec::with_capacity(points.len());
        for p in points {
            match out.last_mut() {
                Some(last) if p.hz - last.hz <= FREQ_TOLERANCE_HZ => {
                    if p.combination.order() < last.combination.order() {
                        *last = p;
                    }
                }
                _ => out.push(p),
            }
        }
        Ok(out)
    }
}

/// Number of integer vectors of dimension `d` with `Σ|k| ≤ n` (saturating).
fn lattice_count(d: usize, n: u32) -> usize {
    // Σ_i 2^i C(d,i) C(n,i).
    let mut total: usize = 1; // i = 0
    let mut cd: usize = 1; // C(d, i)
    let mut cn: usize = 1; // C(n, i)
    let mut p2: usize = 1;
    for i in 1..=d.min(n as usize) {
        cd = cd.saturating_mul(d - i + 1) / i;
        cn = cn.saturating_mul(n as usize - i + 1) / i;
        p2 = p2.saturating_mul(2);
        total = total.saturating_add(p2.saturating_mul(cd).saturating_mul(cn));
    }
    total
}

fn enumerate(k: &mut Vec<i32>, pos: usize, budget: i32, out: &mut Vec<Vec<i32>>) {
    if pos == k.len() {
        out.push(k.clone());
        return;
    }
    for v in -budget..=budget {
        k[pos] = v;
        enumerate(k, pos + 1, budget - v.abs(), out);
    }
    k[pos] = 0;
}

/// One point of the tone lattice: a combination and its frequency in Hz.
#[derive(Debug, Clone, PartialEq)]
pub struct LatticePoint {
    /// The integer vector over the tones.
    pub combination: Combination,
    /// `Σ k_d f_d`, Hz.
    pub hz: f64,
}

/// An integer combination `Σ_d k_d f_d` of the tones of a [`ToneSet`].
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Combination(SmallVec<[i32; 8]>);

impl Combination {
    /// The zero combination (DC) over `n` tones.
    pub fn zero(n: usize) -> Self {
        Self(SmallVec::from_elem(0, n))
    }

    /// The integer coefficients `k_d`.
    pub fn coeffs(&self) -> &[i32] {
        &self.0
    }

    /// Intermodulation order `Σ|k_d|`.
    pub fn order(&self) -> u32 {
        self.0.iter().map(|k| k.unsigned_abs()).sum()
    }

    /// Net count `Σ k_d` (1 for lines near a tone of a resonance, 0 for lines near DC, 3 near the
    /// third harmonic, ...).
    pub fn net(&self) -> i32 {
        self.0.iter().sum()
    }

    /// Whether every coefficient is 0.
    pub fn is_zero(&self) -> bool {
        self.0.iter().all(|&k| k == 0)
    }

    /// Whether the first nonzero coefficient is positive (or all are zero): of `k` and `−k`,
    /// exactly one is canonical.
    pub fn is_canonical(&self) -> bool {
        self.0.iter().find(|&&k| k != 0).is_none_or(|&k| k > 0)
    }

    /// The frequency `Σ k_d f_d` in Hz (negative for combinations below DC).
    pub fn hz(&self, tones: &ToneSet) -> f64 {
        self.0
            .iter()
            .zip(tones.hz())
            .map(|(&k, &f)| f64::from(k) * f)
            .sum()
    }

    /// `self + other` (None on overflow or length mismatch).
    pub fn checked_add(&self, other: &Self) -> Option<Self> {
        if self.0.len() != other.0.len() {
            return None;
        }
        let mut out = self.clone();
        for (a, &b) in out.0.iter_mut().zip(&other.0) {
            *a = a.checked_add(b)?;
        }
        Some(out)
    }

    /// `self − other` (None on overflow or length mismatch).
    pub fn checked_sub(&self, other: &Self) -> Option<Self> {
        self.checked_add(&other.neg())
    }

    /// `−self`.
    pub fn neg(&self) -> Self {
        Self(self.0.iter().map(|&k| k.saturating_neg()).collect())
    }

    /// The combination with coefficients `k` (a vector over the tones, in tone order). Prefer
    /// [`ToneSet::combination`], which checks the length against the tones.
    pub fn from_coeffs(k: &[i32]) -> Self {
        Self(k.iter().copied().collect())
    }

    /// `f1 + 2·f3 − f2`: positive terms first, then negative ones, in tone order; `0` for DC.
    /// This is the one formatter of combinations: every label of a line is made here.
    pub fn display_with(&self, labels: &[impl AsRef<str>]) -> String {
        self.format(labels, "·", " + ", " − ", "−")
    }

    /// Compact ASCII form for file headers and tables, e.g. `2fb-fa`, `fa+fb` (positive terms
    /// first, as a physicist writes it).
    pub fn compact_with(&self, labels: &[impl AsRef<str>]) -> String {
        self.format(labels, "", "+", "-", "-")
    }

    /// LaTeX form, e.g. `2\omega_1 - \omega_2` with `labels = ["\omega_1", "\omega_2"]`.
    pub fn latex_with(&self, labels: &[impl AsRef<str>]) -> String {
        self.format(labels, "", " + ", " - ", "-")
    }

    fn format(
        &self,
        labels: &[impl AsRef<str>],
        times: &str,
        plus: &str,
        minus: &str,
        lead_minus: &str,
    ) -> String {
        let label = |d: usize| {
            labels
                .get(d)
                .map_or_else(|| format!("f{}", d + 1), |s| s.as_ref().to_string())
        };
        let mut out = String::new();
        let pos = self.0.iter().enumerate().filter(|(_, &k)| k > 0);
        let neg = self.0.iter().enumerate().filter(|(_, &k)| k < 0);
        for (d, &k) in pos.chain(neg) {
            let sep = match (out.is_empty(), k > 0) {
                (true, true) => "",
                (true, false) => lead_minus,
                (false, true) => plus,
                (false, false) => minus,
            };
            out.push_str(sep);
            let a = k.unsigned_abs();
            if a != 1 {
                out.push_str(&format!("{a}{times}"));
            }
            out.push_str(&label(d));
        }
        if out.is_empty() {
            out.push('0');
        }
        out
    }
}

impl fmt::Display for Combination {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let labels: Vec<String> = (1..=self.0.len()).map(|d| format!("f{d}")).collect();
        f.write_str(&self.display_with(&labels))
    }
}

/// The mode whose nominal resonance `nominal_hz[n]` (Hz; `None` = unknown, skipped) is
/// spectrally closest to `hz`, with the signed distance `hz − nominal_hz[n]` in Hz.
/// The first of equally close modes wins. The one implementation of the attribution rule: the
/// identification's attribution of lines to modes uses it too ([`nearest_of`]).
pub fn nearest_mode(hz: f64, nominal_hz: &[Option<f64>]) -> Option<(usize, f64)> {
    nearest_of(hz, nominal_hz.iter().copied())
}

/// [`nearest_mode`] over any sequence of nominal resonances (Hz; `None` = unknown, skipped),
/// for callers that hold them in another form than a slice of options.
pub fn nearest_of(
    hz: f64,
    nominal_hz: impl IntoIterator<Item = Option<f64>>,
) -> Option<(usize, f64)> {
    nominal_hz
        .into_iter()
        .enumerate()
        .filter_map(|(n, f)| f.map(|f| (n, hz - f)))
        .min_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positive_terms_first() {
        let k = Combination::from_coeffs(&[-1, 2]);
        assert_eq!(k.compact_with(&["fa", "fb"]), "2fb-fa");
        assert_eq!(k.display_with(&["fa", "fb"]), "2·fb − fa");
        assert_eq!(
            Combination::from_coeffs(&[-1, -1]).compact_with(&["fa", "fb"]),
            "-fa-fb"
        );
        assert_eq!(
            Combination::from_coeffs(&[0, 0]).compact_with(&["fa", "fb"]),
            "0"
        );
    }

    #[test]
    fn printing_and_frequency() {
        let t = ToneSet::new(&[207572.0, 207592.0, 415842.0]).expect("tones");
        let c = t.combination(&[1, -1, 2]).expect("len");
        assert_eq!(c.display_with(t.labels()), "f1 + 2·f3 − f2");
        assert_eq!(c.to_string(), "f1 + 2·f3 − f2");
        assert_eq!(c.hz(&t), 207572.0 - 207592.0 + 2.0 * 415842.0);
        assert_eq!(c.order(), 4);
        assert_eq!(c.net(), 2);
        assert_eq!(
            t.combination(&[0, -2, 0]).expect("len").to_string(),
            "−2·f2"
        );
        assert_eq!(Combination::zero(3).to_string(), "0");
        assert_eq!(
            t.combination(&[2, -1, 0])
                .expect("len")
                .latex_with(&["\\omega_a", "\\omega_b", "c"]),
            "2\\omega_a - \\omega_b"
        );
        let near = nearest_mode(c.hz(&t), &[Some(207582.0), Some(415842.0)]);
        assert_eq!(near.map(|(n, _)| n), Some(1));
        assert_eq!(nearest_mode(1.0, &[None, None]), None);
    }

    #[test]
    fn lattice_points_are_counted_and_merged() {
        assert_eq!(lattice_count(2, 1), 5);
        assert_eq!(lattice_count(3, 2), 25);
        let t = ToneSet::new(&[100.0, 130.0]).expect("tones");
        let pts = t.lattice(2).expect("small");
        // Vectors with Σ|k| ≤ 2: 13 = DC + 6 pairs ±k; the positive member of each pair.
        let hz: Vec<f64> = pts.iter().map(|p| p.hz).collect();
        assert_eq!(hz, vec![0.0, 30.0, 100.0, 130.0, 200.0, 230.0, 260.0]);
        // Commensurate tones: 2·f1 = f2 is found exactly once, as f2 (order 1).
        let t = ToneSet::new(&[100.0, 200.0]).expect("tones");
        let pts = t.lattice(2).expect("small");
        let at200: Vec<_> = pts.iter().filter(|p| p.hz == 200.0).collect();
        assert_eq!(at200.len(), 1);
        assert_eq!(at200[0].combination.coeffs(), &[0, 1]);
        let many = ToneSet::new(&(1..=40).map(f64::from).collect::<Vec<_>>()).expect("tones");
        assert!(matches!(
            many.lattice(9),
            Err(SpectralError::TooLarge { .. })
        ));
    }

    #[test]
    fn bad_tones() {
        assert!(matches!(
            ToneSet::new(&[1.0, -2.0]),
            Err(SpectralError::NonPositiveFrequency { index: 1, .. })
        ));
        assert!(matches!(
            ToneSet::new(&[1.0, 2.0, 1.0]),
            Err(SpectralError::CoincidentFrequencies {
                first: 0,
                second: 2,
                ..
            })
        ));
        assert!(matches!(
            ToneSet::new(&vec![1.0; 100]),
            Err(SpectralError::TooManyTones { count: 100, .. })
        ));
    }
}
