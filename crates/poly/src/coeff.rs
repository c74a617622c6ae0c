//! Coefficients of equation terms: polynomials in the model's parameters.

use crate::{rational_latex, rational_to_f64, PowerProduct, Rational, SparsePoly, VarId};
use num_traits::{One, Signed, Zero};

/// A coefficient `b` of an equation term: a polynomial in the parameters with rational
/// coefficients, such as `g12`, `3/4*beta1 + 1/2` or `g^2`. Variables are parameter indices.
pub type Coeff = SparsePoly<Rational>;

/// A coefficient that is affine in the parameters: `constant + Σ factor_p · p`.
///
/// This is the form identification needs: each equation term contributes `factor_p` times its
/// regressor to the column of parameter `p`, and `constant` times it to the right-hand side.
#[derive(Debug, Clone, PartialEq)]
pub struct AffineForm {
    /// The parameter-free part.
    pub constant: Rational,
    /// `(parameter, factor)` pairs, sorted by parameter, factors nonzero.
    pub terms: Vec<(VarId, Rational)>,
}

impl SparsePoly<Rational> {
    /// The coefficient consisting of one parameter, `p`.
    pub fn param(p: VarId) -> Self {
        Self::var(p)
    }

    /// The coefficient as an affine form, or `None` if some term has degree ≥ 2 in the
    /// parameters (e.g. `g^2` or `a*b`), which linear least squares cannot identify.
    pub fn affine(&self) -> Option<AffineForm> {
        let mut constant = Rational::zero();
        let mut terms = Vec::new();
        for (m, c) in self.terms() {
            match m.factors() {
                [] => constant = *c,
                [(p, 1)] => terms.push((*p, *c)),
                _ => return None,
            }
        }
        Some(AffineForm { constant, terms })
    }

    /// Evaluates the coefficient with parameter values `values[p]`.
    ///
    /// Parameters beyond `values.len()` count as NaN, so a missing value cannot pass silently.
    pub fn eval(&self, values: &[f64]) -> f64 {
        self.terms()
            .map(|(m, c)| {
                let mut x = rational_to_f64(c);
                for &(p, k) in m.factors() {
                    let v = values.get(p.index()).copied().unwrap_or(f64::NAN);
                    x *= v.powi(k as i32);
                }
                x
            })
            .sum()
    }

    /// Readable form with parameter names: `g12`, `3/4*beta1 + 1/2`, `-g^2`, `0`.
    pub fn to_string_with(&self, names: &[impl AsRef<str>]) -> String {
        self.format(names, "*", |k| format!("^{k}"), |r| r.to_string())
    }

    /// LaTeX form with parameter names given in LaTeX: `\frac{3}{4}\beta_1`.
    pub fn to_latex_with(&self, names: &[impl AsRef<str>]) -> String {
        self.format(names, " ", |k| format!("^{{{k}}}"), rational_latex)
    }

    fn format(
        &self,
        names: &[impl AsRef<str>],
        sep: &str,
        power: impl Fn(u32) -> String + Copy,
        number: impl Fn(&Rational) -> String,
    ) -> String {
        if self.is_zero() {
            return "0".to_string();
        }
        let mut out = String::new();
        // Print parameter-free constants last, as physicists write `g + 1/2`.
        let mut ordered: Vec<(&PowerProduct, &Rational)> = self.terms().collect();
        ordered.sort_by_key(|(m, _)| m.is_one());
        for (i, (m, c)) in ordered.into_iter().enumerate() {
            let neg = c.is_negative();
            let mag = c.abs();
            if i == 0 {
                if neg {
                    out.push('-');
                }
            } else {
                out.push_str(if neg { " - " } else { " + " });
            }
            if m.is_one() {
                out.push_str(&number(&mag));
            } else {
                if !mag.is_one() {
                    out.push_str(&number(&mag));
                    out.push_str(sep);
                }
                out.push_str(&m.join(names, sep, power));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Ring;

    fn p(i: u32) -> Coeff {
        Coeff::param(VarId(i))
    }

    #[test]
    fn affine_extraction() {
        let c = p(0)
            .checked_scale_rational(&Rational::new(3, 4))
            .and_then(|a| a.checked_add(&Coeff::constant(Rational::new(1, 2))))
            .expect("small numbers");
        let a = c.affine().expect("affine");
        assert_eq!(a.constant, Rational::new(1, 2));
        assert_eq!(a.terms, vec![(VarId(0), Rational::new(3, 4))]);
        assert_eq!(c.to_string_with(&["beta1"]), "3/4*beta1 + 1/2");
        let sq = p(0).checked_mul(&p(0)).expect("small");
        assert!(sq.affine().is_none());
        assert_eq!(sq.to_string_with(&["g"]), "g^2");
        assert_eq!(
            sq.checked_neg().expect("small").to_string_with(&["g"]),
            "-g^2"
        );
    }

    #[test]
    fn evaluation() {
        let c = p(0)
            .checked_mul(&p(1))
            .and_then(|a| a.checked_add(&Coeff::constant(Rational::new(1, 4))))
            .expect("small");
        assert_eq!(c.eval(&[2.0, 3.0]), 6.25);
        assert!(c.eval(&[2.0]).is_nan());
        assert_eq!(<Coeff as Ring>::one().to_latex_with(&["a"]), "1");
        let l = p(0)
            .checked_scale_rational(&Rational::new(-3, 4))
            .expect("small");
        assert_eq!(l.to_latex_with(&["\\beta_1"]), "-\\frac{3}{4} \\beta_1");
    }
}
