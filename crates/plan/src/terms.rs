//! Which modes a model's parameters touch: the one question about the model's terms that
//! the range (which guesses a drive can move), the evaluation (its findings) and the design
//! (which modes to drive) all ask, answered here below all three.

use harmonid_model::Model;
use std::collections::BTreeSet;

/// The modes the terms of parameter `p` involve (their monomials and equations).
pub(crate) fn param_modes(model: &Model, p: usize) -> BTreeSet<usize> {
    let mut out = BTreeSet::new();
    for (n, eq) in model.eom.iter().enumerate() {
        for (m, c) in eq.terms() {
            if c.variables().iter().any(|v| v.index() == p) {
                out.insert(n);
                // A velocity `d(q)` involves its mode; the pump none.
                let nm = model.modes.len();
                out.extend(
                    m.factors()
                        .iter()
                        .filter(|(v, _)| v.index() < 2 * nm)
                        .map(|(v, _)| v.index() % nm),
                );
            }
        }
    }
    out
}
