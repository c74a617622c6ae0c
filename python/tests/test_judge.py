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


def test_discover_with_error_floor_selects_by_the_held_out_prediction(cli, tmp_path):
    ex = "examples/nanostring_2mode/"
    rounds = []
    for seed in ("1", "2"):
        out = tmp_path / f"round{seed}"
        cli("simulate", MODEL_2, "--values", ex + "values.toml", "--plan", ex + "plan.toml",
            "--seed", seed, "--out", out)
        rounds.append(out)
    pooled = tmp_path / "pooled"
    cli("merge", *rounds, "--out", pooled)
    start = tmp_path / "bare.hb"
    start.write_text(NO_COUPLING)
    held = "round2_couple_q1_q2"
    want = load_json(cli("discover", pooled, start, "--degrees", "3", "--potential", "--json",
                         "--error-floor", "--holdout", held, "--out", tmp_path / "sel.hb"))
    ds = harmonid.Dataset.from_folder(pooled)
    found = harmonid.discover(harmonid.Model.from_file(start), ds, [3], potential=True,
                              error_floor=True, holdout=[held])
    for key in ("candidates", "steps", "fits", "selected_by", "held_out", "holdout_relative_rms"):
        assert_close(found[key], want[key], path=key)
    assert found["selected_by"] == "holdout"
    added = [s["term"] for s in found["steps"] if s["action"] == "added"]
    assert added == ["potential q1^2*q2^2"], found["steps"]
    step = found["steps"][0]
    assert step["holdout_rms_after"] < 0.95 * step["holdout_rms_before"], step
    assert "delta_chi2" not in step
    try:
        harmonid.discover(harmonid.Model.from_file(start), ds, [3], error_floor=True)
    except harmonid.HarmonidError as e:
        assert "--holdout" in str(e), str(e)
    else:
        raise AssertionError("a floor without holdout was accepted")


def test_compare_and_discover_take_a_background(cli, tmp_path):
    bare = tmp_path / "bare.hb"
    bare.write_text(NO_COUPLING)
    want = load_json(cli("compare", DATA_2, MODEL_2, bare, "--json", "--background", "constant"))
    ds = harmonid.Dataset.from_folder(DATA_2)
    models = {MODEL_2: harmonid.Model.from_file(MODEL_2), str(bare): harmonid.Model.from_file(bare)}
    got = harmonid.compare(ds, models, background="constant")
    assert_close(got, want)
    plain = harmonid.compare(ds, models)
    # Two complex offsets (one per mode): four more unknowns in every model.
    assert [m["unknowns"] for m in got["models"]] == [m["unknowns"] + 4 for m in plain["models"]]
    found = harmonid.discover(harmonid.Model.from_file(MODEL_2), ds, [3], potential=True,
                              background="constant")
    assert set(found["result"].background) == {"q1", "q2"}, found["result"].background
    try:
        harmonid.compare(ds, models, background="feedthrough")
    except harmonid.HarmonidError as e:
        assert "background" in str(e), str(e)
    else:
        raise AssertionError("an unknown background word was accepted")


NONSMOOTH_PLAN = """
description = "one-tone drive ladders across the resonance of examples/nonsmooth"
displacement_unit = "m"
[[point]]
name = "p0"
shape = { q1 = 1.0 }
[noise]
sigma_per_quadrature = 2e-9
shots = 5
""" + "".join(
    f"""
[[measurement]]
name = "f{f}"
drives_hz = [{f}.0]
force = {{ q1 = [1.97] }}
drive_levels_v = [1.0]
drive_phases_rad = [0.0]
levels = [0.3, 1.0]
"""
    for f in (9984, 9990, 9995, 10002)
)

DUFFING_DRAG = """
mode q1 at 10 kHz
param beta1, drag1
potential: beta1/4*q1^4
eom q1 += drag1*abs(d(q1))*d(q1)
"""


def test_discover_nonsmooth_equals_cli(cli, tmp_path):
    # examples/nonsmooth (|q|q softening, |q'|q' drag, Duffing) driven at four frequencies, two
    # levels each; from Duffing + drag the family alone (no degrees) offers abs(q1)*q1 and
    # sign(d(q1)), and abs(q1)*q1 is added (about 2.5 s each way).
    plan = tmp_path / "plan.toml"
    plan.write_text(NONSMOOTH_PLAN)
    data = tmp_path / "data"
    cli("simulate", "examples/nonsmooth/model.hb", "--values", "examples/nonsmooth/values.toml",
        "--plan", plan, "--seed", "1", "--out", data)
    start = tmp_path / "start.hb"
    start.write_text(DUFFING_DRAG)
    want = load_json(cli("discover", data, start, "--nonsmooth", "--gain-per-mode", "--json",
                         "--out", tmp_path / "sel.hb"))
    ds = harmonid.Dataset.from_folder(data)
    found = harmonid.discover(harmonid.Model.from_file(start), ds, [], nonsmooth=True,
                              force_model="gain_per_mode")
    for key in ("candidates", "steps", "fits", "selected_by"):
        assert_close(found[key], want[key], path=key)
    assert found["candidates"] == 2
    added = [s["term"] for s in found["steps"] if s["action"] == "added"]
    assert added == ["abs(q1)*q1 in the equation of q1"], found["steps"]
    assert "abs(q1)*q1" in found["source"]
    kappa = found["result"].parameters["b1_absq"]
    assert abs(kappa["value"] / -9.3e12 - 1) < 0.1, kappa
    try:
        harmonid.discover(harmonid.Model.from_file(start), ds, [])
    except harmonid.HarmonidError as e:
        assert "nonsmooth" in str(e), str(e)
    else:
        raise AssertionError("an empty library was accepted")
