//! Stages 3 to 5: expand index families, resolve and check names, lower expressions to exact
//! polynomials, and differentiate the potential into the equations of motion.

use crate::ast::{Expr, Family, File, Index, IndexRel, ModeDecl, Name, ParamDecl, Stmt};
use crate::error::{Code, ModelDiagnostic, Span};
use crate::model::{Bounds, Linear, Mode, Model, ParamKind, Parameter, PUMP_NAME};
use crate::nonsmooth::NonSmooth;
use crate::{MAX_DEGREE, MAX_FAMILY_INSTANCES, MAX_PRODUCT_WORK, MAX_TERMS};
use harmonid_poly::{Coeff, Overflow, Poly, PolyBuilder, Rational, Ring, VarId};
use std::collections::HashMap;

mod nonsmooth_args;
use nonsmooth_args::NONSMOOTH_FUNCTIONS;

/// Values of the index variables in scope.
type Env = Vec<(String, i64)>;

/// `∂U/∂q_n` for every mode `n < n_modes`: the equation terms a potential `U` contributes.
///
/// Walks the terms of `U` once and sends each factor's derivative to its mode's equation, so the
/// cost is proportional to the number of (term, variable) pairs, not to `terms × modes`.
pub fn equations_from_potential(u: &Poly, n_modes: usize) -> Result<Vec<Poly>, Overflow> {
    let mut eom = vec![Poly::zero(); n_modes];
    add_derivatives(u, 0, &mut eom)?;
    Ok(eom)
}

/// Adds `∂F/∂x_{offset+n}` to `eom[n]` for every `n`: a potential's `∂U/∂q_n` (`offset` 0) or a
/// dissipation function's `∂D/∂q̇_n` (`offset` the number of modes: velocities follow the
/// modes among the variables).
fn add_derivatives(u: &Poly, offset: usize, eom: &mut [Poly]) -> Result<(), Overflow> {
    // Each slot collects the terms of ∂U/∂q_v, then sorts and sums them once (many terms on
    // one monomial, e.g. a family of parameters, are summed as a balanced tree: n log n), and is
    // merged once with the directly written terms.
    let mut slots: Vec<PolyBuilder<Coeff>> = (0..eom.len()).map(|_| PolyBuilder::new()).collect();
    for (m, c) in u.terms() {
        for &(v, _) in m.factors() {
            let Some(slot) = v.index().checked_sub(offset).and_then(|i| slots.get_mut(i)) else {
                continue;
            };
            if let Some((k, rest)) = m.derivative(v) {
                let c = if k == 1 {
                    c.clone()
                } else {
                    Ring::checked_scale(c, &Rational::from_integer(i128::from(k)))?
                };
                slot.push(rest, c);
            }
        }
    }
    for (eq, slot) in eom.iter_mut().zip(slots) {
        let slot = slot.finish()?;
        *eq = if eq.is_zero() {
            slot
        } else {
            eq.checked_add(&slot)?
        };
    }
    Ok(())
}

/// Collects diagnostics, keeping one per (code, span): a family that repeats the same mistake
/// reports it once, with a count.
struct Sink<'s> {
    source: &'s str,
    list: Vec<ModelDiagnostic>,
    seen: HashMap<(Code, usize, usize), (usize, usize)>,
}

impl<'s> Sink<'s> {
    fn new(source: &'s str) -> Self {
        Self {
            source,
            list: Vec::new(),
            seen: HashMap::new(),
        }
    }

    /// Whether no diagnostic with this code and span was pushed yet (pushing another one then
    /// only counts a repeat, so callers may skip composing its text).
    fn is_new(&self, code: Code, span: Span) -> bool {
        !self.seen.contains_key(&(code, span.start, span.end))
    }

    fn push(&mut self, d: ModelDiagnostic) {
        let span = d.span.unwrap_or_default();
        let key = (d.code, span.start, span.end);
        if let Some((_, repeats)) = self.seen.get_mut(&key) {
            *repeats += 1;
            return;
        }
        self.seen.insert(key, (self.list.len(), 0));
        self.list.push(d);
    }

    fn finish(mut self) -> Vec<ModelDiagnostic> {
        for (idx, repeats) in self.seen.values() {
            if *repeats > 0 {
                if let Some(d) = self.list.get_mut(*idx) {
                    d.message.push_str(&format!(
                        " (and {repeats} more time{} in this family)",
                        if *repeats == 1 { "" } else { "s" }
                    ));
                }
            }
        }
        self.list.sort_by_key(|d| d.span.map_or(0, |s| s.start));
        self.list.truncate(crate::MAX_DIAGNOSTICS);
        self.list
    }

    fn line_of(&self, offset: usize) -> usize {
        self.source
            .get(..offset)
            .map_or(0, |s| s.bytes().filter(|&b| b == b'\n').count())
            + 1
    }
}

/// A use of an expression: a direct equation term, a potential or a dissipation function, with
/// its index values.
struct Use<'a> {
    target: Target<'a>,
    expr: &'a Expr,
    env: Env,
}

/// Where an expression goes.
#[derive(Clone, Copy)]
enum Target<'a> {
    /// `eom q1 += ...` (`true`: `-=`).
    Eom(&'a Name, bool),
    /// `potential: ...`: each equation gets `∂U/∂q_n`.
    Potential,
    /// `dissipation: ...`: each equation gets `∂D/∂q̇_n`.
    Dissipation,
}

