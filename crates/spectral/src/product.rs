//! Exact products of real multi-tone signals: the complex amplitude of `x_1(t)·…·x_K(t)` at
//! chosen output frequencies (the ĝ of Eq. 2 and S9 of the method's paper).
//!
//! Each factor is a real signal `x_k(t) = Σ_r Re[X_kr e^{i2π f_r t}]` on a common set of input
//! frequencies `f_r ≥ 0`; an input at 0 Hz is the static offset `Re X_k0` (its imaginary part
//! has no effect, and the Jacobian with respect to it is zero). Writing `Re[X e^{iωt}] = ½(X e^{iωt} + X̄ e^{-iωt})`, the product is a
//! sum over every choice of one signed component per factor; a choice whose frequency
//! `Σ ±f_r` lands on an output line contributes `2^{-K} Π (X or X̄)` to the two-sided coefficient
//! there. The complex amplitude at `f > 0` is twice the two-sided coefficient; at `f = 0` it is
//! the DC value itself.
//!
//! [`ProductPlan::new`] does all frequency bookkeeping once: the partial products
//! `x_1·…·x_j` are kept only at the frequencies that can still reach an output line (found by
//! meeting a forward and a backward search in the middle), as a table of in-edges per spectral
//! bin. [`ProductPlan::eval`] is then pure complex multiply-adds into caller-owned scratch.

use crate::SpectralError;
use harmonid_poly::{PowerProduct, VarId};
use num_complex::Complex64;

/// Frequencies closer than this are the same spectral line (Hz).
pub const FREQ_TOLERANCE_HZ: f64 = 1e-6;

/// Most entries one frequency set of a plan may hold before sorting (memory bound).
const MAX_SET_ENTRIES: usize = 1 << 23;
/// Most multiply-add terms a whole plan may hold (memory bound: 8 bytes each).
const MAX_PLAN_EDGES: usize = 1 << 23;
/// Highest product degree a plan supports.
pub const MAX_PRODUCT_DEGREE: usize = 16;

/// Sorts `v` and merges values closer than [`FREQ_TOLERANCE_HZ`] to the first of their run.
fn cluster(mut v: Vec<f64>) -> Vec<f64> {
    v.sort_unstable_by(f64::total_cmp);
    let mut out: Vec<f64> = Vec::with_capacity(v.len());
    for x in v {
        match out.last() {
            Some(&last) if x - last <= FREQ_TOLERANCE_HZ => {}
            _ => out.push(x),
        }
    }
    out
}

/// Index of the element of sorted `reps` within [`FREQ_TOLERANCE_HZ`] of `x`.
fn lookup(reps: &[f64], x: f64) -> Option<usize> {
    let i = reps.partition_point(|&r| r < x - FREQ_TOLERANCE_HZ);
    match reps.get(i) {
        Some(&r) if r <= x + FREQ_TOLERANCE_HZ => Some(i),
        _ => None,
    }
}

/// Lookups in sorted `set` of `x_c` for several shifts `c`, each shift's queries coming in
/// ascending order: one forward-only cursor per shift instead of a binary search per query
/// (plan building does `bins × components` of them).
struct Cursors<'a> {
    set: &'a [f64],
    pos: Vec<usize>,
}

impl<'a> Cursors<'a> {
    fn new(set: &'a [f64], shifts: usize) -> Self {
        Self {
            set,
            pos: vec![0; shifts],
        }
    }

    /// As [`lookup`]`(set, x)`; `x` must not decrease between calls with the same `c`.
    #[inline]
    fn find(&mut self, c: usize, x: f64) -> Option<usize> {
        let p = &mut self.pos[c];
        while *p < self.set.len() && self.set[*p] < x - FREQ_TOLERANCE_HZ {
            *p += 1;
        }
        match self.set.get(*p) {
            Some(&r) if r <= x + FREQ_TOLERANCE_HZ => Some(*p),
            _ => None,
        }
    }
}

/// One level of partial products, stored as in-edges per bin (compressed rows).
#[derive(Debug, Clone, Default)]
pub(crate) struct Level {
    /// `start[d]..start[d+1]` are the edges into bin `d`.
    pub(crate) start: Vec<u32>,
    /// Source bin in the previous level.
    pub(crate) src: Vec<u32>,
    /// Component: `2r` is `X_r`, `2r+1` is `conj(X_r)`.
    pub(crate) comp: Vec<u32>,
    /// `(bin, image)`: bins at `−f` whose image at `+f` is also kept. A partial product of real
    /// signals is real, so its coefficient at `−f` is the conjugate of that at `+f`: these
    /// bins have no edges and are filled by conjugation (about half of the work of a level
    /// whose bins straddle 0 Hz).
    mirror: Vec<(u32, u32)>,
}

