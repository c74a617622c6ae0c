"""Dataset: from_folder against the CSV files, to_folder round trips, from_arrays and its checks."""

import csv

import numpy as np
import pytest
from conftest import DATA_2, REPO

import harmonid


def csv_amplitudes(path):
    """{(shot, freq): complex} from a measurement CSV in metres (the example's unit)."""
    with open(path) as f:
        return {
            (int(r["shot"]), float(r["freq_hz"])): complex(float(r["re"]), float(r["im"]))
            for r in csv.DictReader(f)
        }


def test_from_folder_holds_the_files():
    ds = harmonid.Dataset.from_folder(DATA_2)
    assert ds.measurements == ["single_q1", "single_q2", "couple_q1_q2"]
    assert ds.path == DATA_2
    assert ds.manifest["displacement_unit"] == "m"
    assert ds.truth["modes"]["q1"]["Q"] == 116232.0
    for name in ds.measurements:
        m = ds.measurement(name)
        cells = csv_amplitudes(REPO / DATA_2 / f"{name}.csv")
        shots = 1 + max(s for s, _ in cells)
        assert m["amplitudes"].shape == (shots, len(m["freqs_hz"]), 1)
        assert m["amplitudes"].dtype == np.complex128
        assert list(m["freqs_hz"]) == sorted({f for _, f in cells})
        for (s, f), x in cells.items():
            i = list(m["freqs_hz"]).index(f)
            assert m["amplitudes"][s, i, 0] == x
        assert m["points"] == ["p0"]
        assert m["drive_levels_v"] is not None
    with pytest.raises(KeyError, match="single_q1"):
        ds.measurement("nope")


def test_to_folder_round_trips(tmp_path):
    ds = harmonid.Dataset.from_folder(DATA_2)
    ds.to_folder(tmp_path / "copy")
    back = harmonid.Dataset.from_folder(tmp_path / "copy")
    assert back.manifest == ds.manifest and back.truth == ds.truth
    for name in ds.measurements:
        a, b = ds.measurement(name), back.measurement(name)
        np.testing.assert_array_equal(a["freqs_hz"], b["freqs_hz"])
        np.testing.assert_allclose(a["amplitudes"], b["amplitudes"], rtol=1e-15, atol=0)


def arrays_of(ds):
    """The measurements of a dataset as `from_arrays` takes them (nm, frequencies reversed)."""
    out = {}
    for name in ds.measurements:
        m = ds.measurement(name)
        out[name] = {
            "drives_hz": list(m["drives_hz"]),
            "freqs_hz": m["freqs_hz"][::-1],
            "amplitudes": m["amplitudes"][:, ::-1, 0] * 1e9,
            "drive_levels_v": m["drive_levels_v"],
            "drive_phases_rad": m["drive_phases_rad"],
        }
    return out


def rebuild(ds):
    """`ds` built again from its arrays (in nm, frequencies reversed) and its manifest."""
    man = ds.manifest
    return harmonid.Dataset.from_arrays(
        arrays_of(ds),
        displacement_unit="nm",
        points={p["name"]: p["shape"] for p in man["point"]},
        nominal_hz=man.get("nominal_hz"),
        description=man["description"],
    )


def test_from_arrays_equals_the_folder():
    ds = harmonid.Dataset.from_folder(DATA_2)
    built = rebuild(ds)
    assert {**built.manifest, "displacement_unit": "m"} == ds.manifest
    assert built.path == "<arrays>" and built.truth is None
    assert built.measurements == ds.measurements
    for name in ds.measurements:
        a, b = ds.measurement(name), built.measurement(name)
        np.testing.assert_array_equal(a["freqs_hz"], b["freqs_hz"])
        np.testing.assert_allclose(b["amplitudes"], a["amplitudes"], rtol=1e-15, atol=0)


