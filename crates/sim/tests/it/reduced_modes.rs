//! The reduction to the modes a drive reaches (`ActiveModes`, `ReducedSolver`,
//! `ReducedSensitivity`) against the whole-model solver, on a four-mode model where the
//! closure grows (`c q1² q3`: driving q1 forces q3 at 2f), an idle mode is pumped
//! parametrically by the driven one (`g q1² q2`, q2 tuned so that the drive's 2f is twice its
//! shifted resonance), and a linear coupling `k q2` in q4's equation joins q4 to q2's idle
//! block. Steady states, stability verdicts and growth rates, and sensitivities agree with the
//! whole model's.

use harmonid_sim::{
    ActiveModes, Excitation, HbSettings, HbSolver, ModeValues, ModelValues, NumericModel,
    Observation, ReducedSensitivity, ReducedSolver, SensParam, Sensitivity, SimError,
};
use num_complex::Complex64;

const SOURCE: &str = "mode q1 at 1 kHz\nmode q2 at 995 Hz\nmode q3 at 2 kHz\nmode q4 at 3 kHz\n\
    param beta1\nparam g\nparam c\nparam k\nparam beta3\nparam eta2\nparam eta3\n\
    potential: beta1/4*q1^4\npotential: g/2*q1^2*q2^2\npotential: c*q1^2*q3\n\
    eom q2 += eta2*q2^2*d(q2)\neom q3 += beta3*q3^3 + eta3*q1^2*d(q3)\neom q4 += k*q2\n";

fn model() -> NumericModel {
    let model = harmonid_model::parse_str(SOURCE, "reduced.hb").expect("model");
    let mut v = ModelValues::default();
    for (name, f, q) in [
        ("q1", 1000.0, 50.0),
        ("q2", 995.0, 1000.0),
        ("q3", 2000.0, 1000.0),
        ("q4", 3000.0, 500.0),
    ] {
        v.modes.insert(
            name.into(),
            ModeValues {
                f_hz: Some(f),
                q: Some(q),
            },
        );
    }
    // |q1| ≈ 10 nm: the Duffing shift is a fraction of q1's linewidth, g|q1|²/2 lifts q2's
    // ω² by 1 % (to about 1000 Hz) and modulates it by h = 1 % at 2f (threshold 2/Q2 = 0.2 %).
    for (p, x) in [
        ("beta1", 3.9e20),
        ("g", 7.8e21),
        ("c", 1.6e12),
        ("k", 1.0e6),
        ("beta3", 1.0e21),
        ("eta2", 1.0e14),
        ("eta3", 1.0e10),
    ] {
        v.parameters.insert(p.into(), x);
    }
    NumericModel::from_model(&model, &v).expect("numeric model")
}

fn drive(hz: f64) -> Excitation {
    let f = Complex64::new(7.9e-3, 0.0);
    let z = Complex64::new(0.0, 0.0);
    Excitation::new(vec![hz], vec![vec![f], vec![z], vec![z], vec![z]])
}

#[test]
fn the_closure_and_the_idle_parts_follow_the_terms() {
    let m = model();
    let a = ActiveModes::of(&m, &drive(1000.0), &[]);
    assert_eq!(a.modes(), &[0, 2], "q3 joins through c q1^2");
    assert_eq!(a.idle_parts(), &[vec![1, 3]], "k q2 joins q4 to q2's block");
    // A mode named as forced is active whatever its force.
    let b = ActiveModes::of(&m, &drive(1000.0), &[1]);
    assert_eq!(b.modes(), &[0, 1, 2, 3]);
    // Driving q2 alone reaches q4 (k q2) but not q1 or q3 (each of their terms holds q1).
    let mut d = drive(1000.0);
    d.force.swap(0, 1);
    assert_eq!(ActiveModes::of(&m, &d, &[]).modes(), &[1, 3]);
}

