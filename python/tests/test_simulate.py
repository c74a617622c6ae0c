"""simulate: the dataset equals the one `harmonid simulate` writes; values from results, plans
as dicts, located errors."""

import numpy as np
import pytest
from conftest import DATA_2, MODEL_2, assert_close, load_json

import harmonid

VALUES = "examples/nanostring_2mode/values.toml"
PLAN = "examples/nanostring_2mode/plan.toml"


def assert_same_dataset(got, want, rel=1e-12):
    assert got.measurements == want.measurements
    assert got.manifest == want.manifest
    assert_close(got.truth, want.truth)
    for name in want.measurements:
        a, b = got.measurement(name), want.measurement(name)
        np.testing.assert_array_equal(a["freqs_hz"], b["freqs_hz"])
        scale = np.abs(b["amplitudes"]).max()
        np.testing.assert_allclose(a["amplitudes"], b["amplitudes"], rtol=0, atol=rel * scale)


def test_simulate_equals_cli(cli, tmp_path):
    cli("simulate", MODEL_2, "--values", VALUES, "--plan", PLAN, "--out", tmp_path / "cli")
    want = harmonid.Dataset.from_folder(tmp_path / "cli")
    model = harmonid.Model.from_file(MODEL_2)
    got = harmonid.simulate(model, VALUES, PLAN)
    assert_same_dataset(got, want)
    # The shipped example data were made by the same command (by an earlier version of the
    # solver, converged to its tolerance: hence 1e-9): the round trip of the README.
    assert_same_dataset(got, harmonid.Dataset.from_folder(DATA_2), rel=1e-9)
    r = harmonid.identify(model, got).to_dict()
    cli("identify", MODEL_2, tmp_path / "cli", "--out", tmp_path / "r.json")
    want_r = load_json((tmp_path / "r.json").read_text())
    r["dataset"] = want_r["dataset"]
    assert_close(r, want_r)


def test_values_from_a_result_and_seeds(cli, tmp_path):
    model = harmonid.Model.from_file(MODEL_2)
    result = harmonid.identify(model, harmonid.Dataset.from_folder(DATA_2))
    (tmp_path / "result.json").write_text(result.to_json())
    cli("simulate", MODEL_2, "--values", tmp_path / "result.json", "--plan", PLAN,
        "--seed", "7", "--out", tmp_path / "cli")
    want = harmonid.Dataset.from_folder(tmp_path / "cli")
    assert_same_dataset(harmonid.simulate(model, result, PLAN, seed=7), want)
    assert_same_dataset(harmonid.simulate(model, tmp_path / "result.json", PLAN, seed=7), want)
    other = harmonid.simulate(model, result, PLAN, seed=8).measurement("single_q1")["amplitudes"]
    assert not np.array_equal(other, want.measurement("single_q1")["amplitudes"])


def test_plan_as_a_dict_and_clean_amplitudes():
    model = harmonid.Model.from_file(MODEL_2)
    plan = {
        "noise": {"sigma_per_quadrature": 5e-11, "shots": 3},
        "measurement": [
            {"name": "two", "drives_hz": [207572.5, 207592.5], "force": {"q1": [3.5, 3.5]}}
        ],
    }
    values = {
        "modes": {"q1": {"f_hz": 207582.0, "Q": 116232.0}, "q2": {"f_hz": 415842.0, "Q": 599173.0}},
        "parameters": {"beta1": 2.68e22, "beta2": 3.70e23, "g12": 8.57e22},
    }
    clean = harmonid.simulate(model, values, plan, noise=False).measurement("two")
    assert clean["amplitudes"].shape[0] == 3
    # Without noise every shot is the same steady state; the drive tones are measured.
    np.testing.assert_array_equal(clean["amplitudes"][0], clean["amplitudes"][2])
    assert {207572.5, 207592.5} <= set(clean["freqs_hz"])
    noisy = harmonid.simulate(model, values, plan).measurement("two")["amplitudes"]
    spread = np.std((noisy - clean["amplitudes"]).real)
    assert 1e-11 < spread < 2e-10