def test_from_arrays_errors_name_the_measurement():
    ds = harmonid.Dataset.from_folder(DATA_2)
    pts = {"p0": {"q1": 0.3, "q2": 0.6}}

    def build(edit, **kw):
        arrs = arrays_of(ds)
        edit(arrs["single_q1"])
        return harmonid.Dataset.from_arrays(arrs, points=pts, **kw)

    def nan(m):
        m["amplitudes"] = m["amplitudes"].copy()
        m["amplitudes"][3, 2] = np.nan

    with pytest.raises(harmonid.DatasetError, match=r"single_q1.*shot 3 at"):
        build(nan)
    with pytest.raises(harmonid.DatasetError, match="drive frequency 207573.5 Hz of measurement \"single_q1\""):
        build(lambda m: m.update(drives_hz=[207572.5 + 1, 207592.5]))
    with pytest.raises(harmonid.DatasetError, match="expected \\(shots, 10\\)"):
        build(lambda m: m.update(amplitudes=m["amplitudes"][:, :5]))
    with pytest.raises(harmonid.DatasetError, match="unknown key \"freq\""):
        build(lambda m: m.update(freq=1.0))
    with pytest.raises(harmonid.DatasetError, match="give both"):
        build(lambda m: m.update(drive_phases_rad=None))
    with pytest.raises(harmonid.DatasetError, match="displacement_unit"):
        build(lambda m: None, displacement_unit="inch")


def test_missing_folder_is_located(tmp_path):
    with pytest.raises(harmonid.DatasetError, match="dataset.toml"):
        harmonid.Dataset.from_folder(tmp_path / "nothing")


def test_a_pump_travels_with_its_measurement(tmp_path):
    """`pumps_hz`, `pump_levels`, `pump_phases_rad` in, out, through a folder; half a pump is refused."""
    ds = harmonid.Dataset.from_folder(DATA_2)
    pts = {"p0": {"q1": 0.3, "q2": 0.6}}
    arrs = arrays_of(ds)
    arrs["single_q1"].update(pumps_hz=[415165.0], pump_levels=[0.8], pump_phases_rad=[0.25])
    built = harmonid.Dataset.from_arrays(arrs, points=pts, displacement_unit="nm")
    m = built.measurement("single_q1")
    assert m["pumps_hz"] == [415165.0]
    assert m["pump_levels"] == [0.8] and m["pump_phases_rad"] == [0.25]
    assert "pumps_hz" not in built.measurement("single_q2")
    built.to_folder(tmp_path / "pumped")
    back = harmonid.Dataset.from_folder(tmp_path / "pumped")
    assert back.measurement("single_q1")["pump_levels"] == [0.8]
    arrs["single_q1"].pop("pump_levels")
    with pytest.raises(harmonid.DatasetError, match="pump_levels"):
        harmonid.Dataset.from_arrays(arrs, points=pts, displacement_unit="nm")


def test_merge_pools_two_rounds_and_refuses_another_unit(tmp_path):
    import shutil

    shutil.copytree(REPO / DATA_2, tmp_path / "round2")
    one = harmonid.Dataset.from_folder(DATA_2)
    two = harmonid.Dataset.from_folder(tmp_path / "round2")
    merged = harmonid.Dataset.merge([one, two])
    assert len(merged.measurements) == 2 * len(one.measurements)
    assert "data_single_q1" in merged.measurements
    assert "round2_couple_q1_q2" in merged.measurements
    assert merged.truth is not None
    assert "round2_single_q2" in merged.truth["forces"]
    assert any("round2_single_q1" in n for n in merged.notes)
    merged.to_folder(tmp_path / "merged")
    back = harmonid.Dataset.from_folder(tmp_path / "merged")
    assert back.measurements == merged.measurements
    m = one.measurement("single_q1")
    nm = harmonid.Dataset.from_arrays(
        {"x": {k: m[k] for k in ("drives_hz", "freqs_hz")} | {"amplitudes": m["amplitudes"][:, :, 0] * 1e9}},
        displacement_unit="nm",
        points={"p0": one.manifest["point"][0]["shape"]},
        nominal_hz=one.manifest["nominal_hz"],
    )
    with pytest.raises(harmonid.DatasetError, match="displacement_unit"):
        harmonid.Dataset.merge([one, nm])
