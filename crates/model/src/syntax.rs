//! Stage 1 and 2: the pest parser and the syntax tree built from its pairs.

use crate::ast::{
    EomStmt, Expr, Family, FamilyHead, File, Index, IndexRel, ModeDecl, Name, ParamDecl,
    PotentialStmt, Stmt,
};
use crate::error::{Code, ModelDiagnostic, Span};
use crate::MAX_NESTING;
use harmonid_poly::{parse_decimal, Rational, Ring};
use pest::iterators::Pair;
use pest::Parser as _;

#[derive(pest_derive::Parser)]
#[grammar = "../../grammar/model.pest"]
struct ModelParser;

/// Parses `source` into a syntax tree, or returns every syntax diagnostic.
pub(crate) fn parse(source: &str) -> Result<File, Vec<ModelDiagnostic>> {
    check_nesting(source)?;
    let mut pairs =
        ModelParser::parse(Rule::model, source).map_err(|e| vec![syntax_error(source, e)])?;
    let model = pairs.next().ok_or_else(|| {
        vec![ModelDiagnostic::new(
            Code::Syntax,
            Span::new(0, 0),
            "the parser returned nothing",
            "here",
            "this is a bug in harmonid; please report it with the file",
        )]
    })?;
    let mut b = Builder { errors: Vec::new() };
    let mut statements = Vec::new();
    for p in model.into_inner() {
        if p.as_rule() != Rule::EOI {
            b.statement(p, &mut statements);
        }
    }
    if b.errors.is_empty() {
        Ok(File { statements })
    } else {
        Err(b.errors)
    }
}

/// Refuses brackets nested deeper than [`MAX_NESTING`] before the recursive parser sees them, so
/// hostile input cannot exhaust the stack.
fn check_nesting(source: &str) -> Result<(), Vec<ModelDiagnostic>> {
    let mut depth = 0usize;
    let mut in_comment = false;
    for (i, c) in source.char_indices() {
        match c {
            '\n' => in_comment = false,
            '#' => in_comment = true,
            _ if in_comment => {}
            '(' | '[' | '{' => {
                depth += 1;
                if depth > MAX_NESTING {
                    return Err(vec![ModelDiagnostic::new(
                        Code::TooDeep,
                        Span::new(i, i + 1),
                        format!("brackets are nested more than {MAX_NESTING} deep"),
                        "too deep from here on",
                        "write the expression with fewer nested parentheses or blocks",
                    )]);
                }
            }
            ')' | ']' | '}' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    Ok(())
}

fn rule_words(r: &Rule) -> &'static str {
    match r {
        Rule::EOI => "end of file",
        Rule::model | Rule::family_block => {
            "a statement (mode, modes, param, eom, potential, dissipation, for)"
        }
        Rule::modes_decl | Rule::kw_modes => "`modes`",
        Rule::mode_decl | Rule::kw_mode => "`mode`",
        Rule::param_decl | Rule::kw_param => "`param`",
        Rule::eom_stmt | Rule::kw_eom => "`eom`",
        Rule::potential_stmt | Rule::kw_potential => "`potential`",
        Rule::dissipation_stmt | Rule::kw_dissipation => "`dissipation`",
        Rule::family | Rule::kw_for => "`for`",
        Rule::kw_in => "`in`",
        Rule::kw_at => "`at`",
        Rule::linear_setting | Rule::linear_key => "`f = ...` or `Q = ...`",
        Rule::frequency => "a frequency with its unit",
        Rule::unit => "a frequency unit (Hz, kHz, MHz or GHz)",
        Rule::param_item => "a parameter",
        Rule::lower_op | Rule::upper_op => "`<` or `<=`",
        Rule::lower_op_after => "`>` or `>=`",
        Rule::fix_op => "`=`",
        Rule::signed_number | Rule::number => "a number",
        Rule::integer => "a whole number",
        Rule::eom_op => "`+=` or `-=`",
        Rule::family_head => "index variables and a range (like `i<j in 1..5`)",
        Rule::index_rel => "`<`, `<=`, `!=` or `,` between index variables",
        Rule::range => "a range (like `1..5`)",
        Rule::index_var => "an index variable",
        Rule::name | Rule::ident => "a name",
        Rule::index => "an index",
        Rule::index_shift => "`+` or `-` and a number",
        Rule::expr | Rule::product | Rule::factor | Rule::power | Rule::atom | Rule::call => {
            "an expression"
        }
        Rule::exponent => "an exponent",
        Rule::add_op => "`+` or `-`",
        Rule::mul_op => "`*` or `/`",
        Rule::minus => "`-`",
        Rule::keyword => "a keyword",
        _ => "something else",
    }
}

fn syntax_error(source: &str, e: pest::error::Error<Rule>) -> ModelDiagnostic {
    let pos = match e.location {
        pest::error::InputLocation::Pos(p) => p,
        pest::error::InputLocation::Span((s, _)) => s,
    };
    let mut expected: Vec<&'static str> = match &e.variant {
        pest::error::ErrorVariant::ParsingError { positives, .. } => {
            positives.iter().map(rule_words).collect()
        }
        pest::error::ErrorVariant::CustomError { .. } => Vec::new(),
    };
    // Keep the first occurrence of each wording, in a stable order.
    let mut seen = std::collections::HashSet::new();
    expected.retain(|w| seen.insert(*w));
    // "end of file, `mode`, `modes`, `param`, ..." reads better as "a new statement".
    const STARTS: [&str; 8] = [
        "end of file",
        "`mode`",
        "`modes`",
        "`param`",
        "`eom`",
        "`potential`",
        "`dissipation`",
        "`for`",
    ];
    if expected.iter().filter(|w| STARTS.contains(w)).count() >= 3 {
        expected.retain(|w| !STARTS.contains(w));
        expected.push("a new statement");
    }
    let found = found_text(source, pos);
    let expected_text = match expected.as_slice() {
        [] => "something else".to_string(),
        [one] => (*one).to_string(),
        [init @ .., last] => format!("{} or {}", init.join(", "), last),
    };
    let end = pos + found.len().max(1).min(source.len().saturating_sub(pos));
    let found_words = if found.is_empty() {
        "the end of the file".to_string()
    } else if let Some(c) = found.chars().find(|c| !c.is_ascii()) {
        // Shown by code point: it may be invisible (a byte-order mark, a zero-width space, a
        // non-breaking space) or look like an ASCII character.
        if found.chars().count() == 1 {
            format!("the character U+{:04X}", c as u32)
        } else {
            format!("`{found}` (with the character U+{:04X})", c as u32)
        }
    } else {
        format!("`{found}`")
    };
    ModelDiagnostic::new(
        Code::Syntax,
        Span::new(pos, end.max(pos)),
        format!("expected {expected_text}, found {found_words}"),
        format!("expected {expected_text}"),
        syntax_help(&found, &expected),
    )
}

