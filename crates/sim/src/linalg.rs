//! Small dense LU factorisation with partial pivoting, in place, no allocation.

/// Factorises the row-major `n × n` matrix `a` in place (`L` unit lower, `U` upper) with row
/// pivots `piv`. Returns `false` when a pivot is zero or not finite (singular matrix).
pub(crate) fn lu_factor(a: &mut [f64], n: usize, piv: &mut [usize]) -> bool {
    for k in 0..n {
        let mut p = k;
        let mut best = a[k * n + k].abs();
        for i in k + 1..n {
            let v = a[i * n + k].abs();
            if v > best {
                best = v;
                p = i;
            }
        }
        piv[k] = p;
        if !(best.is_finite() && best > 0.0) {
            return false;
        }
        if p != k {
            for j in 0..n {
                a.swap(k * n + j, p * n + j);
            }
        }
        let d = 1.0 / a[k * n + k];
        let (top, bottom) = a.split_at_mut((k + 1) * n);
        let row_k = &top[k * n..(k + 1) * n];
        for i in 0..n - k - 1 {
            let row = &mut bottom[i * n..(i + 1) * n];
            let l = row[k] * d;
            row[k] = l;
            if l != 0.0 {
                for j in k + 1..n {
                    row[j] -= l * row_k[j];
                }
            }
        }
    }
    true
}

/// Solves `A x = b` in place (`b` becomes `x`) with the factors of [`lu_factor`].
pub(crate) fn lu_solve(a: &[f64], n: usize, piv: &[usize], b: &mut [f64]) {
    for k in 0..n {
        b.swap(k, piv[k]);
    }
    for i in 0..n {
        let mut s = b[i];
        for j in 0..i {
            s -= a[i * n + j] * b[j];
        }
        b[i] = s;
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for j in i + 1..n {
            s -= a[i * n + j] * b[j];
        }
        b[i] = s / a[i * n + i];
    }
}

/// A dense LU factorisation with partial pivoting by faer (blocked, SIMD), with every buffer
/// allocated once: [`DenseLu::factor`] and [`DenseLu::solve`] do not allocate.
pub(crate) struct DenseLu {
    n: usize,
    lu: faer::Mat<f64>,
    rhs: faer::Mat<f64>,
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
    buf: faer::dyn_stack::MemBuffer,
}

impl std::fmt::Debug for DenseLu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "DenseLu({} × {})", self.n, self.n)
    }
}

impl Clone for DenseLu {
    fn clone(&self) -> Self {
        let mut c = Self::new(self.n);
        c.lu.copy_from(&self.lu);
        c.perm.copy_from_slice(&self.perm);
        c.perm_inv.copy_from_slice(&self.perm_inv);
        c
    }
}

impl DenseLu {
    /// Buffers for `n × n` systems.
    pub(crate) fn new(n: usize) -> Self {
        use faer::linalg::lu::partial_pivoting::{factor, solve};
        let req =
            factor::lu_in_place_scratch::<usize, f64>(n, n, faer::Par::Seq, Default::default()).or(
                solve::solve_in_place_scratch::<usize, f64>(n, 1, faer::Par::Seq),
            );
        Self {
            n,
            lu: faer::Mat::zeros(n, n),
            rhs: faer::Mat::zeros(n, 1),
            perm: (0..n).collect(),
            perm_inv: (0..n).collect(),
            buf: faer::dyn_stack::MemBuffer::new(req),
        }
    }

    /// Factorises the row-major `n × n` matrix `a`. `false` when a pivot is zero or not finite.
    pub(crate) fn factor(&mut self, a: &[f64]) -> bool {
        use faer::linalg::lu::partial_pivoting::factor;
        let n = self.n;
        for j in 0..n {
            for i in 0..n {
                self.lu[(i, j)] = a[i * n + j];
            }
        }
        let stack = faer::dyn_stack::MemStack::new(&mut self.buf);
        let _ = factor::lu_in_place(
            self.lu.as_mut(),
            &mut self.perm,
            &mut self.perm_inv,
            faer::Par::Seq,
            stack,
            Default::default(),
        );
        (0..n).all(|k| {
            let d = self.lu[(k, k)];
            d.is_finite() && d != 0.0
        })
    }

    /// Solves `A x = b` in place with the last factorisation.
    pub(crate) fn solve(&mut self, b: &mut [f64]) {
        use faer::linalg::lu::partial_pivoting::solve;
        let n = self.n;
        for i in 0..n {
            self.rhs[(i, 0)] = b[i];
        }
        let perm = faer::perm::PermRef::new_checked(&self.perm, &self.perm_inv, n);
        let stack = faer::dyn_stack::MemStack::new(&mut self.buf);
        solve::solve_in_place(
            self.lu.as_ref(),
            self.lu.as_ref(),
            perm,
            self.rhs.as_mut(),
            faer::Par::Seq,
            stack,
        );
        for i in 0..n {
            b[i] = self.rhs[(i, 0)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_pivoting_system() {
        let a0 = [0.0, 2.0, 1.0, 1.0, 1.0, 0.0, 3.0, 0.0, 1.0];
        let x_true = [1.0, -2.0, 0.5];
        let mut b: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| a0[i * 3 + j] * x_true[j]).sum())
            .collect();
        let mut a = a0;
        let mut piv = [0; 3];
        assert!(lu_factor(&mut a, 3, &mut piv));
        lu_solve(&a, 3, &piv, &mut b);
        for i in 0..3 {
            assert!((b[i] - x_true[i]).abs() < 1e-14);
        }
        let mut s = [1.0, 2.0, 2.0, 4.0];
        assert!(!lu_factor(&mut s, 2, &mut [0; 2]));
        // faer's LU on the same system.
        let mut lu = DenseLu::new(3);
        assert!(lu.factor(&a0));
        let mut b: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| a0[i * 3 + j] * x_true[j]).sum())
            .collect();
        lu.solve(&mut b);
        for i in 0..3 {
            assert!((b[i] - x_true[i]).abs() < 1e-14);
        }
        let mut lu2 = DenseLu::new(2);
        assert!(!lu2.factor(&[1.0, 2.0, 2.0, 4.0]));
    }
}
