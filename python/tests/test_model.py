"""Model: from_file / from_str, modes, parameters, equations, against `harmonid check`."""

import pytest
from conftest import MODEL_2, MODEL_5, REPO, assert_close, load_json

import harmonid

EXAMPLES = ["nanostring_2mode", "nanostring_5mode", "three_wave", "cubic_3mode"]


@pytest.mark.parametrize("name", EXAMPLES)
def test_every_example_matches_check(cli, name):
    path = f"examples/{name}/model.hb"
    m = harmonid.Model.from_file(path)
    want = load_json(cli("check", path, "--json"))
    assert_close(m.to_dict(), want)
    assert m.equations() == want["eom"]
    assert m.parameters == want["parameters"]
    assert list(m.modes) == [x["name"] for x in want["modes"]]
    for x in want["modes"]:
        assert m.modes[x["name"]] == {k: v for k, v in x.items() if k != "name"}
    assert m.identifiable == want["identifiable"]
    assert m.equations("latex") == cli("check", path, "--latex")
    assert m.equations("text") == cli("check", path)
    assert m.source == path


def test_two_mode_equations_read_as_the_paper():
    m = harmonid.Model.from_file(MODEL_2)
    eq = m.equations()
    assert eq["q1"] == {"q1^3": {"beta1": 1.0}, "q1*q2^2": {"g12": 1.0}}
    assert eq["q2"] == {"q1^2*q2": {"g12": 1.0}, "q2^3": {"beta2": 1.0}}
    assert m.modes["q1"]["nominal_hz"] == 207580.0
    assert m.parameters["g12"]["kind"] == "unknown"
    assert "beta_{1}" in m.equations("latex") or "beta" in m.equations("latex")


def test_from_str_equals_from_file():
    text = (REPO / MODEL_5).read_text()
    a = harmonid.Model.from_str(text, MODEL_5)
    b = harmonid.Model.from_file(MODEL_5)
    assert a.to_dict() == b.to_dict()
    assert harmonid.Model.from_str("mode q1\n").source == "<string>"


def test_errors_are_located_exceptions(tmp_path):
    with pytest.raises(harmonid.ModelError) as e:
        harmonid.Model.from_str("mode q1\neom q2 += q1^3\n", "bad.hb")
    text = str(e.value)
    assert "bad.hb:2:5" in text and "not a declared mode" in text
    assert isinstance(e.value, harmonid.HarmonidError) and isinstance(e.value, ValueError)
    with pytest.raises(harmonid.ModelError, match="cannot read"):
        harmonid.Model.from_file(tmp_path / "missing.hb")
    with pytest.raises(ValueError, match="expected"):
        harmonid.Model.from_file(MODEL_2).equations("html")
