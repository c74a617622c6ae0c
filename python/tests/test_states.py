"""states: every steady state, the same as `harmonid states --json`."""

import json

import numpy as np
from conftest import REPO

import harmonid

MODEL = "examples/parametron/model.hb"
VALUES = "examples/parametron/values.toml"


def test_parametron_states_equal_the_command_line(cli):
    want = json.loads(cli("states", MODEL, "--values", VALUES, "--pump", "2000:2e5", "--json"))
    model = harmonid.Model.from_file(REPO / MODEL)
    got = harmonid.states(model, REPO / VALUES, pumps=[(2000.0, 2e5)])
    assert got["paths"] == want["paths"]
    assert [s["stable"] for s in got["states"]] == [s["stable"] for s in want["states"]]
    assert [s["stable"] for s in got["states"]] == [False, True, True]
    # The rest state inside the tongue is a saddle (a real eigenvalue), not oscillatory.
    assert [s["oscillatory"] for s in got["states"]] == [s["oscillatory"] for s in want["states"]]
    assert [s["oscillatory"] for s in got["states"]] == [False, False, False]
    for g, w in zip(got["states"], want["states"]):
        x = g["amplitudes"][0]
        assert abs(x - complex(w["amplitudes"]["q1"]["re"], w["amplitudes"]["q1"]["im"])) <= 1e-9 * max(abs(x), 1e-30)
        assert g["lattice"]["continued"] == w["lattice"]["continued"]
    # The two phase states: equal amplitude, opposite phase.
    a, b = got["states"][1]["amplitudes"][0], got["states"][2]["amplitudes"][0]
    assert np.isclose(a, -b, rtol=1e-9)


def test_no_excitation_is_refused():
    model = harmonid.Model.from_file(REPO / MODEL)
    try:
        harmonid.states(model, REPO / VALUES)
    except harmonid.SimulationError as e:
        assert "no excitation" in str(e)
    else:
        raise AssertionError("states without drive or pump was accepted")


def test_phase_diagram_equals_the_command_line_map(cli, tmp_path):
    out = tmp_path / "map.csv"
    cli("phase-diagram", MODEL, "--values", VALUES, "--pump", "2000:1e5",
        "--x", "pump_hz:1990:2010:21", "--y", "pump_level:1e3:4e5:11", "--out", out)
    want = np.loadtxt(out, delimiter=",", skiprows=1)
    model = harmonid.Model.from_file(REPO / MODEL)
    got = harmonid.phase_diagram(model, REPO / VALUES, ("pump_hz", 1990, 2010, 21),
                                 ("pump_level", 1e3, 4e5, 11), pumps=[(2000.0, 1e5)])
    assert got["stable"].shape == (11, 21)
    assert got["complete"]
    # map.csv rows run over x within y: x, y, stable, unstable, oscillatory.
    assert np.array_equal(got["stable"].ravel(), want[:, 2].astype(int))
    assert np.array_equal(got["unstable"].ravel(), want[:, 3].astype(int))
    assert np.array_equal(got["oscillatory"].ravel(), want[:, 4].astype(int))
    assert np.allclose(np.repeat(got["y"], 21), want[:, 1])
    # Inside the tongue at the top level: two stable phase states and the unstable rest state.
    assert got["stable"][-1, 10] == 2 and got["unstable"][-1, 10] == 1
