//! No panic on any finite input (issue 11): the public numeric entry points of `ident` given
//! arbitrary finite numbers (zeros, subnormals, ±1e308 included) return a value or an error.
//! The dataset reader gets arbitrary rows of numbers as well. Results are not checked here
//! (the accuracy tests do that), only that nothing panics and that what is returned is finite
//! where it claims to be determined.

use harmonid_data::Dataset;
use harmonid_ident::{disturbed_shots, drift_check, identify, solve_ls, Estimator, Settings};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use proptest::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::LazyLock;

/// Any finite f64: normal, subnormal or zero, either sign.
fn finite() -> impl Strategy<Value = f64> {
    prop::num::f64::NORMAL | prop::num::f64::SUBNORMAL | prop::num::f64::ZERO
}

/// A finite f64 that is, three times in four, between 1e-3 and 1e3 (so that the fit is reached,
/// not only the reader's checks).
fn plausible() -> impl Strategy<Value = f64> {
    prop_oneof![1 => finite(), 3 => (-3.0..3.0f64).prop_map(|e| 10f64.powf(e))]
}

fn example() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/nanostring_2mode")
}

static MODEL: LazyLock<harmonid_model::Model> =
    LazyLock::new(|| harmonid_model::load(&example().join("model.hb")).expect("example model"));
static DATA: LazyLock<Dataset> =
    LazyLock::new(|| Dataset::load(example().join("data")).expect("example dataset"));

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn least_squares_never_panics(
        (m, k) in (1usize..6, 1usize..5),
        vals in prop::collection::vec(finite(), 30),
        rhs in prop::collection::vec(finite(), 6),
        bounds in prop::collection::vec(prop::option::of(finite()), 8),
    ) {
        let a = DMatrix::from_fn(m, k, |i, j| vals[(i * k + j) % vals.len()]);
        let b = DVector::from_fn(m, |i, _| rhs[i % rhs.len()]);
        let _ = solve_ls(&a, &b, &bounds[..k], &bounds[4..4 + k]);
    }

    #[test]
    fn pooling_and_drift_never_panic(
        shots in prop::collection::vec(prop::collection::vec((finite(), finite()), 4), 0..8),
        delta in prop::collection::vec(finite(), 0..12),
        var in finite(),
    ) {
        let data: Vec<Vec<Complex64>> = shots
            .iter()
            .map(|s| s.iter().map(|&(re, im)| Complex64::new(re, im)).collect())
            .collect();
        let refs: Vec<&[Complex64]> = data.iter().map(Vec::as_slice).collect();
        let bad = disturbed_shots(&refs, data.len());
        prop_assert!(bad.iter().all(|&s| s < data.len()));
        let _ = drift_check(&delta, var);
    }

    #[test]
    fn the_reader_takes_any_numbers_in_its_rows(
        rows in prop::collection::vec((0u8..3, finite(), finite(), finite()), 1..20),
        levels in (finite(), finite()),
    ) {
        let manifest = format!(
            "format = \"harmonid-dataset/1\"\n[[measurement]]\nname = \"m1\"\n\
             drives_hz = [1000.0]\ndrive_levels_v = [{:e}]\n",
            levels.0
        );
        let mut csv = String::from("shot,freq_hz,re,im\n");
        for (shot, f, re, im) in &rows {
            csv.push_str(&format!("{shot},{f:e},{re:e},{im:e}\n"));
        }
        csv.push_str(&format!("0,1000,{:e},0\n", levels.1));
        match Dataset::from_readers(Path::new("mem"), &manifest, None, |_| Ok(csv.as_bytes())) {
            Ok(ds) => {
                let m = &ds.measurements[0];
                prop_assert!(m.freqs_hz.iter().all(|f| f.is_finite() && *f > 0.0));
                prop_assert!(m.data.iter().all(|x| x.re.is_finite() && x.im.is_finite()));
            }
            Err(e) => prop_assert!(e.to_string().contains("mem")),
        }
    }
}

proptest! {
    // Each case is a whole identification of the example (about 20 ms): few cases.
    #![proptest_config(ProptestConfig { cases: 16, ..ProptestConfig::default() })]

    #[test]
    fn identify_never_panics_on_changed_amplitudes(
        scale in plausible(),
        changes in prop::collection::vec((0usize..3, 0usize..400, finite(), finite()), 0..3),
    ) {
        let mut ms = DATA.measurements.clone();
        for m in &mut ms {
            for x in &mut m.data {
                *x *= scale;
            }
        }
        for (mi, i, re, im) in changes {
            let n = ms[mi].data.len();
            ms[mi].data[i % n] = Complex64::new(re, im);
        }
        let Ok(ds) = Dataset::from_parts("mem", DATA.manifest.clone(), ms, None) else {
            return Ok(());
        };
        let settings = Settings { estimator: Estimator::Linear, ..Settings::default() };
        if let Ok(r) = identify(&MODEL, &ds, &settings) {
            for e in r.parameters.values().filter(|e| e.identifiable) {
                prop_assert!(e.value.is_finite(), "{e:?}");
            }
        }
    }
}