/// What a name resolves to.
#[derive(Debug, Clone, Copy)]
enum Sym {
    Mode(u32),
    Param(u32),
}

struct Decls<'a> {
    modes: Vec<(&'a ModeDecl, Vec<i64>)>,
    params: Vec<(&'a ParamDecl, Vec<i64>)>,
    uses: Vec<Use<'a>>,
    instances: usize,
    stop: bool,
}

/// Expands families and lowers the file to a [`Model`].
pub(crate) fn lower(
    file: &File,
    source: &str,
    origin: &str,
) -> Result<Model, Vec<ModelDiagnostic>> {
    let mut sink = Sink::new(source);
    let mut decls = Decls {
        modes: Vec::new(),
        params: Vec::new(),
        uses: Vec::new(),
        instances: 0,
        stop: false,
    };
    let mut env = Env::new();
    for s in &file.statements {
        expand(s, &mut env, &mut decls, &mut sink);
        if decls.stop {
            break;
        }
    }
    if decls.stop {
        return Err(sink.finish());
    }

    // Names of modes (one index, `q[3]` is `q3`) and parameters (family-wide spelling).
    let param_style = param_styles(&decls.params);
    let mut table: HashMap<String, (Sym, Span)> = HashMap::new();
    let modes = declare_modes(&decls.modes, &mut table, &mut sink);
    let params = declare_params(&decls.params, &param_style, &mut table, &mut sink);
    if modes.is_empty() && sink.list.is_empty() {
        sink.push(ModelDiagnostic::new(
            Code::EmptyModel,
            Span::new(0, 0),
            "the model declares no mode",
            "no `mode` declaration in this file",
            "declare the modes first, as in `mode q1 at 207.58 kHz` (see docs/model-language.md)",
        ));
    }

    let names = Names {
        table: &table,
        style: &param_style,
        n_modes: modes.len() as u32,
        fixed: params.iter().map(fixed_value).collect(),
        factors: std::cell::RefCell::new(Vec::new()),
    };
    // Terms are collected in builders and sorted once: a family can add 10^5 statements in
    // any order, and inserting each into a sorted polynomial would be quadratic.
    let mut eom_terms: Vec<PolyBuilder<Coeff>> = vec![PolyBuilder::new(); modes.len()];
    let mut potential_terms = PolyBuilder::new();
    let mut first_potential: Option<Span> = None;
    let mut dissipation_terms = PolyBuilder::new();
    let mut first_dissipation: Option<Span> = None;
    let n_modes = modes.len();
    for u in &decls.uses {
        let mut ev = Eval {
            names: &names,
            env: &u.env,
            sink: &mut sink,
        };
        // Resolve the target before the expression, so both kinds of error are reported.
        let target = match u.target {
            Target::Eom(name, negate) => match ev.resolve_target(name) {
                Some(n) => Some((n, negate)),
                None => {
                    ev.eval(u.expr);
                    continue;
                }
            },
            Target::Potential | Target::Dissipation => None,
        };
        let Some(p) = ev.eval(u.expr) else { continue };
        if nonsmooth_in_potential(&mut sink, u, &p, n_modes) {
            continue;
        }
        let (builder, negate) = match (u.target, target) {
            (_, Some((n, negate))) => (&mut eom_terms[n as usize], negate),
            (Target::Dissipation, None) => {
                if !has_velocity(&p, n_modes) {
                    no_velocity_in_dissipation(&mut sink, u.expr.span());
                    continue;
                }
                first_dissipation.get_or_insert(u.expr.span());
                (&mut dissipation_terms, false)
            }
            (_, None) => {
                if has_velocity(&p, n_modes) {
                    velocity_in_potential(&mut sink, u.expr.span());
                    continue;
                }
                first_potential.get_or_insert(u.expr.span());
                (&mut potential_terms, false)
            }
        };
        if let Err(Overflow) = builder.push_poly(&p, negate) {
            overflow(&mut sink, u.expr.span());
        } else if builder.pending_len() > MAX_TERMS {
            too_many_terms(&mut sink, u.expr.span());
            break;
        }
    }
    let potential = match potential_terms.finish() {
        Ok(p) => p,
        Err(Overflow) => {
            overflow(&mut sink, first_potential.unwrap_or_default());
            Poly::zero()
        }
    };
    let dissipation = match dissipation_terms.finish() {
        Ok(p) => p,
        Err(Overflow) => {
            overflow(&mut sink, first_dissipation.unwrap_or_default());
            Poly::zero()
        }
    };
    let mut eom = Vec::with_capacity(eom_terms.len());
    for terms in eom_terms {
        eom.push(terms.finish().unwrap_or_else(|Overflow| {
            overflow(&mut sink, Span::default());
            Poly::zero()
        }));
    }
    if sink.list.is_empty() {
        if let Err(Overflow) = add_derivatives(&potential, 0, &mut eom) {
            overflow(&mut sink, first_potential.unwrap_or_default());
        }
        if let Err(Overflow) = add_derivatives(&dissipation, n_modes, &mut eom) {
            overflow(&mut sink, first_dissipation.unwrap_or_default());
        }
    }
    if !sink.list.is_empty() {
        return Err(sink.finish());
    }
    let (eom, nonsmooth) = split_nonsmooth_terms(eom, n_modes);
    Ok(Model {
        source: origin.to_string(),
        modes,
        params,
        eom,
        potential,
        dissipation,
        nonsmooth,
        nonsmooth_factors: names.factors.into_inner(),
    })
}

/// The modes, in declaration order (one index: `q[3]` is `q3`), each name entered in `table`;
/// a mode with more indices or a name taken is reported to `sink` and left out.
fn declare_modes(
    decls: &[(&ModeDecl, Vec<i64>)],
    table: &mut HashMap<String, (Sym, Span)>,
    sink: &mut Sink<'_>,
) -> Vec<Mode> {
    let mut modes = Vec::new();
    for (d, idx) in decls {
        let name = match idx.as_slice() {
            [] => d.name.base.clone(),
            [i] => format!("{}{}", d.name.base, i),
            _ => {
                sink.push(ModelDiagnostic::new(
                    Code::FamilyRange,
                    d.name.span,
                    format!(
                        "a mode has one index, but {}[...] has {}",
                        d.name.base,
                        idx.len()
                    ),
                    "too many indices",
                    "write modes as `q[i]` (which is `q1`, `q2`, ...)",
                ));
                continue;
            }
        };
        if declare(
            table,
            sink,
            &name,
            Sym::Mode(modes.len() as u32),
            d.name.span,
        ) {
            let nominal_hz = d.nominal_hz.map(|(v, _)| v).or(d.f_hz.map(|(v, _)| v));
            modes.push(Mode {
                name,
                nominal_hz,
                f_hz: d.f_hz.map_or(Linear::Unknown, |(v, _)| Linear::Fixed(v)),
                q_factor: d
                    .q_factor
                    .map_or(Linear::Unknown, |(v, _)| Linear::Fixed(v)),
            });
        }
    }
    modes
}

/// The parameters, in declaration order (a family's name in its `style`), each name entered
/// in `table`; a name taken is reported to `sink` and left out.
fn declare_params(
    decls: &[(&ParamDecl, Vec<i64>)],
    style: &Styles,
    table: &mut HashMap<String, (Sym, Span)>,
    sink: &mut Sink<'_>,
) -> Vec<Parameter> {
    let mut params = Vec::new();
    for (d, idx) in decls {
        let name = param_name(&d.name.base, idx, style);
        if declare(
            table,
            sink,
            &name,
            Sym::Param(params.len() as u32),
            d.name.span,
        ) {
            params.push(Parameter {
                name,
                kind: d.value.map_or(ParamKind::Unknown, ParamKind::Fixed),
                bounds: Bounds {
                    lower: d.lower,
                    upper: d.upper,
                },
            });
        }
    }
    params
}

fn overflow(sink: &mut Sink<'_>, span: Span) {
    sink.push(ModelDiagnostic::new(
        Code::Overflow,
        span,
        "exact arithmetic overflowed: a coefficient does not fit a 128-bit rational",
        "coefficients grow too large here",
        "use smaller numbers or powers, or fold large constant factors into a parameter",
    ));
}

fn too_many_terms(sink: &mut Sink<'_>, span: Span) {
    sink.push(ModelDiagnostic::new(
        Code::TooLarge,
        span,
        format!("the model grows beyond {MAX_TERMS} terms"),
        "too many terms",
        "harmonid limits the size of a model to keep checks fast; split or simplify the model",
    ));
}

fn declare(
    table: &mut HashMap<String, (Sym, Span)>,
    sink: &mut Sink<'_>,
    name: &str,
    sym: Sym,
    span: Span,
) -> bool {
    if name == PUMP_NAME {
        sink.push(ModelDiagnostic::new(
            Code::ReservedName,
            span,
            format!("`{name}` is the pump signal's built-in name and cannot be declared"),
            "reserved name",
            "write the pump's coefficient as a parameter (`param lambda`, then `eom q1 += lambda*pump*q1`), or rename this one",
        ));
        return false;
    }
    if let Some((old, old_span)) = table.get(name) {
        let what = match old {
            Sym::Mode(_) => "a mode",
            Sym::Param(_) => "a parameter",
        };
        let line = sink.line_of(old_span.start);
        sink.push(ModelDiagnostic::new(
            Code::Duplicate,
            span,
            format!("`{name}` is declared twice"),
            "second declaration",
            format!("`{name}` is already {what}, declared on line {line}; remove one declaration or rename it"),
        ));
        return false;
    }
    table.insert(name.to_string(), (sym, span));
    true
}

/// How the multi-index parameters of a family `(base, arity)` are spelled: concatenated digits
/// (`g12`) when every index is below 10, otherwise joined by `_` (`g1_12`).
type Styles = HashMap<(String, usize), bool>;

fn param_styles(params: &[(&ParamDecl, Vec<i64>)]) -> Styles {
    let mut styles: Styles = HashMap::new();
    for (d, idx) in params {
        if d.name.indices.is_some() && idx.len() >= 2 {
            let small = idx.iter().all(|&i| i < 10);
            let e = styles
                .entry((d.name.base.clone(), idx.len()))
                .or_insert(true);
            *e &= small;
        }
    }
    styles
}

/// The canonical spelling of parameter `base[idx...]`.
fn param_name(base: &str, idx: &[i64], styles: &Styles) -> String {
    match idx {
        [] => base.to_string(),
        [i] => format!("{base}{i}"),
        _ => {
            let concat = styles
                .get(&(base.to_string(), idx.len()))
                .copied()
                .unwrap_or_else(|| idx.iter().all(|&i| i < 10));
            let parts: Vec<String> = idx.iter().map(i64::to_string).collect();
            format!("{base}{}", parts.join(if concat { "" } else { "_" }))
        }
    }
}

fn expand<'a>(s: &'a Stmt, env: &mut Env, d: &mut Decls<'a>, sink: &mut Sink<'_>) {
    if d.stop {
        return;
    }
    d.instances += 1;
    if d.instances > MAX_FAMILY_INSTANCES {
        d.stop = true;
        let span = match s {
            Stmt::Family(f) => f.head.span,
            Stmt::Mode(m) => m.name.span,
            Stmt::Param(p) => p.span,
            Stmt::Eom(e) => e.expr.span(),
            Stmt::Potential(p) => p.expr.span(),
        };
        sink.push(ModelDiagnostic::new(
            Code::TooLarge,
            span,
            format!("index families expand to more than {MAX_FAMILY_INSTANCES} statements"),
            "the expansion passes the limit here",
            "use smaller ranges; harmonid bounds the size of a model so that checks stay fast",
        ));
        return;
    }
    match s {
        Stmt::Mode(m) => {
            if let Some(idx) = indices(&m.name, env, sink) {
                d.modes.push((m, idx));
            }
        }
        Stmt::Param(p) => {
            if let Some(idx) = indices(&p.name, env, sink) {
                d.params.push((p, idx));
            }
        }
        Stmt::Eom(e) => d.uses.push(Use {
            target: Target::Eom(&e.mode, e.negate),
            expr: &e.expr,
            env: env.clone(),
        }),
        Stmt::Potential(p) => d.uses.push(Use {
            target: if p.dissipation {
                Target::Dissipation
            } else {
                Target::Potential
            },
            expr: &p.expr,
            env: env.clone(),
        }),
        Stmt::Family(f) => expand_family(f, env, d, sink),
    }
}

