//! Every isolated solution of a square polynomial system: the total-degree homotopy, and the
//! parameter homotopy from a neighbouring system's solutions.
//!
//! Total degree: the start system `G_i = x_i^{d_i} − x_0^{d_i}` (in projective coordinates
//! `x_0, …, x_n` on a random affine chart, so that paths whose ends lie at infinity stay
//! bounded) has the `Π d_i` (Bézout number) solutions `x_i = e^{2πik/d_i}`; with the gamma
//! trick every isolated solution of `F` is the end of one of those paths (Sommese & Wampler,
//! *The Numerical Solution of Systems of Polynomials*, 2005, Thm. 8.4.1). A path ends at a
//! finite solution (`x_0 ≠ 0`) or at infinity; ends are polished by Newton on `F` and deduped.

use crate::system::{norm, solve_in_place, PolySystem, Term, ONE, ZERO};
use crate::track::{Linear, PathEnd};
use num_complex::Complex64;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

/// Most paths a total-degree homotopy tracks.
pub const MAX_PATHS: usize = 200_000;
/// A finite end whose homogenising coordinate is below this (relative) is at infinity.
const INFINITY_REL: f64 = 1e-7;
/// The same for a path stopped short of `t = 0` (at a singular end): a finite solution there
/// would be `10³` times the amplitude scale, far beyond any state.
const STOPPED_INFINITY_REL: f64 = 1e-3;
/// Two solutions closer than this (relative to `1 + ‖x‖`) are one.
const SAME_REL: f64 = 1e-7;

/// The solutions found, with what the tracking saw.
#[derive(Debug, Clone, PartialEq)]
pub struct Solutions {
    /// Distinct finite solutions, polished.
    pub points: Vec<Vec<Complex64>>,
    /// Paths tracked.
    pub paths: usize,
    /// Paths that ended at infinity.
    pub at_infinity: usize,
    /// Paths that stopped short of `t = 0` at a finite point Newton on `F` could not polish
    /// (a singular solution, or a failed path).
    pub failed: usize,
}

/// The Bézout number `Π d_i`, `None` above [`MAX_PATHS`].
pub fn bezout(sys: &PolySystem) -> Option<usize> {
    sys.degrees().iter().try_fold(1usize, |a, &d| {
        a.checked_mul(d as usize).filter(|&p| p <= MAX_PATHS)
    })
}

/// A random complex number of modulus one, from `seed`.
pub(crate) fn random_gamma(seed: u64) -> Complex64 {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    Complex64::from_polar(1.0, rng.random_range(0.1..6.2))
}

/// Every isolated solution of `sys` by the total-degree homotopy (see the module docs), the
/// paths in parallel; `None` when the Bézout number exceeds [`MAX_PATHS`]. `seed` fixes the
/// random `γ` and chart.
pub fn total_degree(sys: &PolySystem, seed: u64) -> Option<Solutions> {
    let paths = bezout(sys)?;
    let n = sys.n;
    let d = sys.degrees();
    let (target, start) = homogenised(sys, &d);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x9e37_79b9);
    let patch: Vec<Complex64> = (0..=n)
        .map(|_| Complex64::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)))
        .collect();
    let h = Linear {
        target: &target,
        start: &start,
        gamma: random_gamma(seed),
        patch: Some(&patch),
    };
    let ends: Vec<Option<Vec<Complex64>>> = (0..paths)
        .into_par_iter()
        .map_init(
            || h.work(),
            |w, k| {
                let y0 = start_point(&d, k, &patch);
                // A finite simple root is reached; a path stopped short ends at a singular
                // point, at infinity when its homogenising coordinate is small.
                let (y, rel) = match h.track(&y0, w) {
                    PathEnd::Reached(y) => (y, INFINITY_REL),
                    PathEnd::Stopped { x: y, .. } => (y, STOPPED_INFINITY_REL),
                };
                (y[0].norm() > rel * norm(&y)).then(|| y[1..].iter().map(|z| z / y[0]).collect())
            },
        )
        .collect();
    let mut out = Solutions {
        points: Vec::new(),
        paths,
        at_infinity: 0,
        failed: 0,
    };
    let mut polish = Polisher::new(sys);
    for e in ends {
        match e {
            None => out.at_infinity += 1,
            Some(mut x) => {
                if polish.newton(&mut x, 30) {
                    push_distinct(&mut out.points, x);
                } else {
                    out.failed += 1;
                }
            }
        }
    }
    Some(out)
}

/// The solutions of `target` from those of `from` (a system of the same shape, e.g. at a
/// neighbouring point of parameters) by the linear homotopy `(1 − t) target + t γ from` with
/// the gamma trick: the ends that were reached, polished and deduped.
pub fn parameter(
    target: &PolySystem,
    from: &PolySystem,
    starts: &[Vec<Complex64>],
    seed: u64,
) -> Vec<Vec<Complex64>> {
    let h = Linear {
        target,
        start: from,
        gamma: random_gamma(seed),
        patch: None,
    };
    let mut w = h.work();
    let mut polish = Polisher::new(target);
    let mut out = Vec::new();
    for s in starts {
        if let PathEnd::Reached(mut x) = h.track(s, &mut w) {
            if polish.newton(&mut x, 8) {
                push_distinct(&mut out, x);
            }
        }
    }
    out
}

/// Adds `x` unless a point within [`SAME_REL`] is there; returns whether it was added.
pub(crate) fn push_distinct(list: &mut Vec<Vec<Complex64>>, x: Vec<Complex64>) -> bool {
    let s = 1.0 + norm(&x);
    let same = list.iter().any(|y| {
        y.iter()
            .zip(&x)
            .map(|(a, b)| (a - b).norm_sqr())
            .sum::<f64>()
            .sqrt()
            <= SAME_REL * s
    });
    if !same {
        list.push(x);
    }
    !same
}

