//! Polynomials in the modal coordinates whose coefficients are polynomials in the parameters.

use crate::{rational_latex, Coeff, PowerProduct, Rational, SparsePoly};
use num_traits::{One, Signed};

/// A polynomial in the modal coordinates (variables are mode indices in declaration order) with
/// [`Coeff`] coefficients: the nonlinear part of an equation of motion, or a potential.
pub type Poly = SparsePoly<Coeff>;

impl SparsePoly<Coeff> {
    /// Evaluates every coefficient with parameter values `values[p]`, keeping the term order.
    pub fn eval_coefficients(&self, values: &[f64]) -> Vec<(PowerProduct, f64)> {
        self.terms()
            .map(|(m, c)| (m.clone(), c.eval(values)))
            .collect()
    }

    /// The terms whose coefficient is not affine in the parameters (e.g. `g^2*q1^4`).
    pub fn non_affine_terms(&self) -> Vec<&PowerProduct> {
        self.terms()
            .filter(|(_, c)| c.affine().is_none())
            .map(|(m, _)| m)
            .collect()
    }

    /// Readable form, `beta1 q1^3 + g12 q1 q2^2 - 3/4 k q1^2`, with coefficient sums in
    /// parentheses: `(a + b) q1 q2`.
    pub fn to_string_with(
        &self,
        mode_names: &[impl AsRef<str>],
        param_names: &[impl AsRef<str>],
    ) -> String {
        self.format(
            |c| c.to_string_with(param_names),
            |m| m.join(mode_names, " ", |k| format!("^{k}")),
            |r| r.to_string(),
        )
    }

    /// LaTeX form; names are given already in LaTeX (`q_1`, `\beta_1`).
    pub fn to_latex_with(
        &self,
        mode_names: &[impl AsRef<str>],
        param_names: &[impl AsRef<str>],
    ) -> String {
        self.format(
            |c| c.to_latex_with(param_names),
            |m| m.join(mode_names, " ", |k| format!("^{{{k}}}")),
            rational_latex,
        )
    }