fn expand_family<'a>(f: &'a Family, env: &mut Env, d: &mut Decls<'a>, sink: &mut Sink<'_>) {
    let h = &f.head;
    for (k, (v, sp)) in h.vars.iter().enumerate() {
        let twice = h.vars[..k].iter().any(|(w, _)| w == v);
        if twice || env.iter().any(|(w, _)| w == v) {
            sink.push(ModelDiagnostic::new(
                Code::FamilyRange,
                *sp,
                format!("the index variable `{v}` is already in use"),
                "used twice",
                "give each index variable of nested families its own name, as in `for i<j in 1..5`",
            ));
            return;
        }
    }
    if h.lo > h.hi {
        sink.push(ModelDiagnostic::new(
            Code::FamilyRange,
            h.range_span,
            format!("the range {}..{} is empty", h.lo, h.hi),
            "first bound above the last",
            format!(
                "ranges include both ends and count upwards: write `{}..{}`",
                h.hi, h.lo
            ),
        ));
        return;
    }
    let base = env.len();
    env.extend(h.vars.iter().map(|(v, _)| (v.clone(), h.lo)));
    enumerate_tuples(f, 0, base, env, d, sink);
    env.truncate(base);
}

/// Runs the family body for every index tuple, position `k` onwards; relations `<` and `<=`
/// bound each index by its predecessor, so only valid tuples are visited.
fn enumerate_tuples<'a>(
    f: &'a Family,
    k: usize,
    base: usize,
    env: &mut Env,
    d: &mut Decls<'a>,
    sink: &mut Sink<'_>,
) {
    let h = &f.head;
    if k == h.vars.len() {
        for s in &f.body {
            expand(s, env, d, sink);
            if d.stop {
                return;
            }
        }
        return;
    }
    let prev = if k > 0 {
        Some(env[base + k - 1].1)
    } else {
        None
    };
    let rel = if k > 0 {
        h.rels.get(k - 1).copied()
    } else {
        None
    };
    let start = match (rel, prev) {
        (Some(IndexRel::Lt), Some(p)) => p + 1,
        (Some(IndexRel::Le), Some(p)) => p,
        _ => h.lo,
    };
    for v in start..=h.hi {
        if rel == Some(IndexRel::Ne) && prev == Some(v) {
            continue;
        }
        env[base + k].1 = v;
        enumerate_tuples(f, k + 1, base, env, d, sink);
        if d.stop {
            return;
        }
    }
}

