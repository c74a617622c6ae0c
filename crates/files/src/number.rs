//! Numbers in messages: a user's `1e300` is quoted as `1e300`, not as the 301 digits Rust's `{}`
//! writes for an `f64`.

/// `v` as a message quotes it: plain decimals between 1e-4 and 1e9 (`207580.5`, `0.01`), else
/// scientific (`1e300`, `-2.5e-9`); `inf`, `-inf` and `NaN` as Rust spells them.
///
/// ```
/// assert_eq!(harmonid_files::number(1e300), "1e300");
/// assert_eq!(harmonid_files::number(207580.5), "207580.5");
/// assert_eq!(harmonid_files::number(f64::INFINITY), "inf");
/// ```
pub fn number(v: f64) -> String {
    if !v.is_finite() || v == 0.0 || (1e-4..1e9).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::number;

    #[test]
    fn huge_and_tiny_numbers_are_scientific() {
        assert_eq!(number(1e308), "1e308");
        assert_eq!(number(-1.4142135623730951e308), "-1.4142135623730951e308");
        assert_eq!(number(5e-12), "5e-12");
        assert_eq!(number(0.0), "0");
        assert_eq!(number(-3.5), "-3.5");
        assert_eq!(number(f64::NAN), "NaN");
        assert_eq!(number(f64::NEG_INFINITY), "-inf");
        assert!(number(f64::MAX).len() < 30);
    }
}
