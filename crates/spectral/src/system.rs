//! The nonlinear forces of a whole polynomial system at once, `F_e = Σ_m c_{e,m} m(x)` for every
//! equation `e`, with their Jacobians: what a harmonic-balance residual needs at every Newton
//! step.
//!
//! Evaluating each monomial with its own [`ProductPlan`] chain repeats work: the monomials of
//! one degree share the chain's levels, and in a physical model they share factors. Here every
//! degree-`d` monomial is split as `prefix · last`, the prefix (`d − 1` factors) evaluated once
//! per distinct prefix through a trie of partial products, and each equation's monomials are
//! grouped by their last factor: `Σ c_m prefix_m` is summed on the prefix bins (cheap), then
//! one last level per group gives the output. For coupled Duffing modes
//! (`F_i = β_i q_i³ + Σ_j γ_ij q_i q_j²`) the last factor is `q_i` and the prefixes are the `N`
//! squares `q_j²`: `N` second levels and `N` last levels instead of `N²` of each.
//!
//! The Jacobian of `F_e` with respect to variable `j` is, in the same way,
//! `Σ_m c_m p_{m,j} · (m / x_j)` summed on the prefix bins, then the last level's edges as a
//! scatter into the `(output, input)` block.

use crate::product::{run_level, scatter_jacobian, Chain};
use crate::{ProductPlan, SpectralError};
use harmonid_poly::PowerProduct;
use num_complex::Complex64;
use std::collections::HashMap;

const Z: Complex64 = Complex64::new(0.0, 0.0);
/// Parent of a depth-1 trie node: the level-0 constant 1.
const ROOT: u32 = u32::MAX;

/// A partial product `x_{v_1} ⋯ x_{v_k}` (factors in ascending variable order), as level `k`
/// of the chain of its degree.
#[derive(Debug, Clone)]
struct Node {
    parent: u32,
    var: u32,
    depth: u32,
    /// Offset of its bins in the scratch buffer.
    offset: usize,
    /// Needed by the forces (else only by the Jacobian).
    in_forces: bool,
}

/// `Σ weight · node` on the prefix level, then the last level with `var` (the last factor for
/// the forces, the differentiated variable for the Jacobian), into equation `eq`.
#[derive(Debug, Clone)]
struct Group {
    eq: usize,
    var: usize,
    /// `(node, weight)`; node [`ROOT`] is the constant 1 (degree-1 monomials).
    terms: Vec<(u32, f64)>,
}

/// Everything for the monomials of one degree `≥ 1`.
#[derive(Debug, Clone)]
struct DegreePart {
    degree: usize,
    nodes: Vec<Node>,
    forces: Vec<Group>,
    jacobian: Vec<Group>,
}

/// Precomputed evaluation of a polynomial system's forces on a frequency lattice.
///
/// Build with [`SystemPlan::new`] once per (lattice, system); [`SystemPlan::forces`] and
/// [`SystemPlan::jacobian`] then do not allocate.
#[derive(Debug, Clone)]
pub struct SystemPlan {
    plan: ProductPlan,
    n_vars: usize,
    n_eqs: usize,
    parts: Vec<DegreePart>,
    /// Constant terms `(eq, c)`: the static force `c` on the 0 Hz output lines.
    constants: Vec<(usize, f64)>,
    /// Scratch size for the trie's bins.
    node_bins: usize,
}

/// Caller-owned buffers for [`SystemPlan`], reused across evaluations.
#[derive(Debug, Clone)]
pub struct SystemScratch {
    nodes: Vec<Complex64>,
    acc: Vec<Complex64>,
    last: Vec<Complex64>,
    comps: Vec<Complex64>,
}

