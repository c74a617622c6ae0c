//! Sparse products of variables, `x_a^k_a · x_b^k_b · …`, in canonical order.

use crate::Overflow;
use smallvec::SmallVec;
use std::cmp::Ordering;
use std::fmt::Write as _;

/// Index of a variable: a mode (in declaration order) for [`crate::Poly`], a parameter for
/// [`crate::Coeff`]. Names live with the caller; printing takes a slice of names indexed by it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct VarId(pub u32);

impl VarId {
    /// The index as `usize`, for slicing name or value tables.
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// A product of variables with positive exponents, e.g. `q1*q2^2`; the empty product is `1`.
///
/// Factors are kept sorted by [`VarId`] with no zero exponents, so equal products are equal
/// values. The order between products ([`Ord`]) is graded: lower total degree first, then, among
/// equal degrees, higher powers of earlier variables first (`q1^3 < q1^2*q2 < q1*q2^2 < q2^3`).
#[derive(Debug, Clone, PartialEq, Eq, Hash, Default)]
pub struct PowerProduct {
    factors: SmallVec<[(VarId, u32); 4]>,
    /// Total degree, cached: the graded order compares it first on every comparison.
    degree: u32,
}

impl PowerProduct {
    /// The empty product, `1`.
    pub fn one() -> Self {
        Self::default()
    }

    /// A single variable to the first power.
    pub fn var(v: VarId) -> Self {
        Self::pow_of(v, 1)
    }

    /// `v^k` (the empty product when `k == 0`).
    pub fn pow_of(v: VarId, k: u32) -> Self {
        let mut factors = SmallVec::new();
        if k > 0 {
            factors.push((v, k));
        }
        Self { factors, degree: k }
    }

    /// Builds a product from `(variable, exponent)` pairs in any order; repeated variables add
    /// their exponents and zero exponents vanish.
    pub fn from_factors(pairs: impl IntoIterator<Item = (VarId, u32)>) -> Result<Self, Overflow> {
        let mut out = Self::one();
        for (v, k) in pairs {
            out = out.checked_mul(&Self::pow_of(v, k))?;
        }
        Ok(out)
    }

    /// Builds a product from a dense exponent vector: `exps[i]` is the power of `VarId(i)`.
    pub fn from_exponents(exps: &[u32]) -> Self {
        let factors = exps
            .iter()
            .enumerate()
            .filter(|(_, &k)| k > 0)
            .map(|(i, &k)| (VarId(i as u32), k))
            .collect();
        let degree = exps.iter().fold(0u32, |a, &k| a.saturating_add(k));
        Self { factors, degree }
    }

    /// The `(variable, exponent)` factors, sorted by variable, exponents ≥ 1.
    pub fn factors(&self) -> &[(VarId, u32)] {
        &self.factors
    }

    /// Total degree (sum of exponents); 0 for the empty product.
    pub fn degree(&self) -> u32 {
        self.degree
    }

    /// Whether this is the empty product `1`.
    pub fn is_one(&self) -> bool {
        self.factors.is_empty()
    }

    /// The exponent of `v` (0 if absent).
    pub fn exponent(&self, v: VarId) -> u32 {
        self.factors
            .iter()
            .find(|&&(w, _)| w == v)
            .map_or(0, |&(_, k)| k)
    }

    /// Dense exponent vector of length `n` (variables beyond `n` are ignored).
    pub fn exponents(&self, n: usize) -> Vec<u32> {
        let mut out = vec![0; n];
        for &(v, k) in &self.factors {
            if let Some(slot) = out.get_mut(v.index()) {
                *slot = k;
            }
        }
        out
    }

    /// The product with another power product (exponents add).
    pub fn checked_mul(&self, other: &Self) -> Result<Self, Overflow> {
        let mut factors = SmallVec::with_capacity(self.factors.len() + other.factors.len());
        let (mut i, mut j) = (0, 0);
        while i < self.factors.len() || j < other.factors.len() {
            match (self.factors.get(i), other.factors.get(j)) {
                (Some(&(a, ka)), Some(&(b, kb))) if a == b => {
                    factors.push((a, ka.checked_add(kb).ok_or(Overflow)?));
                    i += 1;
                    j += 1;
                }
                (Some(&(a, ka)), Some(&(b, _))) if a < b => {
                    factors.push((a, ka));
                    i += 1;
                }
                (Some(_), Some(&(b, kb))) => {
                    factors.push((b, kb));
                    j += 1;
                }
                (Some(&f), None) => {
                    factors.push(f);
                    i += 1;
                }
                (None, Some(&f)) => {
                    factors.push(f);
                    j += 1;
                }
                (None, None) => break,
            }
        }
        let degree = self.degree.checked_add(other.degree).ok_or(Overflow)?;
        Ok(Self { factors, degree })
    }