/// Newton on a target system with buffers allocated once.
pub(crate) struct Polisher<'a> {
    sys: &'a PolySystem,
    pw: Vec<Complex64>,
    f: Vec<Complex64>,
    j: Vec<Complex64>,
}

impl<'a> Polisher<'a> {
    pub fn new(sys: &'a PolySystem) -> Self {
        Self {
            sys,
            pw: sys.scratch(),
            f: vec![ZERO; sys.n],
            j: vec![ZERO; sys.n * sys.n],
        }
    }

    /// Newton from `x` (in place), at most `iters` steps; `true` once a step is below `1e-11`
    /// of `1 + ‖x‖`, or the steps stop contracting after one below `1e-8` (the rounding level
    /// of an ill-conditioned root).
    pub fn newton(&mut self, x: &mut [Complex64], iters: usize) -> bool {
        let mut last = f64::INFINITY;
        for _ in 0..iters {
            self.sys.eval(x, &mut self.f, &mut self.j, &mut self.pw);
            let mut dx: Vec<Complex64> = self.f.iter().map(|v| -v).collect();
            if !solve_in_place(&mut self.j, &mut dx, self.sys.n) {
                return false;
            }
            let s = norm(&dx);
            if !s.is_finite() {
                return false;
            }
            for (a, b) in x.iter_mut().zip(&dx) {
                *a += b;
            }
            let scale = 1.0 + norm(x);
            if s <= 1e-11 * scale {
                return true;
            }
            if s > 0.9 * last {
                // No longer contracting: converged to the rounding level, or not converging.
                return last <= 1e-8 * scale;
            }
            last = s;
        }
        false
    }
}

/// `F` homogenised in `x_0` (variables shifted by one) and the start system
/// `x_i^{d_i} − x_0^{d_i}`.
fn homogenised(sys: &PolySystem, d: &[u32]) -> (PolySystem, PolySystem) {
    let shift = |t: &Term, di: u32| {
        let mut factors: Vec<(usize, u32)> = t.factors.iter().map(|&(v, p)| (v + 1, p)).collect();
        let h = di - t.degree();
        if h > 0 {
            factors.insert(0, (0, h));
        }
        Term {
            coef: t.coef,
            factors,
        }
    };
    let target = PolySystem {
        n: sys.n + 1,
        eqs: sys
            .eqs
            .iter()
            .zip(d)
            .map(|(eq, &di)| eq.iter().map(|t| shift(t, di)).collect())
            .collect(),
    };
    let start = PolySystem {
        n: sys.n + 1,
        eqs: d
            .iter()
            .enumerate()
            .map(|(i, &di)| {
                vec![
                    Term {
                        coef: ONE,
                        factors: vec![(i + 1, di)],
                    },
                    Term {
                        coef: -ONE,
                        factors: vec![(0, di)],
                    },
                ]
            })
            .collect(),
    };
    (target, start)
}

/// Start solution `k` (mixed radix over the roots of unity), scaled onto the chart.
fn start_point(d: &[u32], mut k: usize, patch: &[Complex64]) -> Vec<Complex64> {
    let mut y = vec![ONE];
    for &di in d {
        let j = k % di as usize;
        k /= di as usize;
        y.push(Complex64::from_polar(
            1.0,
            std::f64::consts::TAU * j as f64 / di as f64,
        ));
    }
    let s: Complex64 = patch.iter().zip(&y).map(|(a, b)| a * b).sum();
    y.iter().map(|z| z / s).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(re: f64) -> Complex64 {
        Complex64::new(re, 0.0)
    }

    #[test]
    fn univariate_cubic_and_two_circles() {
        // x³ − 6x² + 11x − 6 = (x−1)(x−2)(x−3).
        let sys = PolySystem {
            n: 1,
            eqs: vec![vec![
                Term {
                    coef: c(1.0),
                    factors: vec![(0, 3)],
                },
                Term {
                    coef: c(-6.0),
                    factors: vec![(0, 2)],
                },
                Term {
                    coef: c(11.0),
                    factors: vec![(0, 1)],
                },
                Term {
                    coef: c(-6.0),
                    factors: vec![],
                },
            ]],
        };
        let s = total_degree(&sys, 1).expect("small");
        assert_eq!(s.paths, 3);
        let mut r: Vec<f64> = s.points.iter().map(|p| p[0].re).collect();
        r.sort_by(f64::total_cmp);
        assert!(
            r.iter()
                .zip([1.0, 2.0, 3.0])
                .all(|(a, b)| (a - b).abs() < 1e-10),
            "{r:?}"
        );
        // x² + y² = 4, (x−1)² + y² = 4: Bézout 4, two finite solutions x = 1/2, y = ±√15/2,
        // two at infinity.
        let circle = |a: f64| {
            vec![
                Term {
                    coef: c(1.0),
                    factors: vec![(0, 2)],
                },
                Term {
                    coef: c(-2.0 * a),
                    factors: vec![(0, 1)],
                },
                Term {
                    coef: c(1.0),
                    factors: vec![(1, 2)],
                },
                Term {
                    coef: c(a * a - 4.0),
                    factors: vec![],
                },
            ]
        };
        let sys = PolySystem {
            n: 2,
            eqs: vec![circle(0.0), circle(1.0)],
        };
        let s = total_degree(&sys, 7).expect("small");
        assert_eq!(
            (s.paths, s.points.len(), s.at_infinity + s.failed),
            (4, 2, 2)
        );
        for p in &s.points {
            assert!((p[0] - c(0.5)).norm() < 1e-10);
            assert!((p[1].im.abs() < 1e-10) && (p[1].re.abs() - 15f64.sqrt() / 2.0).abs() < 1e-10);
        }
    }
}