impl SystemPlan {
    /// Plans the system `F_e = Σ c · m(x)` over `n_vars` variables and `n_eqs` equations;
    /// `terms` are `(equation, monomial over variables 0..n_vars, real coefficient)`. Input
    /// and output frequencies are those of `plan` (Hz), which must have planned the degree of
    /// every monomial (see [`ProductPlan::for_degrees`]).
    ///
    /// Errors: an equation or variable index out of range, or a monomial above the plan's
    /// degree ([`SpectralError::TooLarge`]).
    pub fn new(
        plan: ProductPlan,
        n_vars: usize,
        n_eqs: usize,
        terms: &[(usize, PowerProduct, f64)],
    ) -> Result<Self, SpectralError> {
        let mut by_degree: Vec<Vec<(usize, Vec<u32>, f64)>> = Vec::new();
        let mut constants = Vec::new();
        for (eq, m, c) in terms {
            if *eq >= n_eqs {
                return Err(SpectralError::TooLarge {
                    what: "an equation index of a system",
                    needed: *eq + 1,
                    limit: n_eqs,
                });
            }
            if let Some(&(v, _)) = m.factors().iter().find(|(v, _)| v.index() >= n_vars) {
                return Err(SpectralError::TooLarge {
                    what: "a variable index of a system",
                    needed: v.index() + 1,
                    limit: n_vars,
                });
            }
            let d = m.degree() as usize;
            if !plan.has_degree(d) {
                return Err(SpectralError::TooLarge {
                    what: "a monomial degree for this product plan (not planned)",
                    needed: d,
                    limit: plan.max_degree(),
                });
            }
            if *c == 0.0 {
                continue;
            }
            if d == 0 {
                constants.push((*eq, *c));
                continue;
            }
            if by_degree.len() <= d {
                by_degree.resize(d + 1, Vec::new());
            }
            let flat = m.flat_factors().iter().map(|v| v.index() as u32).collect();
            by_degree[d].push((*eq, flat, *c));
        }
        let mut parts = Vec::new();
        let mut node_bins = 0usize;
        for (degree, monos) in by_degree.into_iter().enumerate() {
            if monos.is_empty() {
                continue;
            }
            let part = plan_degree(
                plan.chain_ref(degree),
                degree,
                n_eqs,
                &monos,
                &mut node_bins,
            );
            parts.push(part);
        }
        Ok(Self {
            plan,
            n_vars,
            n_eqs,
            parts,
            constants,
            node_bins,
        })
    }

    /// The product plan (input and output frequencies).
    pub fn plan(&self) -> &ProductPlan {
        &self.plan
    }

    /// Complex multiply-adds of one [`SystemPlan::forces`] evaluation (level edges only).
    pub fn cost(&self) -> usize {
        let mut total = 0;
        for p in &self.parts {
            let chain = self.plan.chain_ref(p.degree);
            for n in p.nodes.iter().filter(|n| n.in_forces) {
                total += chain.levels[n.depth as usize - 1].edges();
            }
            total += p.forces.len() * chain.levels[p.degree - 1].edges();
        }
        total
    }

    /// Fresh buffers sized for this plan.
    pub fn scratch(&self) -> SystemScratch {
        let bins = self.plan.max_bins();
        SystemScratch {
            nodes: vec![Z; self.node_bins],
            acc: vec![Z; bins],
            last: vec![Z; bins],
            comps: vec![Z; 2 * self.n_vars * self.plan.input_hz().len()],
        }
    }

    /// The forces: `out[e·O + o]` is the complex amplitude of `F_e` at output frequency `o`
    /// (`O = output_hz.len()`), conventions as [`ProductPlan::eval`]; `x[v]` is variable `v`'s
    /// spectrum on the input frequencies. Does not allocate.
    ///
    /// # Panics
    /// On shapes that do not match the plan (programming errors).
    pub fn forces(&self, x: &[&[Complex64]], out: &mut [Complex64], s: &mut SystemScratch) {
        let n_out = self.plan.output_hz().len();
        assert_eq!(out.len(), self.n_eqs * n_out, "forces: output length");
        self.load_comps(x, s);
        out.fill(Z);
        for &(eq, c) in &self.constants {
            for (o, &f) in self.plan.output_hz().iter().enumerate() {
                if f <= crate::FREQ_TOLERANCE_HZ {
                    out[eq * n_out + o] += c;
                }
            }
        }
        let r2 = 2 * self.plan.input_hz().len();
        for part in &self.parts {
            let chain = self.plan.chain_ref(part.degree);
            self.eval_nodes(part, chain, true, s);
            let prev_bins = prefix_bins(chain, part.degree);
            for g in &part.forces {
                sum_prefixes(g, part, prev_bins, s);
                let level = &chain.levels[part.degree - 1];
                let comp = &s.comps[g.var * r2..(g.var + 1) * r2];
                run_level(
                    level,
                    &s.acc[..prev_bins],
                    comp,
                    &mut s.last[..level.bins()],
                );
                let row = &mut out[g.eq * n_out..(g.eq + 1) * n_out];
                for ((o, bin), &sc) in row.iter_mut().zip(&chain.out_bin).zip(&chain.out_scale) {
                    if let Some(b) = bin {
                        *o += s.last[*b as usize] * sc;
                    }
                }
            }
        }
    }

