//! The terms of a measurement background and their one spelling (`--background
//! drive,slope,constant`): plain types the unknown table and the settings name, below the
//! fitting code of [`crate::background`].

use num_complex::Complex64;

/// One term of a measurement background; [`BackgroundTerm::name`] is its one spelling
/// (`--background`, Python's `background=`, the result file).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BackgroundTerm {
    /// `B_n·D`: feedthrough proportional to the drive.
    Drive,
    /// `S_n·D·(f − f_ref)`: a slope across the sweep, proportional to the drive.
    Slope,
    /// `C_n`: an offset independent of the drive.
    Constant,
}

impl BackgroundTerm {
    /// Every term, in the order the result lists them.
    pub const ALL: [BackgroundTerm; 3] = [
        BackgroundTerm::Drive,
        BackgroundTerm::Slope,
        BackgroundTerm::Constant,
    ];

    /// The term's name: `drive`, `slope`, `constant`.
    pub fn name(self) -> &'static str {
        match self {
            BackgroundTerm::Drive => "drive",
            BackgroundTerm::Slope => "slope",
            BackgroundTerm::Constant => "constant",
        }
    }

    /// Whether the term is proportional to the drive level (it needs the dataset's levels).
    pub fn needs_drive_levels(self) -> bool {
        self != BackgroundTerm::Constant
    }

    /// The term's coefficient on a line at `f_hz` of mode with nominal resonance `f_ref_hz`
    /// driven at `drive` (`V e^{iφ}`; `None`: no levels recorded, then only `Constant`).
    pub fn factor(self, f_hz: f64, f_ref_hz: f64, drive: Option<Complex64>) -> Option<Complex64> {
        match self {
            BackgroundTerm::Drive => drive,
            BackgroundTerm::Slope => drive.map(|d| d * (f_hz - f_ref_hz)),
            BackgroundTerm::Constant => Some(Complex64::new(1.0, 0.0)),
        }
    }
}

/// The background terms an identification fits (none by default). Read from
/// `drive[,slope][,constant]` (any order, each once; `none` or empty for none).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Background {
    terms: Vec<BackgroundTerm>,
}

impl Background {
    /// The background of these terms (sorted, each once).
    pub fn of(terms: &[BackgroundTerm]) -> Self {
        let mut terms = terms.to_vec();
        terms.sort();
        terms.dedup();
        Background { terms }
    }

    /// The terms, in [`BackgroundTerm::ALL`]'s order.
    pub fn terms(&self) -> &[BackgroundTerm] {
        &self.terms
    }

    /// Whether no background is fitted.
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }
}

/// `drive,slope,constant`, or `none`.
impl std::fmt::Display for Background {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.terms.is_empty() {
            return f.write_str("none");
        }
        let names: Vec<&str> = self.terms.iter().map(|t| t.name()).collect();
        f.write_str(&names.join(","))
    }
}

impl std::str::FromStr for Background {
    type Err = UnknownBackground;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let mut terms = Vec::new();
        for word in s.split(',').map(str::trim).filter(|w| !w.is_empty()) {
            if word == "none" {
                continue;
            }
            let t = BackgroundTerm::ALL
                .into_iter()
                .find(|t| t.name() == word)
                .ok_or_else(|| UnknownBackground {
                    found: word.to_string(),
                })?;
            terms.push(t);
        }
        Ok(Background::of(&terms))
    }
}

/// A word that is no [`BackgroundTerm`]'s name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("background term {found:?} is not one of \"drive\", \"slope\", \"constant\" (e.g. --background drive,slope; \"none\" for no background)")]
pub struct UnknownBackground {
    /// The word given.
    pub found: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn background_words_read_back_and_unknown_ones_are_listed() {
        let b: Background = "constant, drive".parse().expect("parse");
        assert_eq!(
            b.terms(),
            &[BackgroundTerm::Drive, BackgroundTerm::Constant]
        );
        assert_eq!(b.to_string(), "drive,constant");
        assert_eq!(b.to_string().parse::<Background>(), Ok(b));
        assert!("none".parse::<Background>().expect("none").is_empty());
        assert!("".parse::<Background>().expect("empty").is_empty());
        let err = "drive,feedthrough".parse::<Background>().expect_err("bad");
        assert_eq!(err.found, "feedthrough");
        let text = err.to_string();
        assert!(
            text.contains("\"drive\", \"slope\", \"constant\""),
            "{text}"
        );
    }
}
