"""identify: the result equals `harmonid identify --out`, per shot equals `--per-shot`."""

import csv
import subprocess
import sys
import threading

import numpy as np
import pytest
from conftest import DATA_2, MODEL_2, REPO, assert_close, load_json
from test_dataset import rebuild

import harmonid

OPTIONS = [
    ({}, []),
    ({"joint": True}, ["--joint"]),
    ({"force_model": "free"}, ["--free-forces"]),
    ({"force_model": "gain_per_mode"}, ["--gain-per-mode"]),
    ({"unweighted": True, "near_rel": 0.01}, ["--unweighted", "--near-rel", "0.01"]),
    ({"nominal_hz": {"q1": 207590.0}}, ["--nominal", "q1=207590"]),
    ({"estimator": "linear"}, ["--estimator", "linear"]),
    ({"crlb": True}, ["--crlb"]),
    ({"estimator": "linear", "crlb": True}, ["--estimator", "linear", "--crlb"]),
    ({"holdout": ["single_q1"]}, ["--holdout", "single_q1"]),
    ({"error_floor": True}, ["--error-floor"]),
    ({"background": "constant"}, ["--background", "constant"]),
]


def cli_identify(cli, tmp_path, model, data, flags):
    out, shots = tmp_path / "result.json", tmp_path / "shots.csv"
    text = cli("identify", model, data, "--out", out, "--per-shot", shots, *flags)
    with open(shots) as f:
        rows = list(csv.DictReader(f))
    return load_json(out.read_text()), rows, text


@pytest.mark.parametrize("options, flags", OPTIONS)
def test_result_equals_cli(cli, tmp_path, options, flags):
    want, rows, printed = cli_identify(cli, tmp_path, MODEL_2, DATA_2, flags)
    r = harmonid.identify(
        harmonid.Model.from_file(MODEL_2), harmonid.Dataset.from_folder(DATA_2), **options
    )
    assert_close(r.to_dict(), want)
    assert_close(load_json(r.to_json()), want)
    assert_close(r.parameters, want["parameters"])
    assert_close(r.modes, want["modes"])
    assert_close(r.eom, want["eom"])
    assert r.warnings == want["warnings"]
    assert r.summary() in printed
    per_shot = r.per_shot
    assert set(per_shot) == set(rows[0]) - {"shot"}
    for col, arr in per_shot.items():
        assert isinstance(arr, np.ndarray) and arr.shape == (len(rows),)
        want_col = [float(row[col]) for row in rows]
        if col == "outlier":
            assert list(arr) == [bool(int(v)) for v in want_col]
        else:
            assert_close(list(arr), want_col, path=col)


def test_crlb_is_what_the_result_reports():
    r = harmonid.identify(
        harmonid.Model.from_file(MODEL_2), harmonid.Dataset.from_folder(DATA_2)
    )
    d = r.to_dict()
    want = {p: e["crlb"] for p, e in d["parameters"].items() if "crlb" in e}
    for n, m in d["modes"].items():
        want.update({f"{k}:{n}": m[k]["crlb"] for k in ("f_hz", "Q") if "crlb" in m[k]})
    assert r.crlb == (want or None)


@pytest.mark.parametrize("estimator", ["ml", "linear"])
def test_crlb_option_equals_cli(cli, tmp_path, estimator):
    want, _, printed = cli_identify(
        cli, tmp_path, MODEL_2, DATA_2, ["--estimator", estimator, "--crlb"]
    )
    r = harmonid.identify(
        harmonid.Model.from_file(MODEL_2), harmonid.Dataset.from_folder(DATA_2),
        estimator=estimator, crlb=True,
    )
    want_crlb = {p: e["crlb"] for p, e in want["parameters"].items()}
    for n, m in want["modes"].items():
        want_crlb.update({f"{k}:{n}": m[k]["crlb"] for k in ("f_hz", "Q")})
    assert set(want_crlb) == {"f_hz:q1", "Q:q1", "f_hz:q2", "Q:q2", "beta1", "beta2", "g12"}
    assert_close(r.crlb, want_crlb)
    assert "crlb" in printed


def test_arrays_and_a_written_folder_identify_as_the_folder(cli, tmp_path):
    built = rebuild(harmonid.Dataset.from_folder(DATA_2))
    model = harmonid.Model.from_file(MODEL_2)
    got = harmonid.identify(model, built).to_dict()
    want, _, _ = cli_identify(cli, tmp_path, MODEL_2, DATA_2, [])
    assert got["dataset"] == "<arrays>"
    got["dataset"] = want["dataset"]
    # nm → m scaling rounds the amplitudes at 1e-16; the estimates follow to ~1e-9.
    assert_close(got, want, rel=1e-6)
    # A folder written from Python identifies, through the command line, as in Python.
    built.to_folder(tmp_path / "written")
    want2, _, _ = cli_identify(cli, tmp_path, MODEL_2, tmp_path / "written", [])
    got2 = harmonid.identify(model, harmonid.Dataset.from_folder(tmp_path / "written")).to_dict()
    assert_close(got2, want2)


def test_threads_share_models_and_datasets():
    model = harmonid.Model.from_file(MODEL_2)
    ds = harmonid.Dataset.from_folder(DATA_2)
    results = [None] * 4

    def work(i):
        results[i] = harmonid.identify(model, ds).to_dict()

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(r == results[0] for r in results)


