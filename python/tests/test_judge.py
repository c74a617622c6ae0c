"""compare and discover: the same answers as `harmonid compare` and `harmonid discover`."""

from conftest import DATA_2, MODEL_2, assert_close, load_json

import harmonid

NO_COUPLING = """
mode q1 at 207.58 kHz
mode q2 at 415.84 kHz
param beta1, beta2
potential: beta1/4*q1^4 + beta2/4*q2^4
"""


def test_compare_equals_cli(cli, tmp_path):
    bare = tmp_path / "bare.hb"
    bare.write_text(NO_COUPLING)
    want = load_json(cli("compare", DATA_2, MODEL_2, bare, "--json"))
    ds = harmonid.Dataset.from_folder(DATA_2)
    got = harmonid.compare(
        ds,
        {MODEL_2: harmonid.Model.from_file(MODEL_2), str(bare): harmonid.Model.from_file(bare)},
    )
    assert_close(got, want)
    assert got["models"][got["best"]]["model"] == MODEL_2


PER_EQUATION = """
mode q1 at 207.58 kHz
mode q2 at 415.84 kHz
param beta1, beta2, g1, g2
potential: beta1/4*q1^4 + beta2/4*q2^4
eom q1 += g1*q1*q2^2
eom q2 += g2*q1^2*q2
"""


def test_compare_with_error_floor_ranks_by_the_held_out_prediction(cli, tmp_path):
    bare = tmp_path / "per_equation.hb"
    bare.write_text(PER_EQUATION)
    ex = "examples/nanostring_2mode/"
    rounds = []
    for seed in ("1", "2"):
        out = tmp_path / f"round{seed}"
        cli("simulate", MODEL_2, "--values", ex + "values.toml", "--plan", ex + "plan.toml",
            "--seed", seed, "--out", out)
        rounds.append(out)
    pooled = tmp_path / "pooled"
    cli("merge", *rounds, "--out", pooled)
    held = "round2_couple_q1_q2"
    want = load_json(cli("compare", pooled, MODEL_2, bare, "--json", "--error-floor", "--holdout", held))
    ds = harmonid.Dataset.from_folder(pooled)
    models = {MODEL_2: harmonid.Model.from_file(MODEL_2), str(bare): harmonid.Model.from_file(bare)}
    got = harmonid.compare(ds, models, holdout=[held], error_floor=True)
    assert_close(got, want)
    assert got["ranked_by"] == "holdout"
    assert all(m["holdout_relative_rms"] < 0.05 for m in got["models"]), got["models"]
    try:
        harmonid.compare(ds, models, error_floor=True)
    except harmonid.HarmonidError as e:
        assert "holdout" in str(e), str(e)
    else:
        raise AssertionError("a floor without holdout was accepted")


def test_discover_finds_the_coupling_back():
    ds = harmonid.Dataset.from_folder(DATA_2)
    start = harmonid.Model.from_str(NO_COUPLING, "bare.hb")
    found = harmonid.discover(start, ds, [3], potential=True)
    added = [s["term"] for s in found["steps"] if s["action"] == "added"]
    assert added == ["potential q1^2*q2^2"], found["steps"]
    assert isinstance(found["model"], harmonid.Model)
    assert "u_22" in found["result"].parameters
    assert found["source"].splitlines()[0].startswith("# Selected by harmonid discover")
    # The written model reads back.
    back = harmonid.Model.from_str(found["source"], "selected.hb")
    assert list(back.parameters) == list(found["model"].parameters)
