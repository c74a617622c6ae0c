//! Which modes a model's parameters touch: the one question about the model's terms that
//! the range (which guesses a drive can move), the evaluation (its findings) and the design
//! (which modes to drive) all ask, answered here below all three.

use harmonid_model::Model;
use std::collections::BTreeSet;

/// The modes the terms of parameter `p` involve (their monomials and equations).
pub(crate) fn param_modes(model: &Model, p: usize) -> BTreeSet<usize> {
    let mut out = BTreeSet::new();
    let nm = model.modes.len();
    // Polynomial and non-smooth terms alike; a non-smooth factor (`abs(q1)`) involves the
    // variable it is applied to.
    for (n, m, c) in model.all_terms() {
        if c.variables().iter().any(|v| v.index() == p) {
            out.insert(n);
            let (poly, nonsmooth) = model.split_nonsmooth(m);
            let vars = poly.factors().iter().map(|&(v, _)| v).chain(
                nonsmooth
                    .iter()
                    .filter_map(|&(k, _)| model.nonsmooth_factors.get(k).map(|f| f.var())),
            );
            // A velocity `d(q)` involves its mode; the pump none.
            out.extend(vars.filter(|v| v.index() < 2 * nm).map(|v| v.index() % nm));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::param_modes;

    #[test]
    fn a_parameter_of_non_smooth_terms_involves_the_modes_they_act_on() {
        let model = harmonid_model::parse_str(
            "mode q1, f = 1 kHz, Q = 1000\nmode q2, f = 2 kHz, Q = 1000\nparam kappa, drag, g\neom q1 += kappa*abs(q1)*q1 + g*abs(d(q2))*q1\neom q2 += drag*abs(d(q2))*d(q2)\n",
            "t.hb",
        )
        .expect("parses");
        let p = |name: &str| {
            model
                .params
                .iter()
                .position(|x| x.name == name)
                .expect("param")
        };
        let modes = |name: &str| param_modes(&model, p(name)).into_iter().collect::<Vec<_>>();
        assert_eq!(modes("kappa"), [0]);
        assert_eq!(modes("drag"), [1]);
        assert_eq!(modes("g"), [0, 1], "abs(d(q2)) involves q2");
    }
}
