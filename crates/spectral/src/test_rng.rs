//! Seeded test values (xorshift), so the tests need no extra dependency.

use num_complex::Complex64;

/// A small deterministic generator.
pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    /// Uniform in [−1, 1).
    pub(crate) fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }

    /// Real and imaginary parts uniform in [−1, 1).
    pub(crate) fn c(&mut self) -> Complex64 {
        Complex64::new(self.next(), self.next())
    }

    /// Uniform in `0..n`.
    pub(crate) fn below(&mut self, n: usize) -> usize {
        ((self.next() + 1.0) * 0.5 * n as f64) as usize % n
    }
}