/// The token at `pos`, for "found ..." (a word, a number, or one character).
fn found_text(source: &str, pos: usize) -> String {
    let rest = source.get(pos..).unwrap_or("");
    let mut chars = rest.chars();
    let Some(first) = chars.next() else {
        return String::new();
    };
    if first.is_alphanumeric() || first == '_' || first == '.' {
        rest.chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == '.')
            .take(24)
            .collect()
    } else {
        first.to_string()
    }
}

fn syntax_help(found: &str, expected: &[&str]) -> String {
    if let Some(c) = found.chars().find(|c| !c.is_ascii()) {
        return format!(
            "the model language is ASCII: names are letters, digits and `_`; U+{:04X} is not one of them (retype the line, or save the file as plain text)",
            c as u32
        );
    }
    if found == "-" && expected.contains(&"a number") {
        return "this number must be positive (a frequency or a quality factor): write it without a sign, as in `at 207.58 kHz` or `Q = 1e5`; signed numbers are for parameter values and bounds (`param b = -2`, `param g >= -1`)".to_string();
    }
    if expected.contains(&"`*` or `/`")
        && found
            .chars()
            .next()
            .is_some_and(|c| c.is_alphabetic() || c == '(')
    {
        return "products need an explicit `*`, as in `beta1/4*q1^4`".to_string();
    }
    if expected.contains(&"a frequency unit (Hz, kHz, MHz or GHz)") {
        return "write the unit after the number, as in `207.58 kHz`".to_string();
    }
    const RESERVED: [&str; 10] = [
        "mode",
        "modes",
        "param",
        "params",
        "eom",
        "potential",
        "dissipation",
        "for",
        "in",
        "at",
    ];
    if RESERVED.contains(&found)
        && expected
            .iter()
            .any(|w| w.contains("name") || *w == "a parameter")
    {
        return format!("`{found}` is a reserved word of the model language; choose another name");
    }
    if found.is_empty() {
        return "the file ends in the middle of a statement; complete it or remove it".to_string();
    }
    "statements start with `mode`, `modes`, `param`, `eom`, `potential`, `dissipation` or `for`; see docs/model-language.md".to_string()
}

