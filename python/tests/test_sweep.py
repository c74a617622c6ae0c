"""sweep: numpy arrays equal to `harmonid sweep` CSV output."""

import csv
import numpy as np
import pytest
from conftest import MODEL_2

import harmonid

VALUES = "examples/nanostring_2mode/values.toml"


def read_csv(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def test_single_tone_equals_cli(cli, tmp_path):
    out = tmp_path / "curve.csv"
    cli("sweep", MODEL_2, "--values", VALUES, "--from", "207540", "--to", "207700",
        "--force", "q1=3.5", "--points", "400", "--out", out)
    rows = read_csv(out)
    model = harmonid.Model.from_file(MODEL_2)
    r = harmonid.sweep(model, VALUES, 207540, 207700, {"q1": 3.5}, points=400)
    assert r["modes"] == ["q1", "q2"] and r["harmonics"] == [1, 3]
    assert r["amplitudes"].shape == (len(rows), 2, 2)
    # points is a resolution: consecutive points at most (to - from)/points apart in frequency
    # (the corrector may carry a step a few per cent further), so at least points + 1 of them.
    assert len(r["f_hz"]) > 400
    assert np.max(np.abs(np.diff(r["f_hz"]))) <= 1.25 * (207700 - 207540) / 400
    np.testing.assert_allclose(r["f_hz"], [float(x["f_hz"]) for x in rows], rtol=1e-12, atol=0)
    assert list(r["stable"]) == [x["stable"] == "1" for x in rows]
    for n, mode in enumerate(r["modes"]):
        for i, h in enumerate(r["harmonics"]):
            for part, f in (("re", np.real), ("im", np.imag)):
                want = [float(x[f"{mode}_h{h}_{part}"]) for x in rows]
                np.testing.assert_allclose(f(r["amplitudes"][:, n, i]), want, rtol=1e-12, atol=0)
    # This drive folds the Duffing curve: up and down sweeps jump at different frequencies.
    assert r["complete"] and len(r["folds_hz"]) == 2
    assert r["jumps_up_hz"][0] > r["jumps_down_hz"][0]
    # Values as a dict are the same values.
    values = {
        "modes": {"q1": {"f_hz": 207582.0, "Q": 116232.0}, "q2": {"f_hz": 415842.0, "Q": 599173.0}},
        "parameters": {"beta1": 2.68e22, "beta2": 3.70e23, "g12": 8.57e22},
    }
    same = harmonid.sweep(model, values, 207540, 207700, {"q1": 3.5}, points=400)
    np.testing.assert_array_equal(same["amplitudes"], r["amplitudes"])


def test_two_tone_equals_cli(cli, tmp_path):
    out = tmp_path / "two.csv"
    cli("sweep", MODEL_2, "--values", VALUES, "--from", "207560", "--to", "207620",
        "--force", "q1=3.5", "--two-tone", "20", "--points", "60", "--out", out)
    rows = read_csv(out)
    model = harmonid.Model.from_file(MODEL_2)
    r = harmonid.sweep(model, VALUES, 207560, 207620, {"q1": 3.5}, two_tone_spacing_hz=20,
                       points=60)
    assert r["lines_offset_hz"] == [-30.0, -10.0, 10.0, 30.0]
    # q1 is swept past: its four lines; q2 (cubic model, odd orders) has no line near 415 kHz.
    assert [off for _, _, off in r["mode_lines"]["q1"]] == [-30.0, -10.0, 10.0, 30.0]
    assert r["mode_lines"]["q2"] == []
    for direction in ("up", "down"):
        want = [x for x in rows if x["direction"] == direction]
        got = r[direction]
        np.testing.assert_allclose(got["centre_hz"], [float(x["centre_hz"]) for x in want],
                                   rtol=1e-12, atol=0)
        assert list(got["stable"]) == [x["stable"] == "1" for x in want]
        for mode in r["modes"]:
            labels = [lab for lab, _, _ in r["mode_lines"][mode]]
            assert got["amplitudes"][mode].shape == (len(want), len(labels))
            for i, lab in enumerate(labels):
                z = got["amplitudes"][mode][:, i]
                np.testing.assert_allclose(np.abs(z), [float(x[f"{mode}_{lab}_abs"]) for x in want],
                                           rtol=1e-12, atol=0)
                # The CSV prints phases to 1e-9 rad.
                ph = np.array([float(x[f"{mode}_{lab}_phase_rad"]) for x in want])
                big = np.abs(z) > 0
                np.testing.assert_allclose(np.angle(z)[big], ph[big], rtol=0, atol=6e-10)


def test_bad_values_and_forces_raise():
    model = harmonid.Model.from_file(MODEL_2)
    with pytest.raises(harmonid.SimulationError, match="beta1"):
        harmonid.sweep(model, {"modes": {"q1": {"f_hz": 1e5, "Q": 1e4},
                                         "q2": {"f_hz": 2e5, "Q": 1e4}}},
                       9e4, 1.1e5, {"q1": 1.0})
    with pytest.raises(harmonid.SimulationError, match="not a mode"):
        harmonid.sweep(model, VALUES, 207540, 207700, {"q7": 1.0})
    with pytest.raises(harmonid.SimulationError, match="cannot read the values file"):
        harmonid.sweep(model, "nope.toml", 207540, 207700, {"q1": 1.0})


def test_limit_cycles_equal_cli(cli, tmp_path):
    # The driven van der Pol–Duffing: a quasi-periodic branch from each Hopf point, as
    # `harmonid sweep --limit-cycles` writes them.
    model_path, values = "examples/vdp_duffing/model.hb", "examples/vdp_duffing/values.toml"
    out = tmp_path / "lc.csv"
    cli("sweep", model_path, "--values", values, "--from", "980", "--to", "1020",
        "--force", "q1=0.446", "--points", "400", "--limit-cycles", out)
    rows = read_csv(out)
    model = harmonid.Model.from_file(model_path)
    r = harmonid.sweep(model, values, 980, 1020, {"q1": 0.446}, points=400, limit_cycles=True)
    branches = r["limit_cycles"]
    assert len(branches) == len(r["hopf"]) == 2
    for h, b in enumerate(branches, start=1):
        assert "why" not in b, b.get("why")
        want = [x for x in rows if x["hopf"] == str(h)]
        assert len(b["f_hz"]) == len(want) > 0
        np.testing.assert_allclose(b["f2_hz"], [float(x["f2_hz"]) for x in want], rtol=1e-9)
        np.testing.assert_allclose(b["f2_abs"][:, 0], [float(x["q1_f2_abs"]) for x in want], rtol=1e-6)
        assert b["stable"] == [None if x["stable"] == "" else x["stable"] == "1" for x in want]
        # Where it ends, in the command line's words (not Rust's debug text).
        assert b["end"] in ("the end of the range", "the most points") or b["end"].startswith(
            ("another Hopf point near ", "no step converged after ")
        ), b["end"]
    # Without the option, no branches are computed.
    assert "limit_cycles" not in harmonid.sweep(model, values, 980, 1020, {"q1": 0.446}, points=400)
