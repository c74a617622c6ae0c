//! The one dense LU of the crate ([`DenseLu`]): faer's partial pivoting with coupled parts
//! factorised apart, or an unblocked in-place kernel for small dense systems; no allocation
//! after set-up.

/// Factorises the row-major `n × n` matrix `a` in place (`L` unit lower, `U` upper) with row
/// pivots `piv`. Returns `false` when a pivot is zero or not finite (singular matrix).
fn lu_factor(a: &mut [f64], n: usize, piv: &mut [usize]) -> bool {
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
fn lu_solve(a: &[f64], n: usize, piv: &[usize], b: &mut [f64]) {
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

/// Sign of the determinant from the factors of [`lu_factor`].
fn small_det_sign(lu: &[f64], n: usize, piv: &[usize]) -> f64 {
    let mut s = 1.0;
    for k in 0..n {
        if piv[k] != k {
            s = -s;
        }
        if lu[k * n + k] < 0.0 {
            s = -s;
        }
    }
    s
}

/// The groups `0..ng` joined into parts when `coupled[gi·ng + gj]` marks a block between them
/// (either way): calls `visit(group, first)` for every group, part after part (in the order of
/// their first group, `first` on it), groups ascending within a part. `parent` is scratch of
/// `ng` entries. Does not allocate.
pub(crate) fn coupled_parts(
    coupled: &[bool],
    ng: usize,
    parent: &mut [usize],
    mut visit: impl FnMut(usize, bool),
) {
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for (g, p) in parent.iter_mut().enumerate().take(ng) {
        *p = g;
    }
    for gi in 0..ng {
        for gj in 0..ng {
            if gi != gj && coupled[gi * ng + gj] {
                let (ri, rj) = (root(parent, gi), root(parent, gj));
                parent[ri.max(rj)] = ri.min(rj);
            }
        }
    }
    for g0 in 0..ng {
        if root(parent, g0) != g0 {
            continue;
        }
        for g in g0..ng {
            if root(parent, g) == g0 {
                visit(g, g == g0);
            }
        }
    }
}

/// Scratch of a multi-column solve ([`DenseLu::solve_columns`]) of `n` rows and up to `cols`
/// columns.
pub(crate) struct ColumnScratch {
    n: usize,
    cols: usize,
    /// The right-hand sides in the factorisation's row order.
    rows: faer::Mat<f64>,
    buf: faer::dyn_stack::MemBuffer,
}

impl ColumnScratch {
    fn new(n: usize, cols: usize) -> Self {
        use faer::linalg::lu::partial_pivoting::solve;
        let req = solve::solve_in_place_scratch::<usize, f64>(n, cols, faer::Par::Seq);
        Self {
            n,
            cols,
            rows: faer::Mat::zeros(n, cols),
            buf: faer::dyn_stack::MemBuffer::new(req),
        }
    }
}

impl std::fmt::Debug for ColumnScratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ColumnScratch({} × {})", self.n, self.cols)
    }
}

impl Clone for ColumnScratch {
    fn clone(&self) -> Self {
        Self::new(self.n, self.cols)
    }
}

/// Systems from this many unknowns are factorised on every core: below, the threads' set-up
/// costs more than they save (and the design runs many small systems side by side).
const PARALLEL_LU_MIN: usize = 1024;

/// The parallelism of an `n × n` factorisation ([`PARALLEL_LU_MIN`]).
fn lu_par(n: usize) -> faer::Par {
    if n >= PARALLEL_LU_MIN {
        faer::Par::rayon(0)
    } else {
        faer::Par::Seq
    }
}

/// A dense LU factorisation with partial pivoting by faer (blocked, SIMD), with every buffer
/// allocated once: [`DenseLu::factor`] and [`DenseLu::solve`] do not allocate.
///
/// The unknowns come in groups of `block` (a mode's lines, in the harmonic balance). Groups
/// that the matrix does not couple, directly or through others, are factorised apart: a mode
/// with no drive and no force from the others (its amplitudes are zero, so it does not act on
/// the driven modes) is its own small system. The cost falls from `n³` to the sum of the
/// cubes of the coupled parts (a one-mode measurement of a five-mode model: 25× less), with
/// the same solution: a block-diagonal matrix (after reordering) is exactly its blocks.
pub(crate) struct DenseLu {
    n: usize,
    block: usize,
    /// The factors of each coupled part on the diagonal, in the order of `order`.
    lu: faer::Mat<f64>,
    /// `order[p]`: the unknown at position `p` (parts one after another).
    order: Vec<usize>,
    /// `(offset, size)` of each coupled part in `order`.
    parts: Vec<(usize, usize)>,
    /// Row permutations of each part's factorisation (local indices, at the part's offset).
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
    rhs: faer::Mat<f64>,
    buf: faer::dyn_stack::MemBuffer,
    /// `[gi·G + gj]`: the block of groups `gi`, `gj` holds a non-zero (scratch).
    coupled: Vec<bool>,
    /// Union–find scratch of the groups.
    parent: Vec<usize>,
    /// Sign of the determinant of the last factorised matrix (`0.0` when singular).
    det_sign: f64,
    /// The small-system kernel ([`DenseLu::dense`]): the factors in place (row-major) and
    /// the row pivots; `None` for faer's.
    small: Option<(Vec<f64>, Vec<usize>)>,
}

