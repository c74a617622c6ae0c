//! The symbolic expansion against Supplementary Note II of the method's paper: Eq. S1, S2, S3
//! (coefficients written in as printed) and the frequency families of Table S1.

use harmonid_poly::PowerProduct;
use harmonid_spectral::{mixing_table, MixingTable, ToneAssignment, Window};
use std::collections::BTreeMap;

/// `combination → coefficient string` of every line.
fn lines(t: &MixingTable, a: &ToneAssignment) -> BTreeMap<Vec<i32>, String> {
    let names = a.symbols();
    t.lines
        .iter()
        .map(|l| {
            (
                l.combination.coeffs().to_vec(),
                l.coefficient.to_string_with(&names),
            )
        })
        .collect()
}

fn expect(pairs: &[(&[i32], &str)]) -> BTreeMap<Vec<i32>, String> {
    pairs
        .iter()
        .map(|(k, c)| (k.to_vec(), c.to_string()))
        .collect()
}

// ω1 = 1000 Hz, δ = 1 Hz, ω3 = 3000.5 Hz (near 1:3); f1 = ω1 + δ (X1), f2 = ω1 − δ (X2).
const W1: f64 = 1000.0;
const D: f64 = 1.0;
const W3: f64 = 3000.5;

fn q1_two_tones_q3_one() -> ToneAssignment {
    let drives = vec![
        ("q1".to_string(), vec![W1 + D, W1 - D]),
        ("q3".to_string(), vec![W3]),
    ];
    ToneAssignment::from_drives(&["q1", "q3"], &drives).expect("valid drives")
}

#[test]
fn eq_s1_duffing_under_two_tones() {
    let drives = vec![("q1".to_string(), vec![W1 + D, W1 - D])];
    let a = ToneAssignment::from_drives(&["q1"], &drives).expect("valid");
    let t = mixing_table(
        &PowerProduct::from_exponents(&[3]),
        &a,
        &[Some(W1)],
        Window::default(),
    )
    .expect("small");
    // Eq. S1: 3/4 [ (X1³ + 2X1X2²) cos(ω1+δ) + (X2³ + 2X2X1²) cos(ω1−δ) + X1²X2 cos(ω1+3δ)
    //   + X1X2² cos(ω1−3δ) + 1/3 X1³ cos(3ω1+3δ) + 1/3 X2³ cos(3ω1−3δ) + X1²X2 cos(3ω1+δ)
    //   + X1X2² cos(3ω1−δ) ].
    let want = expect(&[
        (&[1, 0], "3/4*X1^3 + 3/2*X1*X2^2"),
        (&[0, 1], "3/2*X1^2*X2 + 3/4*X2^3"),
        (&[2, -1], "3/4*X1^2*X2"),
        (&[-1, 2], "3/4*X1*X2^2"),
        (&[3, 0], "1/4*X1^3"),
        (&[0, 3], "1/4*X2^3"),
        (&[2, 1], "3/4*X1^2*X2"),
        (&[1, 2], "3/4*X1*X2^2"),
    ]);
    assert_eq!(lines(&t, &a), want);
    // ω1 ± δ, ω1 ± 3δ near the resonance; the four third-harmonic lines off it.
    assert_eq!(t.near(0).count(), 4);
    assert_eq!(t.off_resonance().count(), 4);
    // Frequencies as printed in the paper.
    let hz: Vec<f64> = t.lines.iter().map(|l| l.hz).collect();
    assert_eq!(
        hz,
        vec![997.0, 999.0, 1001.0, 1003.0, 2997.0, 2999.0, 3001.0, 3003.0]
    );
    let c = a.tones().combination(&[2, -1]).expect("len");
    assert_eq!(c.display_with(a.tones().labels()), "2·f1 − f2");
}

#[test]
fn eq_s2_internal_resonance_term() {
    let a = q1_two_tones_q3_one();
    let t = mixing_table(
        &PowerProduct::from_exponents(&[2, 1]),
        &a,
        &[Some(W1), Some(W3)],
        Window::default(),
    )
    .expect("small");
    // Eq. S2 with its prefactor 1/2 distributed; 2ω1 − ω3 < 0 here, so those lines appear with
    // the canonical (positive-frequency) combination ω3 − 2ω1 (cos is even).
    let want = expect(&[
        (&[0, 0, 1], "1/2*X1^2*X3 + 1/2*X2^2*X3"),
        (&[1, -1, 1], "1/2*X1*X2*X3"),
        (&[-1, 1, 1], "1/2*X1*X2*X3"),
        (&[1, 1, 1], "1/2*X1*X2*X3"),
        (&[-1, -1, 1], "1/2*X1*X2*X3"),
        (&[2, 0, 1], "1/4*X1^2*X3"),
        (&[0, 2, 1], "1/4*X2^2*X3"),
        (&[-2, 0, 1], "1/4*X1^2*X3"),
        (&[0, -2, 1], "1/4*X2^2*X3"),
    ]);
    assert_eq!(lines(&t, &a), want);
    // The paper's observation: no line at the drives ω1 ± δ; lines at ω3 and ω3 ± 2δ. Near the
    // 1:3 resonance the lines ω3 − 2ω1 (− 2δ, + 2δ) land within 1 % of ω1 (not on a drive).
    assert!(t.line(&a.tones().unit(0)).is_none() && t.line(&a.tones().unit(1)).is_none());
    let near1: Vec<f64> = t.near(0).map(|l| l.hz).collect();
    assert_eq!(near1, vec![998.5, 1000.5, 1002.5]);
    let near3: Vec<f64> = t.near(1).map(|l| l.hz).collect();
    assert_eq!(near3, vec![2998.5, 3000.5, 3002.5]);
}