struct Builder {
    errors: Vec<ModelDiagnostic>,
}

/// The span of a pair without the trailing spaces and comments that pest's implicit
/// whitespace may have attached to it.
fn span(p: &Pair<'_, Rule>) -> Span {
    let s = Span::from_pest(p.as_span());
    let mut text = p.as_str();
    loop {
        text = text.trim_end();
        let line_start = text.rfind('\n').map_or(0, |i| i + 1);
        match text[line_start..].find('#') {
            Some(h) => text = &text[..line_start + h],
            None => break,
        }
    }
    Span::new(s.start, s.start + text.len())
}

impl Builder {
    fn statement(&mut self, p: Pair<'_, Rule>, out: &mut Vec<Stmt>) {
        match p.as_rule() {
            Rule::mode_decl => {
                if let Some(m) = self.mode_decl(p) {
                    out.push(Stmt::Mode(m));
                }
            }
            Rule::modes_decl => {
                for n in p.into_inner().filter(|q| q.as_rule() == Rule::name) {
                    if let Some(name) = self.name(n) {
                        out.push(Stmt::Mode(ModeDecl {
                            name,
                            nominal_hz: None,
                            f_hz: None,
                            q_factor: None,
                        }));
                    }
                }
            }
            Rule::param_decl => {
                for item in p.into_inner().filter(|q| q.as_rule() == Rule::param_item) {
                    if let Some(d) = self.param_item(item) {
                        out.push(Stmt::Param(d));
                    }
                }
            }
            Rule::eom_stmt => {
                let mut name = None;
                let mut negate = false;
                let mut expr = None;
                for q in p.into_inner() {
                    match q.as_rule() {
                        Rule::name => name = self.name(q),
                        Rule::eom_op => negate = q.as_str() == "-=",
                        Rule::expr => expr = self.expr(q),
                        _ => {}
                    }
                }
                if let (Some(mode), Some(expr)) = (name, expr) {
                    out.push(Stmt::Eom(EomStmt { mode, negate, expr }));
                }
            }
            Rule::potential_stmt | Rule::dissipation_stmt => {
                let dissipation = p.as_rule() == Rule::dissipation_stmt;
                if let Some(e) = p.into_inner().find(|q| q.as_rule() == Rule::expr) {
                    if let Some(expr) = self.expr(e) {
                        out.push(Stmt::Potential(PotentialStmt { expr, dissipation }));
                    }
                }
            }
            Rule::family => self.family(p, out),
            _ => {}
        }
    }

