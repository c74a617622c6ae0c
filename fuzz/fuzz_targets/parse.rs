//! Fuzz the model parser on raw bytes (not only UTF-8): any input must give a model or
//! diagnostics, never a panic or a hang; a model must print back and serialise.
//!
//! Run with `cargo +nightly fuzz run parse fuzz/corpus/parse -- -max_len=4096` from the
//! repository root (needs `cargo install cargo-fuzz`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    match harmonid_model::parse_bytes(data, "fuzz.hb") {
        Ok(model) => {
            let _ = model.to_text();
            let _ = model.to_json();
        }
        Err(e) => {
            let _ = e.render_plain(80);
        }
    }
});