impl std::fmt::Debug for DenseLu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "DenseLu({} × {}, {} parts)",
            self.n,
            self.n,
            self.parts.len()
        )
    }
}

impl Clone for DenseLu {
    fn clone(&self) -> Self {
        let mut c = Self::with_blocks(self.n, self.block);
        if self.lu.nrows() == self.n && self.n > 0 {
            c.allocate();
            c.lu.copy_from(&self.lu);
        }
        c.order.copy_from_slice(&self.order);
        c.parts.clone_from(&self.parts);
        c.perm.copy_from_slice(&self.perm);
        c.perm_inv.copy_from_slice(&self.perm_inv);
        c.det_sign = self.det_sign;
        c.small.clone_from(&self.small);
        c
    }
}

impl DenseLu {
    /// Buffers for `n × n` systems, every unknown its own group.
    #[cfg(test)]
    pub(crate) fn new(n: usize) -> Self {
        Self::with_blocks(n, 1)
    }

    /// Buffers for small `n × n` systems factorised whole by an unblocked in-place kernel:
    /// the single-tone continuation's few harmonics of few modes, where faer's set-up and the
    /// search for uncoupled parts cost more than the factorisation (2000-point Duffing sweep,
    /// 4 unknowns: 2.3 ms with this kernel, 3.1 ms with faer's).
    pub(crate) fn dense(n: usize) -> Self {
        let mut lu = Self::with_blocks(0, 1);
        lu.n = n;
        lu.small = Some((vec![0.0; n * n], vec![0; n]));
        lu
    }

    /// Buffers for `n × n` systems whose unknowns come in groups of `block` (`n` a multiple of
    /// `block`; otherwise one group). The `n × n` factors and faer's scratch are allocated at
    /// the first factorisation: a solver used only for its Jacobian (the idle modes' blocks of
    /// a stability check, [`crate::ReducedSolver::stability`]) never zero-fills them.
    pub(crate) fn with_blocks(n: usize, block: usize) -> Self {
        let block = if block > 0 && n.is_multiple_of(block) {
            block
        } else {
            n.max(1)
        };
        Self {
            n,
            block,
            lu: faer::Mat::new(),
            order: (0..n).collect(),
            parts: vec![(0, n)],
            perm: (0..n).collect(),
            perm_inv: (0..n).collect(),
            rhs: faer::Mat::zeros(n, 1),
            buf: faer::dyn_stack::MemBuffer::new(faer::dyn_stack::StackReq::EMPTY),
            coupled: vec![true; (n / block).pow(2)],
            parent: vec![0; n / block],
            det_sign: 1.0,
            small: None,
        }
    }

    /// The factors' `n × n` storage and faer's scratch, once (see [`DenseLu::with_blocks`]).
    fn allocate(&mut self) {
        use faer::linalg::lu::partial_pivoting::{factor, solve};
        let n = self.n;
        if self.lu.nrows() == n {
            return;
        }
        let req =
            factor::lu_in_place_scratch::<usize, f64>(n, n, lu_par(n), Default::default()).or(
                solve::solve_in_place_scratch::<usize, f64>(n, 1, faer::Par::Seq),
            );
        self.lu = faer::Mat::zeros(n, n);
        self.buf = faer::dyn_stack::MemBuffer::new(req);
    }

    /// Whether a factorisation is held (its storage exists; [`DenseLu::dense`] always).
    fn allocated(&self) -> bool {
        self.small.is_some() || self.lu.nrows() == self.n
    }

    /// Marks in `self.coupled` the blocks of `a` that hold a non-zero.
    fn scan_coupling(&mut self, a: &[f64]) {
        let (n, b) = (self.n, self.block);
        let ng = n / b;
        for gi in 0..ng {
            for gj in 0..ng {
                self.coupled[gi * ng + gj] = gi == gj
                    || (gi * b..(gi + 1) * b).any(|i| {
                        a[i * n + gj * b..i * n + (gj + 1) * b]
                            .iter()
                            .any(|&v| v != 0.0)
                    });
            }
        }
    }

