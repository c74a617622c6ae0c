//! `abs(x)`, `sign(x)`, `tanh(x/c)` in terms: the argument checked (one mode or one velocity,
//! a positive scale) and the factor turned into its variable (see `crate::nonsmooth`).

use super::{Eval, Sink};
use crate::ast::Expr;
use crate::error::{Code, ModelDiagnostic, Span};
use crate::nonsmooth::NonSmooth;
use harmonid_poly::{rational_to_f64, Poly, Rational, VarId};

/// The non-smooth functions a term may hold.
pub(super) const NONSMOOTH_FUNCTIONS: [&str; 3] = ["abs", "sign", "tanh"];

fn bad<T>(sink: &mut Sink<'_>, sp: Span, message: String, label: &str, help: String) -> Option<T> {
    sink.push(ModelDiagnostic::new(
        Code::BadNonSmooth,
        sp,
        message,
        label,
        help,
    ));
    None
}

impl Eval<'_, '_, '_, '_> {
    /// `abs(x)`, `sign(x)` or `tanh(x/c)`: the variable that stands for the factor.
    pub(super) fn nonsmooth(&mut self, f: &str, args: &[Expr], sp: Span) -> Option<Poly> {
        let [arg] = args else {
            return bad(
                self.sink,
                sp,
                format!("`{f}(...)` takes one argument, here it has {}", args.len()),
                "one argument",
                format!(
                    "write `{f}` of one mode or one velocity, as in {}",
                    example(f)
                ),
            );
        };
        let (x, scale) = match (f, arg) {
            ("tanh", Expr::Product(parts, _)) => match parts.as_slice() {
                [(false, x), (true, c)] => (x, Some(self.tanh_scale(c)?)),
                _ => {
                    return bad(
                        self.sink,
                        arg.span(),
                        "`tanh(...)` takes one mode or one velocity divided by a positive scale"
                            .into(),
                        "not `x / c`",
                        "write it as `tanh(d(q1)/1e-3)`: the velocity (or mode) divided by a number or a fixed parameter; coefficients go outside: `mu1*tanh(d(q1)/v0)`".into(),
                    )
                }
            },
            ("tanh", x) => {
                // The argument's own faults first (a sum, a parameter), then the scale.
                self.nonsmooth_var_of(f, x)?;
                return self.no_scale(x);
            }
            _ => (arg, None),
        };
        let var = self.nonsmooth_var_of(f, x)?;
        let factor = match f {
            "abs" => NonSmooth::Abs(var),
            "sign" => NonSmooth::Sign(var),
            _ => NonSmooth::Tanh(var, scale.unwrap_or(1.0)),
        };
        let mut list = self.names.factors.borrow_mut();
        let k = match list.iter().position(|g| same(g, &factor)) {
            Some(k) => k,
            None => {
                list.push(factor);
                list.len() - 1
            }
        };
        Some(Poly::var(VarId(2 * self.names.n_modes + 1 + k as u32)))
    }

    /// The mode or velocity a non-smooth function is applied to.
    fn nonsmooth_var_of(&mut self, f: &str, x: &Expr) -> Option<VarId> {
        let sp = x.span();
        let outside = format!(
            "write `{f}` of one mode or one velocity, as in {}",
            example(f)
        );
        let p = match x {
            Expr::Name(_) | Expr::Call(..) if is_call_not_d(x) => {
                return bad(
                    self.sink,
                    sp,
                    format!("`{f}(...)` of another function: functions do not nest in model terms"),
                    "nested function",
                    outside,
                );
            }
            Expr::Name(_) | Expr::Call(..) => self.eval(x)?,
            Expr::Sum(..) => {
                return bad(
                    self.sink,
                    sp,
                    format!("`{f}(...)` of a sum: harmonid takes {f} of one mode or one velocity"),
                    "a sum",
                    format!(
                        "{outside}; a relative motion such as `{f}(q1 - q2)` is not supported yet"
                    ),
                );
            }
            Expr::Neg(..) => {
                return bad(
                    self.sink,
                    sp,
                    format!("`{f}(...)` of a negated mode or velocity"),
                    "minus sign inside",
                    format!(
                        "write the sign outside the function: {}",
                        example(f).replacen('`', "`-", 1)
                    ),
                );
            }
            _ => {
                return bad(
                    self.sink,
                    sp,
                    format!(
                        "`{f}(...)` takes one mode or one velocity, not a product, power or number"
                    ),
                    "not one mode or velocity",
                    format!(
                        "{outside}; coefficients and other factors go outside: `kappa1*abs(q1)*q1`"
                    ),
                );
            }
        };
        let nm = self.names.n_modes as usize;
        let single = match p.terms().collect::<Vec<_>>().as_slice() {
            [(m, c)]
                if c.as_constant()
                    .is_some_and(|r| r == Rational::from_integer(1)) =>
            {
                match m.factors() {
                    [(v, 1)] if v.index() < 2 * nm => Some(*v),
                    _ => None,
                }
            }
            _ => None,
        };
        match single {
            Some(v) => Some(v),
            None => bad(
                self.sink,
                sp,
                format!("`{f}(...)` of a parameter, a number or the pump: harmonid takes {f} of one mode or one velocity"),
                "not a mode or velocity",
                format!("{outside}; a parameter is a coefficient outside the function: `kappa1*abs(q1)*q1`"),
            ),
        }
    }

