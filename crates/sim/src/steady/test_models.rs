//! The hand-built models the steady-state family's unit tests share.

use crate::{NumericModel, Term};

/// One Duffing mode at 1 kHz with quality factor `q`: `q̈ + γq̇ + ω²q + β q³`.
pub(super) fn duffing(beta: f64, q: f64) -> NumericModel {
    NumericModel::new(
        vec!["q".into()],
        vec![1000.0],
        vec![q],
        vec![Term {
            eq: 0,
            coef: beta,
            factors: vec![(0, 3)],
        }],
    )
    .expect("model")
}
