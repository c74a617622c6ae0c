//! The test models, shared by the modules (and the bench builds its own the same way).

use harmonid_model::Model;
use harmonid_sim::{ModelValues, NumericModel};

/// A hardening Duffing at `F0` Hz with quality factor `Q`: `q̈ + γq̇ + ω²q + β q³ = F cos Ωt`.
pub const F0: f64 = 1000.0;
/// Quality factor of the test modes.
pub const Q: f64 = 1000.0;
/// The cubic coefficient, N/kg/m³.
pub const BETA: f64 = 1e12;

pub fn parse(src: &str, values: &str) -> (Model, ModelValues, NumericModel) {
    let model = harmonid_model::parse_str(src, "test.hb").expect("parses");
    let values: ModelValues = toml::from_str(values).expect("values");
    let num = NumericModel::from_model(&model, &values).expect("numeric");
    (model, values, num)
}

/// The Duffing of [`F0`], [`Q`], [`BETA`] (`beta` a parameter).
pub fn duffing() -> (Model, ModelValues, NumericModel) {
    parse(
        "mode q1, f = 1 kHz, Q = 1000\nparam beta\neom q1 += beta*q1^3\n",
        "[parameters]\nbeta = 1e12\n",
    )
}

/// The parametron: the Duffing with `lambda*pump*q1` (λ = 1 per unit of pump level).
pub fn parametron() -> (Model, ModelValues, NumericModel) {
    parse(
        "mode q1, f = 1 kHz, Q = 1000\nparam beta, lambda\neom q1 += beta*q1^3 + lambda*pump*q1\n",
        "[parameters]\nbeta = 1e12\nlambda = 1.0\n",
    )
}

/// Two Duffing modes at 1000 and 1004 Hz with a dispersive coupling `g/2 q1² q2²`.
pub fn two_mode() -> (Model, ModelValues, NumericModel) {
    parse(
        "mode q1, f = 1 kHz, Q = 1000\nmode q2, f = 1.004 kHz, Q = 800\nparam b1, b2, g\npotential: b1/4*q1^4 + b2/4*q2^4 + g/2*q1^2*q2^2\n",
        "[parameters]\nb1 = 1e12\nb2 = 2e12\ng = 3e12\n",
    )
}
