//! Fuzz the dataset reader: a manifest (`dataset.toml`) and one CSV, from one input split at
//! its first NUL byte; every measurement of the manifest reads that CSV. Any input must give a
//! dataset or an error, never a panic or a hang.
//!
//! Run with `cargo +nightly fuzz run dataset fuzz/corpus/dataset -- -max_len=8192`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let (manifest, csv) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    let Ok(manifest) = std::str::from_utf8(manifest) else {
        return;
    };
    let result =
        harmonid_data::Dataset::from_readers(Path::new("fuzz"), manifest, None, |_| Ok(csv));
    match result {
        Ok(ds) => {
            let _ = ds.check_modes(&["q1", "q2"]);
            let _ = ds.input_files();
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
});
