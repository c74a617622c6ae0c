//! Sparse polynomials over a ring of coefficients, in canonical term order.

use crate::{Overflow, PowerProduct, Rational, Ring, VarId};
use smallvec::SmallVec;
use std::cmp::Ordering;

/// Storage of the terms: sorted by power product, no zero coefficients. Inline room for one
/// term, because most coefficients of an equation term are a single parameter.
type Terms<C> = SmallVec<[(PowerProduct, C); 1]>;

/// A sparse polynomial `Σ c_m · m` over [`PowerProduct`]s `m` with coefficients in a [`Ring`].
///
/// Terms are kept in canonical order (see [`PowerProduct`]'s `Ord`) with no zero coefficients,
/// so two equal polynomials have identical term lists and print identically. Sums are merges
/// and derivatives keep the order, so both are linear in the number of terms; to build a large
/// polynomial from terms in arbitrary order use [`PolyBuilder`] (one sort at the end) rather than
/// repeated [`SparsePoly::add_term`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SparsePoly<C> {
    terms: Terms<C>,
}

/// Collects terms in any order, then sorts and merges them once into a [`SparsePoly`].
#[derive(Debug, Clone, Default)]
pub struct PolyBuilder<C> {
    pending: Vec<(PowerProduct, C)>,
}

impl<C: Ring> PolyBuilder<C> {
    /// An empty builder.
    pub fn new() -> Self {
        Self {
            pending: Vec::new(),
        }
    }

    /// Adds `c · m` (merged with equal power products at [`PolyBuilder::finish`]).
    pub fn push(&mut self, m: PowerProduct, c: C) {
        if !c.is_zero() {
            self.pending.push((m, c));
        }
    }

    /// Adds every term of `p`, negated if `negate`.
    pub fn push_poly(&mut self, p: &SparsePoly<C>, negate: bool) -> Result<(), Overflow> {
        self.pending.reserve(p.len());
        for (m, c) in &p.terms {
            let c = if negate { c.checked_neg()? } else { c.clone() };
            self.pending.push((m.clone(), c));
        }
        Ok(())
    }

    /// Number of terms pushed so far (an upper bound on the final number of terms).
    pub fn pending_len(&self) -> usize {
        self.pending.len()
    }

    /// The polynomial: terms sorted, equal power products summed, zeros dropped.
    pub fn finish(self) -> Result<SparsePoly<C>, Overflow> {
        let mut pending = self.pending;
        // Families usually produce terms already in canonical order: then no sort is needed.
        if !pending.is_sorted_by(|a, b| a.0 <= b.0) {
            pending.sort_by(|a, b| a.0.cmp(&b.0));
        }
        let mut terms: Terms<C> = SmallVec::with_capacity(pending.len());
        let mut pending = pending.into_iter().peekable();
        while let Some((m, c)) = pending.next() {
            // All coefficients of one power product, summed as a balanced tree: n coefficients
            // that are themselves sums (e.g. one parameter each) cost n log n, not n².
            let mut run = vec![c];
            while let Some((_, c)) = pending.next_if(|(next, _)| *next == m) {
                run.push(c);
            }
            let c = balanced_sum(run)?;
            if !c.is_zero() {
                terms.push((m, c));
            }
        }
        Ok(SparsePoly { terms })
    }
}

/// `Σ values` by pairwise sums (a balanced tree), so that sums whose size grows with each
/// addition cost `n log n` in total instead of `n²`. An empty list gives zero.
fn balanced_sum<C: Ring>(mut values: Vec<C>) -> Result<C, Overflow> {
    while values.len() > 1 {
        let mut next = Vec::with_capacity(values.len().div_ceil(2));
        let mut it = values.into_iter();
        while let Some(a) = it.next() {
            next.push(match it.next() {
                Some(b) => a.checked_add(&b)?,
                None => a,
            });
        }
        values = next;
    }
    Ok(values.pop().unwrap_or_else(C::zero))
}

impl<C: Ring> SparsePoly<C> {
    /// The zero polynomial.
    pub fn zero() -> Self {
        Self {
            terms: SmallVec::new(),
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
            p.terms.push((m, c));
        }
        p
    }

    /// The polynomial `x_v`.
    pub fn var(v: VarId) -> Self {
        Self::term(PowerProduct::var(v), C::one())
    }

    /// Terms in canonical order, with nonzero coefficients.
    pub fn terms(
        &self,
    ) -> impl ExactSizeIterator<Item = (&PowerProduct, &C)> + DoubleEndedIterator + Clone {
        self.terms.iter().map(|(m, c)| (m, c))
    }

    fn position(&self, m: &PowerProduct) -> Result<usize, usize> {
        self.terms.binary_search_by(|(k, _)| k.cmp(m))
    }

