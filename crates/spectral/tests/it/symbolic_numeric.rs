//! Property test: the symbolic mixing table, evaluated at random real amplitudes, equals the
//! numeric product of the same signals at every line (and the product vanishes elsewhere).

use harmonid_poly::PowerProduct;
use harmonid_spectral::{
    mixing_table, monomial_amplitudes, ProductPlan, ToneAssignment, Window, FREQ_TOLERANCE_HZ,
};
use num_complex::Complex64;
use proptest::prelude::*;

/// Tone frequencies (integers, Hz, possibly commensurate), their modes, the monomial's
/// exponents over three modes, the sideband order, amplitude seeds.
type Case = (Vec<(u32, usize)>, Vec<u32>, u32, Vec<f64>);

fn case() -> impl Strategy<Value = Case> {
    (
        proptest::sample::subsequence((1..=60u32).collect::<Vec<_>>(), 1..=4),
        proptest::collection::vec(0u32..=2, 3..=3).prop_filter("degree 1..=4", |e| {
            let d: u32 = e.iter().sum();
            (1..=4).contains(&d)
        }),
        prop_oneof![Just(1u32), Just(3u32)],
        proptest::collection::vec(-2.0f64..2.0, 40..=40),
    )
        .prop_flat_map(|(tones, exps, sb, amps)| {
            let n = tones.len();
            (
                proptest::collection::vec(0usize..3, n..=n)
                    .prop_map(move |modes| tones.iter().copied().zip(modes).collect::<Vec<_>>()),
                Just(exps),
                Just(sb),
                Just(amps),
            )
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
    #[test]
    fn symbolic_equals_numeric((tones, exps, sb, amps) in case()) {
        let names = ["q1", "q2", "q3"];
        let mut drives: Vec<(String, Vec<f64>)> = Vec::new();
        for &(f, m) in &tones {
            match drives.iter_mut().find(|(n, _)| n == names[m]) {
                Some((_, v)) => v.push(f64::from(f)),
                None => drives.push((names[m].to_string(), vec![f64::from(f)])),
            }
        }
        let mut a = ToneAssignment::from_drives(&names, &drives).expect("valid tones");
        a.add_own_sidebands(sb).expect("small");
        let m = PowerProduct::from_exponents(&exps);
        let nominal = [Some(10.0), Some(30.0), Some(50.0)];
        let table = mixing_table(&m, &a, &nominal, Window::default()).expect("small");
        let x: Vec<f64> = amps.iter().take(a.components().len()).copied().collect();
        prop_assume!(x.len() == a.components().len());

        // Numeric: every component frequency (distinct) as an input line.
        let mut input: Vec<f64> = Vec::new();
        for c in a.components() {
            let hz = c.combination.hz(a.tones());
            if !input.iter().any(|&f| (f - hz).abs() <= FREQ_TOLERANCE_HZ) {
                input.push(hz);
            }
        }
        let mut spectra = vec![vec![Complex64::new(0.0, 0.0); input.len()]; 3];
        for (c, &xc) in a.components().iter().zip(&x) {
            let hz = c.combination.hz(a.tones());
            let r = input.iter().position(|&f| (f - hz).abs() <= FREQ_TOLERANCE_HZ).expect("listed");
            spectra[c.mode][r] += Complex64::new(xc, 0.0);
        }
        let mut output: Vec<f64> = table.lines.iter().map(|l| l.hz).collect();
        // Plus frequencies between lattice points, where nothing may land.
        output.extend([0.5, 17.25, 101.5]);
        let plan = ProductPlan::new(&input, &output, 4).expect("plan");
        let mut scratch = plan.scratch();
        let mut out = vec![Complex64::new(0.0, 0.0); output.len()];
        let modal: Vec<&[Complex64]> = spectra.iter().map(|v| v.as_slice()).collect();
        monomial_amplitudes(&plan, &m, &modal, &mut out, &mut scratch);
        let scale: f64 = exps
            .iter()
            .enumerate()
            .map(|(n, &e)| spectra[n].iter().map(|z| z.norm()).sum::<f64>().powi(e as i32))
            .product::<f64>()
            .max(1e-300);
        for (l, o) in table.lines.iter().zip(&out) {
            let s = l.eval(&x);
            prop_assert!((o.re - s).abs() <= 1e-12 * scale && o.im.abs() <= 1e-12 * scale,
                "line {} at {} Hz: symbolic {} vs numeric {}", l.combination, l.hz, s, o);
        }
        for o in &out[table.lines.len()..] {
            prop_assert!(o.norm() <= 1e-12 * scale, "off-lattice output {}", o);
        }
    }
}