impl Level {
    pub(crate) fn bins(&self) -> usize {
        self.start.len().saturating_sub(1)
    }

    /// Multiply-adds of one evaluation.
    pub(crate) fn edges(&self) -> usize {
        self.src.len()
    }
}

/// The plan for products of exactly `K` factors.
#[derive(Debug, Clone, Default)]
pub(crate) struct Chain {
    /// Levels 1..=K (level 0 is the constant 1 at 0 Hz).
    pub(crate) levels: Vec<Level>,
    /// Per output: bin of the last level, or `None` if no combination lands there.
    pub(crate) out_bin: Vec<Option<u32>>,
    /// Per output: 2^{1-K} for f > 0, 2^{-K} at DC.
    pub(crate) out_scale: Vec<f64>,
}

/// Precomputed index tables for exact products of real multi-tone signals.
///
/// Build once per (input frequencies, output frequencies, maximum degree) and evaluate many
/// times with [`ProductPlan::eval`] or [`monomial_amplitudes`]. Frequencies are in Hz.
#[derive(Debug, Clone)]
pub struct ProductPlan {
    input_hz: Vec<f64>,
    output_hz: Vec<f64>,
    /// `chains[k]` handles products of `k` factors, `k = 0..=max_degree` (`None`: a degree
    /// [`ProductPlan::for_degrees`] was not asked for).
    chains: Vec<Option<Chain>>,
    /// Largest number of bins of any level (scratch size).
    max_bins: usize,
}

/// Caller-owned buffers for [`ProductPlan::eval`], reused across evaluations.
#[derive(Debug, Clone)]
pub struct ProductScratch {
    a: Vec<Complex64>,
    b: Vec<Complex64>,
    comp: Vec<Complex64>,
}

impl ProductPlan {
    /// Plans products of up to `max_degree` factors.
    ///
    /// `input_hz`: frequencies (≥ 0, distinct) where the factor signals have components; an
    /// input at 0 Hz carries the static offset `Re X` (DC), needed by even-degree terms;
    /// `output_hz`: frequencies (≥ 0, repeats allowed) where product amplitudes are wanted;
    /// `max_degree`: largest product degree to support (at most [`MAX_PRODUCT_DEGREE`]).
    ///
    /// Errors: negative or non-finite inputs, inputs closer than [`FREQ_TOLERANCE_HZ`],
    /// negative outputs, or tables beyond the memory bound ([`SpectralError::TooLarge`]).
    pub fn new(
        input_hz: &[f64],
        output_hz: &[f64],
        max_degree: usize,
    ) -> Result<Self, SpectralError> {
        let all: Vec<usize> = (0..=max_degree).collect();
        Self::for_degrees(input_hz, output_hz, &all)
    }

    /// As [`ProductPlan::new`], planning only products of the listed numbers of factors (a
    /// cubic model needs degree 3 only; each degree's tables cost set-up time). Evaluating
    /// another degree panics.
    pub fn for_degrees(
        input_hz: &[f64],
        output_hz: &[f64],
        degrees: &[usize],
    ) -> Result<Self, SpectralError> {
        let max_degree = degrees.iter().copied().max().unwrap_or(0);
        for (index, &hz) in input_hz.iter().enumerate() {
            if !(hz.is_finite() && hz >= 0.0) {
                return Err(SpectralError::NegativeInputFrequency { index, hz });
            }
        }
        let mut order: Vec<usize> = (0..input_hz.len()).collect();
        order.sort_by(|&a, &b| input_hz[a].total_cmp(&input_hz[b]));
        for w in order.windows(2) {
            if input_hz[w[1]] - input_hz[w[0]] <= FREQ_TOLERANCE_HZ {
                let (first, second) = (w[0].min(w[1]), w[0].max(w[1]));
                return Err(SpectralError::CoincidentFrequencies {
                    what: "input",
                    first,
                    second,
                    hz: input_hz[first],
                });
            }
        }
        for (index, &hz) in output_hz.iter().enumerate() {
            if !(hz.is_finite() && hz >= 0.0) {
                return Err(SpectralError::NegativeOutputFrequency { index, hz });
            }
        }
        if max_degree > MAX_PRODUCT_DEGREE {
            return Err(SpectralError::TooLarge {
                what: "a product plan's degree",
                needed: max_degree,
                limit: MAX_PRODUCT_DEGREE,
            });
        }
        let comp_hz: Vec<f64> = input_hz.iter().flat_map(|&f| [f, -f]).collect();
        let outputs = cluster(output_hz.to_vec());
        let mut chains = Vec::with_capacity(max_degree + 1);
        let mut total_edges = 0usize;
        let mut max_bins = 1usize;
        for k in 0..=max_degree {
            if !degrees.contains(&k) {
                chains.push(None);
                continue;
            }
            let chain = build_chain(k, &comp_hz, &outputs, output_hz, &mut total_edges)?;
            for l in &chain.levels {
                max_bins = max_bins.max(l.bins());
            }
            chains.push(Some(chain));
        }
        Ok(Self {
            input_hz: input_hz.to_vec(),
            output_hz: output_hz.to_vec(),
            chains,
            max_bins,
        })
    }

