"""linear_response: the probe response about a steady state (harmonid response), as numpy arrays
equal to the command line's CSV; about rest, the Lorentzians; the sweep's Hopf points."""

import csv
import math

import numpy as np

import harmonid

DUFFING = "mode q1 at 1 kHz\nparam alpha\npotential: alpha/4*q1^4\n"
VALUES = {"modes": {"q1": {"f_hz": 1000.0, "Q": 1000.0}}, "parameters": {"alpha": 4e15}}
VALUES_TOML = "[modes.q1]\nf_hz = 1000.0\nQ = 1000.0\n[parameters]\nalpha = 4e15\n"


def test_at_rest_it_is_the_lorentzian(tmp_path):
    (tmp_path / "m.hb").write_text(DUFFING)
    model = harmonid.Model.from_file(str(tmp_path / "m.hb"))
    f = np.linspace(990.0, 1010.0, 41)
    r = harmonid.linear_response(model, VALUES, "q1", f, probe_force=2.0, noise_psd=1e-6)
    assert r["amplitudes"].shape == (41, 1, 1) and r["idler_offset_hz"] is None
    w, o = 2 * math.pi * 1000.0, 2 * math.pi * f
    lorentz = 2.0 / (w * w - o * o + 1j * o * w / 1000.0)
    np.testing.assert_allclose(r["amplitudes"][:, 0, 0], lorentz, rtol=1e-9, atol=0)
    np.testing.assert_allclose(r["noise_psd"][:, 0], 1e-6 * np.abs(lorentz / 2.0) ** 2, rtol=1e-9)


def test_driven_equals_cli(cli, tmp_path):
    (tmp_path / "m.hb").write_text(DUFFING)
    (tmp_path / "v.toml").write_text(VALUES_TOML)
    out = tmp_path / "r.csv"
    cli("response", tmp_path / "m.hb", "--values", tmp_path / "v.toml", "--drives", "q1:1008",
        "--force", "q1=3", "--probe", "q1", "--from", "1000", "--to", "1004", "--points", "9",
        "--noise-psd", "1e-6", "--out", out)
    with open(out) as fh:
        rows = list(csv.DictReader(fh))
    model = harmonid.Model.from_file(str(tmp_path / "m.hb"))
    f = [float(x["f_probe_hz"]) for x in rows]
    r = harmonid.linear_response(model, VALUES, "q1", f, drives={"q1": [1008.0]},
                                 force={"q1": 3.0}, noise_psd=1e-6)
    assert r["stable"] is True and r["idler_offset_hz"] == -2016.0
    j = list(r["offsets_hz"]).index(-2016.0)
    np.testing.assert_allclose(np.abs(r["amplitudes"][:, 0, 0]),
                               [float(x["q1_signal_abs_m"]) for x in rows], rtol=1e-12)
    np.testing.assert_allclose(np.abs(r["amplitudes"][:, 0, j]),
                               [float(x["q1_idler_abs_m"]) for x in rows], rtol=1e-12)
    # The idler is conjugated onto its physical frequency 2 f_d - f_p.
    np.testing.assert_allclose(-np.angle(r["amplitudes"][:, 0, j]),
                               [float(x["q1_idler_phase_rad"]) for x in rows], atol=1e-8)
    np.testing.assert_allclose(r["noise_psd"][:, 0],
                               [float(x["q1_noise_psd_m2_per_hz"]) for x in rows], rtol=1e-12)


def test_sweep_reports_hopf_points(tmp_path):
    (tmp_path / "vdp.hb").write_text(
        "mode q1 at 1 kHz\nparam mu, alpha, eta\npotential: alpha/4*q1^4\n"
        "eom q1 += mu*d(q1) + eta*q1^2*d(q1)\n")
    model = harmonid.Model.from_file(str(tmp_path / "vdp.hb"))
    values = {"modes": {"q1": {"f_hz": 1000.0, "Q": 1e4}},
              "parameters": {"mu": -1.2566370614359172, "alpha": 1.0527578027828646e16,
                             "eta": 1.2566370614359172e12}}
    r = harmonid.sweep(model, values, 998.0, 1002.0, {"q1": 0.02368705}, points=400)
    # The closed form of the averaged equations (crates/sim/tests/it/hopf.rs).
    assert [round(h[0], 3) for h in r["hopf"]] == [999.801, 1000.399]
    assert [h[2] for h in r["hopf"]] == [True, False]
