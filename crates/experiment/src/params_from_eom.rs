//! Parameter values from equation coefficients: a `truth.toml`, or a result of a model written
//! per equation, gives `[eom.q1] "q1^3" = 2.68e22` but no `[parameters]`. `simulate` can run on
//! those coefficients directly; planning and scoring need the parameters themselves (its unknowns
//! are the parameters). Every coefficient is affine in the parameters,
//! `b_m^(n) = c_0 + Σ_p a_p p`, so the given coefficients are a linear system in the missing
//! parameters, solved here by least squares with the columns equilibrated (coefficients span
//! 1e18–1e24) and its rank checked.

use crate::ExperimentError;
use harmonid_model::{Model, ParamKind};
use harmonid_poly::{rational_to_f64, Rational};
use harmonid_sim::{parse_monomial, ModelValues};
use nalgebra::{DMatrix, DVector};
use std::collections::BTreeMap;

/// An eigenvalue of the equilibrated normal matrix below this fraction of the largest (a
/// singular value below 1e-6 of the largest) leaves parameters determined only in combination.
const RANK_TOL: f64 = 1e-12;

/// What [`parameters_from_eom`] derived.
#[derive(Debug, Clone, PartialEq)]
pub struct DerivedParameters {
    /// The values with the derived parameters in `parameters` (everything else as given).
    pub values: ModelValues,
    /// The parameters derived, in the model's order, with their values.
    pub derived: Vec<(String, f64)>,
    /// How many given coefficients the least squares used.
    pub coefficients: usize,
    /// The given coefficient the model's form reproduces worst, `[eom.MODE] "MONOMIAL"`, and its
    /// misfit relative to the largest coefficient of its equation (about 1e-16 when the
    /// coefficients come from this model; larger when the device is not of the model's form).
    pub worst: Option<(String, f64)>,
}

/// Fills the model's unknown parameters that `values` does not give from its `[eom]`
/// coefficients. Returns `None` when nothing is missing or no `[eom]` is given (the caller's own
/// "no value given" error then names what is missing).
///
/// Errors: a coefficient not affine in the parameters, a parameter that no given coefficient
/// involves, or parameters the coefficients determine only in combination (the linear map from
/// parameters to coefficients is not invertible); each names the parameters.
pub fn parameters_from_eom(
    model: &Model,
    values: &ModelValues,
    origin: &str,
) -> Result<Option<DerivedParameters>, ExperimentError> {
    let err = |message: String| ExperimentError::Values {
        origin: origin.to_string(),
        message,
    };
    let missing: Vec<usize> = model
        .params
        .iter()
        .enumerate()
        .filter(|(_, p)| {
            matches!(p.kind, ParamKind::Unknown) && !values.parameters.contains_key(&p.name)
        })
        .map(|(i, _)| i)
        .collect();
    if missing.is_empty() || values.eom.is_empty() {
        return Ok(None);
    }
    let rows = coefficient_rows(model, values, &missing).map_err(err)?;
    let a = DMatrix::from_fn(rows.len(), missing.len(), |i, j| rows[i].a[j]);
    let rhs = DVector::from_fn(rows.len(), |i, _| rows[i].rhs);
    let name = |col: usize| model.params[missing[col]].name.clone();
    // Equilibrate: each column to unit norm; a column of zeros is a parameter nothing involves.
    let norms: Vec<f64> = (0..missing.len()).map(|j| a.column(j).norm()).collect();
    let unseen: Vec<String> = (0..missing.len())
        .filter(|&j| norms[j] == 0.0)
        .map(name)
        .collect();
    if !unseen.is_empty() {
        return Err(err(format!(
            "no value for {}: not in [parameters], and none of the given [eom] coefficients involves {}",
            unseen.join(", "),
            if unseen.len() == 1 { "it" } else { "them" }
        )));
    }
    let scaled = DMatrix::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)] / norms[j]);
    let tied: Vec<String> = tied_columns(&scaled).into_iter().map(name).collect();
    if !tied.is_empty() {
        return Err(err(format!(
            "the given [eom] coefficients determine {} only in combination (the model's map from parameters to coefficients is not invertible); give them in [parameters]",
            tied.join(", ")
        )));
    }
    let y = scaled
        .svd(true, true)
        .solve(&rhs, 0.0)
        .map_err(|e| err(format!("least squares failed: {e}")))?;
    let x: Vec<f64> = (0..missing.len()).map(|j| y[j] / norms[j]).collect();
    let fitted = &a * DVector::from_column_slice(&x);
    let worst = rows
        .iter()
        .zip(fitted.iter())
        .map(|(r, f)| {
            (
                r.label.clone(),
                (f - r.rhs).abs() / r.scale.max(f64::MIN_POSITIVE),
            )
        })
        .max_by(|a, b| a.1.total_cmp(&b.1));
    let mut out = values.clone();
    let mut derived = Vec::new();
    for (col, &v) in x.iter().enumerate() {
        if !v.is_finite() {
            return Err(err(format!(
                "{} = {v} from the [eom] coefficients",
                name(col)
            )));
        }
        out.parameters.insert(name(col), v);
        derived.push((name(col), v));
    }
    Ok(Some(DerivedParameters {
        values: out,
        derived,
        coefficients: rows.len(),
        worst,
    }))
}