    /// The input frequencies, Hz, in the order given to [`ProductPlan::new`].
    pub fn input_hz(&self) -> &[f64] {
        &self.input_hz
    }

    /// The output frequencies, Hz, in the order given to [`ProductPlan::new`].
    pub fn output_hz(&self) -> &[f64] {
        &self.output_hz
    }

    /// The largest product degree this plan supports.
    pub fn max_degree(&self) -> usize {
        self.chains.len() - 1
    }

    /// Number of complex multiply-adds one evaluation of a degree-`k` product costs (0 if `k`
    /// exceeds [`ProductPlan::max_degree`]).
    pub fn cost(&self, k: usize) -> usize {
        self.chains
            .get(k)
            .and_then(Option::as_ref)
            .map_or(0, |c| c.levels.iter().map(|l| l.src.len()).sum())
    }

    /// The chain for products of `degree` factors (`degree ≤ max_degree`).
    pub(crate) fn chain_ref(&self, degree: usize) -> &Chain {
        self.chains[degree]
            .as_ref()
            .expect("products of this degree were not planned")
    }

    /// Whether products of `degree` factors were planned.
    pub fn has_degree(&self, degree: usize) -> bool {
        self.chains.get(degree).is_some_and(Option::is_some)
    }

    /// Largest number of bins of any level.
    pub(crate) fn max_bins(&self) -> usize {
        self.max_bins
    }

    /// Fresh buffers sized for this plan.
    pub fn scratch(&self) -> ProductScratch {
        ProductScratch {
            a: vec![Complex64::new(0.0, 0.0); self.max_bins],
            b: vec![Complex64::new(0.0, 0.0); self.max_bins],
            comp: vec![Complex64::new(0.0, 0.0); 2 * self.input_hz.len()],
        }
    }

    /// Complex amplitude of the product `x_1(t)·…·x_K(t)`, `K = factors.len() ≤ max_degree`.
    ///
    /// Convention (DATA_FORMAT): the product signal is `Σ_o Re[out[o] e^{i2π output_hz[o] t}]`,
    /// and at `f = 0` `out[o]` is the DC value itself. Factor `k` is the real signal
    /// `x_k(t) = Σ_r Re[factors[k][r] e^{i2π input_hz[r] t}]` (each `factors[k]` has
    /// `input_hz.len()` entries). Exact: every combination of ± components whose frequency lands
    /// on an output line (within [`FREQ_TOLERANCE_HZ`]) is summed, conjugates included. The
    /// empty product is the constant 1. Does not allocate.
    ///
    /// # Panics
    /// If `factors.len() > max_degree`, a factor's length differs from `input_hz.len()`, `out`'s
    /// length differs from `output_hz.len()`, or `scratch` was made by another plan (all
    /// programming errors, not data errors).
    pub fn eval(
        &self,
        factors: &[&[Complex64]],
        out: &mut [Complex64],
        scratch: &mut ProductScratch,
    ) {
        self.eval_with(factors.len(), |k| factors[k], out, scratch);
    }

