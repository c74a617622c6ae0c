//! Velocities as variables of the products (nonlinear damping, issue 20): a velocity's spectrum
//! is its mode's `iΩX`, and a derivative by the velocity carries back onto `X`.

use num_complex::Complex64;
use std::f64::consts::TAU;

/// The spectrum of the velocity of amplitudes `x` at frequencies `freqs_hz` (cycled when `x`
/// holds several modes' lines one after another): `out[i] = i 2π f X[i]`.
pub fn velocity_spectrum(freqs_hz: &[f64], x: &[Complex64], out: &mut [Complex64]) {
    let nr = freqs_hz.len();
    for (i, (v, x)) in out.iter_mut().zip(x).enumerate() {
        *v = Complex64::new(0.0, TAU * freqs_hz[i % nr]) * x;
    }
}

/// A derivative by the real and imaginary parts of a velocity `V = iΩX` at `f_hz`, as one by
/// those of `X`: `Re V = −Ω Im X` and `Im V = Ω Re X`, so `(∂/∂Re X, ∂/∂Im X) = (Ω ∂/∂Im V,
/// −Ω ∂/∂Re V)`.
pub fn velocity_to_amplitude(
    d_re_v: Complex64,
    d_im_v: Complex64,
    f_hz: f64,
) -> (Complex64, Complex64) {
    let w = TAU * f_hz;
    (d_im_v * w, -d_re_v * w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_velocity_derivative_is_the_chain_rule_of_its_spectrum() {
        // g(V) = V²: dg/dRe V = 2V, dg/dIm V = 2iV; g as a function of X by central differences.
        let (f, x) = (3.0, Complex64::new(0.4, -0.7));
        let v = |x: Complex64| {
            let mut out = [Complex64::new(0.0, 0.0)];
            velocity_spectrum(&[f], &[x], &mut out);
            out[0]
        };
        let g = |x: Complex64| v(x) * v(x);
        let (dre, dim) = velocity_to_amplitude(2.0 * v(x), Complex64::i() * 2.0 * v(x), f);
        let h = 1e-6;
        let fd_re = (g(x + h) - g(x - h)) / (2.0 * h);
        let fd_im = (g(x + Complex64::i() * h) - g(x - Complex64::i() * h)) / (2.0 * h);
        assert!((fd_re - dre).norm() < 1e-6 * dre.norm(), "{fd_re} {dre}");
        assert!((fd_im - dim).norm() < 1e-6 * dim.norm(), "{fd_im} {dim}");
    }
}
