"""plan and evaluate_plan: the plan file, the bounds and the table equal `harmonid plan`'s.

Design is compared on a one-mode Duffing resonator (0.2 s) and on the two-mode nanostring (about
0.1 s each side); the two-mode model's shipped plan is scored (`--evaluate`, 0.1 s)."""

import pytest
from conftest import MODEL_2, assert_close, load_json

import harmonid

VALUES_2 = "examples/nanostring_2mode/values.toml"
PLAN_2 = "examples/nanostring_2mode/plan.toml"
DUFFING = "mode q1 at 207.582 kHz\nparam beta1\npotential: beta1/4*q1^4\n"
DUFFING_VALUES = {"modes": {"q1": {"f_hz": 207582.0, "Q": 116232.0}}, "parameters": {"beta1": 2.68e22}}
DUFFING_VALUES_TOML = '[modes.q1]\nf_hz = 207582.0\nQ = 116232.0\n[parameters]\nbeta1 = 2.68e22\n'


def test_evaluate_equals_cli(cli, tmp_path):
    printed = cli("plan", MODEL_2, "--values", VALUES_2, "--noise", "0.05nm", "--shots", "20",
                  "--evaluate", PLAN_2, "--bounds", tmp_path / "bounds.json")
    want = load_json((tmp_path / "bounds.json").read_text())
    model = harmonid.Model.from_file(MODEL_2)
    r = harmonid.evaluate_plan(model, VALUES_2, PLAN_2, 0.05e-9, 20)
    assert_close(r.bounds, want)
    assert r.table() == printed
    assert r.shots == 20 and r.findings == []
    assert set(r.quantities) == {"f_hz:q1", "Q:q1", "f_hz:q2", "Q:q2", "beta1", "beta2", "g12"}
    for name, q in r.quantities.items():
        what, _, mode = name.partition(":")
        rel = want["modes"][mode][what] if mode else want["parameters"][name]
        assert_close(q["rel"], rel, path=name)
        assert abs(q["std"] / abs(q["value"]) - rel) <= 1e-12 * rel
    # The worked example of docs/planning.md: β2 is the worst bound, 0.224.
    assert round(r.bounds["parameters"]["beta2"], 3) == 0.224
    # The plan as a dict scores the same.
    assert_close(harmonid.evaluate_plan(model, VALUES_2, r.plan, 0.05e-9, 20).bounds, want)


@pytest.mark.parametrize("points, flags", [(None, []), ([{"q1": 0.309}], ["--point", "q1=0.309"])])
def test_design_equals_cli(cli, tmp_path, points, flags):
    (tmp_path / "duffing.hb").write_text(DUFFING)
    (tmp_path / "values.toml").write_text(DUFFING_VALUES_TOML)
    # The plan names the model file as given: the same path on both sides.
    model_path = str(tmp_path / "duffing.hb")
    printed = cli("plan", model_path, "--values", tmp_path / "values.toml", "--noise", "5e-11",
                  "--shots", "20", "--out", tmp_path / "plan.toml",
                  "--bounds", tmp_path / "bounds.json", *flags)
    model = harmonid.Model.from_file(model_path)
    r = harmonid.plan(model, DUFFING_VALUES, 5e-11, 20, points=points)
    assert r.toml == (tmp_path / "plan.toml").read_text()
    assert_close(r.bounds, load_json((tmp_path / "bounds.json").read_text()))
    assert r.table() == printed
    assert len(r.plan["measurement"]) == 1
    assert "PlanResult(1 measurements" in repr(r)
    # The designed plan scores as designed (over the same devices of the guess's range; only
    # the design says how it checked them), and simulates (a PlanResult is a plan).
    scored = harmonid.evaluate_plan(model, DUFFING_VALUES, r, 5e-11, 20).bounds
    assert scored["over_range"].pop("checked") is None
    designed = r.bounds
    assert "stepped across its range" in designed["over_range"].pop("checked")
    assert_close(scored, designed)
    # Over a range the measurement is a drive ladder: half, three quarters and all of it.
    assert r.plan["measurement"][0]["levels"] == [0.5, 0.75, 1.0]
    data = harmonid.simulate(model, DUFFING_VALUES, r, noise=False)
    assert data.measurements == ["single_q1[0]", "single_q1[1]", "single_q1[2]"]
    single = harmonid.plan(model, DUFFING_VALUES, 5e-11, 20, points=points, ladder=[1.0])
    assert "levels" not in single.plan["measurement"][0]


def test_design_two_mode_equals_cli(cli, tmp_path):
    """The two-mode nanostring at 0.05 nm, 20 shots, at most three measurements, designed at
    the guess alone (the guess is the device)."""
    printed = cli("plan", MODEL_2, "--values", VALUES_2, "--noise", "0.05nm", "--shots", "20",
                  "--max-measurements", "3", "--out", tmp_path / "plan.toml",
                  "--bounds", tmp_path / "bounds.json", "--nominal")
    r = harmonid.plan(harmonid.Model.from_file(MODEL_2), VALUES_2, 0.05e-9, 20, max_measurements=3,
                      nominal=True)
    assert r.toml == (tmp_path / "plan.toml").read_text()
    assert_close(r.bounds, load_json((tmp_path / "bounds.json").read_text()))
    assert r.table() == printed
    assert len(r.plan["measurement"]) == 3
    # At least twice better in the worst bound than the paper's recipe (β2: 0.224).
    assert max(r.bounds["parameters"].values()) < 0.224 / 2


