//! Fuzz the model parser: any input must give a model or diagnostics, never a panic or a hang.
//!
//! Run with `cargo +nightly fuzz run parse -- -max_len=4096` from the repository root
//! (needs `cargo install cargo-fuzz`). Seeds: `examples/*/model.hb`, `tests/fixtures/broken/*.hb`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        match harmonid_model::parse_str(text, "fuzz.hb") {
            Ok(model) => {
                let _ = model.to_text();
                let _ = model.to_json();
            }
            Err(e) => {
                let _ = e.render_plain(80);
            }
        }
    }
});