/// Evaluates the indices of a name in the current environment.
fn indices(name: &Name, env: &Env, sink: &mut Sink<'_>) -> Option<Vec<i64>> {
    let Some(list) = &name.indices else {
        return Some(Vec::new());
    };
    let mut out = Vec::with_capacity(list.len());
    for i in list {
        match i {
            Index::Lit(v) => out.push(*v),
            Index::Var {
                name: v,
                shift,
                span,
            } => {
                let Some((_, val)) = env.iter().rev().find(|(w, _)| w == v) else {
                    if sink.is_new(Code::UnknownName, *span) {
                        sink.push(ModelDiagnostic::new(
                            Code::UnknownName,
                            *span,
                            format!("`{v}` is not an index variable of an enclosing family"),
                            "unknown index variable",
                            format!("introduce it with `for {v} in 1..N:` or write a number"),
                        ));
                    } else {
                        sink.push(ModelDiagnostic::new(Code::UnknownName, *span, "", "", ""));
                    }
                    return None;
                };
                let x = val + shift;
                if x < 0 {
                    sink.push(ModelDiagnostic::new(
                        Code::FamilyRange,
                        *span,
                        format!("the index {v}{shift:+} is {x} when {v} = {val}, below 0"),
                        "negative index",
                        "indices are whole numbers from 0 up; shrink the family's range",
                    ));
                    return None;
                }
                out.push(x);
            }
        }
    }
    Some(out)
}