    fn format(
        &self,
        coeff: impl Fn(&Coeff) -> String,
        mono: impl Fn(&PowerProduct) -> String,
        number: impl Fn(&Rational) -> String,
    ) -> String {
        if self.is_zero() {
            return "0".to_string();
        }
        let mut out = String::new();
        for (i, (m, c)) in self.terms().enumerate() {
            // A single-term coefficient carries its own sign; factor it out for `a - b` style.
            let (neg, body) = match c.terms().collect::<Vec<_>>().as_slice() {
                [(pm, r)] => {
                    let mag = r.abs();
                    let body = if pm.is_one() {
                        number(&mag)
                    } else if mag.is_one() {
                        coeff(&Coeff::term((*pm).clone(), Rational::one()))
                    } else {
                        coeff(&Coeff::term((*pm).clone(), mag))
                    };
                    (r.is_negative(), body)
                }
                _ => (false, format!("({})", coeff(c))),
            };
            if i == 0 {
                if neg {
                    out.push('-');
                }
            } else {
                out.push_str(if neg { " - " } else { " + " });
            }
            let is_unit = body == "1";
            if m.is_one() {
                out.push_str(&body);
            } else {
                if !is_unit {
                    out.push_str(&body);
                    out.push(' ');
                }
                out.push_str(&mono(m));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Overflow, VarId};
    use proptest::prelude::*;

    fn q(i: u32) -> Poly {
        Poly::var(VarId(i))
    }
    fn par(i: u32) -> Poly {
        Poly::constant(Coeff::param(VarId(i)))
    }
    fn rat(n: i128, d: i128) -> Poly {
        Poly::constant(Coeff::constant(Rational::new(n, d)))
    }

    #[test]
    fn dispersive_potential_gives_unit_factors() -> Result<(), Overflow> {
        // U = beta1/4 q1^4 + g12/2 q1^2 q2^2
        let u = par(0)
            .checked_mul(&rat(1, 4))?
            .checked_mul(&q(0).checked_pow(4)?)?
            .checked_add(
                &par(1)
                    .checked_mul(&rat(1, 2))?
                    .checked_mul(&q(0).checked_pow(2)?)?
                    .checked_mul(&q(1).checked_pow(2)?)?,
            )?;
        let modes = ["q1", "q2"];
        let params = ["beta1", "g12"];
        assert_eq!(
            u.derivative(VarId(0))?.to_string_with(&modes, &params),
            "beta1 q1^3 + g12 q1 q2^2"
        );
        assert_eq!(
            u.derivative(VarId(1))?.to_string_with(&modes, &params),
            "g12 q1^2 q2"
        );
        Ok(())
    }

    #[test]
    fn readable_and_latex_forms() -> Result<(), Overflow> {
        let p = par(0)
            .checked_add(&par(1))?
            .checked_mul(&q(0))?
            .checked_mul(&q(1))?
            .checked_sub(
                &rat(3, 4)
                    .checked_mul(&par(0))?
                    .checked_mul(&q(0).checked_pow(2)?)?,
            )?;
        assert_eq!(
            p.to_string_with(&["q1", "q2"], &["a", "b"]),
            "-3/4*a q1^2 + (a + b) q1 q2"
        );
        assert_eq!(
            p.to_latex_with(&["q_1", "q_2"], &["a", "b"]),
            "-\\frac{3}{4} a q_1^{2} + (a + b) q_1 q_2"
        );
        assert_eq!(
            rat(-1, 2)
                .checked_mul(&q(1))?
                .to_string_with(&["q1", "q2"], &["a"]),
            "-1/2 q2"
        );
        Ok(())
    }

    fn arb_poly() -> impl Strategy<Value = Poly> {
        // Up to 6 terms over 3 modes and 2 parameters, small exponents and rationals.
        prop::collection::vec(
            (
                prop::collection::vec(0u32..3, 3),
                prop::collection::vec(0u32..2, 2),
                -5i128..=5,
                1i128..=4,
            ),
            0..6,
        )
        .prop_map(|terms| {
            let mut p = Poly::zero();
            for (mexp, pexp, n, d) in terms {
                let c = Coeff::term(PowerProduct::from_exponents(&pexp), Rational::new(n, d));
                p.add_term(PowerProduct::from_exponents(&mexp), c)
                    .expect("small");
            }
            p
        })
    }

    proptest! {
        #[test]
        fn derivative_is_linear(a in arb_poly(), b in arb_poly(), v in 0u32..3) {
            let v = VarId(v);
            let lhs = a.checked_add(&b)?.derivative(v)?;
            let rhs = a.derivative(v)?.checked_add(&b.derivative(v)?)?;
            prop_assert_eq!(lhs, rhs);
            let two = Rational::from_integer(2);
            prop_assert_eq!(a.checked_scale_rational(&two)?.derivative(v)?, a.derivative(v)?.checked_scale_rational(&two)?);
        }

        #[test]
        fn product_rule(a in arb_poly(), b in arb_poly(), v in 0u32..3) {
            let v = VarId(v);
            let lhs = a.checked_mul(&b)?.derivative(v)?;
            let rhs = a.derivative(v)?.checked_mul(&b)?.checked_add(&a.checked_mul(&b.derivative(v)?)?)?;
            prop_assert_eq!(lhs, rhs);
        }

        #[test]
        fn expansion_is_canonical(a in arb_poly(), b in arb_poly(), c in arb_poly()) {
            // (a + b) c and c b + a c are the same polynomial, built in different orders:
            // they must compare equal and print identically.
            let lhs = a.checked_add(&b)?.checked_mul(&c)?;
            let rhs = c.checked_mul(&b)?.checked_add(&a.checked_mul(&c)?)?;
            let names = ["q1", "q2", "q3"];
            let pnames = ["a", "b"];
            prop_assert_eq!(lhs.to_string_with(&names, &pnames), rhs.to_string_with(&names, &pnames));
            prop_assert_eq!(lhs, rhs);
        }

        #[test]
        fn builder_equals_incremental_sum(a in arb_poly(), b in arb_poly(), seed in 0u64..1000) {
            // Pushing the terms of a and b in a scrambled order and finishing once gives a + b.
            let mut terms: Vec<(PowerProduct, Coeff)> = a.terms().chain(b.terms())
                .map(|(m, c)| (m.clone(), c.clone())).collect();
            let n = terms.len().max(1);
            for i in 0..terms.len() {
                terms.swap(i, (seed as usize).wrapping_mul(i + 7) % n);
            }
            let mut builder = crate::PolyBuilder::new();
            for (m, c) in terms {
                builder.push(m, c);
            }
            let built = builder.finish()?;
            prop_assert_eq!(&built, &a.checked_add(&b)?);
            let mut incremental = a.clone();
            for (m, c) in b.terms() {
                incremental.add_term(m.clone(), c.clone())?;
            }
            prop_assert_eq!(built, incremental);
        }

        #[test]
        fn evaluation_is_a_ring_homomorphism(a in arb_poly(), b in arb_poly(), x in prop::collection::vec(-2.0f64..2.0, 2)) {
            // Evaluating coefficients commutes with addition.
            let sum: f64 = a.checked_add(&b)?.eval_coefficients(&x).iter().map(|(_, c)| c).sum();
            let parts: f64 = a.eval_coefficients(&x).iter().chain(b.eval_coefficients(&x).iter()).map(|(_, c)| c).sum();
            prop_assert!((sum - parts).abs() <= 1e-9 * (1.0 + parts.abs()));
        }
    }
}
