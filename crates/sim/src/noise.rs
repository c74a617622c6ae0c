//! Seeded measurement noise in the frequency domain.

use num_complex::Complex64;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

/// A seeded source of Gaussian noise (ChaCha8), reproducible across platforms.
#[derive(Debug, Clone)]
pub struct NoiseGen {
    rng: rand_chacha::ChaCha8Rng,
}

impl NoiseGen {
    /// A generator with `seed`.
    pub fn new(seed: u64) -> Self {
        Self {
            rng: rand_chacha::ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// A complex number whose real and imaginary parts are independent `N(0, sigma²)`.
    pub fn complex(&mut self, sigma: f64) -> Complex64 {
        let a: f64 = StandardNormal.sample(&mut self.rng);
        let b: f64 = StandardNormal.sample(&mut self.rng);
        Complex64::new(a * sigma, b * sigma)
    }
}

/// Per-quadrature standard deviation of a lock-in amplitude (`X = (2/N) Σ x_j e^{−iθ_j}`) when
/// white noise of RMS `rms` is added to each of the `n_samples` samples of the window:
/// `rms · sqrt(2 / n_samples)`.
pub fn lockin_noise_sigma(rms: f64, n_samples: f64) -> f64 {
    rms * (2.0 / n_samples).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_statistics() {
        let mut g = NoiseGen::new(7);
        let n = 20000;
        let (mut s_re, mut s_im, mut s_ri) = (0.0, 0.0, 0.0);
        for _ in 0..n {
            let z = g.complex(2.0);
            s_re += z.re * z.re;
            s_im += z.im * z.im;
            s_ri += z.re * z.im;
        }
        let n = n as f64;
        assert!((s_re / n - 4.0).abs() < 0.15);
        assert!((s_im / n - 4.0).abs() < 0.15);
        assert!((s_ri / n).abs() < 0.1);
    }
}
