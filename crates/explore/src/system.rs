//! A square polynomial system `F(x) = 0` in complex unknowns, with its Jacobian: what the
//! homotopies track. Small (a few unknowns), so plain loops and a stack-sized LU.

use num_complex::Complex64;

pub(crate) const ZERO: Complex64 = Complex64::new(0.0, 0.0);
pub(crate) const ONE: Complex64 = Complex64::new(1.0, 0.0);

/// One term `coef · Π x_var^pow`.
#[derive(Debug, Clone, PartialEq)]
pub struct Term {
    /// Complex coefficient.
    pub coef: Complex64,
    /// `(variable, power)` factors, powers ≥ 1, each variable once.
    pub factors: Vec<(usize, u32)>,
}

impl Term {
    /// Total degree.
    pub fn degree(&self) -> u32 {
        self.factors.iter().map(|f| f.1).sum()
    }
}

/// `n` polynomial equations in `n` complex unknowns.
#[derive(Debug, Clone, PartialEq)]
pub struct PolySystem {
    /// Number of unknowns (= equations).
    pub n: usize,
    /// The terms of each equation.
    pub eqs: Vec<Vec<Term>>,
}

impl PolySystem {
    /// Degree of each equation (at least 1).
    pub fn degrees(&self) -> Vec<u32> {
        self.eqs
            .iter()
            .map(|e| e.iter().map(Term::degree).max().unwrap_or(1).max(1))
            .collect()
    }

    /// Highest power of any variable.
    fn max_pow(&self) -> usize {
        self.eqs
            .iter()
            .flatten()
            .flat_map(|t| t.factors.iter().map(|f| f.1 as usize))
            .max()
            .unwrap_or(1)
    }

    /// Scratch for [`PolySystem::eval`].
    pub fn scratch(&self) -> Vec<Complex64> {
        vec![ZERO; self.n * (self.max_pow() + 1)]
    }

    /// `f = F(x)` and, when `jac` is not empty, `jac[i·n + j] = ∂F_i/∂x_j` (both overwritten).
    pub fn eval(
        &self,
        x: &[Complex64],
        f: &mut [Complex64],
        jac: &mut [Complex64],
        pw: &mut [Complex64],
    ) {
        let n = self.n;
        let stride = pw.len() / n.max(1);
        for v in 0..n {
            let row = &mut pw[v * stride..(v + 1) * stride];
            row[0] = ONE;
            for k in 1..stride {
                row[k] = row[k - 1] * x[v];
            }
        }
        let with_jac = !jac.is_empty();
        if with_jac {
            jac.iter_mut().for_each(|z| *z = ZERO);
        }
        for (i, eq) in self.eqs.iter().enumerate() {
            let mut acc = ZERO;
            for t in eq {
                let mut val = t.coef;
                for &(v, p) in &t.factors {
                    val *= pw[v * stride + p as usize];
                }
                acc += val;
                if !with_jac {
                    continue;
                }
                for (a, &(v, p)) in t.factors.iter().enumerate() {
                    let mut d = t.coef * p as f64 * pw[v * stride + p as usize - 1];
                    for (b, &(w, q)) in t.factors.iter().enumerate() {
                        if a != b {
                            d *= pw[w * stride + q as usize];
                        }
                    }
                    jac[i * n + v] += d;
                }
            }
            f[i] = acc;
        }
    }
}

/// Solves `a · x = b` in place (`a` row-major `n × n`, destroyed; `b` becomes `x`) by Gaussian
/// elimination with partial pivoting. `false` when a pivot vanishes.
pub(crate) fn solve_in_place(a: &mut [Complex64], b: &mut [Complex64], n: usize) -> bool {
    for k in 0..n {
        let mut p = k;
        let mut best = a[k * n + k].norm_sqr();
        for i in k + 1..n {
            let v = a[i * n + k].norm_sqr();
            if v > best {
                best = v;
                p = i;
            }
        }
        if best.is_nan() || best <= 0.0 || !best.is_finite() {
            return false;
        }
        if p != k {
            for j in 0..n {
                a.swap(k * n + j, p * n + j);
            }
            b.swap(k, p);
        }
        let inv = ONE / a[k * n + k];
        for i in k + 1..n {
            let m = a[i * n + k] * inv;
            if m == ZERO {
                continue;
            }
            for j in k + 1..n {
                let s = a[k * n + j];
                a[i * n + j] -= m * s;
            }
            let s = b[k];
            b[i] -= m * s;
        }
    }
    for k in (0..n).rev() {
        let mut s = b[k];
        for j in k + 1..n {
            s -= a[k * n + j] * b[j];
        }
        b[k] = s / a[k * n + k];
    }
    true
}

/// `sqrt(Σ |z|²)`.
pub(crate) fn norm(x: &[Complex64]) -> f64 {
    x.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobian_matches_finite_differences() {
        let c = |re, im| Complex64::new(re, im);
        let sys = PolySystem {
            n: 2,
            eqs: vec![
                vec![
                    Term {
                        coef: c(1.0, 0.5),
                        factors: vec![(0, 3)],
                    },
                    Term {
                        coef: c(-2.0, 0.0),
                        factors: vec![(0, 1), (1, 2)],
                    },
                    Term {
                        coef: c(0.3, 0.0),
                        factors: vec![],
                    },
                ],
                vec![Term {
                    coef: c(0.7, -0.2),
                    factors: vec![(1, 2)],
                }],
            ],
        };
        let x = [c(0.3, -0.4), c(1.1, 0.2)];
        let mut f = [ZERO; 2];
        let mut j = [ZERO; 4];
        let mut pw = sys.scratch();
        sys.eval(&x, &mut f, &mut j, &mut pw);
        for v in 0..2 {
            let h = 1e-6;
            let mut xp = x;
            xp[v] += h;
            let mut fp = [ZERO; 2];
            sys.eval(&xp, &mut fp, &mut [], &mut pw);
            for i in 0..2 {
                let fd = (fp[i] - f[i]) / h;
                assert!(
                    (fd - j[i * 2 + v]).norm() < 1e-5,
                    "{fd} vs {}",
                    j[i * 2 + v]
                );
            }
        }
        assert_eq!(sys.degrees(), vec![3, 2]);
    }

    #[test]
    fn lu_solves() {
        let c = |re| Complex64::new(re, 0.0);
        let mut a = vec![c(0.0), c(2.0), c(1.0), c(1.0)];
        let mut b = vec![c(4.0), c(3.0)];
        assert!(solve_in_place(&mut a, &mut b, 2));
        assert!((b[0] - c(1.0)).norm() < 1e-14 && (b[1] - c(2.0)).norm() < 1e-14);
    }
}
