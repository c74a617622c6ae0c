//! The checked ring operations shared by rationals and polynomials.

use crate::Rational;
use num_traits::{CheckedAdd, CheckedMul, One, Zero};

/// An exact coefficient overflowed its 128-bit rational representation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("exact arithmetic overflowed 128-bit rationals (a coefficient or exponent is too large)")]
pub struct Overflow;

/// A commutative ring with checked arithmetic: the coefficient type of a [`crate::Poly`] level.
pub trait Ring: Clone + PartialEq + std::fmt::Debug {
    /// The additive identity.
    fn zero() -> Self;
    /// The multiplicative identity.
    fn one() -> Self;
    /// Whether this is exactly zero.
    fn is_zero(&self) -> bool;
    /// `self + other`, or [`Overflow`].
    fn checked_add(&self, other: &Self) -> Result<Self, Overflow>;
    /// `self * other`, or [`Overflow`].
    fn checked_mul(&self, other: &Self) -> Result<Self, Overflow>;
    /// `-self`, or [`Overflow`].
    fn checked_neg(&self) -> Result<Self, Overflow>;
    /// `self * k` for a rational `k`, or [`Overflow`].
    fn checked_scale(&self, k: &Rational) -> Result<Self, Overflow>;
}

impl Ring for Rational {
    fn zero() -> Self {
        Zero::zero()
    }
    fn one() -> Self {
        One::one()
    }
    fn is_zero(&self) -> bool {
        Zero::is_zero(self)
    }
    fn checked_add(&self, other: &Self) -> Result<Self, Overflow> {
        CheckedAdd::checked_add(self, other).ok_or(Overflow)
    }
    fn checked_mul(&self, other: &Self) -> Result<Self, Overflow> {
        CheckedMul::checked_mul(self, other).ok_or(Overflow)
    }
    fn checked_neg(&self) -> Result<Self, Overflow> {
        let n = self.numer().checked_neg().ok_or(Overflow)?;
        Ok(Rational::new_raw(n, *self.denom()))
    }
    fn checked_scale(&self, k: &Rational) -> Result<Self, Overflow> {
        Ring::checked_mul(self, k)
    }
}
