//! Lists in messages: indices as `3, 7, 12`, long name lists cut to the first few.

/// Shot or point indices for a message: `3, 7, 12`.
pub fn index_list(xs: &[usize]) -> String {
    xs.iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The first `shown` of `items`, then `"N more"` for the rest, so that a message about a
/// stepped sweep's hundreds of measurements (or unknowns) stays readable.
pub fn first_and_more(mut items: Vec<String>, shown: usize) -> Vec<String> {
    if items.len() > shown {
        let more = items.len() - shown;
        items.truncate(shown);
        items.push(format!("{more} more"));
    }
    items
}

/// At most this many characters of one header name are quoted in a message.
const NAME_CHARS: usize = 24;
/// At most this many header names are quoted in a message.
const NAMES_SHOWN: usize = 12;

/// A file's header names for a message: each quoted and escaped (`"\u{feff}f"`, `"a\tb"`), cut
/// to 24 characters with `…`, the first 12 then "N more". A binary file read as text has one
/// "name" of kilobytes; it is quoted as a short excerpt, never whole.
pub fn header_names<'a>(names: impl IntoIterator<Item = &'a str>) -> String {
    let quoted = names
        .into_iter()
        .map(|n| {
            let escaped: String = n.escape_debug().collect();
            let mut cut: String = escaped.chars().take(NAME_CHARS).collect();
            if cut.len() < escaped.len() {
                cut.push('…');
            }
            format!("\"{cut}\"")
        })
        .collect();
    first_and_more(quoted, NAMES_SHOWN).join(", ")
}

#[cfg(test)]
mod tests {
    use super::header_names;

    #[test]
    fn header_names_are_escaped_and_cut() {
        assert_eq!(header_names(["f", "X", "Y"]), r#""f", "X", "Y""#);
        assert_eq!(header_names(["\u{feff}f"]), r#""\u{feff}f""#);
        let binary = "\"".repeat(5000);
        let shown = header_names([binary.as_str()]);
        assert!(shown.len() < 60 && shown.ends_with("…\""), "{shown}");
        let many: Vec<String> = (0..100).map(|i| format!("c{i}")).collect();
        let shown = header_names(many.iter().map(String::as_str));
        assert!(shown.ends_with("\"c11\", 88 more"), "{shown}");
    }
}