    /// Refuses `tanh(x)` without a scale: tanh takes a pure number, and a mode is in metres
    /// (a velocity in m/s), so the scale would be 1 m, where tanh is linear at any amplitude a
    /// resonator reaches: almost surely `tanh(x/x0)` was meant.
    fn no_scale<T>(&mut self, x: &Expr) -> Option<T> {
        let sp = x.span();
        let written = self
            .sink
            .source
            .get(sp.start..sp.end)
            .unwrap_or("q1")
            .to_string();
        let velocity = matches!(x, Expr::Call(g, _, _) if g == "d");
        let (unit, c) = if velocity {
            ("m/s", "1e-3")
        } else {
            ("m", "1e-9")
        };
        bad(
            self.sink,
            sp,
            format!("`tanh({written})` has no scale: tanh takes a pure number, and `{written}` is in {unit}"),
            "no scale",
            format!("write `tanh({written}/{c})`, the scale in {unit} where tanh bends, or a fixed parameter (`param c0 = {c}` and `tanh({written}/c0)`); without one the scale is 1 {unit}, where tanh is linear at any amplitude a resonator reaches. A coordinate that is a pure number in this model takes `tanh({written}/1)`"),
        )
    }

    /// Refuses a power of `sign` above the first in a product or power `p` (written at `sp`;
    /// checked on the whole, so `sign(x)^3` is named as itself): `sign(x)²`
    /// is 1 wherever `x ≠ 0`, so the term is a constant force (or the smooth term without its
    /// sign), almost surely written by mistake; `sign(x)³` is `sign(x)`.
    pub(super) fn sign_powers(&mut self, p: &Poly, sp: Span) -> Option<()> {
        let base = 2 * self.names.n_modes as usize + 1;
        let found = {
            let list = self.names.factors.borrow();
            p.terms().find_map(|(m, _)| {
                m.factors().iter().find_map(|&(v, e)| {
                    let factor = *list.get(v.index().checked_sub(base)?)?;
                    (e >= 2 && matches!(factor, NonSmooth::Sign(_))).then_some((factor, e))
                })
            })
        };
        let Some((factor, e)) = found else {
            return Some(());
        };
        let vars = self.variable_names();
        let name = factor.name(&vars);
        let x = vars.get(factor.var().index()).map_or("x", String::as_str);
        if e % 2 == 0 {
            bad(
                self.sink,
                sp,
                format!("`{name}^{e}` is 1 wherever `{x}` is not zero: the term is its other factors alone (a constant force if there are none), almost surely not what was meant"),
                "an even power of sign",
                format!("keep one factor for a force that changes sign with `{x}` (Coulomb friction: `mu1*sign(d(q1))`); for a magnitude write abs (`kappa1*abs(q1)*q1`); a constant force is a static load, not a term of the model"),
            )
        } else {
            bad(
                self.sink,
                sp,
                format!("`{name}^{e}` is `{name}`"),
                "an odd power of sign",
                format!("write `{name}` once"),
            )
        }
    }

    /// The variables' names as the model writes them: modes (`q1`), then velocities (`d(q1)`).
    fn variable_names(&self) -> Vec<String> {
        let nm = self.names.n_modes as usize;
        let mut out = vec![String::new(); 2 * nm];
        for (name, (sym, _)) in self.names.table {
            if let super::Sym::Mode(i) = *sym {
                let i = i as usize;
                if i < nm {
                    out[nm + i] = format!("d({name})");
                    out[i] = name.clone();
                }
            }
        }
        out
    }

    /// The scale `c` of `tanh(x/c)`: a positive number or a fixed parameter.
    fn tanh_scale(&mut self, c: &Expr) -> Option<f64> {
        let sp = c.span();
        let p = self.eval(c)?;
        let coeff = if p.is_zero() {
            Some(0.0)
        } else {
            p.as_constant().and_then(|k| {
                let vars = k.variables();
                let values: Option<Vec<f64>> = (0..self.names.fixed.len())
                    .map(|i| match self.names.fixed[i] {
                        Some(v) => Some(v),
                        None if vars.iter().any(|v| v.index() == i) => None,
                        None => Some(0.0),
                    })
                    .collect();
                match k.as_constant() {
                    Some(r) => Some(rational_to_f64(&r)),
                    None => values.map(|v| k.eval(&v)),
                }
            })
        };
        match coeff {
            Some(v) if v > 0.0 && v.is_finite() => Some(v),
            Some(0.0) => bad(
                self.sink,
                sp,
                "`tanh(x/0)`: the scale of tanh must be positive".into(),
                "zero scale",
                "tanh(x/c) tends to sign(x) as c goes to 0: write `sign(d(q1))` for Coulomb friction, or a small positive c as in `tanh(d(q1)/1e-6)`".into(),
            ),
            Some(_) => bad(
                self.sink,
                sp,
                "the scale of tanh must be a positive number".into(),
                "not positive",
                "write the sign outside the function: `-mu1*tanh(d(q1)/1e-3)`".into(),
            ),
            None => bad(
                self.sink,
                sp,
                "the scale of tanh must be a number or a fixed parameter, not a mode or an unknown parameter".into(),
                "not a known number",
                "give a number (`tanh(d(q1)/1e-3)`) or fix the parameter (`param v0 = 1e-3`); an unknown scale does not enter linearly and cannot be identified".into(),
            ),
        }
    }
}

/// A call that is not the velocity `d(...)`.
fn is_call_not_d(x: &Expr) -> bool {
    matches!(x, Expr::Call(g, _, _) if g != "d")
}

/// Two factors are the same variable: same function, same argument, same scale.
fn same(a: &NonSmooth, b: &NonSmooth) -> bool {
    match (a, b) {
        (NonSmooth::Tanh(u, c), NonSmooth::Tanh(v, d)) => u == v && c.to_bits() == d.to_bits(),
        _ => a == b,
    }
}

fn example(f: &str) -> &'static str {
    match f {
        "abs" => "`kappa1*abs(q1)*q1`",
        "sign" => "`mu1*sign(d(q1))`",
        _ => "`mu1*tanh(d(q1)/1e-3)`",
    }
}