    /// The coefficient of `m` (None when it is zero).
    pub fn coeff(&self, m: &PowerProduct) -> Option<&C> {
        self.position(m).ok().map(|i| &self.terms[i].1)
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

    /// Highest total degree of a term (0 for constants and for zero). The graded order puts
    /// the highest degree last.
    pub fn degree(&self) -> u32 {
        self.terms.last().map_or(0, |(m, _)| m.degree())
    }

    /// The constant term, if the polynomial is a constant (or zero).
    pub fn as_constant(&self) -> Option<C> {
        match self.terms.as_slice() {
            [] => Some(C::zero()),
            [(m, c)] if m.is_one() => Some(c.clone()),
            _ => None,
        }
    }

    /// Adds `c · m` in place, merging with an existing term and dropping it if it cancels.
    ///
    /// Appending past the last term is O(1); inserting elsewhere moves the later terms, so build
    /// large polynomials from unordered terms with [`PolyBuilder`].
    pub fn add_term(&mut self, m: PowerProduct, c: C) -> Result<(), Overflow> {
        if c.is_zero() {
            return Ok(());
        }
        if self.terms.last().is_none_or(|(last, _)| *last < m) {
            self.terms.push((m, c));
            return Ok(());
        }
        match self.position(&m) {
            Ok(i) => {
                let sum = self.terms[i].1.checked_add(&c)?;
                if sum.is_zero() {
                    self.terms.remove(i);
                } else {
                    self.terms[i].1 = sum;
                }
            }
            Err(i) => self.terms.insert(i, (m, c)),
        }
        Ok(())
    }

    /// `self + other` (a merge of the two sorted term lists).
    pub fn checked_add(&self, other: &Self) -> Result<Self, Overflow> {
        let mut terms: Terms<C> = SmallVec::with_capacity(self.len() + other.len());
        let (mut a, mut b) = (self.terms.iter().peekable(), other.terms.iter().peekable());
        loop {
            let next = match (a.peek(), b.peek()) {
                (Some((ma, ca)), Some((mb, cb))) => match ma.cmp(mb) {
                    Ordering::Less => a.next().cloned(),
                    Ordering::Greater => b.next().cloned(),
                    Ordering::Equal => {
                        let sum = ca.checked_add(cb)?;
                        let m = ma.clone();
                        a.next();
                        b.next();
                        (!sum.is_zero()).then_some((m, sum))
                    }
                },
                (Some(_), None) => a.next().cloned(),
                (None, Some(_)) => b.next().cloned(),
                (None, None) => break,
            };
            if let Some(t) = next {
                terms.push(t);
            }
        }
        Ok(Self { terms })
    }

    /// `self - other`.
    pub fn checked_sub(&self, other: &Self) -> Result<Self, Overflow> {
        self.checked_add(&other.checked_neg()?)
    }

    /// `-self`.
    pub fn checked_neg(&self) -> Result<Self, Overflow> {
        let mut terms: Terms<C> = SmallVec::with_capacity(self.len());
        for (m, c) in &self.terms {
            terms.push((m.clone(), c.checked_neg()?));
        }
        Ok(Self { terms })
    }

    /// `self * other`, expanded.
    pub fn checked_mul(&self, other: &Self) -> Result<Self, Overflow> {
        if let ([(m, c)], _) | (_, [(m, c)]) = (self.terms.as_slice(), other.terms.as_slice()) {
            // A single term times a polynomial keeps the order (monomial order), no sort.
            let rest = if self.len() == 1 { other } else { self };
            let mut terms: Terms<C> = SmallVec::with_capacity(rest.len());
            for (mr, cr) in &rest.terms {
                let prod = cr.checked_mul(c)?;
                if !prod.is_zero() {
                    terms.push((mr.checked_mul(m)?, prod));
                }
            }
            return Ok(Self { terms });
        }
        let mut out = PolyBuilder::new();
        out.pending.reserve(self.len() * other.len());
        for (ma, ca) in &self.terms {
            for (mb, cb) in &other.terms {
                out.push(ma.checked_mul(mb)?, ca.checked_mul(cb)?);
            }
        }
        out.finish()
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
        let mut terms: Terms<C> = SmallVec::with_capacity(self.len());
        for (m, a) in &self.terms {
            let prod = a.checked_mul(c)?;
            if !prod.is_zero() {
                terms.push((m.clone(), prod));
            }
        }
        Ok(Self { terms })
    }

    /// `k · self` for a rational `k`.
    pub fn checked_scale_rational(&self, k: &Rational) -> Result<Self, Overflow> {
        let mut terms: Terms<C> = SmallVec::with_capacity(self.len());
        for (m, a) in &self.terms {
            let prod = a.checked_scale(k)?;
            if !prod.is_zero() {
                terms.push((m.clone(), prod));
            }
        }
        Ok(Self { terms })
    }

    /// `∂self/∂x_v`, term by term. Linear in the number of terms: dividing the terms that hold
    /// `x_v` by it keeps their order.
    pub fn derivative(&self, v: VarId) -> Result<Self, Overflow> {
        let mut terms: Terms<C> = SmallVec::new();
        for (m, c) in &self.terms {
            if let Some((k, rest)) = m.derivative(v) {
                let c = if k == 1 {
                    c.clone()
                } else {
                    c.checked_scale(&Rational::from_integer(i128::from(k)))?
                };
                terms.push((rest, c));
            }
        }
        Ok(Self { terms })
    }

    /// The variables that occur in some term, sorted.
    pub fn variables(&self) -> Vec<VarId> {
        let mut vars: Vec<VarId> = self
            .terms
            .iter()
            .flat_map(|(m, _)| m.factors().iter().map(|&(v, _)| v))
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