/// One given coefficient as a linear equation in the missing parameters:
/// `Σ_j a[j]·p_j = rhs`, with `rhs` the given value less the known part of the coefficient.
struct Row {
    /// `[eom.MODE] "MONOMIAL"`, for the misfit's message.
    label: String,
    /// Factors of the missing parameters, in the order of `missing`.
    a: Vec<f64>,
    /// Given value less the constant and the known parameters' part.
    rhs: f64,
    /// The largest given coefficient of its equation, the misfit's unit.
    scale: f64,
}

/// The rows of every term of each equation `values.eom` gives (a model term it omits counts as
/// given zero, a given term the model lacks as a row of zeros); a message for a coefficient that
/// is not affine in the parameters or a monomial that does not read.
fn coefficient_rows(
    model: &Model,
    values: &ModelValues,
    missing: &[usize],
) -> Result<Vec<Row>, String> {
    let known: Vec<f64> = model
        .params
        .iter()
        .map(|p| match p.kind {
            ParamKind::Fixed(v) => v,
            ParamKind::Unknown => values.parameters.get(&p.name).copied().unwrap_or(0.0),
        })
        .collect();
    let col_of: BTreeMap<usize, usize> = missing.iter().enumerate().map(|(c, &p)| (p, c)).collect();
    let names: Vec<String> = model.modes.iter().map(|m| m.name.clone()).collect();
    let mut rows = Vec::new();
    for (n, eq) in model.eom.iter().enumerate() {
        let Some(given) = values.eom.get(&names[n]) else {
            continue;
        };
        let mut given_by_factors = BTreeMap::new();
        for (mono, &b) in given {
            let mut f = parse_monomial(mono, &names)
                .map_err(|e| format!("[eom.{}] \"{mono}\": {e}", names[n]))?;
            f.sort_unstable();
            given_by_factors.insert(f, (mono.clone(), b));
        }
        let scale = given.values().fold(0.0f64, |s, b| s.max(b.abs()));
        let mut seen = Vec::new();
        for (m, c) in eq.terms() {
            let mut f: Vec<(usize, u32)> =
                m.factors().iter().map(|&(v, k)| (v.index(), k)).collect();
            f.sort_unstable();
            let label = model.monomial_name(m);
            let form = c.affine().ok_or_else(|| {
                format!(
                    "the coefficient of {label} in the equation of {} is not linear in the parameters; give [parameters] instead of [eom.{}]",
                    names[n], names[n]
                )
            })?;
            let (label, b) = match given_by_factors.get(&f) {
                Some((mono, b)) => (mono.clone(), *b),
                None => (label, 0.0),
            };
            seen.push(f);
            let mut a = vec![0.0; missing.len()];
            let mut rhs = b - to_f64(&form.constant);
            for (p, factor) in &form.terms {
                let factor = to_f64(factor);
                match col_of.get(&p.index()) {
                    Some(&col) => a[col] += factor,
                    None => rhs -= factor * known[p.index()],
                }
            }
            let label = format!("[eom.{}] \"{label}\"", names[n]);
            rows.push(Row {
                label,
                a,
                rhs,
                scale,
            });
        }
        // Given terms the model's equation does not have: the model reproduces them as zero.
        for (f, (mono, b)) in &given_by_factors {
            if !seen.contains(f) {
                rows.push(Row {
                    label: format!("[eom.{}] \"{mono}\"", names[n]),
                    a: vec![0.0; missing.len()],
                    rhs: *b,
                    scale,
                });
            }
        }
    }
    Ok(rows)
}

/// The columns of `scaled` (unit columns) in the null space of the system: the eigenvectors of
/// its normal matrix with eigenvalues below [`RANK_TOL`] of the largest (a thin SVD of a wide
/// system has no row for them).
fn tied_columns(scaled: &DMatrix<f64>) -> Vec<usize> {
    let gram = scaled.tr_mul(scaled).symmetric_eigen();
    let lmax = gram.eigenvalues.max();
    let mut tied = Vec::new();
    for (k, &l) in gram.eigenvalues.iter().enumerate() {
        if l <= RANK_TOL * lmax {
            for j in 0..scaled.ncols() {
                if gram.eigenvectors[(j, k)].abs() > 1e-6 && !tied.contains(&j) {
                    tied.push(j);
                }
            }
        }
    }
    tied.sort_unstable();
    tied
}