    /// The Jacobian of the forces with respect to the real and imaginary parts of the inputs:
    /// `block(e, v, jac_re, jac_im)` is called once per (equation, variable, degree) with a
    /// nonzero derivative, `jac_re[o·R + r] = ∂F_e[o]/∂Re x_v[r]` and
    /// `jac_im[o·R + r] = ∂F_e[o]/∂Im x_v[r]` (`R = input_hz.len()`; see
    /// [`ProductPlan::eval_jacobian`]); the caller adds the blocks up. `jac_re` and `jac_im`
    /// are caller buffers of `O · R` entries, overwritten. Does not allocate.
    ///
    /// # Panics
    /// On shapes that do not match the plan (programming errors).
    pub fn jacobian(
        &self,
        x: &[&[Complex64]],
        jac_re: &mut [Complex64],
        jac_im: &mut [Complex64],
        s: &mut SystemScratch,
        mut block: impl FnMut(usize, usize, &[Complex64], &[Complex64]),
    ) {
        let r_len = self.plan.input_hz().len();
        let n_out = self.plan.output_hz().len();
        assert!(
            jac_re.len() == n_out * r_len && jac_im.len() == n_out * r_len,
            "jacobian: blocks must hold output_hz.len() * input_hz.len() entries"
        );
        self.load_comps(x, s);
        for part in &self.parts {
            let chain = self.plan.chain_ref(part.degree);
            self.eval_nodes(part, chain, false, s);
            let prev_bins = prefix_bins(chain, part.degree);
            for g in &part.jacobian {
                sum_prefixes(g, part, prev_bins, s);
                scatter_jacobian(chain, part.degree, &s.acc, 1.0, r_len, jac_re, jac_im);
                block(g.eq, g.var, jac_re, jac_im);
            }
        }
    }

    /// Each variable's components `X_r`, `conj X_r` in the plans' interleaved order.
    fn load_comps(&self, x: &[&[Complex64]], s: &mut SystemScratch) {
        let r_len = self.plan.input_hz().len();
        assert_eq!(x.len(), self.n_vars, "one spectrum per variable");
        assert_eq!(
            s.comps.len(),
            2 * self.n_vars * r_len,
            "scratch does not belong to this plan; make it with SystemPlan::scratch"
        );
        for (v, xv) in x.iter().enumerate() {
            assert_eq!(
                xv.len(),
                r_len,
                "variable {v}: one amplitude per input frequency"
            );
            for (r, &z) in xv.iter().enumerate() {
                s.comps[2 * (v * r_len + r)] = z;
                s.comps[2 * (v * r_len + r) + 1] = z.conj();
            }
        }
    }

    /// Evaluates the trie's nodes (those of the forces, or all).
    fn eval_nodes(&self, part: &DegreePart, chain: &Chain, forces: bool, s: &mut SystemScratch) {
        let r2 = 2 * self.plan.input_hz().len();
        let one = [Complex64::new(1.0, 0.0)];
        for node in &part.nodes {
            if forces && !node.in_forces {
                continue;
            }
            let level = &chain.levels[node.depth as usize - 1];
            let comp = &s.comps[node.var as usize * r2..(node.var as usize + 1) * r2];
            let (head, tail) = s.nodes.split_at_mut(node.offset);
            let prev: &[Complex64] = if node.parent == ROOT {
                &one
            } else {
                let p = &part.nodes[node.parent as usize];
                &head[p.offset..p.offset + chain.levels[p.depth as usize - 1].bins()]
            };
            run_level(level, prev, comp, &mut tail[..level.bins()]);
        }
    }
}

/// Bins of the prefix level (`degree − 1`) of `chain`: 1 (the constant) for degree 1.
fn prefix_bins(chain: &Chain, degree: usize) -> usize {
    if degree == 1 {
        1
    } else {
        chain.levels[degree - 2].bins()
    }
}

/// `s.acc = Σ weight · node` over the prefix bins.
fn sum_prefixes(g: &Group, part: &DegreePart, bins: usize, s: &mut SystemScratch) {
    let acc = &mut s.acc[..bins];
    acc.fill(Z);
    for &(node, w) in &g.terms {
        if node == ROOT {
            acc[0] += w;
            continue;
        }
        let off = part.nodes[node as usize].offset;
        for (a, &v) in acc.iter_mut().zip(&s.nodes[off..off + bins]) {
            *a += v * w;
        }
    }
}