struct Names<'t> {
    table: &'t HashMap<String, (Sym, Span)>,
    style: &'t Styles,
    /// Modes: the velocity of mode `m` is the variable `n_modes + m`.
    n_modes: u32,
    /// The value of each fixed parameter (a `tanh` scale may be one).
    fixed: Vec<Option<f64>>,
    /// The distinct non-smooth factors met so far: `factors[k]` is the variable
    /// `2 n_modes + 1 + k` (shared by every statement, so equal factors are one variable).
    factors: std::cell::RefCell<Vec<NonSmooth>>,
}

struct Eval<'n, 'e, 's, 'src> {
    names: &'n Names<'n>,
    env: &'e Env,
    sink: &'s mut Sink<'src>,
}

impl Eval<'_, '_, '_, '_> {
    fn canonical(&mut self, n: &Name) -> Option<String> {
        let idx = indices(n, self.env, self.sink)?;
        Some(param_name(&n.base, &idx, self.names.style))
    }

    fn written(&self, n: &Name, canonical: &str) -> String {
        match &n.indices {
            None => format!("`{canonical}`"),
            Some(list) => {
                let vars: Vec<String> = list
                    .iter()
                    .filter_map(|i| match i {
                        Index::Var { name, .. } => self
                            .env
                            .iter()
                            .rev()
                            .find(|(w, _)| w == name)
                            .map(|(w, v)| format!("{w} = {v}")),
                        Index::Lit(_) => None,
                    })
                    .collect();
                if vars.is_empty() {
                    format!("`{canonical}`")
                } else {
                    format!("`{canonical}` (with {})", vars.join(", "))
                }
            }
        }
    }

    fn resolve_target(&mut self, n: &Name) -> Option<u32> {
        let name = self.canonical(n)?;
        match self.names.table.get(&name) {
            Some((Sym::Mode(m), _)) => Some(*m),
            Some((Sym::Param(_), _)) => {
                let w = self.written(n, &name);
                self.sink.push(ModelDiagnostic::new(
                    Code::UndeclaredMode,
                    n.span,
                    format!("{w} is a parameter, not a mode: only modes have equations of motion"),
                    "not a mode",
                    "write `eom MODE += ...` with a mode declared by `mode`",
                ));
                None
            }
            None => {
                if self.sink.is_new(Code::UndeclaredMode, n.span) {
                    let w = self.written(n, &name);
                    let modes = self.mode_list();
                    self.sink.push(ModelDiagnostic::new(
                        Code::UndeclaredMode,
                        n.span,
                        format!("a term is added to the equation of {w}, which is not a declared mode"),
                        "undeclared mode",
                        format!("the declared modes are {modes}; declare it with `mode {name}` or fix the name"),
                    ));
                } else {
                    self.sink.push(ModelDiagnostic::new(
                        Code::UndeclaredMode,
                        n.span,
                        "",
                        "",
                        "",
                    ));
                }
                None
            }
        }
    }

    fn mode_list(&self) -> String {
        let mut modes: Vec<(u32, &str)> = self
            .names
            .table
            .iter()
            .filter_map(|(k, (s, _))| match s {
                Sym::Mode(i) => Some((*i, k.as_str())),
                Sym::Param(_) => None,
            })
            .collect();
        modes.sort_unstable();
        match modes.len() {
            0 => "none".to_string(),
            n if n <= 8 => modes.iter().map(|(_, s)| *s).collect::<Vec<_>>().join(", "),
            n => format!("{} ... {} ({n} modes)", modes[0].1, modes[n - 1].1),
        }
    }

    /// The declared names `base` followed by a digit (`q1, q2, ...`), shortened when long.
    fn family_list(&self, base: &str) -> String {
        let mut list: Vec<&str> = self
            .names
            .table
            .keys()
            .filter(|k| {
                k.strip_prefix(base)
                    .is_some_and(|rest| rest.starts_with(|c: char| c.is_ascii_digit()))
            })
            .map(String::as_str)
            .collect();
        list.sort_by(|a, b| (a.len(), a).cmp(&(b.len(), b)));
        match list.len() {
            0 => "none".to_string(),
            n if n <= 8 => list.join(", "),
            n => format!("{}, {}, ..., {} ({n} names)", list[0], list[1], list[n - 1]),
        }
    }

    fn suggestion(&self, name: &str) -> Option<String> {
        let mut best: Option<(usize, &str)> = None;
        for k in self.names.table.keys() {
            let d = edit_distance(name, k);
            if d <= 2 && best.is_none_or(|(bd, bk)| (d, k.as_str()) < (bd, bk)) {
                best = Some((d, k));
            }
        }
        best.map(|(_, k)| k.to_string())
    }

