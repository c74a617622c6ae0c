//! The syntax tree of a model file. Every node carries its [`Span`] in the source.

use crate::error::Span;
use harmonid_poly::Rational;

/// A whole file.
#[derive(Debug, Clone)]
pub(crate) struct File {
    pub statements: Vec<Stmt>,
}

/// One statement.
#[derive(Debug, Clone)]
pub(crate) enum Stmt {
    Mode(ModeDecl),
    Param(ParamDecl),
    Eom(EomStmt),
    Potential(PotentialStmt),
    Family(Family),
}

/// `mode q1 at 207.58 kHz, Q = 1e4` (also each name of `modes q1, q2`).
#[derive(Debug, Clone)]
pub(crate) struct ModeDecl {
    pub name: Name,
    pub nominal_hz: Option<(f64, Span)>,
    pub f_hz: Option<(f64, Span)>,
    pub q_factor: Option<(f64, Span)>,
}

/// One declared parameter with its value or bounds.
#[derive(Debug, Clone)]
pub(crate) struct ParamDecl {
    pub name: Name,
    pub value: Option<f64>,
    pub lower: Option<f64>,
    pub upper: Option<f64>,
    pub span: Span,
}

/// `eom q1 += expr` (`negate` for `-=`).
#[derive(Debug, Clone)]
pub(crate) struct EomStmt {
    pub mode: Name,
    pub negate: bool,
    pub expr: Expr,
}

/// `potential: expr`, or `dissipation: expr` (a dissipation function of the velocities).
#[derive(Debug, Clone)]
pub(crate) struct PotentialStmt {
    pub expr: Expr,
    pub dissipation: bool,
}

/// `for i<j in 1..5 { ... }`.
#[derive(Debug, Clone)]
pub(crate) struct Family {
    pub head: FamilyHead,
    pub body: Vec<Stmt>,
}

/// Relation between consecutive index variables of a family head.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum IndexRel {
    Lt,
    Le,
    Ne,
    Any,
}

/// `i<j in 1..5`.
#[derive(Debug, Clone)]
pub(crate) struct FamilyHead {
    pub vars: Vec<(String, Span)>,
    pub rels: Vec<IndexRel>,
    pub lo: i64,
    pub hi: i64,
    pub range_span: Span,
    pub span: Span,
}

/// A name, plain (`beta1`) or indexed (`g[i,j]`).
#[derive(Debug, Clone)]
pub(crate) struct Name {
    pub base: String,
    pub indices: Option<Vec<Index>>,
    pub span: Span,
}

/// An index inside brackets.
#[derive(Debug, Clone)]
pub(crate) enum Index {
    Lit(i64),
    Var {
        name: String,
        shift: i64,
        span: Span,
    },
}

/// A polynomial expression (before checking that it is one).
#[derive(Debug, Clone)]
pub(crate) enum Expr {
    Num(Rational, Span),
    Name(Name),
    /// `f(args)`: `d(q1)` is a velocity; other functions are refused.
    Call(String, Vec<Expr>, Span),
    Neg(Box<Expr>, Span),
    /// `a + b - c`: terms with a flag "subtracted" (n-ary, so long sums do not nest).
    Sum(Vec<(bool, Expr)>, Span),
    /// `a * b / c`: factors with a flag "divided by" (n-ary).
    Product(Vec<(bool, Expr)>, Span),
    Pow(Box<Expr>, Box<Expr>, Span),
}

impl Expr {
    pub fn span(&self) -> Span {
        match self {
            Expr::Num(_, s)
            | Expr::Call(_, _, s)
            | Expr::Neg(_, s)
            | Expr::Sum(_, s)
            | Expr::Product(_, s)
            | Expr::Pow(_, _, s) => *s,
            Expr::Name(n) => n.span,
        }
    }
}
