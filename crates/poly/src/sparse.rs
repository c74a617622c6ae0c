//! Sparse polynomials over a ring of coefficients, in canonical term order.

use crate::{Overflow, PowerProduct, Rational, Ring, VarId};
use std::collections::BTreeMap;

/// A sparse polynomial `Σ c_m · m` over [`PowerProduct`]s `m` with coefficients in a [`Ring`].
///
/// Terms are kept in canonical order (see [`PowerProduct`]'s `Ord`) with no zero coefficients,
/// so two equal polynomials have identical term lists and print identically.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SparsePoly<C> {
    terms: BTreeMap<PowerProduct, C>,
}

impl<C: Ring> SparsePoly<C> {
    /// The zero polynomial.
    pub fn zero() -> Self {
        Self {
            terms: BTreeMap::new(),
        }
    }

    /// The constant polynomial `c`.
    pub fn constant(c: C) -> Self {
        Self::term(PowerProduct::one(), c)
    }

    /// The single term `c · m`.
    pub fn term(m: PowerProduct, c: C) -> Self {
        let mut p = Self::zero();
        if !c.is_zero() {
            p.terms.insert(m, c);
        }
        p
    }

    /// The polynomial `x_v`.
    pub fn var(v: VarId) -> Self {
        Self::term(PowerProduct::var(v), C::one())
    }

    /// Terms in canonical order, with nonzero coefficients.
    pub fn terms(&self) -> impl ExactSizeIterator<Item = (&PowerProduct, &C)> + Clone {
        self.terms.iter()
    }

    /// The coefficient of `m` (None when it is zero).
    pub fn coeff(&self, m: &PowerProduct) -> Option<&C> {
        self.terms.get(m)
    }

    /// Number of nonzero terms.
    pub fn len(&self) -> usize {
        self.terms.len()
    }

    /// Whether this is the zero polynomial.
    pub fn is_zero(&self) -> bool {
        self.terms.is_empty()
    }

    /// Whether there are no terms (the same as [`Self::is_zero`]).
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// Highest total degree of a term (0 for constants and for zero).
    pub fn degree(&self) -> u32 {
        self.terms.keys().map(PowerProduct::degree).max().unwrap_or(0)
    }

    /// The constant term, if the polynomial is a constant (or zero).
    pub fn as_constant(&self) -> Option<C> {
        match self.terms.len() {
            0 => Some(C::zero()),
            1 => self
                .terms
                .get(&PowerProduct::one())
                .cloned(),
            _ => None,
        }
    }

    /// Adds `c · m` in place, merging with an existing term and dropping it if it cancels.
    pub fn add_term(&mut self, m: PowerProduct, c: C) -> Result<(), Overflow> {
        if c.is_zero() {
            return Ok(());
        }
        match self.terms.entry(m) {
            std::collections::btree_map::Entry::Vacant(e) => {
                e.insert(c);
            }
            std::collections::btree_map::Entry::Occupied(mut e) => {
                let sum = e.get().checked_add(&c)?;
                if sum.is_zero() {
                    e.remove();
                } else {
                    *e.get_mut() = sum;
                }
            }
        }
        Ok(())
    }

    /// `self + other`.
    pub fn checked_add(&self, other: &Self) -> Result<Self, Overflow> {
        let mut out = self.clone();
        for (m, c) in &other.terms {
            out.add_term(m.clone(), c.clone())?;
        }
        Ok(out)
    }

    /// `self - other`.
    pub fn checked_sub(&self, other: &Self) -> Result<Self, Overflow> {
        self.checked_add(&other.checked_neg()?)
    }

    /// `-self`.
    pub fn checked_neg(&self) -> Result<Self, Overflow> {
        let mut terms = BTreeMap::new();
        for (m, c) in &self.terms {
            terms.insert(m.clone(), c.checked_neg()?);
        }
        Ok(Self { terms })
    }

    /// `self * other`, expanded.
    pub fn checked_mul(&self, other: &Self) -> Result<Self, Overflow> {
        let mut out = Self::zero();
        for (ma, ca) in &self.terms {
            for (mb, cb) in &other.terms {
                out.add_term(ma.checked_mul(mb)?, ca.checked_mul(cb)?)?;
            }
        }
        Ok(out)
    }

    /// `self^k`, expanded (`self^0 = 1`).
    pub fn checked_pow(&self, k: u32) -> Result<Self, Overflow> {
        let mut out = Self::constant(C::one());
        let mut base = self.clone();
        let mut k = k;
        while k > 0 {
            if k & 1 == 1 {
                out = out.checked_mul(&base)?;
            }
            k >>= 1;
            if k > 0 {
                base = base.checked_mul(&base)?;
            }
        }
        Ok(out)
    }

    /// `c · self` for a coefficient `c`.
    pub fn checked_scale(&self, c: &C) -> Result<Self, Overflow> {
        let mut out = Self::zero();
        for (m, a) in &self.terms {
            out.add_term(m.clone(), a.checked_mul(c)?)?;
        }
        Ok(out)
    }

    /// `k · self` for a rational `k`.
    pub fn checked_scale_rational(&self, k: &Rational) -> Result<Self, Overflow> {
        let mut out = Self::zero();
        for (m, a) in &self.terms {
            out.add_term(m.clone(), a.checked_scale(k)?)?;
        }
        Ok(out)
    }

    /// `∂self/∂x_v`, term by term.
    pub fn derivative(&self, v: VarId) -> Result<Self, Overflow> {
        let mut out = Self::zero();
        for (m, c) in &self.terms {
            if let Some((k, rest)) = m.derivative(v) {
                let k = Rational::from_integer(i128::from(k));
                out.add_term(rest, c.checked_scale(&k)?)?;
            }
        }
        Ok(out)
    }

    /// The variables that occur in some term, sorted.
    pub fn variables(&self) -> Vec<VarId> {
        let mut vars: Vec<VarId> = self
            .terms
            .keys()
            .flat_map(|m| m.factors().iter().map(|&(v, _)| v))
            .collect();
        vars.sort_unstable();
        vars.dedup();
        vars
    }
}

impl<C: Ring> Ring for SparsePoly<C> {
    fn zero() -> Self {
        Self::zero()
    }
    fn one() -> Self {
        Self::constant(C::one())
    }
    fn is_zero(&self) -> bool {
        self.terms.is_empty()
    }
    fn checked_add(&self, other: &Self) -> Result<Self, Overflow> {
        SparsePoly::checked_add(self, other)
    }
    fn checked_mul(&self, other: &Self) -> Result<Self, Overflow> {
        SparsePoly::checked_mul(self, other)
    }
    fn checked_neg(&self) -> Result<Self, Overflow> {
        SparsePoly::checked_neg(self)
    }
    fn checked_scale(&self, k: &Rational) -> Result<Self, Overflow> {
        self.checked_scale_rational(k)
    }
}
