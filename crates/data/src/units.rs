//! Lengths and their units: one table for the dataset's `displacement_unit` and for lengths
//! typed on the command line (`--noise 0.05nm`).

/// Every length unit harmonid reads, with how many of it make one metre. Dividing by the count
/// keeps `0.05nm` exactly `5e-11`.
pub const LENGTH_UNITS: [(&str, f64); 7] = [
    ("m", 1.0),
    ("mm", 1e3),
    ("um", 1e6),
    ("µm", 1e6),
    ("nm", 1e9),
    ("pm", 1e12),
    ("fm", 1e15),
];

/// The dataset unit for data kept in the instrument's volts: no sensor calibration applied, so
/// every amplitude, noise level and coefficient fitted from it is in volts (see
/// `docs/data-format.md`). Its scale is 1.
pub const VOLTS: &str = "V";

/// The names of [`LENGTH_UNITS`], for messages: `m, mm, um, µm, nm, pm, fm`.
pub fn length_unit_names() -> String {
    LENGTH_UNITS
        .iter()
        .map(|(u, _)| *u)
        .collect::<Vec<_>>()
        .join(", ")
}

/// Metres per `unit` (a name of [`LENGTH_UNITS`], or [`VOLTS`] with scale 1), or `None` for
/// a unit harmonid does not know.
pub fn metres_per(unit: &str) -> Option<f64> {
    if unit == VOLTS {
        return Some(1.0);
    }
    LENGTH_UNITS
        .iter()
        .find(|(u, _)| *u == unit)
        .map(|(_, per_m)| 1.0 / per_m)
}

/// What is wrong with a length typed by the user.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LengthError {
    /// The number part does not parse.
    #[error("expected a number in metres or with a unit ({units}), e.g. 0.05nm", units = length_unit_names())]
    NotANumber,
    /// The suffix is not a unit of [`LENGTH_UNITS`].
    #[error("unknown unit `{0}` (use {units})", units = length_unit_names())]
    UnknownUnit(String),
    /// Negative, NaN or infinite.
    #[error("not a length (finite, ≥ 0)")]
    OutOfRange,
}

/// Parses `0.05nm`, `50 pm`, `1e-10` or `1e-10m` into metres (no suffix: metres). Negative,
/// NaN and infinite values are refused; the caller decides whether zero is allowed.
pub fn parse_length(text: &str) -> Result<f64, LengthError> {
    let t = text.trim();
    let split = t
        .find(|c: char| c.is_alphabetic() && c != 'e' && c != 'E')
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let unit = unit.trim();
    let per_m = if unit.is_empty() {
        1.0
    } else {
        LENGTH_UNITS
            .iter()
            .find(|(u, _)| *u == unit)
            .map(|(_, k)| *k)
            .ok_or_else(|| LengthError::UnknownUnit(unit.to_string()))?
    };
    let v: f64 = num.trim().parse().map_err(|_| LengthError::NotANumber)?;
    if !(v.is_finite() && v >= 0.0) {
        return Err(LengthError::OutOfRange);
    }
    Ok(v / per_m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lengths_parse_exactly() {
        assert_eq!(parse_length("0.05nm"), Ok(5e-11));
        assert_eq!(parse_length("50pm"), Ok(5e-11));
        assert_eq!(parse_length(" 2 um "), Ok(2e-6));
        assert_eq!(parse_length("2µm"), Ok(2e-6));
        assert_eq!(parse_length("1e-10"), Ok(1e-10));
        assert_eq!(parse_length("1E-10m"), Ok(1e-10));
        assert_eq!(parse_length("3fm"), Ok(3e-15));
        assert_eq!(parse_length("0"), Ok(0.0));
        assert_eq!(
            parse_length("1 furlong"),
            Err(LengthError::UnknownUnit("furlong".into()))
        );
        assert_eq!(parse_length("-1nm"), Err(LengthError::OutOfRange));
        assert!(parse_length("nannm").is_err());
        assert!(parse_length("inf").is_err());
        assert_eq!(parse_length("1e999nm"), Err(LengthError::OutOfRange));
        assert_eq!(parse_length("nm"), Err(LengthError::NotANumber));
    }

    #[test]
    fn dataset_units_scale_as_the_literals() {
        assert_eq!(metres_per("m"), Some(1.0));
        assert_eq!(metres_per("um"), Some(1e-6));
        assert_eq!(metres_per("µm"), Some(1e-6));
        assert_eq!(metres_per("nm"), Some(1e-9));
        assert_eq!(metres_per("pm"), Some(1e-12));
        assert_eq!(metres_per("fm"), Some(1e-15));
        assert_eq!(metres_per("V"), Some(1.0));
        assert_eq!(metres_per("inch"), None);
    }
}