    /// `∂/∂v` of this product: `Some((k, rest))` meaning `k · rest`, or `None` if `v` is absent.
    pub fn derivative(&self, v: VarId) -> Option<(u32, Self)> {
        let pos = self.factors.iter().position(|&(w, _)| w == v)?;
        let k = self.factors[pos].1;
        let mut rest = self.clone();
        rest.degree -= 1;
        if k == 1 {
            rest.factors.remove(pos);
        } else {
            rest.factors[pos].1 = k - 1;
        }
        Some((k, rest))
    }

    /// The variables with their exponents expanded into a flat list, `q1*q2^2 → [q1, q2, q2]`.
    pub fn flat_factors(&self) -> Vec<VarId> {
        self.factors
            .iter()
            .flat_map(|&(v, k)| std::iter::repeat_n(v, k as usize))
            .collect()
    }

    /// Canonical name: factors in variable order, `name^k` for k ≥ 2, joined by `*`; `"1"` for the
    /// empty product. This is the monomial name of `DATA_FORMAT.md` when `names` are the mode
    /// names in declaration order.
    pub fn name(&self, names: &[impl AsRef<str>]) -> String {
        self.join(names, "*", |k| format!("^{k}"))
    }

    /// Name with a custom separator and exponent format, e.g. `" "` and `^{k}` for LaTeX.
    pub fn join(
        &self,
        names: &[impl AsRef<str>],
        sep: &str,
        power: impl Fn(u32) -> String,
    ) -> String {
        if self.factors.is_empty() {
            return "1".to_string();
        }
        let mut out = String::new();
        for (i, &(v, k)) in self.factors.iter().enumerate() {
            if i > 0 {
                out.push_str(sep);
            }
            match names.get(v.index()) {
                Some(n) => out.push_str(n.as_ref()),
                None => {
                    let _ = write!(out, "x{}", v.0);
                }
            }
            if k >= 2 {
                out.push_str(&power(k));
            }
        }
        out
    }
}

impl Ord for PowerProduct {
    /// Graded lexicographic order (a monomial order: `a < b` implies `a·c < b·c`, so dividing
    /// every term of a sorted polynomial by one variable keeps it sorted).
    fn cmp(&self, other: &Self) -> Ordering {
        self.degree.cmp(&other.degree).then_with(|| {
            // Same degree: walk both factor lists; the product with the earlier variable, or
            // the higher power of the same variable, comes first.
            for (&(a, ka), &(b, kb)) in self.factors.iter().zip(other.factors.iter()) {
                if a != b {
                    return a.cmp(&b);
                }
                if ka != kb {
                    return kb.cmp(&ka);
                }
            }
            self.factors.len().cmp(&other.factors.len())
        })
    }
}

impl PartialOrd for PowerProduct {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pp(exps: &[u32]) -> PowerProduct {
        PowerProduct::from_exponents(exps)
    }

    #[test]
    fn names_follow_data_format() {
        let names = ["q1", "q2", "q3"];
        assert_eq!(pp(&[3, 0, 0]).name(&names), "q1^3");
        assert_eq!(pp(&[1, 2, 0]).name(&names), "q1*q2^2");
        assert_eq!(pp(&[1, 1, 1]).name(&names), "q1*q2*q3");
        assert_eq!(pp(&[0, 2, 0]).name(&names), "q2^2");
        assert_eq!(pp(&[0, 0, 0]).name(&names), "1");
    }

    #[test]
    fn graded_order() {
        let mut v = vec![
            pp(&[0, 3]),
            pp(&[1, 2]),
            pp(&[3, 0]),
            pp(&[2, 1]),
            pp(&[1, 0]),
        ];
        v.sort();
        assert_eq!(
            v,
            vec![
                pp(&[1, 0]),
                pp(&[3, 0]),
                pp(&[2, 1]),
                pp(&[1, 2]),
                pp(&[0, 3])
            ]
        );
    }

    #[test]
    fn multiplication_and_derivative() {
        let a = pp(&[1, 2, 0]);
        let b = pp(&[0, 1, 1]);
        assert_eq!(a.checked_mul(&b), Ok(pp(&[1, 3, 1])));
        assert_eq!(a.derivative(VarId(1)), Some((2, pp(&[1, 1, 0]))));
        assert_eq!(a.derivative(VarId(0)), Some((1, pp(&[0, 2, 0]))));
        assert_eq!(a.derivative(VarId(2)), None);
        assert_eq!(a.flat_factors(), vec![VarId(0), VarId(1), VarId(1)]);
    }
}