    /// The coupled parts from `self.coupled` into `order` and `parts`.
    fn find_parts(&mut self) {
        let b = self.block;
        let ng = self.n / b;
        self.parts.clear();
        let (order, parts) = (&mut self.order, &mut self.parts);
        let mut pos = 0;
        coupled_parts(&self.coupled, ng, &mut self.parent, |g, first| {
            if first {
                parts.push((pos, 0));
            }
            for i in g * b..(g + 1) * b {
                order[pos] = i;
                pos += 1;
            }
            if let Some(last) = parts.last_mut() {
                last.1 += b;
            }
        });
    }

    /// As [`DenseLu::factor`], with the blocks that may hold non-zeros given (`coupled[gi·G +
    /// gj]` for the block of group rows `gi`, columns `gj`, `G = n / block`; the assembler
    /// knows them, which saves a scan of the matrix). A block not marked must be zero.
    pub(crate) fn factor_coupled(&mut self, a: &[f64], coupled: &[bool]) -> bool {
        if self.small.is_some() {
            return self.factor(a);
        }
        self.coupled.copy_from_slice(coupled);
        self.factor_parts(a)
    }

    /// Factorises the row-major `n × n` matrix `a`. `false` when a pivot is zero or not finite.
    pub(crate) fn factor(&mut self, a: &[f64]) -> bool {
        if let Some((lu, piv)) = self.small.as_mut() {
            lu.copy_from_slice(a);
            let regular = lu_factor(lu, self.n, piv);
            self.det_sign = if regular {
                small_det_sign(lu, self.n, piv)
            } else {
                0.0
            };
            return regular;
        }
        self.scan_coupling(a);
        self.factor_parts(a)
    }

    fn factor_parts(&mut self, a: &[f64]) -> bool {
        use faer::linalg::lu::partial_pivoting::factor;
        let n = self.n;
        self.allocate();
        self.find_parts();
        // det A = Π over the parts of det(P)·Π diag(U): the parts are a symmetric reordering
        // (det unchanged), each a row-pivoted LU with `L` unit lower.
        let mut sign = 1.0;
        for &(off, size) in &self.parts {
            for jl in 0..size {
                let j = self.order[off + jl];
                for il in 0..size {
                    self.lu[(off + il, off + jl)] = a[self.order[off + il] * n + j];
                }
            }
            let stack = faer::dyn_stack::MemStack::new(&mut self.buf);
            let (info, _) = factor::lu_in_place(
                self.lu.as_mut().submatrix_mut(off, off, size, size),
                &mut self.perm[off..off + size],
                &mut self.perm_inv[off..off + size],
                lu_par(size),
                stack,
                Default::default(),
            );
            if info.transposition_count % 2 == 1 {
                sign = -sign;
            }
        }
        let mut regular = true;
        for k in 0..n {
            let d = self.lu[(k, k)];
            regular &= d.is_finite() && d != 0.0;
            if d < 0.0 {
                sign = -sign;
            }
        }
        self.det_sign = if regular { sign } else { 0.0 };
        regular
    }

    /// Sign of the determinant of the last factorised matrix: `±1.0`, `0.0` when it was
    /// singular. The harmonic balance follows it along the drive ramp: it changes exactly where
    /// a branch passes a fold (or a branch point).
    pub(crate) fn det_sign(&self) -> f64 {
        self.det_sign
    }

    /// Solves `A x = b` in place with the last factorisation.
    pub(crate) fn solve(&mut self, b: &mut [f64]) {
        let n = self.n;
        if let Some((lu, piv)) = &self.small {
            lu_solve(lu, n, piv, b);
            return;
        }
        // Before any factorisation, the factors of a zero matrix (as the eager allocation
        // held): a singular system, whose solve is not finite.
        self.allocate();
        let b = faer::MatMut::from_column_major_slice_mut(b, n, 1);
        let Self {
            lu,
            order,
            parts,
            perm,
            perm_inv,
            rhs,
            buf,
            ..
        } = self;
        solve_ordered(
            lu.as_ref(),
            order,
            parts,
            (perm, perm_inv),
            b,
            rhs.as_mut(),
            buf,
        );
    }

    /// Scratch for [`DenseLu::solve_columns`] with `k` right-hand sides.
    pub(crate) fn columns_scratch(&self, k: usize) -> ColumnScratch {
        ColumnScratch::new(self.n, k)
    }