    /// [`ProductPlan::eval`] with factor `k` given by `factor(k)`, `k = 0..degree`.
    ///
    /// # Panics
    /// As [`ProductPlan::eval`].
    pub fn eval_with<'f>(
        &self,
        degree: usize,
        factor: impl Fn(usize) -> &'f [Complex64],
        out: &mut [Complex64],
        scratch: &mut ProductScratch,
    ) {
        let chain = self.chain(degree, out.len(), scratch);
        let last = run_levels(
            chain,
            degree,
            &factor,
            &mut scratch.a,
            &mut scratch.b,
            &mut scratch.comp,
        );
        let last_buf: &[Complex64] = if last { &scratch.b } else { &scratch.a };
        for ((o, bin), &s) in out.iter_mut().zip(&chain.out_bin).zip(&chain.out_scale) {
            *o = match bin {
                Some(b) => last_buf[*b as usize] * s,
                None => Complex64::new(0.0, 0.0),
            };
        }
    }

    /// Jacobian of the product's output amplitudes with respect to the real and imaginary
    /// parts of factor `wrt`'s amplitudes.
    ///
    /// Writing `X = factors[wrt][r] = a + ib`, on return
    /// `jac_re[o·R + r] = ∂out[o]/∂a` and `jac_im[o·R + r] = ∂out[o]/∂b` (complex numbers:
    /// their real parts are the derivatives of `Re out[o]`, their imaginary parts those of
    /// `Im out[o]`), `R = input_hz.len()`. The product is real-linear in each factor signal
    /// (but not holomorphic: conjugates appear, so `jac_im ≠ i·jac_re` in general). Cost about one
    /// [`ProductPlan::eval`]. Does not allocate.
    ///
    /// # Panics
    /// As [`ProductPlan::eval`], or if `wrt ≥ factors.len()` or the Jacobians are not
    /// `output_hz.len() · input_hz.len()` long.
    pub fn eval_jacobian(
        &self,
        factors: &[&[Complex64]],
        wrt: usize,
        jac_re: &mut [Complex64],
        jac_im: &mut [Complex64],
        scratch: &mut ProductScratch,
    ) {
        assert!(
            wrt < factors.len(),
            "eval_jacobian: wrt = {wrt} but only {} factors",
            factors.len()
        );
        self.jacobian_with(
            factors.len(),
            |k| if k < wrt { factors[k] } else { factors[k + 1] },
            1.0,
            jac_re,
            jac_im,
            scratch,
        );
    }

    /// Jacobian core: the first `degree - 1` factors come from `others(k)`; the differentiated
    /// factor is the last one. Results are multiplied by `mult`.
    fn jacobian_with<'f>(
        &self,
        degree: usize,
        others: impl Fn(usize) -> &'f [Complex64],
        mult: f64,
        jac_re: &mut [Complex64],
        jac_im: &mut [Complex64],
        scratch: &mut ProductScratch,
    ) {
        let r_len = self.input_hz.len();
        let n_out = self.output_hz.len();
        assert!(
            jac_re.len() == n_out * r_len && jac_im.len() == n_out * r_len,
            "eval_jacobian: Jacobians must hold output_hz.len() * input_hz.len() = {} entries, got {} and {}",
            n_out * r_len,
            jac_re.len(),
            jac_im.len()
        );
        assert!(
            degree >= 1,
            "eval_jacobian: a product of 0 factors has no Jacobian"
        );
        let chain = self.chain(degree, n_out, scratch);
        // Partial product of the other K-1 factors, then the last level's edges give the
        // derivative with respect to each component of the differentiated factor.
        let last = run_levels(
            chain,
            degree - 1,
            &others,
            &mut scratch.a,
            &mut scratch.b,
            &mut scratch.comp,
        );
        let prev: &[Complex64] = if last { &scratch.b } else { &scratch.a };
        scatter_jacobian(chain, degree, prev, mult, r_len, jac_re, jac_im);
    }

    /// The chain for `degree` factors, after checking shapes.
    fn chain(&self, degree: usize, out_len: usize, scratch: &ProductScratch) -> &Chain {
        assert!(
            degree < self.chains.len(),
            "product of {degree} factors, but the plan was built for max_degree = {}",
            self.chains.len() - 1
        );
        assert_eq!(
            out_len,
            self.output_hz.len(),
            "output buffer length must equal output_hz.len()"
        );
        assert!(
            scratch.a.len() >= self.max_bins
                && scratch.b.len() >= self.max_bins
                && scratch.comp.len() == 2 * self.input_hz.len(),
            "scratch does not belong to this plan; make it with ProductPlan::scratch"
        );
        self.chain_ref(degree)
    }
}

/// Runs the first `n` levels of `chain` with factors `factor(0..n)`; level 0 (the constant 1)
/// is written to `a`. Returns whether the level-`n` values sit in `b` (else in `a`).
fn run_levels<'f>(
    chain: &Chain,
    n: usize,
    factor: &impl Fn(usize) -> &'f [Complex64],
    a: &mut [Complex64],
    b: &mut [Complex64],
    comp: &mut [Complex64],
) -> bool {
    let r_len = comp.len() / 2;
    a[0] = Complex64::new(1.0, 0.0);
    let (mut prev, mut cur) = (a, b);
    let mut in_b = false;
    for (j, level) in chain.levels.iter().take(n).enumerate() {
        let x = factor(j);
        assert_eq!(
            x.len(),
            r_len,
            "factor {j} has {} amplitudes, expected input_hz.len() = {r_len}",
            x.len()
        );
        for (r, &v) in x.iter().enumerate() {
            comp[2 * r] = v;
            comp[2 * r + 1] = v.conj();
        }
        run_level(level, prev, comp, cur);
        std::mem::swap(&mut prev, &mut cur);
        in_b = !in_b;
    }
    in_b
}

