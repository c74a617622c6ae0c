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