#[test]
fn reduced_states_and_stability_are_the_whole_models() {
    let m = model();
    let settings = HbSettings::default();
    let (mut unstable, mut idle_only) = (0, 0);
    for i in 0..21 {
        let hz = 990.0 + i as f64;
        let d = drive(hz);
        let mut full = HbSolver::new(&m, &d, &settings.lattice).expect("full");
        let mut red = ReducedSolver::new(&m, &d, &settings.lattice, &[]).expect("reduced");
        assert_eq!(full.lattice(), red.lattice());
        assert!(
            red.unknowns() * 2 == full.unknowns(),
            "two of four modes solved"
        );
        let a = full.solve(&settings);
        let b = red.solve(&settings);
        assert!(a.converged() && b.converged(), "{hz} Hz");
        let scale = a
            .amplitudes
            .iter()
            .flatten()
            .map(|z| z.norm())
            .fold(0.0, f64::max);
        let diff = a
            .amplitudes
            .iter()
            .flatten()
            .zip(b.amplitudes.iter().flatten())
            .map(|(x, y)| (x - y).norm())
            .fold(0.0, f64::max);
        assert!(
            diff <= 1e-10 * scale,
            "{hz} Hz: state differs by {diff:e} of {scale:e}"
        );
        assert!(b.amplitudes[1]
            .iter()
            .chain(&b.amplitudes[3])
            .all(|z| z.norm() == 0.0));
        let sa = full.stability(&a).expect("full stability");
        let sb = red.stability(&b).expect("reduced stability");
        assert_eq!(sa.stable, sb.stable, "{hz} Hz: {sa:?} vs {sb:?}");
        let tol = 1e-6 * sa.growth_rate.abs().max(1.0);
        assert!(
            (sa.growth_rate - sb.growth_rate).abs() <= tol,
            "{hz} Hz: growth {} vs {}",
            sa.growth_rate,
            sb.growth_rate
        );
        assert_eq!(sa.linear_decay_rate, sb.linear_decay_rate);
        // The verdict without the spectra of the blocks a norm bound proves decaying is the
        // same, with the same rates when unstable.
        match red.unstable(&b).expect("quick verdict") {
            None => assert!(sb.stable, "{hz} Hz"),
            Some(v) => assert_eq!((v.stable, v.growth_rate), (false, sb.growth_rate)),
        }
        if !sb.stable {
            unstable += 1;
            // The active modes alone are stable there: the idle block (q2 pumped
            // parametrically) is what grows.
            let keep = [0, 2];
            let mut alone = HbSolver::with_lattice(
                &m.restricted(&keep).expect("restricted"),
                &d.restricted(&keep),
                b.lattice_hz.clone(),
            )
            .expect("active alone");
            let st = alone.solve(&settings);
            if alone.stability(&st).expect("active stability").stable {
                idle_only += 1;
            }
        }
    }
    assert!(
        unstable > 0 && idle_only > 0,
        "{unstable} unstable, {idle_only} through q2 alone"
    );
}

#[test]
fn reduced_sensitivities_are_the_whole_models() {
    let m = model();
    let settings = HbSettings::default();
    let d = drive(1001.0);
    let mut full = HbSolver::new(&m, &d, &settings.lattice).expect("full");
    let mut red = ReducedSolver::new(&m, &d, &settings.lattice, &[]).expect("reduced");
    let a = full.solve(&settings);
    let b = red.solve(&settings);
    assert!(a.converged() && b.converged());
    let mut params: Vec<SensParam> = (0..4)
        .flat_map(|n| [SensParam::OmegaSq(n), SensParam::Gamma(n)])
        .chain((0..7).map(SensParam::Param))
        .collect();
    for quad in 0..2 {
        params.push(SensParam::Force {
            tone: 0,
            mode: 0,
            quad,
        });
    }
    let shape = vec![1.0, 0.5, 0.3, 0.2];
    let obs: Vec<Observation> = [0.0, 1001.0, 2002.0, 3003.0]
        .iter()
        .filter(|&&f| a.index(f).is_some())
        .map(|&f_hz| Observation {
            f_hz,
            shape: shape.clone(),
        })
        .collect();
    assert!(obs.len() >= 3, "the lattice holds 0, f, 2f");
    let no = obs.len();
    let mut sf = Sensitivity::new(&full, &d.tones_hz, &params, &obs).expect("full set-up");
    let mut sr = ReducedSensitivity::new(&red, &d.tones_hz, &params, &obs).expect("set-up");
    let mut of = vec![Complex64::new(0.0, 0.0); params.len() * no];
    let mut or = of.clone();
    sf.compute(&mut full, &a, &mut of).expect("full");
    sr.compute(&mut red, &b, &mut or).expect("reduced");
    for (k, p) in params.iter().enumerate() {
        let (x, y) = (&of[k * no..(k + 1) * no], &or[k * no..(k + 1) * no]);
        let scale = x.iter().map(|z| z.norm()).fold(0.0, f64::max);
        let diff = x
            .iter()
            .zip(y)
            .map(|(u, v)| (u - v).norm())
            .fold(0.0, f64::max);
        assert!(
            diff <= 1e-10 * scale.max(f64::MIN_POSITIVE),
            "{p:?}: {diff:e} of {scale:e}"
        );
    }
    // The idle modes' own quantities move nothing.
    for p in [SensParam::OmegaSq(1), SensParam::Gamma(3)] {
        let k = params.iter().position(|q| *q == p).expect("asked");
        assert!(
            of[k * no..(k + 1) * no].iter().all(|z| z.norm() == 0.0),
            "{p:?}"
        );
    }
    // A force on an idle mode is refused, not silently zero.
    let idle_force = [SensParam::Force {
        tone: 0,
        mode: 1,
        quad: 0,
    }];
    let e = ReducedSensitivity::new(&red, &d.tones_hz, &idle_force, &obs).expect_err("idle");
    assert!(matches!(e, SimError::IdleForce { mode: 1 }), "{e}");
}