    fn eval(&mut self, e: &Expr) -> Option<Poly> {
        match e {
            Expr::Num(r, _) => Some(Poly::constant(Coeff::constant(*r))),
            Expr::Name(n) => self.name(n),
            Expr::Call(f, args, sp) if f == "d" => self.velocity(args, *sp),
            Expr::Call(f, args, sp) if NONSMOOTH_FUNCTIONS.contains(&f.as_str()) => {
                self.nonsmooth(f, args, *sp)
            }
            Expr::Call(f, _, sp) => {
                let help = if self.names.table.contains_key(f.as_str()) {
                    format!("to multiply, write the `*`: `{f}*(...)`")
                } else {
                    "model terms are sums of products of modes, parameters and numbers; \
                     replace a function by the terms of its Taylor polynomial that matter"
                        .to_string()
                };
                self.sink.push(ModelDiagnostic::new(
                    Code::NotPolynomial,
                    *sp,
                    format!("`{f}(...)` is a function, but model terms must be polynomials"),
                    "not a polynomial",
                    help,
                ));
                None
            }
            Expr::Neg(a, sp) => {
                let a = self.eval(a)?;
                self.ok(a.checked_neg(), *sp)
            }
            Expr::Sum(terms, sp) => {
                let mut acc = PolyBuilder::new();
                let mut ok = true;
                for (neg, t) in terms {
                    let Some(p) = self.eval(t) else {
                        ok = false;
                        continue;
                    };
                    if !ok {
                        continue;
                    }
                    if acc.push_poly(&p, *neg).is_err() {
                        overflow(self.sink, *sp);
                        return None;
                    }
                    if acc.pending_len() > MAX_TERMS {
                        too_many_terms(self.sink, *sp);
                        return None;
                    }
                }
                if !ok {
                    return None;
                }
                self.ok(acc.finish(), *sp)
            }
            Expr::Product(factors, sp) => {
                let mut acc = Poly::constant(Coeff::constant(Rational::from_integer(1)));
                let mut ok = true;
                for (div, f) in factors {
                    let Some(p) = self.eval(f) else {
                        ok = false;
                        continue;
                    };
                    if !ok {
                        continue;
                    }
                    acc = if *div {
                        let k = self.divisor(&p, f.span())?;
                        self.ok(acc.checked_scale_rational(&k), *sp)?
                    } else {
                        self.mul(&acc, &p, *sp)?
                    };
                }
                if ok {
                    self.sign_powers(&acc, *sp)?;
                }
                ok.then_some(acc)
            }
            Expr::Pow(base, exp, sp) => {
                let b = self.eval(base)?;
                let k = self.exponent(exp)?;
                let mut acc = Poly::constant(Coeff::constant(Rational::from_integer(1)));
                for _ in 0..k {
                    acc = self.mul(&acc, &b, *sp)?;
                }
                self.sign_powers(&acc, *sp)?;
                Some(acc)
            }
        }
    }

    fn ok(&mut self, r: Result<Poly, Overflow>, sp: Span) -> Option<Poly> {
        match r {
            Ok(p) => Some(p),
            Err(Overflow) => {
                overflow(self.sink, sp);
                None
            }
        }
    }

    /// `a * b` with the resource guards: degree, number of term pairs, number of terms.
    fn mul(&mut self, a: &Poly, b: &Poly, sp: Span) -> Option<Poly> {
        let deg = a.degree() + b.degree();
        let pdeg = coeff_degree(a) + coeff_degree(b);
        if deg > MAX_DEGREE || pdeg > MAX_DEGREE {
            self.sink.push(ModelDiagnostic::new(
                Code::TooLarge,
                sp,
                format!(
                    "this term has degree {} (above the limit of {MAX_DEGREE})",
                    deg.max(pdeg)
                ),
                "degree too high",
                "harmonid accepts polynomials up to this degree; lower the power",
            ));
            return None;
        }
        let work = size(a).saturating_mul(size(b));
        if work > MAX_PRODUCT_WORK {
            self.sink.push(ModelDiagnostic::new(
                Code::TooLarge,
                sp,
                format!(
                    "expanding this product multiplies {} by {} terms, more than the limit of {MAX_PRODUCT_WORK}",
                    size(a),
                    size(b)
                ),
                "too large to expand",
                "write the expanded terms you need, or use fewer modes in one product",
            ));
            return None;
        }
        let p = self.ok(a.checked_mul(b), sp)?;
        if p.len() > MAX_TERMS {
            too_many_terms(self.sink, sp);
            return None;
        }
        Some(p)
    }

    fn divisor(&mut self, p: &Poly, sp: Span) -> Option<Rational> {
        let c = p.as_constant().and_then(|c| c.as_constant());
        match c {
            Some(r) if *r.numer() == i128::MIN => {
                overflow(self.sink, sp);
                None
            }
            Some(r) if r != Rational::from_integer(0) => {
                Some(Rational::new(*r.denom(), *r.numer()))
            }
            Some(_) => {
                self.sink.push(ModelDiagnostic::new(
                    Code::NotPolynomial,
                    sp,
                    "division by zero",
                    "this is zero",
                    "divide only by nonzero numbers",
                ));
                None
            }
            None => {
                self.sink.push(ModelDiagnostic::new(
                    Code::NotPolynomial,
                    sp,
                    "division by an expression that contains modes or parameters is not polynomial",
                    "divides by a variable",
                    "divide only by numbers, as in `beta1/4*q1^4`; for a ratio of parameters introduce one parameter for it",
                ));
                None
            }
        }
    }

