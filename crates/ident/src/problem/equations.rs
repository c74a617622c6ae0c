//! The model's equations of motion as affine coefficients of monomials.

use super::{IdentError, Problem, Unknown};
use harmonid_model::{Model, ParamKind};
use harmonid_poly::{rational_to_f64, PowerProduct};

/// One term of an equation: monomial, constant part of its coefficient, parameter factors.
#[derive(Debug, Clone)]
pub(super) struct Term {
    pub(super) monomial: usize,
    pub(super) konst: f64,
    pub(super) params: Vec<(usize, f64)>,
}

impl Problem {
    /// The modes an unknown involves (for visibility), or `None` for force unknowns.
    pub(super) fn unknown_modes(&self, u: &Unknown) -> Vec<Vec<usize>> {
        match u {
            Unknown::OmegaSq(n) | Unknown::Gamma(n) => vec![vec![*n]],
            Unknown::Param(p) => {
                let mut out = Vec::new();
                for (n, terms) in self.eqs.iter().enumerate() {
                    for t in terms {
                        if t.params.iter().any(|(q, _)| q == p) {
                            // A velocity involves its mode; the pump (after every velocity)
                            // none.
                            let nm = self.mode_names.len();
                            let mut s: Vec<usize> = match &self.ns[t.monomial] {
                                Some(ns) => self.nonsmooth_modes(ns),
                                None => self.monomials[t.monomial]
                                    .factors()
                                    .iter()
                                    .filter(|(v, _)| v.index() < 2 * nm)
                                    .map(|(v, _)| v.index() % nm)
                                    .collect(),
                            };
                            s.push(n);
                            s.sort_unstable();
                            s.dedup();
                            out.push(s);
                        }
                    }
                }
                out
            }
            Unknown::Force { .. } | Unknown::Gain { .. } | Unknown::Background { .. } => Vec::new(),
        }
    }

    /// values `theta[p]`: `(monomial, b)`.
    pub fn eom_coefficients(&self, n: usize, theta: &[f64]) -> Vec<(PowerProduct, f64)> {
        self.eqs[n]
            .iter()
            .map(|t| {
                let b = t.konst + t.params.iter().map(|&(p, f)| f * theta[p]).sum::<f64>();
                (self.monomials[t.monomial].clone(), b)
            })
            .collect()
    }
}

/// The monomials of every equation and each equation's terms, with fixed parameters folded into
/// the constant part; errors when a coefficient is not affine or a polynomial term has degree
/// < 2. The terms with a non-smooth factor (`Model::nonsmooth`) come after the polynomial ones
/// of their equation; their monomials hold the factors' variables.
pub(super) fn build_equations(
    model: &Model,
    mode_names: &[String],
) -> Result<(Vec<PowerProduct>, Vec<Vec<Term>>), IdentError> {
    let nm = model.modes.len();
    let mut monomials: Vec<PowerProduct> = Vec::new();
    let mut eqs = Vec::with_capacity(nm);
    for (n, eq) in model.eom.iter().enumerate() {
        let mut terms = Vec::new();
        let ns = model.nonsmooth.get(n).into_iter().flat_map(|p| p.terms());
        for (m, c) in eq.terms().chain(ns) {
            let smooth = m.factors().iter().all(|(v, _)| v.index() <= 2 * nm);
            let Some(aff) = c.affine() else {
                return Err(IdentError::Unsupported(format!(
                    "the coefficient of {} in the equation of {} is not affine in the parameters",
                    model.monomial_name(m),
                    mode_names[n]
                )));
            };
            if smooth && m.degree() < 2 {
                return Err(IdentError::Unsupported(format!(
                    "the equation of {} has a term {} of degree {} < 2; linear and constant terms beyond ω² are not supported by the identification",
                    mode_names[n],
                    model.monomial_name(m),
                    m.degree()
                )));
            }
            let idx = match monomials.iter().position(|x| x == m) {
                Some(i) => i,
                None => {
                    monomials.push(m.clone());
                    monomials.len() - 1
                }
            };
            let mut konst = rational_to_f64(&aff.constant);
            let mut params = Vec::new();
            for (p, f) in aff.terms {
                let f = rational_to_f64(&f);
                match model.params[p.index()].kind {
                    ParamKind::Fixed(v) => konst += f * v,
                    ParamKind::Unknown => params.push((p.index(), f)),
                }
            }
            terms.push(Term {
                monomial: idx,
                konst,
                params,
            });
        }
        eqs.push(terms);
    }
    Ok((monomials, eqs))
}

#[cfg(test)]
mod tests {
    use super::super::testkit;
    use super::super::{IdentError, Problem, Settings};
    use super::build_equations;

    #[test]
    fn terms_are_affine_in_the_parameters() {
        let m = testkit::model();
        let names: Vec<String> = m.modes.iter().map(|x| x.name.clone()).collect();
        let (monos, eqs) = build_equations(&m, &names).expect("equations");
        // a: beta a^3 + g a b^2; b: g a^2 b.
        assert_eq!(eqs[0].len(), 2);
        assert_eq!(eqs[1].len(), 1);
        assert_eq!(monos.len(), 3);
        for t in eqs.iter().flatten() {
            assert_eq!(t.konst, 0.0);
            assert_eq!(t.params.len(), 1);
            assert!((t.params[0].1 - 1.0).abs() < 1e-15);
        }
        let ds = testkit::dataset(true, 1, 0.0, 1);
        let p = Problem::new(&m, &ds, &Settings::default()).expect("problem");
        let c = p.eom_coefficients(1, &[2.0, 5.0]);
        assert_eq!(c.len(), 1);
        assert_eq!(c[0].0.name(&names), "a^2*b");
        assert_eq!(c[0].1, 5.0);
        assert_eq!(
            p.unknown_modes(&super::Unknown::Param(1)),
            vec![vec![0, 1], vec![0, 1]]
        );
    }

    #[test]
    fn fixed_parameters_fold_into_the_constant() {
        let src = testkit::MODEL.replace("param beta, g", "param g\nparam beta = 2");
        let m = harmonid_model::parse_str(&src, "t.hb").expect("model");
        let names: Vec<String> = m.modes.iter().map(|x| x.name.clone()).collect();
        let (_, eqs) = build_equations(&m, &names).expect("equations");
        assert!(eqs[0].iter().any(|t| t.konst == 2.0 && t.params.is_empty()));
    }

    #[test]
    fn a_linear_coupling_is_unsupported() {
        let src = format!("{}potential: k*a*b\nparam k\n", testkit::MODEL);
        let m = harmonid_model::parse_str(&src, "t.hb").expect("model");
        let names: Vec<String> = m.modes.iter().map(|x| x.name.clone()).collect();
        let err = build_equations(&m, &names).expect_err("refused");
        assert!(
            matches!(&err, IdentError::Unsupported(s) if s.contains("degree 1")),
            "{err}"
        );
    }
}
