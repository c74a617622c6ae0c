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