def test_the_verdict_on_the_fit():
    """goodness_of_fit is the result file's; a model without q1's Duffing term does not fit
    the example (simulated with it), and says so first."""
    ds = harmonid.Dataset.from_folder(DATA_2)
    good = harmonid.identify(harmonid.Model.from_file(MODEL_2), ds)
    g = good.goodness_of_fit
    assert g == good.to_dict()["goodness_of_fit"]
    assert g["fits"] is True and 0.0 < g["p_value"] <= 1.0
    assert len(g["lines"]) == sum(m["lines"] for m in g["measurements"])
    assert not repr(good).startswith("IdentifyResult(THE MODEL")
    no_beta1 = harmonid.Model.from_str(
        "mode q1 at 207.58 kHz\nmode q2 at 415.84 kHz\nparam beta2, g12\n"
        "potential: beta2/4*q2^4\npotential: g12/2*q1^2*q2^2\n"
    )
    bad = harmonid.identify(no_beta1, ds)
    assert bad.goodness_of_fit["fits"] is False and bad.goodness_of_fit["p_value"] < 1e-6
    assert bad.warnings[0].startswith("THE MODEL DOES NOT FIT THE DATA")
    assert bad.summary().startswith("THE MODEL DOES NOT FIT THE DATA")
    assert repr(bad).startswith("IdentifyResult(THE MODEL DOES NOT FIT THE DATA")
    assert harmonid.identify(no_beta1, ds, estimator="linear").goodness_of_fit is None


def test_errors_are_located(tmp_path):
    model = harmonid.Model.from_file(MODEL_2)
    ds = harmonid.Dataset.from_folder(DATA_2)
    with pytest.raises(harmonid.IdentifyError, match=r"dataset.toml: measurement \"single_q1\""):
        harmonid.identify(model, ds, near_rel=1e-9)
    with pytest.raises(harmonid.HarmonidError, match="force_model"):
        harmonid.identify(model, ds, force_model="magic")
    with pytest.raises(harmonid.HarmonidError, match=r"estimator=\"mle\": expected \"ml\""):
        harmonid.identify(model, ds, estimator="mle")
    with pytest.raises(harmonid.HarmonidError, match="no mode \"q9\""):
        harmonid.identify(model, ds, nominal_hz={"q9": 1e5})
    with pytest.raises(TypeError):
        harmonid.identify(model, ds, unknown_option=1)
    other = harmonid.Model.from_str("mode a at 1 kHz\nmode b at 2 kHz\nparam k\neom a += k*a^3\n")
    with pytest.raises(harmonid.HarmonidError):
        harmonid.identify(other, ds)


def test_identify_alone_does_not_import_numpy():
    """numpy is imported only when arrays are asked for (it costs ~90 ms in a fresh process)."""
    code = (
        "import sys, harmonid\n"
        f"r = harmonid.identify(harmonid.Model.from_file({MODEL_2!r}),"
        f" harmonid.Dataset.from_folder({DATA_2!r}))\n"
        "assert 'numpy' not in sys.modules, 'identify imported numpy'\n"
        "assert r.per_shot['g12'].shape == (20,)\n"
        "assert 'numpy' in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=REPO)


def test_background_is_reported_and_bad_words_refused(tmp_path):
    model = harmonid.Model.from_file(MODEL_2)
    data = harmonid.Dataset.from_folder(DATA_2)
    r = harmonid.identify(model, data, background="constant")
    bg = r.background
    assert set(bg) == {"q1", "q2"}
    for b in bg.values():
        assert set(b) >= {"unit", "f_ref_hz", "constant"}
        assert "drive" not in b
        for part in ("re", "im"):
            e = b["constant"][part]
            assert np.isfinite(e["value"]) and e["stderr"] > 0
    assert r.to_dict()["background"] == bg
    assert harmonid.identify(model, data).background == {}
    with pytest.raises(harmonid.HarmonidError, match="not one of"):
        harmonid.identify(model, data, background="drive,offset")
    with pytest.raises(harmonid.HarmonidError, match="output-error estimator"):
        harmonid.identify(model, data, background="constant", estimator="linear")


def test_unfit_names_what_was_not_fitted_and_what_would_help(cli, tmp_path):
    """Without the two-mode measurement nothing shapes g12: `unfit` names it, why and the
    measurement that would help, as the command line writes it; None when all was fitted."""
    from test_dataset import arrays_of

    ds = harmonid.Dataset.from_folder(DATA_2)
    model = harmonid.Model.from_file(MODEL_2)
    assert harmonid.identify(model, ds).unfit is None
    arrays = arrays_of(ds)
    del arrays["couple_q1_q2"]
    singles = harmonid.Dataset.from_arrays(
        arrays,
        displacement_unit="nm",
        points={p["name"]: p["shape"] for p in ds.manifest["point"]},
        nominal_hz=ds.manifest.get("nominal_hz"),
        description="singles only",
    )
    r = harmonid.identify(model, singles)
    assert r.unfit == r.to_dict()["unfit"]
    [g12] = [u for u in r.unfit if "g12" in u["unknowns"]]
    assert g12["why"] == "not_determined" and g12["unknowns"] == ["g12"]
    assert g12["advice"].startswith("a measurement with responses near the resonances of q1+q2")
    assert "not fitted: not determined (g12)" in r.summary()
    # The command line on the same data writes the same field.
    singles.to_folder(tmp_path / "singles")
    want, _, _ = cli_identify(cli, tmp_path, MODEL_2, tmp_path / "singles", [])
    assert_close(r.unfit, want["unfit"], rel=1e-6)
