//! Fuzz the plan and values TOML readers: a plan (`plan.toml`) and a values file, from one
//! input split at its first NUL byte. Any input must give a plan (which writes itself back as
//! TOML that reads again to the same plan) or a located error, values or an error, and, with
//! the two-mode example model, an excitation, a manifest or an error: never a panic or a hang.
//!
//! Run with `cargo +nightly fuzz run plan fuzz/corpus/plan -- -max_len=8192`.
#![no_main]

use harmonid_experiment::{values_from_toml, Plan};
use harmonid_sim::NumericModel;
use libfuzzer_sys::fuzz_target;
use std::sync::LazyLock;

static MODEL: LazyLock<harmonid_model::Model> = LazyLock::new(|| {
    harmonid_model::parse_str(
        include_str!("../../examples/nanostring_2mode/model.hb"),
        "model.hb",
    )
    .expect("the example model parses")
});

fuzz_target!(|data: &[u8]| {
    let (plan, values) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    let (Ok(plan), Ok(values)) = (std::str::from_utf8(plan), std::str::from_utf8(values)) else {
        return;
    };
    let plan = match Plan::from_toml(plan, "plan.toml") {
        Ok(p) => Some(p),
        Err(e) => {
            let _ = e.to_string();
            None
        }
    };
    if let Some(p) = &plan {
        let back = p.to_toml();
        let again = Plan::from_toml(&back, "written.toml")
            .unwrap_or_else(|e| panic!("a checked plan writes TOML it cannot read: {e}\n{back}"));
        assert_eq!(
            again.to_toml(),
            back,
            "the written plan reads back differently"
        );
    }
    let values = match values_from_toml(values, "values.toml") {
        Ok(v) => v,
        Err(e) => {
            let _ = e.to_string();
            return;
        }
    };
    let Ok(num) = NumericModel::from_model(&MODEL, &values) else {
        return;
    };
    if let Some(p) = &plan {
        let _ = p.point_shapes(&num);
        let _ = p.manifest(&num);
        for m in &p.measurements {
            let _ = m.excitation(&num).map_err(|e| e.to_string());
        }
    }
});
