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
/// `drive[,slope][,constant]` (any order, each once; `none` for none).
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

/// Reads `drive,slope,constant` or `none`. An empty text, an empty word (`drive,`), a word
/// given twice and `none` beside a term are refused rather than read as something else: a
/// typo in a shell variable should not silently fit no background.
impl std::str::FromStr for Background {
    type Err = BadBackground;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let words: Vec<&str> = s.split(',').map(str::trim).collect();
        if words == ["none"] {
            return Ok(Background::default());
        }
        let mut terms = Vec::new();
        for word in words {
            let t = BackgroundTerm::ALL
                .into_iter()
                .find(|t| t.name() == word)
                .ok_or_else(|| BadBackground::Unknown(word.to_string()))?;
            if terms.contains(&t) {
                return Err(BadBackground::Repeated(t.name()));
            }
            terms.push(t);
        }
        Ok(Background::of(&terms))
    }
}

/// A background text that names no background: a word that is no [`BackgroundTerm`]'s name
/// (empty included), or a term given twice.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BadBackground {
    /// A word that is no term's name.
    #[error("background term {0:?} is not one of \"drive\", \"slope\", \"constant\" (e.g. --background drive,slope; \"none\" for no background)")]
    Unknown(String),
    /// A term named twice.
    #[error("background term {0:?} is given twice: name each of \"drive\", \"slope\", \"constant\" at most once (e.g. --background drive,slope)")]
    Repeated(&'static str),
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
        for bad in ["", "drive,", "none,drive", " , "] {
            let err = bad.parse::<Background>().expect_err(bad);
            assert!(matches!(err, BadBackground::Unknown(_)), "{bad:?}: {err}");
        }
        let err = "drive, drive".parse::<Background>().expect_err("twice");
        assert_eq!(err, BadBackground::Repeated("drive"));
        assert!(
            err.to_string().contains("\"drive\" is given twice"),
            "{err}"
        );
        let err = "drive,feedthrough".parse::<Background>().expect_err("bad");
        assert_eq!(err, BadBackground::Unknown("feedthrough".into()));
        let text = err.to_string();
        assert!(
            text.contains("\"drive\", \"slope\", \"constant\""),
            "{text}"
        );
    }
}