fn to_f64(r: &Rational) -> f64 {
    rational_to_f64(r)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(src: &str) -> Model {
        harmonid_model::parse_str(src, "test.hb").expect("model")
    }

    const TWO_MODE: &str =
        "mode q1 at 207.58 kHz\nmode q2 at 415.84 kHz\nparam beta1, beta2, g12\n\
        potential: beta1/4*q1^4 + beta2/4*q2^4\npotential: g12/2*q1^2*q2^2\n";

    fn eom(entries: &[(&str, &[(&str, f64)])]) -> ModelValues {
        let mut v = ModelValues::default();
        for (mode, terms) in entries {
            v.eom.insert(
                mode.to_string(),
                terms.iter().map(|(m, b)| (m.to_string(), *b)).collect(),
            );
        }
        v
    }

    #[test]
    fn a_truth_file_gives_the_parameters_of_a_potential_model() {
        let m = model(TWO_MODE);
        let v = eom(&[
            ("q1", &[("q1^3", 2.68e22), ("q1*q2^2", 8.57e22)]),
            ("q2", &[("q2^3", 3.7e23), ("q1^2*q2", 8.57e22)]),
        ]);
        let d = parameters_from_eom(&m, &v, "truth.toml")
            .expect("ok")
            .expect("derived");
        let p = &d.values.parameters;
        for (name, want) in [("beta1", 2.68e22), ("beta2", 3.7e23), ("g12", 8.57e22)] {
            let got = p[name];
            assert!((got / want - 1.0).abs() < 1e-12, "{name}: {got} vs {want}");
        }
        assert_eq!(d.coefficients, 4);
        let (_, worst) = d.worst.expect("worst");
        assert!(worst < 1e-14, "{worst}");
    }

    #[test]
    fn coefficients_of_another_form_are_fitted_and_their_misfit_named() {
        // A device whose two dispersive coefficients differ (not a potential): g12 is their
        // least-squares compromise and the misfit is reported.
        let m = model(TWO_MODE);
        let v = eom(&[
            ("q1", &[("q1^3", 2.68e22), ("q1*q2^2", 8.0e22)]),
            (
                "q2",
                &[("q2^3", 3.7e23), ("q1^2*q2", 9.0e22), ("q1^2", 1e10)],
            ),
        ]);
        let d = parameters_from_eom(&m, &v, "truth.toml")
            .expect("ok")
            .expect("derived");
        assert!((d.values.parameters["g12"] / 8.5e22 - 1.0).abs() < 1e-12);
        let (label, worst) = d.worst.expect("worst");
        assert!(worst > 1e-3, "{label} {worst}");
    }

    #[test]
    fn given_parameters_and_fixed_ones_are_kept() {
        let m = model(TWO_MODE);
        let mut v = eom(&[("q1", &[("q1^3", 2.68e22), ("q1*q2^2", 8.57e22)])]);
        v.parameters.insert("beta2".into(), 1.0);
        let d = parameters_from_eom(&m, &v, "t")
            .expect("ok")
            .expect("derived");
        assert_eq!(d.values.parameters["beta2"], 1.0);
        assert_eq!(
            d.derived
                .iter()
                .map(|(n, _)| n.as_str())
                .collect::<Vec<_>>(),
            ["beta1", "g12"]
        );
        // Nothing missing: nothing to do.
        let mut all = d.values.clone();
        all.eom.clear();
        assert!(parameters_from_eom(&m, &all, "t").expect("ok").is_none());
    }

    #[test]
    fn an_uninvertible_map_names_the_parameters() {
        let m = model("mode q1 at 1 kHz\nparam a, b, c\neom q1 += (a + b) * q1^3 + c * q1^2\n");
        let v = eom(&[("q1", &[("q1^3", 2.0), ("q1^2", 1.0)])]);
        let e = parameters_from_eom(&m, &v, "truth.toml").expect_err("tied");
        let text = e.to_string();
        assert!(
            text.contains("a, b") && text.contains("only in combination"),
            "{text}"
        );
        assert!(!text.contains("b, c"), "{text}");
    }

    #[test]
    fn a_parameter_no_coefficient_involves_is_named() {
        let m = model(TWO_MODE);
        let v = eom(&[("q1", &[("q1^3", 2.68e22), ("q1*q2^2", 8.57e22)])]);
        let e = parameters_from_eom(&m, &v, "truth.toml").expect_err("beta2");
        assert!(e.to_string().contains("no value for beta2"), "{e}");
    }

    #[test]
    fn a_coefficient_not_linear_in_the_parameters_is_refused() {
        let m = model("mode q1 at 1 kHz\nparam g\neom q1 += g^2 * q1^3\n");
        let v = eom(&[("q1", &[("q1^3", 4.0)])]);
        let e = parameters_from_eom(&m, &v, "truth.toml").expect_err("nonlinear");
        assert!(
            e.to_string().contains("not linear in the parameters"),
            "{e}"
        );
    }
}