/// One level: `cur[d] = Σ_{edges into d} prev[src] · comp[c]`, then the mirrored bins.
#[inline]
pub(crate) fn run_level(
    level: &Level,
    prev: &[Complex64],
    comp: &[Complex64],
    cur: &mut [Complex64],
) {
    for (cd, w) in cur.iter_mut().zip(level.start.windows(2)) {
        let (lo, hi) = (w[0] as usize, w[1] as usize);
        let mut acc = Complex64::new(0.0, 0.0);
        for (&s, &c) in level.src[lo..hi].iter().zip(&level.comp[lo..hi]) {
            acc += prev[s as usize] * comp[c as usize];
        }
        *cd = acc;
    }
    for &(d, img) in &level.mirror {
        cur[d as usize] = cur[img as usize].conj();
    }
}

/// The Jacobian of a degree-`degree` product through the last level of `chain`, given the
/// partial product `prev` of the other factors (times `mult`) on that level's source bins:
/// overwrites `jac_re[o·R + r] = ∂out[o]/∂Re X_r` and `jac_im[o·R + r] = ∂out[o]/∂Im X_r`
/// (`R = r_len`) of the differentiated factor's amplitudes `X`.
pub(crate) fn scatter_jacobian(
    chain: &Chain,
    degree: usize,
    prev: &[Complex64],
    mult: f64,
    r_len: usize,
    jac_re: &mut [Complex64],
    jac_im: &mut [Complex64],
) {
    let zero = Complex64::new(0.0, 0.0);
    jac_re.fill(zero);
    jac_im.fill(zero);
    let level = &chain.levels[degree - 1];
    let i = Complex64::new(0.0, 1.0);
    for (o, (bin, &s)) in chain.out_bin.iter().zip(&chain.out_scale).enumerate() {
        let Some(d) = bin else { continue };
        let d = *d as usize;
        let (lo, hi) = (level.start[d] as usize, level.start[d + 1] as usize);
        let row_re = &mut jac_re[o * r_len..(o + 1) * r_len];
        let row_im = &mut jac_im[o * r_len..(o + 1) * r_len];
        for e in lo..hi {
            let p = prev[level.src[e] as usize] * (s * mult);
            let c = level.comp[e] as usize;
            let r = c / 2;
            row_re[r] += p;
            // ∂X/∂b = i, ∂X̄/∂b = −i.
            if c.is_multiple_of(2) {
                row_im[r] += p * i;
            } else {
                row_im[r] -= p * i;
            }
        }
    }
}

/// `{s ± c : s ∈ set, c ∈ comps}` clustered, with the memory bound.
fn expand(set: &[f64], comps: &[f64], sign: f64) -> Result<Vec<f64>, SpectralError> {
    let needed = set.len().saturating_mul(comps.len());
    if needed > MAX_SET_ENTRIES {
        return Err(SpectralError::TooLarge {
            what: "a product plan's intermediate frequency set",
            needed,
            limit: MAX_SET_ENTRIES,
        });
    }
    let mut v = Vec::with_capacity(needed);
    for &s in set {
        for &c in comps {
            v.push(s + sign * c);
        }
    }
    Ok(cluster(v))
}

/// Builds the plan for products of exactly `k` factors.
fn build_chain(
    k: usize,
    comp_hz: &[f64],
    outputs: &[f64],
    output_hz: &[f64],
    total_edges: &mut usize,
) -> Result<Chain, SpectralError> {
    // Forward reachable sets F[j] (sums of j components) and backward sets B[j] (frequencies
    // from which an output is reachable with k-j more components), grown from whichever side is
    // smaller until they meet.
    let mut fwd: Vec<Vec<f64>> = vec![vec![0.0]];
    let mut bwd: Vec<Vec<f64>> = vec![outputs.to_vec()]; // bwd[i] is level k - i
    while fwd.len() - 1 < k - (bwd.len() - 1) {
        let (fa, bb) = (&fwd[fwd.len() - 1], &bwd[bwd.len() - 1]);
        if fa.len() <= bb.len() {
            let next = expand(fa, comp_hz, 1.0)?;
            fwd.push(next);
        } else {
            let next = expand(bb, comp_hz, -1.0)?;
            bwd.push(next);
        }
    }
    let meet = fwd.len() - 1;
    // kept[j]: bins of level j that are both reachable and useful.
    let mut kept: Vec<Vec<f64>> = vec![Vec::new(); k + 1];
    let b_meet = &bwd[k - meet];
    kept[meet] = fwd[meet]
        .iter()
        .copied()
        .filter(|&f| lookup(b_meet, f).is_some())
        .collect();
    for j in (0..meet).rev() {
        let mut next = Cursors::new(&kept[j + 1], comp_hz.len());
        kept[j] = fwd[j]
            .iter()
            .copied()
            .filter(|&f| (0..comp_hz.len()).any(|c| next.find(c, f + comp_hz[c]).is_some()))
            .collect();
    }
    for j in meet + 1..=k {
        let mut prev = Cursors::new(&kept[j - 1], comp_hz.len());
        kept[j] = bwd[k - j]
            .iter()
            .copied()
            .filter(|&f| (0..comp_hz.len()).any(|c| prev.find(c, f - comp_hz[c]).is_some()))
            .collect();
    }
    let mut levels = Vec::with_capacity(k);
    for j in 1..=k {
        let mut level = Level {
            start: Vec::with_capacity(kept[j].len() + 1),
            ..Level::default()
        };
        level.start.push(0);
        let mut prev = Cursors::new(&kept[j - 1], comp_hz.len());
        for (d, &f) in kept[j].iter().enumerate() {
            if f < -FREQ_TOLERANCE_HZ {
                if let Some(img) = lookup(&kept[j], -f) {
                    level.mirror.push((d as u32, img as u32));
                    level.start.push(level.src.len() as u32);
                    continue;
                }
            }
            for (c, &fc) in comp_hz.iter().enumerate() {
                if let Some(s) = prev.find(c, f - fc) {
                    level.src.push(s as u32);
                    level.comp.push(c as u32);
                }
            }
            level.start.push(level.src.len() as u32);
        }
        *total_edges = total_edges.saturating_add(level.src.len());
        if *total_edges > MAX_PLAN_EDGES {
            return Err(SpectralError::TooLarge {
                what: "a product plan's multiply-add table",
                needed: *total_edges,
                limit: MAX_PLAN_EDGES,
            });
        }
        levels.push(level);
    }
    let last = &kept[k];
    let out_bin = output_hz
        .iter()
        .map(|&f| lookup(last, f).map(|b| b as u32))
        .collect();
    let half = 0.5f64.powi(k as i32);
    let out_scale = output_hz
        .iter()
        .map(|&f| {
            if f <= FREQ_TOLERANCE_HZ {
                half
            } else {
                2.0 * half
            }
        })
        .collect();
    Ok(Chain {
        levels,
        out_bin,
        out_scale,
    })
}

