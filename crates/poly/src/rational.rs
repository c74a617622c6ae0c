//! Exact rational numbers and their conversion from decimal literals.

use num_traits::{CheckedMul, ToPrimitive, Zero};

/// Exact rational number with 128-bit numerator and denominator.
pub type Rational = num_rational::Ratio<i128>;

/// Converts a rational to the nearest `f64` (`num / den` evaluated in floating point).
pub fn rational_to_f64(r: &Rational) -> f64 {
    // Both parts fit i128; dividing their f64 images loses at most a few ulps, which is fine for
    // numeric evaluation (exact arithmetic stays in `Rational`).
    match (r.numer().to_f64(), r.denom().to_f64()) {
        (Some(n), Some(d)) => n / d,
        _ => f64::NAN,
    }
}

/// LaTeX form of a rational magnitude: `3` or `\frac{3}{4}`.
pub fn rational_latex(r: &Rational) -> String {
    if r.is_integer() {
        r.numer().to_string()
    } else {
        format!("\\frac{{{}}}{{{}}}", r.numer(), r.denom())
    }
}

/// Parses a decimal literal such as `3`, `0.75`, `2.68e22` or `1E-3` into an exact rational.
///
/// Returns `None` when the text is not a plain decimal number or its exact value does not fit a
/// 128-bit rational (e.g. `1e60`). A sign is not accepted; callers handle unary minus.
pub fn parse_decimal(text: &str) -> Option<Rational> {
    let (mantissa, exponent) = match text.find(['e', 'E']) {
        Some(pos) => (&text[..pos], text[pos + 1..].parse::<i32>().ok()?),
        None => (text, 0),
    };
    let (int_part, frac_part) = match mantissa.find('.') {
        Some(pos) => (&mantissa[..pos], &mantissa[pos + 1..]),
        None => (mantissa, ""),
    };
    if int_part.is_empty() && frac_part.is_empty() {
        return None;
    }
    if !int_part
        .bytes()
        .chain(frac_part.bytes())
        .all(|b| b.is_ascii_digit())
    {
        return None;
    }
    let digits = format!("{int_part}{frac_part}");
    let digits = digits.trim_start_matches('0');
    let mut numer: i128 = if digits.is_empty() {
        0
    } else {
        digits.parse().ok()?
    };
    let scale = exponent.checked_sub(i32::try_from(frac_part.len()).ok()?)?;
    if numer.is_zero() {
        return Some(Rational::zero());
    }
    let mut denom: i128 = 1;
    let ten = Rational::from_integer(10);
    let mut factor = Rational::from_integer(1);
    for _ in 0..scale.unsigned_abs() {
        factor = factor.checked_mul(&ten)?;
    }
    if scale >= 0 {
        numer = numer.checked_mul(*factor.numer())?;
    } else {
        denom = *factor.numer();
    }
    Some(Rational::new(numer, denom))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_plain_and_scientific_decimals() {
        assert_eq!(parse_decimal("3"), Some(Rational::from_integer(3)));
        assert_eq!(parse_decimal("0.75"), Some(Rational::new(3, 4)));
        assert_eq!(parse_decimal(".5"), Some(Rational::new(1, 2)));
        assert_eq!(
            parse_decimal("2.68e22"),
            Some(Rational::from_integer(268 * 10i128.pow(20)))
        );
        assert_eq!(parse_decimal("1E-3"), Some(Rational::new(1, 1000)));
        assert_eq!(parse_decimal("0.000"), Some(Rational::zero()));
        assert_eq!(parse_decimal("1e60"), None);
        assert_eq!(parse_decimal("abc"), None);
        assert_eq!(parse_decimal("."), None);
    }

    #[test]
    fn converts_to_f64() {
        assert_eq!(rational_to_f64(&Rational::new(3, 4)), 0.75);
        assert_eq!(rational_to_f64(&Rational::new(-1, 3)), -1.0 / 3.0);
    }
}