#[test]
fn eq_s3_cubic_in_the_third_equation() {
    let a = q1_two_tones_q3_one();
    let t = mixing_table(
        &PowerProduct::from_exponents(&[3, 0]),
        &a,
        &[Some(W1), Some(W3)],
        Window::Hz(10.0),
    )
    .expect("small");
    let want = expect(&[
        (&[1, 0, 0], "3/4*X1^3 + 3/2*X1*X2^2"),
        (&[0, 1, 0], "3/2*X1^2*X2 + 3/4*X2^3"),
        (&[2, -1, 0], "3/4*X1^2*X2"),
        (&[-1, 2, 0], "3/4*X1*X2^2"),
        (&[3, 0, 0], "1/4*X1^3"),
        (&[0, 3, 0], "1/4*X2^3"),
        (&[2, 1, 0], "3/4*X1^2*X2"),
        (&[1, 2, 0], "3/4*X1*X2^2"),
    ]);
    assert_eq!(lines(&t, &a), want);
    // "b_111^(3) does not have an effect at ω3": no line exactly at ω3; but 3ω1 ± δ lie
    // within 10 Hz of it (the near-1:3 resonance).
    assert!(t.line(&a.tones().unit(2)).is_none());
    let near3: Vec<f64> = t.near(1).map(|l| l.hz).collect();
    assert_eq!(near3, vec![2997.0, 2999.0, 3001.0, 3003.0]);
}

/// Offsets, in units of δ, of the lines near resonance `centre` (Hz).
fn offsets(t: &MixingTable, mode: usize, centre: f64, delta: f64) -> Vec<i64> {
    t.near(mode)
        .map(|l| ((l.hz - centre) / delta).round() as i64)
        .collect()
}

#[test]
fn table_s1_dispersive_terms() {
    // The nanostring: ω1 = 207582 Hz, ω2 = 415842 Hz, δ = 10 Hz; tones ω1 ± δ and ω2.
    let (w1, w2, d) = (207582.0, 415842.0, 10.0);
    let drives = vec![
        ("q1".to_string(), vec![w1 - d, w1 + d]),
        ("q2".to_string(), vec![w2]),
    ];
    let nominal = [Some(w1), Some(w2)];
    let q1q2q2 = PowerProduct::from_exponents(&[1, 2]);
    let q1q1q2 = PowerProduct::from_exponents(&[2, 1]);
    for sideband_order in [1u32, 5] {
        let mut a = ToneAssignment::from_drives(&["q1", "q2"], &drives).expect("valid");
        let added = a.add_own_sidebands(sideband_order).expect("small");
        let t122 = mixing_table(&q1q2q2, &a, &nominal, Window::default()).expect("small");
        let t112 = mixing_table(&q1q1q2, &a, &nominal, Window::default()).expect("small");
        // b_122^(1) q1 q2²: close to ω1 only; b_112^(2) q1² q2: close to ω2 only.
        assert_eq!(t122.near(1).count(), 0);
        assert_eq!(t112.near(0).count(), 0);
        let (near1, near2, off122, off112): (Vec<i64>, Vec<i64>, Vec<i64>, Vec<i64>);
        near1 = offsets(&t122, 0, w1, d);
        near2 = offsets(&t112, 1, w2, d);
        off122 = t122
            .off_resonance()
            .map(|l| ((l.hz - (2.0 * w2 - w1)) / d).round() as i64)
            .filter(|k| k.abs() < 100)
            .collect();
        off112 = t112
            .off_resonance()
            .map(|l| ((l.hz - (w2 - 2.0 * w1)) / d).round() as i64)
            .filter(|k| k.abs() < 100)
            .collect();
        if sideband_order == 1 {
            assert_eq!(added, 0);
            assert_eq!(near1, vec![-1, 1]); // ω1 ± δ
            assert_eq!(near2, vec![-2, 0, 2]); // ω2, ω2 ± 2δ
            assert_eq!(off122, vec![-1, 1]); // 2ω2 − ω1 ± δ
            assert_eq!(off112, vec![-2, 0, 2]); // ω2 − 2ω1, ± 2δ
                                                // The coefficients: ½ X1 X3² at ω1 − δ, ½ (X1² + X2²) X3 at ω2, ½ X1 X2 X3 at ω2 ± 2δ.
            let names = a.symbols();
            let at = |t: &MixingTable, k: &[i32]| {
                let c = a.tones().combination(k).expect("len");
                t.line(&c).map(|l| l.coefficient.to_string_with(&names))
            };
            assert_eq!(at(&t122, &[1, 0, 0]).as_deref(), Some("1/2*X1*X3^2"));
            assert_eq!(at(&t122, &[-1, 0, 2]).as_deref(), Some("1/4*X1*X3^2"));
            assert_eq!(
                at(&t112, &[0, 0, 1]).as_deref(),
                Some("1/2*X1^2*X3 + 1/2*X2^2*X3")
            );
            assert_eq!(at(&t112, &[1, -1, 1]).as_deref(), Some("1/2*X1*X2*X3"));
        } else {
            // q1 carries ω1 ± 3δ, ω1 ± 5δ: the families continue as in Table S1.
            assert_eq!(added, 4);
            assert_eq!(near1, vec![-5, -3, -1, 1, 3, 5]);
            assert_eq!(near2, vec![-10, -8, -6, -4, -2, 0, 2, 4, 6, 8, 10]);
            assert_eq!(off122, vec![-5, -3, -1, 1, 3, 5]);
            assert_eq!(off112, vec![-10, -8, -6, -4, -2, 0, 2, 4, 6, 8, 10]);
        }
    }
}