/// The `i`-th factor (0-based, exponents expanded) of a power product.
fn nth_factor(m: &PowerProduct, mut i: usize) -> VarId {
    for &(v, k) in m.factors() {
        if i < k as usize {
            return v;
        }
        i -= k as usize;
    }
    panic!("factor index beyond the degree of the monomial")
}

/// The amplitude of a monomial in the modal coordinates: `modal[n]` is mode `n`'s spectrum on
/// `plan.input_hz()`; the factors of `m` (a [`PowerProduct`] over mode indices) pick the spectra.
/// Output as in [`ProductPlan::eval`]. Does not allocate.
///
/// # Panics
/// If a mode index of `m` is not below `modal.len()`, or as [`ProductPlan::eval`].
pub fn monomial_amplitudes(
    plan: &ProductPlan,
    m: &PowerProduct,
    modal: &[&[Complex64]],
    out: &mut [Complex64],
    scratch: &mut ProductScratch,
) {
    let degree = m.degree() as usize;
    plan.eval_with(degree, |i| modal[nth_factor(m, i).index()], out, scratch);
}

/// Jacobian of a monomial's output amplitudes with respect to the real and imaginary parts of
/// mode `wrt`'s amplitudes `modal[wrt][r] = a_r + i b_r`:
/// `jac_re[o·R + r] = ∂out[o]/∂a_r`, `jac_im[o·R + r] = ∂out[o]/∂b_r` (see
/// [`ProductPlan::eval_jacobian`]). If `m` does not contain `wrt`, both are zero. For a power
/// `q_n^p` the product rule gives `p` times the Jacobian of one factor. Does not allocate.
///
/// # Panics
/// As [`monomial_amplitudes`] and [`ProductPlan::eval_jacobian`].
pub fn monomial_jacobian(
    plan: &ProductPlan,
    m: &PowerProduct,
    modal: &[&[Complex64]],
    wrt: VarId,
    jac_re: &mut [Complex64],
    jac_im: &mut [Complex64],
    scratch: &mut ProductScratch,
) {
    let p = m.exponent(wrt);
    if p == 0 {
        jac_re.fill(Complex64::new(0.0, 0.0));
        jac_im.fill(Complex64::new(0.0, 0.0));
        return;
    }
    let degree = m.degree() as usize;
    // Drop one copy of `wrt` from the factor list: the first occurrence's position.
    let skip = {
        let mut pos = 0usize;
        for &(v, k) in m.factors() {
            if v == wrt {
                break;
            }
            pos += k as usize;
        }
        pos
    };
    plan.jacobian_with(
        degree,
        |i| {
            let i = if i < skip { i } else { i + 1 };
            modal[nth_factor(m, i).index()]
        },
        f64::from(p),
        jac_re,
        jac_im,
        scratch,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::test_rng::Rng;

    /// Brute force over every signed component choice (independent of the plan's tables).
    fn brute_force(input: &[f64], output: &[f64], factors: &[&[Complex64]]) -> Vec<Complex64> {
        let k = factors.len();
        let n = 2 * input.len();
        let mut out = vec![Complex64::new(0.0, 0.0); output.len()];
        let total = n.pow(k as u32);
        for idx in 0..total {
            let mut rest = idx;
            let mut f = 0.0;
            let mut v = Complex64::new(1.0, 0.0);
            for x in factors {
                let c = rest % n;
                rest /= n;
                let (r, neg) = (c / 2, c % 2 == 1);
                f += if neg { -input[r] } else { input[r] };
                v *= if neg { x[r].conj() } else { x[r] } * 0.5;
            }
            for (o, &fo) in output.iter().enumerate() {
                if (f - fo).abs() <= FREQ_TOLERANCE_HZ {
                    out[o] += if fo <= FREQ_TOLERANCE_HZ { v } else { 2.0 * v };
                }
            }
        }
        out
    }

    #[test]
    fn single_tone_cube_is_three_quarters() {
        // (A cos ωt)^3 = 3/4 A^3 cos ωt + 1/4 A^3 cos 3ωt.
        let plan = ProductPlan::new(&[100.0], &[100.0, 300.0, 0.0], 3).expect("plan");
        let mut s = plan.scratch();
        let x = [Complex64::new(2.0, 0.0)];
        let mut out = [Complex64::new(0.0, 0.0); 3];
        plan.eval(&[&x, &x, &x], &mut out, &mut s);
        assert!((out[0] - Complex64::new(6.0, 0.0)).norm() < 1e-14);
        assert!((out[1] - Complex64::new(2.0, 0.0)).norm() < 1e-14);
        assert!(out[2].norm() < 1e-14);
        // (A cos ωt)^2 = A²/2 + A²/2 cos 2ωt: DC is the value itself.
        let plan = ProductPlan::new(&[100.0], &[0.0, 200.0], 2).expect("plan");
        let mut s = plan.scratch();
        let mut out = [Complex64::new(0.0, 0.0); 2];
        plan.eval(&[&x, &x], &mut out, &mut s);
        assert!((out[0] - Complex64::new(2.0, 0.0)).norm() < 1e-14);
        assert!((out[1] - Complex64::new(2.0, 0.0)).norm() < 1e-14);
        // Empty product is 1 at DC.
        plan.eval(&[], &mut out, &mut s);
        assert_eq!(out, [Complex64::new(1.0, 0.0), Complex64::new(0.0, 0.0)]);
    }

    #[test]
    fn matches_combinatorial_brute_force_at_mhz() {
        let mut rng = Rng(0x9e3779b97f4a7c15);
        let input = [207572.0, 207592.0, 207582.5, 415842.0, 415832.0, 415852.0];
        let mut output: Vec<f64> = input.to_vec();
        output.extend([207552.0, 207612.0, 415822.0, 623424.0, 0.0, 20.0]);
        let plan = ProductPlan::new(&input, &output, 4).expect("plan");
        let mut s = plan.scratch();
        for k in 0..=4 {
            let xs: Vec<Vec<Complex64>> = (0..k)
                .map(|_| input.iter().map(|_| rng.c()).collect())
                .collect();
            let refs: Vec<&[Complex64]> = xs.iter().map(|v| v.as_slice()).collect();
            let mut out = vec![Complex64::new(0.0, 0.0); output.len()];
            plan.eval(&refs, &mut out, &mut s);
            let want = brute_force(&input, &output, &refs);
            let scale = want.iter().map(|z| z.norm()).fold(1e-300, f64::max);
            for (a, b) in out.iter().zip(&want) {
                assert!((a - b).norm() <= 1e-12 * scale, "k={k}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn static_offset_input() {
        // x = c + A cos ωt with c = 3, A = 2:  x² = (c² + A²/2) + 2cA cos ωt + A²/2 cos 2ωt.
        let plan = ProductPlan::new(&[0.0, 100.0], &[0.0, 100.0, 200.0], 2).expect("plan");
        let mut s = plan.scratch();
        let x = [Complex64::new(3.0, 0.0), Complex64::new(2.0, 0.0)];
        let mut out = [Complex64::new(0.0, 0.0); 3];
        plan.eval(&[&x, &x], &mut out, &mut s);
        let want = [11.0, 12.0, 2.0];
        for (o, w) in out.iter().zip(want) {
            assert!((o - Complex64::new(w, 0.0)).norm() < 1e-13, "{o} vs {w}");
        }
        // Against brute force with DC among random multi-tone inputs, degrees 1..=4.
        let mut rng = Rng(77);
        let input = [0.0, 10.0, 12.0, 21.0];
        let output = [0.0, 10.0, 12.0, 2.0, 22.0, 31.0, 33.0];
        let plan = ProductPlan::new(&input, &output, 4).expect("plan");
        let mut s = plan.scratch();
        for k in 1..=4 {
            let xs: Vec<Vec<Complex64>> = (0..k)
                .map(|_| {
                    let mut v: Vec<Complex64> = input.iter().map(|_| rng.c()).collect();
                    v[0].im = 0.0; // a static offset is real
                    v
                })
                .collect();
            let refs: Vec<&[Complex64]> = xs.iter().map(|v| v.as_slice()).collect();
            let mut out = vec![Complex64::new(0.0, 0.0); output.len()];
            plan.eval(&refs, &mut out, &mut s);
            let want = brute_force(&input, &output, &refs);
            for (a, b) in out.iter().zip(&want) {
                assert!((a - b).norm() <= 1e-12, "k={k}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let mut rng = Rng(12345);
        let input = [10.0, 12.0, 21.0, 31.0];
        let output = [10.0, 12.0, 8.0, 14.0, 0.0, 2.0, 33.0];
        let plan = ProductPlan::new(&input, &output, 3).expect("plan");
        let mut s = plan.scratch();
        let q1: Vec<Complex64> = input.iter().map(|_| rng.c()).collect();
        let q2: Vec<Complex64> = input.iter().map(|_| rng.c()).collect();
        let m = PowerProduct::from_exponents(&[2, 1]);
        let (nr, no) = (input.len(), output.len());
        for wrt in [VarId(0), VarId(1)] {
            let mut jr = vec![Complex64::new(0.0, 0.0); nr * no];
            let mut ji = jr.clone();
            monomial_jacobian(&plan, &m, &[&q1, &q2], wrt, &mut jr, &mut ji, &mut s);
            for r in 0..nr {
                for (dir, jac) in [
                    (Complex64::new(1.0, 0.0), &jr),
                    (Complex64::new(0.0, 1.0), &ji),
                ] {
                    let h = 1e-5;
                    let mut plus = [q1.clone(), q2.clone()];
                    let mut minus = [q1.clone(), q2.clone()];
                    plus[wrt.index()][r] += dir * h;
                    minus[wrt.index()][r] -= dir * h;
                    let mut op = vec![Complex64::new(0.0, 0.0); no];
                    let mut om = op.clone();
                    monomial_amplitudes(&plan, &m, &[&plus[0], &plus[1]], &mut op, &mut s);
                    monomial_amplitudes(&plan, &m, &[&minus[0], &minus[1]], &mut om, &mut s);
                    for o in 0..no {
                        let fd = (op[o] - om[o]) / (2.0 * h);
                        assert!(
                            (fd - jac[o * nr + r]).norm() < 1e-8,
                            "o={o} r={r}: {fd} vs {}",
                            jac[o * nr + r]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn planning_some_degrees_gives_the_same_products() {
        let f = [0.0, 99.5, 100.0, 100.5, 201.0];
        let full = ProductPlan::new(&f, &f, 3).expect("plan");
        let cubic = ProductPlan::for_degrees(&f, &f, &[3]).expect("plan");
        assert!(cubic.has_degree(3) && !cubic.has_degree(2) && !cubic.has_degree(4));
        assert_eq!(cubic.cost(2), 0);
        assert_eq!(cubic.cost(3), full.cost(3));
        let mut rng = Rng(7);
        let x: Vec<Complex64> = f.iter().map(|_| rng.c()).collect();
        let (mut a, mut b) = (
            vec![Complex64::new(0.0, 0.0); 5],
            vec![Complex64::new(0.0, 0.0); 5],
        );
        full.eval(&[&x, &x, &x], &mut a, &mut full.scratch());
        cubic.eval(&[&x, &x, &x], &mut b, &mut cubic.scratch());
        assert_eq!(a, b);
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(matches!(
            ProductPlan::new(&[1.0, -2.0], &[1.0], 2),
            Err(SpectralError::NegativeInputFrequency { index: 1, .. })
        ));
        assert!(matches!(
            ProductPlan::new(&[1.0, f64::NAN], &[1.0], 2),
            Err(SpectralError::NegativeInputFrequency { index: 1, .. })
        ));
        assert!(matches!(
            ProductPlan::new(&[5.0, 1.0, 5.0 + 1e-7], &[1.0], 2),
            Err(SpectralError::CoincidentFrequencies {
                first: 0,
                second: 2,
                ..
            })
        ));
        assert!(matches!(
            ProductPlan::new(&[1.0], &[-1.0], 2),
            Err(SpectralError::NegativeOutputFrequency { index: 0, .. })
        ));
        let many: Vec<f64> = (1..=400)
            .map(|i| f64::from(i) * std::f64::consts::PI)
            .collect();
        assert!(matches!(
            ProductPlan::new(&many, &many, 9),
            Err(SpectralError::TooLarge { .. })
        ));
    }
}