    fn family(&mut self, p: Pair<'_, Rule>, out: &mut Vec<Stmt>) {
        let mut heads = Vec::new();
        let mut body = Vec::new();
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::family_head => heads.push(self.family_head(q)),
                Rule::family_block => {
                    for s in q.into_inner() {
                        self.statement(s, &mut body);
                    }
                }
                Rule::kw_for => {}
                _ => self.statement(q, &mut body),
            }
        }
        // `for a: for b: s` is `for a { for b { s } }`.
        let mut stmts = body;
        for head in heads.into_iter().rev() {
            match head {
                Some(head) => stmts = vec![Stmt::Family(Family { head, body: stmts })],
                None => return,
            }
        }
        out.extend(stmts);
    }

    fn family_head(&mut self, p: Pair<'_, Rule>) -> Option<FamilyHead> {
        let sp = span(&p);
        let mut vars = Vec::new();
        let mut rels = Vec::new();
        let mut range = None;
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::index_var => vars.push((q.as_str().to_string(), span(&q))),
                Rule::index_rel => rels.push(match q.as_str() {
                    "<" => IndexRel::Lt,
                    "<=" => IndexRel::Le,
                    "!=" => IndexRel::Ne,
                    _ => IndexRel::Any,
                }),
                Rule::range => {
                    let rs = span(&q);
                    let ints: Vec<_> = q.into_inner().map(|i| self.integer(&i)).collect();
                    if let [Some(lo), Some(hi)] = ints.as_slice() {
                        range = Some((*lo, *hi, rs));
                    }
                }
                _ => {}
            }
        }
        let (lo, hi, range_span) = range?;
        Some(FamilyHead {
            vars,
            rels,
            lo,
            hi,
            range_span,
            span: sp,
        })
    }

    fn integer(&mut self, p: &Pair<'_, Rule>) -> Option<i64> {
        match p.as_str().parse::<i64>() {
            Ok(v) if v <= crate::MAX_INDEX => Some(v),
            _ => {
                self.errors.push(ModelDiagnostic::new(
                    Code::FamilyRange,
                    span(p),
                    format!("the index {} is too large", p.as_str()),
                    "too large",
                    format!("indices go up to {}", crate::MAX_INDEX),
                ));
                None
            }
        }
    }

    fn number(&mut self, p: &Pair<'_, Rule>) -> Option<Rational> {
        match parse_decimal(p.as_str()) {
            Some(r) => Some(r),
            None => {
                self.errors.push(ModelDiagnostic::new(
                    Code::BadNumber,
                    span(p),
                    format!("the number {} cannot be represented exactly", p.as_str()),
                    "too many digits or too large an exponent",
                    "numbers in expressions are exact rationals with 128-bit numerator and \
                     denominator; use fewer digits, or fold the scale into a parameter",
                ));
                None
            }
        }
    }

    /// A number that only needs a floating-point value (frequencies, Q, bounds, fixed values).
    fn float(&mut self, p: &Pair<'_, Rule>) -> Option<f64> {
        match p.as_str().parse::<f64>() {
            Ok(v) if v.is_finite() => Some(v),
            _ => {
                self.errors.push(ModelDiagnostic::new(
                    Code::BadNumber,
                    span(p),
                    format!("the number {} is out of range", p.as_str()),
                    "not a finite number",
                    "use a number between about 1e-300 and 1e300",
                ));
                None
            }
        }
    }

    fn signed(&mut self, p: Pair<'_, Rule>) -> Option<f64> {
        let mut neg = false;
        let mut v = None;
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::minus => neg = true,
                Rule::number => v = self.float(&q),
                _ => {}
            }
        }
        v.map(|x| if neg { -x } else { x })
    }

    fn frequency(&mut self, p: Pair<'_, Rule>) -> Option<(f64, Span)> {
        let sp = span(&p);
        let text = p.as_str().to_string();
        let mut value = None;
        let mut scale: i128 = 1;
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::number => {
                    // Exact where possible, so that `207.58 kHz` is exactly 207580 Hz.
                    value = match parse_decimal(q.as_str()) {
                        Some(r) => Some(Ok(r)),
                        None => Some(Err(self.float(&q)?)),
                    };
                }
                Rule::unit => {
                    scale = match q.as_str() {
                        "kHz" => 1_000,
                        "MHz" => 1_000_000,
                        "GHz" => 1_000_000_000,
                        _ => 1,
                    }
                }
                _ => {}
            }
        }
        let v = match value? {
            Ok(r) => match Ring::checked_mul(&r, &Rational::from_integer(scale)) {
                Ok(x) => harmonid_poly::rational_to_f64(&x),
                Err(_) => harmonid_poly::rational_to_f64(&r) * scale as f64,
            },
            Err(v) => v * scale as f64,
        };
        self.positive_frequency(v, sp, &text)
    }

    fn positive_frequency(&mut self, v: f64, sp: Span, text: &str) -> Option<(f64, Span)> {
        if v > 0.0 && v.is_finite() {
            Some((v, sp))
        } else {
            self.errors.push(ModelDiagnostic::new(
                Code::BadLinear,
                sp,
                format!("a resonance frequency must be positive, found {text}"),
                "not positive",
                "give the frequency in Hz, kHz, MHz or GHz, as in `207.58 kHz`",
            ));
            None
        }
    }

    fn mode_decl(&mut self, p: Pair<'_, Rule>) -> Option<ModeDecl> {
        let mut name = None;
        let mut nominal = None;
        let mut f_hz = None;
        let mut q_factor = None;
        let mut ok = true;
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::name => name = self.name(q),
                Rule::frequency => {
                    nominal = self.frequency(q);
                    ok &= nominal.is_some();
                }
                Rule::linear_setting => {
                    let sp = span(&q);
                    let mut inner = q.into_inner();
                    let key = inner
                        .next()
                        .map(|k| k.as_str().to_string())
                        .unwrap_or_default();
                    let Some(val) = inner.next() else { continue };
                    let is_freq = val.as_rule() == Rule::frequency;
                    let val_span = span(&val);
                    if key == "f" {
                        if !is_freq {
                            self.errors.push(ModelDiagnostic::new(
                                Code::BadLinear,
                                val_span,
                                "the resonance frequency `f` needs a unit",
                                "no unit",
                                "write it as in `f = 207.582 kHz` (Hz, kHz, MHz or GHz)",
                            ));
                            ok = false;
                            continue;
                        }
                        if f_hz.is_some() {
                            self.dup_setting(sp, "f");
                            ok = false;
                        }
                        f_hz = self.frequency(val);
                        ok &= f_hz.is_some();
                    } else {
                        if is_freq {
                            self.errors.push(ModelDiagnostic::new(
                                Code::BadLinear,
                                val_span,
                                "the quality factor `Q` is a plain number and takes no unit",
                                "unexpected unit",
                                "write it as in `Q = 1.2e5`",
                            ));
                            ok = false;
                            continue;
                        }
                        if q_factor.is_some() {
                            self.dup_setting(sp, "Q");
                            ok = false;
                        }
                        match self.float(&val) {
                            Some(v) if v > 0.0 => q_factor = Some((v, val_span)),
                            Some(_) => {
                                self.errors.push(ModelDiagnostic::new(
                                    Code::BadLinear,
                                    val_span,
                                    "a quality factor must be positive",
                                    "not positive",
                                    "Q = f / (full width at half maximum) is a positive number",
                                ));
                                ok = false;
                            }
                            None => ok = false,
                        }
                    }
                }
                _ => {}
            }
        }
        let name = name?;
        ok.then_some(ModeDecl {
            name,
            nominal_hz: nominal,
            f_hz,
            q_factor,
        })
    }

    fn dup_setting(&mut self, sp: Span, key: &str) {
        self.errors.push(ModelDiagnostic::new(
            Code::Duplicate,
            sp,
            format!("`{key}` is given twice for this mode"),
            "second value",
            "give each of `f` and `Q` at most once",
        ));
    }

    fn param_item(&mut self, p: Pair<'_, Rule>) -> Option<ParamDecl> {
        let sp = span(&p);
        let mut name = None;
        let mut value = None;
        let mut lower = None;
        let mut upper = None;
        let mut pending_before: Option<f64> = None;
        let mut op_after: Option<Rule> = None;
        let mut ok = true;
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::signed_number => {
                    let v = self.signed(q);
                    ok &= v.is_some();
                    if name.is_none() {
                        pending_before = v;
                    } else if let Some(v) = v {
                        match op_after {
                            Some(Rule::fix_op) => value = Some(v),
                            Some(Rule::upper_op) => upper = Some(v),
                            Some(Rule::lower_op_after) => lower = Some(v),
                            _ => {}
                        }
                    }
                }
                Rule::lower_op if name.is_none() => lower = pending_before,
                Rule::upper_op | Rule::lower_op_after | Rule::fix_op => {
                    op_after = Some(q.as_rule())
                }
                Rule::name => name = self.name(q),
                _ => {}
            }
        }
        let name = name?;
        if value.is_some() && lower.is_some() {
            self.errors.push(ModelDiagnostic::new(
                Code::BadBound,
                sp,
                format!(
                    "parameter {} has both a fixed value and a bound",
                    p_name(&name)
                ),
                "value and bound",
                "a fixed parameter needs no bound: keep either `= value` or the bounds",
            ));
            ok = false;
        }
        if let (Some(lo), Some(hi)) = (lower, upper) {
            if lo > hi {
                self.errors.push(ModelDiagnostic::new(
                    Code::BadBound,
                    sp,
                    format!("the bounds of {} are empty: {lo} > {hi}", p_name(&name)),
                    "empty interval",
                    "write the lower bound first, as in `0 <= g12 <= 1e24`",
                ));
                ok = false;
            }
        }
        ok.then_some(ParamDecl {
            name,
            value,
            lower,
            upper,
            span: sp,
        })
    }

    fn name(&mut self, p: Pair<'_, Rule>) -> Option<Name> {
        let sp = span(&p);
        let mut base = String::new();
        let mut indices: Option<Vec<Index>> = None;
        let mut ok = true;
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::ident => base = q.as_str().to_string(),
                Rule::index => {
                    let isp = span(&q);
                    let mut var = None;
                    let mut lit = None;
                    let mut shift = 0i64;
                    for r in q.into_inner() {
                        match r.as_rule() {
                            Rule::integer => {
                                lit = self.integer(&r);
                                ok &= lit.is_some();
                            }
                            Rule::index_var => var = Some(r.as_str().to_string()),
                            Rule::index_shift => {
                                let neg = r.as_str().trim_start().starts_with('-');
                                if let Some(i) = r.into_inner().next() {
                                    match self.integer(&i) {
                                        Some(v) => shift = if neg { -v } else { v },
                                        None => ok = false,
                                    }
                                }
                            }
                            _ => {}
                        }
                    }
                    let idx = match (var, lit) {
                        (Some(name), _) => Index::Var {
                            name,
                            shift,
                            span: isp,
                        },
                        (None, Some(v)) => Index::Lit(v),
                        (None, None) => continue,
                    };
                    indices.get_or_insert_with(Vec::new).push(idx);
                }
                _ => {}
            }
        }
        ok.then_some(Name {
            base,
            indices,
            span: sp,
        })
    }

    fn expr(&mut self, p: Pair<'_, Rule>) -> Option<Expr> {
        let sp = span(&p);
        let mut terms = Vec::new();
        let mut negate_next = false;
        let mut ok = true;
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::add_op => negate_next = q.as_str() == "-",
                Rule::product => match self.product(q) {
                    Some(e) => terms.push((negate_next, e)),
                    None => ok = false,
                },
                _ => {}
            }
        }
        if !ok {
            return None;
        }
        if terms.len() == 1 && !terms[0].0 {
            return terms.pop().map(|(_, e)| e);
        }
        Some(Expr::Sum(terms, sp))
    }

    fn product(&mut self, p: Pair<'_, Rule>) -> Option<Expr> {
        let sp = span(&p);
        let mut factors = Vec::new();
        let mut divide_next = false;
        let mut ok = true;
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::mul_op => divide_next = q.as_str() == "/",
                Rule::factor => match self.factor(q) {
                    Some(e) => factors.push((divide_next, e)),
                    None => ok = false,
                },
                _ => {}
            }
        }
        if !ok {
            return None;
        }
        if factors.len() == 1 {
            return factors.pop().map(|(_, e)| e);
        }
        Some(Expr::Product(factors, sp))
    }

    fn factor(&mut self, p: Pair<'_, Rule>) -> Option<Expr> {
        let sp = span(&p);
        let mut minuses = 0usize;
        let mut inner = None;
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::minus => minuses += 1,
                Rule::power => inner = Some(self.power(q)?),
                _ => {}
            }
        }
        let e = inner?;
        Some(if minuses % 2 == 1 {
            Expr::Neg(Box::new(e), sp)
        } else {
            e
        })
    }

    fn power(&mut self, p: Pair<'_, Rule>) -> Option<Expr> {
        let sp = span(&p);
        let mut base = None;
        let mut exponent = None;
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::atom => base = Some(self.atom(q)?),
                Rule::exponent => exponent = Some(self.exponent(q)?),
                _ => {}
            }
        }
        let base = base?;
        Some(match exponent {
            Some(e) => Expr::Pow(Box::new(base), Box::new(e), sp),
            None => base,
        })
    }

    fn exponent(&mut self, p: Pair<'_, Rule>) -> Option<Expr> {
        let sp = span(&p);
        let mut neg = false;
        let mut e = None;
        for q in p.into_inner() {
            match q.as_rule() {
                Rule::minus => neg = true,
                Rule::number => e = Some(Expr::Num(self.number(&q)?, span(&q))),
                Rule::expr => e = Some(self.expr(q)?),
                Rule::name => e = Some(Expr::Name(self.name(q)?)),
                _ => {}
            }
        }
        let e = e?;
        Some(if neg { Expr::Neg(Box::new(e), sp) } else { e })
    }

    fn atom(&mut self, p: Pair<'_, Rule>) -> Option<Expr> {
        let q = p.into_inner().next()?;
        match q.as_rule() {
            Rule::number => Some(Expr::Num(self.number(&q)?, span(&q))),
            Rule::name => Some(Expr::Name(self.name(q)?)),
            Rule::expr => self.expr(q),
            Rule::call => {
                let sp = span(&q);
                let mut inner = q.into_inner();
                let fname = inner
                    .next()
                    .map(|i| i.as_str().to_string())
                    .unwrap_or_default();
                let mut args = Vec::new();
                for a in inner {
                    args.push(self.expr(a)?);
                }
                Some(Expr::Call(fname, args, sp))
            }
            _ => None,
        }
    }
}

fn p_name(n: &Name) -> String {
    match &n.indices {
        None => n.base.clone(),
        Some(_) => format!("{}[...]", n.base),
    }
}