/// The trie and groups for the degree-`degree` monomials `(eq, sorted factors, coefficient)`.
fn plan_degree(
    chain: &Chain,
    degree: usize,
    n_eqs: usize,
    monos: &[(usize, Vec<u32>, f64)],
    node_bins: &mut usize,
) -> DegreePart {
    let mut part = DegreePart {
        degree,
        nodes: Vec::new(),
        forces: Vec::new(),
        jacobian: Vec::new(),
    };
    let mut ids: HashMap<Vec<u32>, u32> = HashMap::new();
    // The node for a sorted factor sequence, creating its prefixes first.
    let mut node_for =
        |seq: &[u32], in_forces: bool, part: &mut DegreePart, node_bins: &mut usize| -> u32 {
            let mut parent = ROOT;
            for k in 1..=seq.len() {
                let key = &seq[..k];
                let id = match ids.get(key) {
                    Some(&id) => id,
                    None => {
                        let id = part.nodes.len() as u32;
                        let bins = chain.levels[k - 1].bins();
                        part.nodes.push(Node {
                            parent,
                            var: seq[k - 1],
                            depth: k as u32,
                            offset: *node_bins,
                            in_forces: false,
                        });
                        *node_bins += bins;
                        ids.insert(key.to_vec(), id);
                        id
                    }
                };
                part.nodes[id as usize].in_forces |= in_forces;
                parent = id;
            }
            parent
        };
    // Forces: per equation, factor out greedily the variable most of its monomials contain.
    for eq in 0..n_eqs {
        let mut left: Vec<&(usize, Vec<u32>, f64)> =
            monos.iter().filter(|(e, _, _)| *e == eq).collect();
        while !left.is_empty() {
            let mut count: HashMap<u32, usize> = HashMap::new();
            for (_, f, _) in &left {
                let mut seen = f.clone();
                seen.dedup();
                for v in seen {
                    *count.entry(v).or_default() += 1;
                }
            }
            let best = count
                .iter()
                .max_by_key(|&(&v, &n)| (n, std::cmp::Reverse(v)))
                .map(|(&v, _)| v)
                .expect("a monomial has a factor");
            let mut group = Group {
                eq,
                var: best as usize,
                terms: Vec::new(),
            };
            left.retain(|(_, f, c)| {
                let Some(pos) = f.iter().position(|&v| v == best) else {
                    return true;
                };
                let mut rest = f.clone();
                rest.remove(pos);
                let node = if rest.is_empty() {
                    ROOT
                } else {
                    node_for(&rest, true, &mut part, node_bins)
                };
                group.terms.push((node, *c));
                false
            });
            part.forces.push(group);
        }
    }
    // Jacobian: per (equation, variable), Σ c · p · (m / x_v).
    let mut jac: Vec<Group> = Vec::new();
    for (eq, f, c) in monos {
        let mut vars = f.clone();
        vars.dedup();
        for v in vars {
            let p = f.iter().filter(|&&u| u == v).count() as f64;
            let pos = f.iter().position(|&u| u == v).expect("v is a factor");
            let mut rest = f.clone();
            rest.remove(pos);
            let node = if rest.is_empty() {
                ROOT
            } else {
                node_for(&rest, false, &mut part, node_bins)
            };
            match jac.iter_mut().find(|g| g.eq == *eq && g.var == v as usize) {
                Some(g) => g.terms.push((node, c * p)),
                None => jac.push(Group {
                    eq: *eq,
                    var: v as usize,
                    terms: vec![(node, c * p)],
                }),
            }
        }
    }
    part.jacobian = jac;
    part
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{monomial_amplitudes, monomial_jacobian};
    use harmonid_poly::VarId;

    use crate::test_rng::Rng;

    /// A random system and lattice (with a 0 Hz line), evaluated both ways.
    fn check(seed: u64) {
        let mut rng = Rng(seed);
        let (n_vars, n_eqs) = (1 + rng.below(3), 1 + rng.below(3));
        // Two tones and some of their combinations, plus DC.
        let (f1, f2) = (100.0 + 10.0 * rng.next(), 103.0 + 10.0 * rng.next());
        let mut lattice = vec![0.0, f1, f2, 2.0 * f1 - f2, 2.0 * f2 - f1, f1 + f2, f2 - f1];
        lattice.iter_mut().for_each(|f| *f = f64::abs(*f));
        lattice.sort_by(f64::total_cmp);
        let plan = ProductPlan::new(&lattice, &lattice, 4).expect("plan");
        let mut terms = Vec::new();
        for _ in 0..8 {
            let degree = rng.below(5);
            let mut e = vec![0u32; n_vars];
            for _ in 0..degree {
                e[rng.below(n_vars)] += 1;
            }
            terms.push((
                rng.below(n_eqs),
                PowerProduct::from_exponents(&e),
                rng.next(),
            ));
        }
        let sys = SystemPlan::new(plan.clone(), n_vars, n_eqs, &terms).expect("system");
        let x: Vec<Vec<Complex64>> = (0..n_vars)
            .map(|_| lattice.iter().map(|_| rng.c()).collect())
            .collect();
        let refs: Vec<&[Complex64]> = x.iter().map(|v| v.as_slice()).collect();
        let nr = lattice.len();
        // Forces against the monomial-by-monomial products.
        let mut got = vec![Z; n_eqs * nr];
        let mut s = sys.scratch();
        sys.forces(&refs, &mut got, &mut s);
        let mut want = vec![Z; n_eqs * nr];
        let mut ps = plan.scratch();
        let mut out = vec![Z; nr];
        for (eq, m, c) in &terms {
            monomial_amplitudes(&plan, m, &refs, &mut out, &mut ps);
            for (w, o) in want[eq * nr..(eq + 1) * nr].iter_mut().zip(&out) {
                *w += o * c;
            }
        }
        for (g, w) in got.iter().zip(&want) {
            assert!(
                (g - w).norm() <= 1e-12 * (1.0 + w.norm()),
                "seed {seed}: {g} vs {w}"
            );
        }
        // Jacobian blocks, summed, against the per-monomial Jacobians.
        let mut got = vec![Z; 2 * n_eqs * n_vars * nr * nr];
        let (mut jr, mut ji) = (vec![Z; nr * nr], vec![Z; nr * nr]);
        let bsz = nr * nr;
        sys.jacobian(&refs, &mut jr, &mut ji, &mut s, |e, v, a, b| {
            let k = 2 * (e * n_vars + v) * bsz;
            for i in 0..bsz {
                got[k + i] += a[i];
                got[k + bsz + i] += b[i];
            }
        });
        let mut want = vec![Z; got.len()];
        for (eq, m, c) in &terms {
            for v in 0..n_vars {
                monomial_jacobian(&plan, m, &refs, VarId(v as u32), &mut jr, &mut ji, &mut ps);
                let k = 2 * (eq * n_vars + v) * bsz;
                for i in 0..bsz {
                    want[k + i] += jr[i] * c;
                    want[k + bsz + i] += ji[i] * c;
                }
            }
        }
        for (g, w) in got.iter().zip(&want) {
            assert!(
                (g - w).norm() <= 1e-12 * (1.0 + w.norm()),
                "seed {seed}: {g} vs {w}"
            );
        }
    }

    #[test]
    fn matches_monomial_by_monomial_products() {
        for seed in 1..60 {
            check(seed * 7919);
        }
    }

    #[test]
    fn coupled_duffing_shares_the_squares() {
        // F_i = q_i^3 + Σ_j q_i q_j^2 over 4 modes: 4 second levels and 4 last levels.
        let n = 4;
        let lattice = [1.0, 1.1, 2.0, 2.3];
        let plan = ProductPlan::new(&lattice, &lattice, 3).expect("plan");
        let mut terms = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let mut e = vec![0u32; n];
                e[i] += 1;
                e[j] += 2;
                terms.push((i, PowerProduct::from_exponents(&e), 1.0));
            }
        }
        let sys = SystemPlan::new(plan.clone(), n, n, &terms).expect("system");
        let chain = plan.chain_ref(3);
        let per_monomial = plan.cost(3) * terms.len();
        let want =
            n * (chain.levels[0].edges() + chain.levels[1].edges() + chain.levels[2].edges());
        assert_eq!(sys.cost(), want);
        assert!(
            sys.cost() * 3 < per_monomial,
            "{} vs {per_monomial}",
            sys.cost()
        );
    }

    #[test]
    fn bad_indices_are_errors() {
        let plan = ProductPlan::new(&[1.0], &[1.0], 3).expect("plan");
        let m = PowerProduct::from_exponents(&[0, 3]);
        assert!(SystemPlan::new(plan.clone(), 1, 1, &[(0, m.clone(), 1.0)]).is_err());
        assert!(SystemPlan::new(plan.clone(), 2, 1, &[(1, m.clone(), 1.0)]).is_err());
        let m4 = PowerProduct::from_exponents(&[4]);
        assert!(SystemPlan::new(plan, 1, 1, &[(0, m4, 1.0)]).is_err());
    }
}