def test_design_limits_equal_cli(cli, tmp_path):
    """A force limit too low for the nonlinearity: the CLI and Python agree on the poor bounds."""
    (tmp_path / "duffing.hb").write_text(DUFFING)
    (tmp_path / "values.toml").write_text(DUFFING_VALUES_TOML)
    model_path = str(tmp_path / "duffing.hb")
    cli("plan", model_path, "--values", tmp_path / "values.toml", "--noise", "5e-11",
        "--shots", "20", "--out", tmp_path / "plan.toml", "--bounds", tmp_path / "b.json",
        "--max-force", "1e-3", "--bandwidth", "0.25", "--max-frequencies", "8")
    r = harmonid.plan(harmonid.Model.from_file(model_path), tmp_path / "values.toml", 5e-11, 20,
                      max_force=1e-3, bandwidth_hz=0.25, max_frequencies=8)
    assert r.toml == (tmp_path / "plan.toml").read_text()
    assert_close(r.bounds, load_json((tmp_path / "b.json").read_text()))
    assert r.bounds["parameters"]["beta1"] > 1.0


def test_errors_are_located(tmp_path):
    model = harmonid.Model.from_file(MODEL_2)
    with pytest.raises(harmonid.PlanError, match=r"3 measurements are needed .*max-measurements is 1"):
        harmonid.plan(model, VALUES_2, 5e-11, 20, max_measurements=1)
    with pytest.raises(harmonid.PlanError, match="positive per-quadrature"):
        harmonid.evaluate_plan(model, VALUES_2, PLAN_2, -1.0)
    with pytest.raises(harmonid.PlanError, match="shots must be at least 1"):
        harmonid.plan(model, VALUES_2, 5e-11, 0)
    bad = tmp_path / "plan.toml"
    bad.write_text('[[measurement]]\nname = "x"\ndrives_hz = [1.0]\nforce = { q1 = [1.0] }\nforse = 1\n')
    with pytest.raises(harmonid.PlanError, match=r"plan.toml:5"):
        harmonid.evaluate_plan(model, VALUES_2, bad, 5e-11)
    with pytest.raises(harmonid.SimulationError, match="nope.toml"):
        harmonid.evaluate_plan(model, "nope.toml", PLAN_2, 5e-11)
    with pytest.raises(TypeError):
        harmonid.evaluate_plan(model, VALUES_2, 3.0, 5e-11)


def test_truth_file_is_a_guess():
    """A truth.toml gives [eom] coefficients only: the parameters are solved from them, and the
    score equals the values file's with the same parameters (as `harmonid plan --values`)."""
    model = harmonid.Model.from_file(MODEL_2)
    truth = "tests/data/nanostring_ls50_2mode/truth.toml"
    from_truth = harmonid.evaluate_plan(model, truth, PLAN_2, 0.05e-9, 20)
    from_values = harmonid.evaluate_plan(model, VALUES_2, PLAN_2, 0.05e-9, 20)
    assert from_truth.table() == from_values.table()


BEAM = "examples/import/beam.hb"
BEAM_VALUES_TOML = '[modes.q1]\nf_hz = 42.7909\nQ = 1450.0\n[parameters]\nbeta1 = -93.1\neta1 = 0.495\n'


def test_instrument_plan_equals_cli(cli, tmp_path):
    """plan(instrument="mfli-mf") writes the command line's plan, [instrument] included, and
    is held to the MFLI: the tones' summed volts within --max-voltage, a filter the MFLI has;
    the MFLI without MF-MD is refused, naming the option."""
    (tmp_path / "values.toml").write_text(BEAM_VALUES_TOML)
    cli("plan", BEAM, "--values", tmp_path / "values.toml", "--noise", "0.0418", "--shots", "10",
        "--grid-hz", "0.001", "--gain", "q1=447", "--max-voltage", "0.45", "--instrument",
        "mfli-mf", "--nominal", "--out", tmp_path / "plan.toml")
    model = harmonid.Model.from_file(BEAM)
    kw = dict(bandwidth_hz=0.001, gains={"q1": 447.0}, max_voltage=0.45, nominal=True)
    r = harmonid.plan(model, tmp_path / "values.toml", 0.0418, 10, instrument="mfli-mf", **kw)
    assert r.toml == (tmp_path / "plan.toml").read_text()
    inst = r.plan["instrument"]
    assert inst["profile"] == "mfli-mf" and inst["max_output_v"] == 0.45
    for level in inst["level"]:
        assert level["output_v"] == pytest.approx(sum(abs(v) for v in level["drives_v"]))
        assert level["output_v"] <= 0.45 + 1e-12
        assert 1 <= level["filter_order"] <= 8 and level["demodulators"] <= 4
    with pytest.raises(harmonid.PlanError, match="MF-MD"):
        harmonid.plan(model, tmp_path / "values.toml", 0.0418, 10, instrument="mfli", **kw)
    with pytest.raises(harmonid.PlanError, match="unknown instrument"):
        harmonid.plan(model, tmp_path / "values.toml", 0.0418, 10, instrument="sr830", **kw)
    with pytest.raises(harmonid.PlanError, match="max-voltage"):
        harmonid.plan(model, tmp_path / "values.toml", 0.0418, 10, instrument="mfli-mf",
                      **{**kw, "max_voltage": float("nan")})