def test_time_domain_equals_cli(cli, tmp_path):
    """The time-domain engine with the command line's flags (a one-mode Duffing resonator, a
    short lock-in window and per-sample noise, so that each shot is its own run: 0.1 s)."""
    (tmp_path / "duffing.hb").write_text("mode q1 at 207.582 kHz\nparam beta1\npotential: beta1/4*q1^4\n")
    (tmp_path / "values.toml").write_text(
        "[modes.q1]\nf_hz = 207582.0\nQ = 116232.0\n[parameters]\nbeta1 = 2.68e22\n"
    )
    (tmp_path / "plan.toml").write_text(
        "[noise]\nsigma_per_quadrature = 5e-11\nshots = 2\n\n[[measurement]]\nname = \"two\"\n"
        "drives_hz = [207560.0, 207600.0]\nforce = { q1 = [1.0, 1.0] }\nbandwidth_hz = 40.0\n"
    )
    cli("simulate", tmp_path / "duffing.hb", "--values", tmp_path / "values.toml",
        "--plan", tmp_path / "plan.toml", "--time-domain", "--steps-per-period", "8",
        "--rtol", "1e-7", "--noise-rms-nm", "0.1", "--seed", "3", "--out", tmp_path / "cli")
    want = harmonid.Dataset.from_folder(tmp_path / "cli")
    model = harmonid.Model.from_file(tmp_path / "duffing.hb")
    td = {"steps_per_period": 8, "rtol": 1e-7, "noise_rms_nm": 0.1}
    got = harmonid.simulate(model, tmp_path / "values.toml", tmp_path / "plan.toml",
                            time_domain=td, seed=3)
    assert_same_dataset(got, want)
    hb = harmonid.simulate(model, tmp_path / "values.toml", tmp_path / "plan.toml", seed=3)
    assert not np.array_equal(hb.measurement("two")["amplitudes"], want.measurement("two")["amplitudes"])
    with pytest.raises(harmonid.SimulationError, match="unknown setting \"steps\""):
        harmonid.simulate(model, tmp_path / "values.toml", tmp_path / "plan.toml",
                          time_domain={"steps": 8})


def test_errors_are_located(tmp_path):
    model = harmonid.Model.from_file(MODEL_2)
    bad = tmp_path / "plan.toml"
    bad.write_text('[[measurement]]\nname = "x"\ndrives_hz = [1.0]\nforce = { q1 = [1.0] }\nforse = 1\n')
    with pytest.raises(harmonid.SimulationError, match="plan.toml"):
        harmonid.simulate(model, VALUES, bad)
    with pytest.raises(harmonid.SimulationError, match="values"):
        harmonid.simulate(model, {"parameters": {"beta1": "big"}}, PLAN)
    with pytest.raises(harmonid.SimulationError, match="nope.toml"):
        harmonid.simulate(model, "nope.toml", PLAN)


def test_a_pumped_plan_simulates_and_identifies_its_pump_coefficient():
    """Parametric pumping from Python: a plan dict with a pump, its coefficient identified."""
    model = harmonid.Model.from_str(
        "mode q1 at 1 kHz\nparam beta1, lambda\npotential: beta1/4*q1^4\n"
        "eom q1 += lambda*pump*q1\n"
    )
    values = {"modes": {"q1": {"f_hz": 1000.0, "Q": 1000.0}},
              "parameters": {"beta1": 1e12, "lambda": 1.0}}
    pump = {"pumps_hz": [2000.0], "pump_phases_rad": [0.0]}
    plan = {
        "noise": {"sigma_per_quadrature": 1e-10, "shots": 5},
        "point": [{"name": "p", "shape": {"q1": 1.0}}],
        "measurement": [
            {"name": name, "drives_hz": [1001.0], "force": {"q1": [10.0]},
             "drive_levels_v": [1.0], "drive_phases_rad": [0.0],
             "pump_levels": [level], **pump}
            for name, level in [("off", 0.0), ("on", 4e4)]
        ],
    }
    ds = harmonid.simulate(model, values, plan)
    assert ds.measurement("on")["pumps_hz"] == [2000.0]
    r = harmonid.identify(model, ds).to_dict()
    lam = r["parameters"]["lambda"]
    assert abs(lam["value"] - 1.0) < 4 * lam["stderr"] and lam["stderr"] < 1e-3
    assert "q1*pump" in r["eom"]["q1"]
