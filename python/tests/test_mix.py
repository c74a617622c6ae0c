"""mix: the records equal `harmonid mix --json`, line by line."""

import pytest
from conftest import MODEL_2, assert_close, load_json

import harmonid


def cli_records(cli, *args):
    want = load_json(cli("mix", *args, "--json"))
    out = []
    for t in want["terms"]:
        for line in t["lines"]:
            out.append(
                {
                    "equation": t["equation"],
                    "monomial": t["monomial"],
                    "term_coefficient": t["term_coefficient"],
                    "velocity_factors": t["velocity_factors"],
                    "combination": line["label"],
                    "coeffs": line["combination"],
                    "freq_hz": line["freq_hz"],
                    "coefficient": line["coefficient"],
                    "near": line["near"],
                    "second_order": line["second_order"],
                    "via": line["via"],
                }
            )
    return out


@pytest.mark.parametrize(
    "drives, options, flags",
    [
        ({"q1": [207572, 207592], "q2": [415842]}, {}, []),
        ({"q1": [207572, 207592]}, {"sidebands": 3}, ["--sidebands", "3"]),
        ({"q1": [207572.5, 207592.5], "q2": [415841.5]}, {"window_hz": 200.0}, ["--window", "200"]),
    ],
)
def test_records_equal_cli(cli, drives, options, flags):
    args = [MODEL_2]
    for mode, tones in drives.items():
        args += ["--drives", f"{mode}:" + ",".join(repr(float(f)) for f in tones)]
    want = cli_records(cli, *args, *flags)
    got = harmonid.mix(harmonid.Model.from_file(MODEL_2), drives, **options)
    assert len(want) > 10
    assert_close(got, want)
    # Pairs work as well as a dict.
    assert harmonid.mix(harmonid.Model.from_file(MODEL_2), list(drives.items()), **options) == got


def test_velocity_terms_equal_cli_and_carry_i(cli):
    model = "examples/damped_2mode/model.hb"
    want = cli_records(cli, model, "--drives", "q1:999990.0", "--drives", "q2:1600000.0")
    got = harmonid.mix(harmonid.Model.from_file(model), {"q1": [999990.0], "q2": [1600000.0]})
    assert_close(got, want)
    # eta1 q1^2 d(q1) at the tone: i·(1/4 X1^3 ω(X1)), a force in quadrature with the motion.
    line = next(
        r for r in got if r["monomial"] == "q1^2*d(q1)" and r["combination"] == "f1"
    )
    assert line["coefficient"] == "i·(1/4*X1^3*ω(X1))"
    assert line["velocity_factors"] == 1


def test_records_make_a_dataframe():
    pd = pytest.importorskip("pandas")
    recs = harmonid.mix(harmonid.Model.from_file(MODEL_2), {"q1": [207572, 207592]})
    df = pd.DataFrame(recs)
    near = df[(df.monomial == "q1^3") & (df.near == "q1")]
    # Table S1: q1^3 under two tones gives the tones themselves and the third-order sidebands.
    assert sorted(near.combination) == sorted(["f1", "f2", "2·f1 − f2", "2·f2 − f1"])
    assert set(df.columns) >= {"equation", "freq_hz", "coefficient", "near"}


def test_bad_input_raises():
    m = harmonid.Model.from_file(MODEL_2)
    with pytest.raises(harmonid.HarmonidError, match="no tones"):
        harmonid.mix(m, {})
    with pytest.raises(harmonid.HarmonidError, match="too high"):
        harmonid.mix(m, {"q1": [1.0, 2.0]}, sidebands=99)
    with pytest.raises(harmonid.HarmonidError, match="does not declare"):
        harmonid.mix(m, {"q1": [1.0]}, nominal_hz={"q9": 1.0})
    with pytest.raises(harmonid.HarmonidError):
        harmonid.mix(m, {"q7": [1.0]})