    fn exponent(&mut self, e: &Expr) -> Option<u32> {
        let p = self.eval(e)?;
        let sp = e.span();
        let r = match p.as_constant().and_then(|c| c.as_constant()) {
            Some(r) => r,
            None => {
                self.sink.push(ModelDiagnostic::new(
                    Code::NotPolynomial,
                    sp,
                    "an exponent must be a whole number, not an expression in modes or parameters",
                    "not a number",
                    "write powers with whole-number exponents, as in `q1^3`",
                ));
                return None;
            }
        };
        if !r.is_integer() {
            self.sink.push(ModelDiagnostic::new(
                Code::NotPolynomial,
                sp,
                format!(
                    "the exponent {} is not a whole number, so the term is not a polynomial",
                    self.sink.source.get(sp.start..sp.end).unwrap_or("")
                ),
                "fractional exponent",
                "use whole-number exponents 0, 1, 2, ... (`q1^2`, `q1^3`)",
            ));
            return None;
        }
        let k = *r.numer();
        if k < 0 {
            self.sink.push(ModelDiagnostic::new(
                Code::NotPolynomial,
                sp,
                format!("the exponent {k} is negative, so the term is not a polynomial"),
                "negative exponent",
                "use whole-number exponents 0, 1, 2, ...; terms like 1/q1 are not polynomial",
            ));
            return None;
        }
        if k > i128::from(MAX_DEGREE) {
            self.sink.push(ModelDiagnostic::new(
                Code::TooLarge,
                sp,
                format!("the exponent {k} is above the limit of {MAX_DEGREE}"),
                "exponent too large",
                "harmonid accepts polynomials up to this degree; lower the power",
            ));
            return None;
        }
        u32::try_from(k).ok()
    }

    fn name(&mut self, n: &Name) -> Option<Poly> {
        // A plain name that is an index variable in scope is its value.
        if n.indices.is_none() {
            if let Some((_, v)) = self.env.iter().rev().find(|(w, _)| *w == n.base) {
                return Some(Poly::constant(Coeff::constant(Rational::from_integer(
                    i128::from(*v),
                ))));
            }
        }
        if n.indices.is_none() && n.base == PUMP_NAME {
            return Some(Poly::var(VarId(2 * self.names.n_modes)));
        }
        let name = self.canonical(n)?;
        match self.names.table.get(&name) {
            Some((Sym::Mode(m), _)) => Some(Poly::var(VarId(*m))),
            Some((Sym::Param(p), _)) => Some(Poly::constant(Coeff::param(VarId(*p)))),
            None if has_index_var(n) => {
                if self.sink.is_new(Code::FamilyRange, n.span) {
                    let w = self.written(n, &name);
                    let declared = self.family_list(&n.base);
                    self.sink.push(ModelDiagnostic::new(
                        Code::FamilyRange,
                        n.span,
                        format!("the index family runs out of range: {w} is not declared"),
                        "out of range",
                        format!("declared with this stem: {declared}; shrink the family's range or declare `{name}`"),
                    ));
                } else {
                    self.sink
                        .push(ModelDiagnostic::new(Code::FamilyRange, n.span, "", "", ""));
                }
                None
            }
            None => {
                if self.sink.is_new(Code::UnknownName, n.span) {
                    let w = self.written(n, &name);
                    let help = match self.suggestion(&name) {
                        Some(s) => format!("did you mean `{s}`? Otherwise declare it with `param {name}` or `mode {name}`"),
                        None => format!("declare it with `param {name}` (a coefficient) or `mode {name}` (a mode)"),
                    };
                    self.sink.push(ModelDiagnostic::new(
                        Code::UnknownName,
                        n.span,
                        format!("unknown name {w}: it is neither a declared mode nor a parameter"),
                        "not declared",
                        help,
                    ));
                } else {
                    self.sink
                        .push(ModelDiagnostic::new(Code::UnknownName, n.span, "", "", ""));
                }
                None
            }
        }
    }
}

impl Eval<'_, '_, '_, '_> {
    /// `d(q1)`: the velocity of mode q1, the variable after every mode's.
    fn velocity(&mut self, args: &[Expr], sp: Span) -> Option<Poly> {
        let bad = |sink: &mut Sink<'_>, message: String, help: String| {
            sink.push(ModelDiagnostic::new(
                Code::BadVelocity,
                sp,
                message,
                "not the velocity of a mode",
                help,
            ));
            None
        };
        let [arg] = args else {
            return bad(
                self.sink,
                format!("`d(...)` takes one mode, here it has {}", args.len()),
                "write the velocity of each mode on its own: `d(q1)`".into(),
            );
        };
        match arg {
            Expr::Name(n) => {
                let p = self.name(n)?;
                let var = p
                    .terms()
                    .next()
                    .and_then(|(m, _)| m.factors().first().map(|&(v, _)| v));
                match var {
                    Some(v) if v.index() < self.names.n_modes as usize => {
                        Some(Poly::var(VarId(self.names.n_modes + v.0)))
                    }
                    _ => bad(
                        self.sink,
                        format!("`d(...)` takes a mode, and `{}` is not one", n.base),
                        "velocities are of modes: write `d(q1)` for a declared mode q1".into(),
                    ),
                }
            }
            Expr::Call(g, _, _) if g == "d" => bad(
                self.sink,
                "`d(d(...))` is an acceleration, and model terms hold positions and velocities only"
                    .into(),
                "an acceleration term changes the mass: rescale the mode instead, or write `d(q1)`"
                    .into(),
            ),
            _ => bad(
                self.sink,
                "`d(...)` takes one mode name".into(),
                "write the velocity of each mode on its own, as in `d(q1) + d(q2)`".into(),
            ),
        }
    }
}