    /// Solves `A X = B` in place for every column of `b` (`n` rows) with the last
    /// factorisation: one blocked triangular solve per coupled part (matrix products) instead
    /// of one matrix-vector sweep per column. `buf` from [`DenseLu::columns_scratch`] for at
    /// least `b.ncols()` columns. Does not allocate.
    pub(crate) fn solve_columns(&self, b: faer::MatMut<'_, f64>, buf: &mut ColumnScratch) {
        let k = b.ncols();
        assert!(
            b.nrows() == self.n && k <= buf.cols,
            "solve_columns: shapes"
        );
        if !self.allocated() {
            // Never factorised: nothing to solve with (callers factorise first).
            let mut b = b;
            b.fill(f64::NAN);
            return;
        }
        if let Some((lu, piv)) = &self.small {
            let mut b = b;
            for c in 0..k {
                let col = buf.rows.as_mut().col_mut(0).try_as_col_major_mut();
                let col = col
                    .expect("a column of a faer matrix is contiguous")
                    .as_slice_mut();
                for i in 0..self.n {
                    col[i] = b[(i, c)];
                }
                lu_solve(lu, self.n, piv, col);
                for i in 0..self.n {
                    b[(i, c)] = col[i];
                }
            }
            return;
        }
        solve_ordered(
            self.lu.as_ref(),
            &self.order,
            &self.parts,
            (&self.perm, &self.perm_inv),
            b,
            buf.rows.as_mut().subcols_mut(0, k),
            &mut buf.buf,
        );
    }
}

