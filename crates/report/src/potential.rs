//! The potential matrix (the method's Fig. 5c): for every pair of modes, the nonlinear potential
//! `U_nl(q_i, q_j)` with the other coordinates at rest, as 2-D maps; the diagonal shows
//! `U_nl(q_i)`. Lower triangle: the identified model; upper triangle: the truth when known.
//!
//! `U_nl` is the work of the nonlinear forces along the straight path from the origin,
//! `U_nl(q) = Σ_terms b · m(q) · q_n / (deg m + 1)` for a term `b·m(q)` in the equation of
//! `q_n`: exact for forces derived from a potential (`∂U/∂q_n`), J/kg per m² of modal mass.
//! Velocity terms (`d(q)`: damping) are left out: they store no energy.

use harmonid_plot::{PotentialCell, PotentialMatrix};
use harmonid_sim::NumericModel;

/// `U_nl(q)` of `model` (see the module docs).
pub fn u_nl(model: &NumericModel, q: &[f64]) -> f64 {
    model
        .terms()
        .iter()
        .filter(|t| is_conservative(model, t))
        .map(|t| {
            let m: f64 = t
                .factors
                .iter()
                .map(|&(i, k)| q[i].powi(k as i32))
                .product();
            t.coef * m * q[t.eq] / f64::from(t.degree() + 1)
        })
        .sum()
}

/// Whether some position-only term couples two different modes.
pub fn has_couplings(model: &NumericModel) -> bool {
    model
        .terms()
        .iter()
        .filter(|t| is_conservative(model, t))
        .any(|t| t.factors.iter().any(|&(i, _)| i != t.eq) || t.factors.len() > 1)
}

/// A term of the positions alone (no velocity factor).
fn is_conservative(model: &NumericModel, t: &harmonid_sim::Term) -> bool {
    t.factors.iter().all(|&(i, _)| i < model.n_modes())
}

fn cell(model: &NumericModel, i: usize, j: usize, q_max: &[f64], g: usize) -> PotentialCell {
    let nm = model.n_modes();
    let grid = |a: f64, k: usize| -a + 2.0 * a * k as f64 / (g - 1) as f64;
    if i == j {
        let q: Vec<f64> = (0..g).map(|k| grid(q_max[i], k)).collect();
        let u = q
            .iter()
            .map(|&x| {
                let mut v = vec![0.0; nm];
                v[i] = x;
                u_nl(model, &v)
            })
            .collect();
        return PotentialCell::Curve { q, u };
    }
    // Row coordinate q_i (vertical), column coordinate q_j (horizontal).
    let mut values = Vec::with_capacity(g * g);
    let mut v = vec![0.0; nm];
    for r in 0..g {
        for c in 0..g {
            v[i] = grid(q_max[i], r);
            v[j] = grid(q_max[j], c);
            values.push(u_nl(model, &v));
        }
    }
    PotentialCell::Map {
        n: g,
        x: (-q_max[j], q_max[j]),
        y: (-q_max[i], q_max[i]),
        values,
    }
}

/// The matrix for `identified` (lower triangle and diagonal) and `truth` (upper triangle),
/// each coordinate over `±q_max[n]` (m).
pub fn matrix(
    identified: &NumericModel,
    truth: Option<&NumericModel>,
    q_max: &[f64],
) -> PotentialMatrix {
    let n = identified.n_modes();
    let g = if n <= 3 { 31 } else { 21 };
    let cells = (0..n)
        .map(|i| {
            (0..n)
                .map(|j| {
                    if i >= j {
                        cell(identified, i, j, q_max, g)
                    } else if let Some(t) = truth {
                        cell(t, i, j, q_max, g)
                    } else {
                        PotentialCell::Empty
                    }
                })
                .collect()
        })
        .collect();
    let q_text: Vec<String> = identified
        .mode_names
        .iter()
        .zip(q_max)
        .map(|(m, a)| format!("|{m}| ≤ {}", harmonid_plot::style::num(*a, 2)))
        .collect();
    PotentialMatrix {
        title: "nonlinear potential U_nl (J/kg)".into(),
        modes: identified.mode_names.clone(),
        cells,
        note: format!(
            "lower: identified{} · colour scale per pair (viridis) · {} m",
            if truth.is_some() {
                " · upper: truth"
            } else {
                ""
            },
            q_text.join(", ")
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harmonid_sim::{ModeValues, ModelValues};

    #[test]
    fn u_nl_integrates_a_potential() {
        // U = β/4 q1⁴ + γ/2 q1² q2²  →  forces β q1³ + γ q1 q2² and γ q1² q2.
        let names = vec!["q1".to_string(), "q2".to_string()];
        let mut v = ModelValues::default();
        for n in &names {
            v.modes.insert(
                n.clone(),
                ModeValues {
                    f_hz: Some(1.0),
                    q: Some(10.0),
                },
            );
        }
        v.eom.insert(
            "q1".into(),
            [("q1^3".into(), 2.0), ("q1*q2^2".into(), 3.0)].into(),
        );
        v.eom.insert("q2".into(), [("q1^2*q2".into(), 3.0)].into());
        let m = NumericModel::from_values(&names, &v).expect("model");
        let (a, b) = (0.7f64, -1.3f64);
        let exact = 2.0 / 4.0 * a.powi(4) + 3.0 / 2.0 * a * a * b * b;
        assert!((u_nl(&m, &[a, b]) - exact).abs() < 1e-12);
        assert!(has_couplings(&m));
    }
}