/// Whether `p` holds a non-smooth factor (a variable after the pump's `2 n_modes`).
fn has_nonsmooth(p: &Poly, n_modes: usize) -> bool {
    p.terms()
        .any(|(m, _)| m.factors().iter().any(|&(v, _)| v.index() > 2 * n_modes))
}

/// Moves the terms with a non-smooth factor out of the polynomial equations: `(eom, nonsmooth)`.
fn split_nonsmooth_terms(eom: Vec<Poly>, n_modes: usize) -> (Vec<Poly>, Vec<Poly>) {
    let mut smooth = Vec::with_capacity(eom.len());
    let mut rough = Vec::with_capacity(eom.len());
    for eq in eom {
        if !has_nonsmooth(&eq, n_modes) {
            smooth.push(eq);
            rough.push(Poly::zero());
            continue;
        }
        let mut a = PolyBuilder::new();
        let mut b = PolyBuilder::new();
        for (m, c) in eq.terms() {
            let is_rough = m.factors().iter().any(|&(v, _)| v.index() > 2 * n_modes);
            if is_rough { &mut b } else { &mut a }.push(m.clone(), c.clone());
        }
        // Splitting a sorted polynomial into two keeps each sorted and free of repeats, so
        // finishing cannot overflow.
        smooth.push(a.finish().unwrap_or_else(|Overflow| Poly::zero()));
        rough.push(b.finish().unwrap_or_else(|Overflow| Poly::zero()));
    }
    (smooth, rough)
}

/// The value of a fixed parameter.
fn fixed_value(p: &Parameter) -> Option<f64> {
    match p.kind {
        ParamKind::Fixed(v) => Some(v),
        ParamKind::Unknown => None,
    }
}

/// Refuses a non-smooth factor in a potential or dissipation function `p` (returns whether it
/// did).
fn nonsmooth_in_potential(sink: &mut Sink<'_>, u: &Use<'_>, p: &Poly, n_modes: usize) -> bool {
    if matches!(u.target, Target::Eom(..)) || !has_nonsmooth(p, n_modes) {
        return false;
    }
    let span = u.expr.span();
    let (what, example) = if matches!(u.target, Target::Dissipation) {
        ("a dissipation function", "eom q1 += drag1*abs(d(q1))*d(q1)")
    } else {
        ("a potential", "eom q1 += kappa1*abs(q1)*q1")
    };
    sink.push(ModelDiagnostic::new(
        Code::BadNonSmooth,
        span,
        format!("{what} cannot hold `abs`, `sign` or `tanh`: harmonid differentiates it, and these functions have no polynomial derivative"),
        "non-smooth factor here",
        format!("write the force in the equation instead, as in `{example}`"),
    ));
    true
}

/// Whether `p` holds a velocity (a variable from `n_modes` on, before the pump's `2 n_modes`).
fn has_velocity(p: &Poly, n_modes: usize) -> bool {
    p.terms().any(|(m, _)| {
        m.factors()
            .iter()
            .any(|&(v, _)| (n_modes..2 * n_modes).contains(&v.index()))
    })
}

fn velocity_in_potential(sink: &mut Sink<'_>, span: Span) {
    sink.push(ModelDiagnostic::new(
        Code::VelocityInPotential,
        span,
        "a potential depends on the positions only, and this one holds a velocity `d(...)`",
        "velocity in a potential",
        "write velocity-dependent forces as `eom q1 += eta*q1^2*d(q1)`, or as a dissipation function: `dissipation: eta/4*q1^2*d(q1)^2`",
    ));
}

fn no_velocity_in_dissipation(sink: &mut Sink<'_>, span: Span) {
    sink.push(ModelDiagnostic::new(
        Code::BadVelocity,
        span,
        "a dissipation function gives each equation its derivative by a velocity, and this one holds no velocity `d(...)`",
        "no velocity",
        "write it in the velocities, as in `dissipation: eta/4*q1^2*d(q1)^2`; position-only terms belong in `potential:`",
    ));
}

fn has_index_var(n: &Name) -> bool {
    n.indices
        .as_ref()
        .is_some_and(|l| l.iter().any(|i| matches!(i, Index::Var { .. })))
}

fn size(p: &Poly) -> usize {
    p.terms().map(|(_, c)| c.len()).sum()
}

fn coeff_degree(p: &Poly) -> u32 {
    p.terms().map(|(_, c)| c.degree()).max().unwrap_or(0)
}

/// Levenshtein distance, for "did you mean" suggestions (short names only).
fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    if a.len().abs_diff(b.len()) > 2 || a.len() > 64 || b.len() > 64 {
        return usize::MAX;
    }
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    let mut cur = vec![0; b.len() + 1];
    for i in 1..=a.len() {
        cur[0] = i;
        for j in 1..=b.len() {
            let sub = prev[j - 1] + usize::from(a[i - 1] != b[j - 1]);
            cur[j] = sub.min(prev[j] + 1).min(cur[j - 1] + 1);
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    prev[b.len()]
}