/// The solve of [`DenseLu`]: `b`'s rows gathered into `rows` in the factorisation's order,
/// each coupled part solved with its factors, the solution scattered back into `b`.
fn solve_ordered(
    lu: faer::MatRef<'_, f64>,
    order: &[usize],
    parts: &[(usize, usize)],
    (perm, perm_inv): (&[usize], &[usize]),
    mut b: faer::MatMut<'_, f64>,
    mut rows: faer::MatMut<'_, f64>,
    buf: &mut faer::dyn_stack::MemBuffer,
) {
    use faer::linalg::lu::partial_pivoting::solve;
    for c in 0..b.ncols() {
        for (p, &i) in order.iter().enumerate() {
            rows[(p, c)] = b[(i, c)];
        }
    }
    for &(off, size) in parts {
        let perm = faer::perm::PermRef::new_checked(
            &perm[off..off + size],
            &perm_inv[off..off + size],
            size,
        );
        let lu = lu.submatrix(off, off, size, size);
        solve::solve_in_place(
            lu,
            lu,
            perm,
            rows.as_mut().subrows_mut(off, size),
            faer::Par::Seq,
            faer::dyn_stack::MemStack::new(buf),
        );
    }
    for c in 0..b.ncols() {
        for (p, &i) in order.iter().enumerate() {
            b[(i, c)] = rows[(p, c)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Groups the matrix does not couple are factorised apart, with the solution of the whole.
    #[test]
    fn uncoupled_groups_factorise_apart() {
        // Six unknowns in groups of two: groups 0 and 2 coupled (one way only), group 1 alone.
        let n = 6;
        let mut a = vec![0.0; n * n];
        let mut set = |i: usize, j: usize, v: f64| a[i * n + j] = v;
        for i in 0..n {
            set(i, i, 3.0 + i as f64);
        }
        set(0, 1, 0.0);
        set(1, 0, 2.0);
        set(2, 3, -1.5);
        set(3, 2, 4.0);
        set(4, 5, 1.0);
        set(0, 5, 0.7); // group 0 ← group 2
        set(5, 4, 0.0);
        let x_true = [1.0, -2.0, 0.5, 3.0, -1.0, 2.5];
        let rhs: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| a[i * n + j] * x_true[j]).sum())
            .collect();
        let mut lu = DenseLu::with_blocks(n, 2);
        assert!(lu.factor(&a));
        assert_eq!(lu.parts, vec![(0, 4), (4, 2)]);
        assert_eq!(lu.order, vec![0, 1, 4, 5, 2, 3]);
        let mut b = rhs.clone();
        lu.solve(&mut b);
        for i in 0..n {
            assert!((b[i] - x_true[i]).abs() < 1e-14, "{i}: {}", b[i]);
        }
        let mut cols = faer::Mat::<f64>::from_fn(n, 3, |i, j| rhs[i] * j as f64);
        let mut buf = lu.columns_scratch(3);
        lu.solve_columns(cols.as_mut(), &mut buf);
        for j in 0..3 {
            for i in 0..n {
                assert!((cols[(i, j)] - x_true[i] * j as f64).abs() < 1e-13);
            }
        }
        // A singular part is reported even when the others are fine.
        let mut s = a.clone();
        for j in 0..n {
            s[2 * n + j] = 0.0;
        }
        assert!(!lu.factor(&s));
    }

    /// The sign of the determinant, over coupled parts, against a brute-force determinant
    /// (cofactor expansion) on pseudo-random matrices with uncoupled groups.
    #[test]
    fn determinant_sign_matches_brute_force() {
        fn det(a: &[f64], n: usize) -> f64 {
            if n == 1 {
                return a[0];
            }
            (0..n)
                .map(|j| {
                    let minor: Vec<f64> = (1..n)
                        .flat_map(|i| (0..n).filter(move |&c| c != j).map(move |c| (i, c)))
                        .map(|(i, c)| a[i * n + c])
                        .collect();
                    let sgn = if j % 2 == 0 { 1.0 } else { -1.0 };
                    sgn * a[j] * det(&minor, n - 1)
                })
                .sum()
        }
        let n = 6;
        let mut seed = 12345u64;
        let mut rand = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut lu = DenseLu::with_blocks(n, 2);
        let mut small = DenseLu::dense(n);
        let mut seen = [false; 2];
        for trial in 0..200 {
            let mut a: Vec<f64> = (0..n * n).map(|_| rand()).collect();
            if trial % 2 == 0 {
                // Group 1 uncoupled from the others.
                for k in 0..n {
                    for i in 2..4 {
                        if !(2..4).contains(&k) {
                            a[i * n + k] = 0.0;
                            a[k * n + i] = 0.0;
                        }
                    }
                }
            }
            let d = det(&a, n);
            assert!(lu.factor(&a));
            assert_eq!(lu.det_sign(), d.signum(), "trial {trial}: det {d}");
            assert!(small.factor(&a));
            assert_eq!(
                small.det_sign(),
                d.signum(),
                "small kernel, trial {trial}: det {d}"
            );
            seen[usize::from(d > 0.0)] = true;
        }
        assert_eq!(seen, [true, true]);
        let singular = vec![1.0; n * n];
        assert!(!lu.factor(&singular));
        assert_eq!(lu.det_sign(), 0.0);
    }

    #[test]
    fn solves_a_pivoting_system() {
        let a0 = [0.0, 2.0, 1.0, 1.0, 1.0, 0.0, 3.0, 0.0, 1.0];
        let x_true = [1.0, -2.0, 0.5];
        let mut b: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| a0[i * 3 + j] * x_true[j]).sum())
            .collect();
        // The first pivot is zero: the rows must be exchanged.
        let mut lu = DenseLu::new(3);
        assert!(lu.factor(&a0));
        lu.solve(&mut b);
        for i in 0..3 {
            assert!((b[i] - x_true[i]).abs() < 1e-14);
        }
        // Several right-hand sides at once, as column-by-column solves give.
        let mut cols = faer::Mat::<f64>::from_fn(3, 2, |i, j| {
            (0..3)
                .map(|c| a0[i * 3 + c] * x_true[c] * (j + 1) as f64)
                .sum()
        });
        let mut buf = lu.columns_scratch(2);
        lu.solve_columns(cols.as_mut(), &mut buf);
        for j in 0..2 {
            for i in 0..3 {
                assert!((cols[(i, j)] - x_true[i] * (j + 1) as f64).abs() < 1e-14);
            }
        }
        let mut lu2 = DenseLu::new(2);
        assert!(!lu2.factor(&[1.0, 2.0, 2.0, 4.0]));
        // The small-system kernel: the same solutions, one column or several.
        let mut small = DenseLu::dense(3);
        assert!(small.factor(&a0));
        let mut b: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|j| a0[i * 3 + j] * x_true[j]).sum())
            .collect();
        small.solve(&mut b);
        let mut cols = faer::Mat::<f64>::from_fn(3, 2, |i, j| {
            (0..3)
                .map(|c| a0[i * 3 + c] * x_true[c] * (j + 1) as f64)
                .sum()
        });
        let mut buf = small.columns_scratch(2);
        small.solve_columns(cols.as_mut(), &mut buf);
        for i in 0..3 {
            assert!((b[i] - x_true[i]).abs() < 1e-14);
            for j in 0..2 {
                assert!((cols[(i, j)] - x_true[i] * (j + 1) as f64).abs() < 1e-14);
            }
        }
        let mut small2 = DenseLu::dense(2);
        assert!(!small2.factor(&[1.0, 2.0, 2.0, 4.0]));
        assert_eq!(small2.det_sign(), 0.0);
    }
}
