"""harmonid.io: instrument files in, a Dataset out; every convention explicit."""

import math

import numpy as np
import pytest

import harmonid
import harmonid.io

STEPS = [98.0, 99.5, 100.25, 101.0]


def truth(f, h, j):
    """A Duffing-like response at harmonic h of step f, sample j, in metres."""
    w0, w = 2 * math.pi * 100.0, 2 * math.pi * f
    lin = 1 / complex(w0 * w0 - w * w, w * w0 / 50.0)
    return lin * (1e-3 / h) ** (h - 1) * (1 + 1e-4 * j)


def write_zi(tmp_path, k_m_per_v, clock):
    """Two LabOne demodulator CSVs (drive and second harmonic): RMS volts, x − iy."""
    files = []
    for h in (1, 2):
        lines = ["chunk;timestamp;x;y;freq;phase;dio;trigger;auxin0;auxin1"]
        tick = 1_000_000
        for f in STEPS:
            for j in range(5):
                z = truth(f, h, j).conjugate() / math.sqrt(2) / k_m_per_v
                lines.append(f"0;{tick};{z.real!r};{z.imag!r};{f * h!r};0;0;0;0;0")
                tick += int(0.1 * clock)
            tick += int(clock)
        p = tmp_path / f"dev1_demods_{h - 1}_sample_00000.csv"
        p.write_text("\n".join(lines) + "\n")
        files.append(p)
    return files


def test_zi_csv(tmp_path):
    k, clock = 2.5e-7, 60e6
    files = write_zi(tmp_path, k, clock)
    ds = harmonid.io.read_zi_csv(
        files,
        amplitude="rms",
        quadrature="x-iy",
        metres_per_unit=k,
        clockbase_hz=clock,
        drive_level=0.2,
        settle_s=0.15,
    )
    assert isinstance(ds, harmonid.Dataset)
    assert len(ds.measurements) == 4
    assert any("8 of 20 samples dropped" in n for n in ds.notes)
    assert ds.manifest["import"]["format"] == "zi-csv"
    for k_step, name in enumerate(ds.measurements):
        m = ds.measurement(name)
        assert m["amplitudes"].shape == (3, 2, 1)
        for j in range(3):
            for h in (1, 2):
                want = truth(STEPS[k_step], h, j + 2)
                got = m["amplitudes"][j, h - 1, 0]
                assert abs(got - want) <= 1e-12 * abs(want)


def test_zi_csv_keeps_volts_and_refuses_a_bad_convention(tmp_path):
    files = write_zi(tmp_path, 1.0, 60e6)
    ds = harmonid.io.read_zi_csv(
        files, amplitude="peak", quadrature="x+iy", metres_per_unit=None, clockbase_hz=60e6
    )
    assert ds.manifest["displacement_unit"] == "V"
    with pytest.raises(harmonid.DatasetError, match="amplitude"):
        harmonid.io.read_zi_csv(
            files, amplitude="RMS?", quadrature="x+iy", metres_per_unit=None, clockbase_hz=60e6
        )
    with pytest.raises(TypeError):
        # No convention is defaulted: a missing keyword is an error.
        harmonid.io.read_zi_csv(files, quadrature="x+iy", metres_per_unit=None, clockbase_hz=60e6)
    with pytest.raises(harmonid.DatasetError, match="clockbase"):
        harmonid.io.read_zi_csv(
            files, amplitude="rms", quadrature="x+iy", metres_per_unit=None, clockbase_hz=-1.0
        )


def test_read_table_with_a_mapping(tmp_path):
    rows = ["f R phase_deg level"]
    for f in STEPS:
        for j in range(2):
            w = 2 * math.pi * f
            a = truth(f, 1, j) * -(w * w)
            rows.append(f"{f!r} {abs(a)!r} {math.degrees(np.angle(a))!r} 0.3")
    data = tmp_path / "sweep.txt"
    data.write_text("\n".join(rows) + "\n")
    mapping = tmp_path / "map.toml"
    mapping.write_text(
        '[columns]\nfreq_hz = "f"\nr = "R"\ntheta = "phase_deg"\ndrive_level = "level"\n'
        '[conventions]\namplitude = "peak"\nquadrature = "x+iy"\nphase_unit = "deg"\n'
        'response = "acceleration"\ndisplacement_unit = "m"\nmetres_per_unit = 1.0\n'
    )
    ds = harmonid.io.read_table([data], mapping)
    assert len(ds.measurements) == 4
    for k_step, name in enumerate(ds.measurements):
        x = ds.measurement(name)["amplitudes"][:, 0, 0]
        for j in range(2):
            want = truth(STEPS[k_step], 1, j)
            assert abs(x[j] - want) <= 1e-12 * abs(want)
    with pytest.raises(harmonid.DatasetError, match="map.toml"):
        mapping.write_text('[columns]\nfreq_hz = "f"\n')
        harmonid.io.read_table([data], mapping)


def test_zi_sweeper_gives_the_noise(tmp_path):
    p = tmp_path / "sweep.csv"
    rows = ["grid;count;x;xstddev;y;ystddev"]
    for f in STEPS:
        z = truth(f, 1, 0)
        rows.append(f"{f!r};10;{z.real!r};{abs(z) * 1e-3!r};{z.imag!r};{abs(z) * 1e-3!r}")
    p.write_text("\n".join(rows) + "\n")
    ds = harmonid.io.read_zi_sweeper(
        [p], amplitude="peak", quadrature="x+iy", metres_per_unit=1.0
    )
    assert len(ds.measurements) == 4
    for k_step, name in enumerate(ds.measurements):
        m = ds.measurement(name)
        want = truth(STEPS[k_step], 1, 0)
        assert m["amplitudes"].shape == (1, 1, 1)
        assert abs(m["amplitudes"][0, 0, 0] - want) <= 1e-12 * abs(want)
        assert m["samples"][0] == 10
        assert abs(m["std"][0] - abs(want) * 1e-3) <= 1e-12 * abs(want) * 1e-3


def test_from_arrays_takes_a_sweep_and_a_given_noise(tmp_path):
    steps = []
    for f in STEPS:
        z = truth(f, 1, 0)
        steps.append(
            {
                "drives_hz": [f],
                "freqs_hz": [f],
                "amplitudes": np.array([[z]]),
                "drive_levels_v": [0.2],
                "drive_phases_rad": [0.0],
                "std": [abs(z) * 1e-3],
                "samples": [8],
            }
        )
    ds = harmonid.Dataset.from_arrays({}, sweeps=[{"name": "up", "steps": steps}])
    assert ds.measurements == [f"up[{k}]" for k in range(4)]
    sweep = ds.manifest["sweep"][0]
    assert sweep["name"] == "up" and sweep["direction"] == "up"
    m = ds.measurement("up[2]")
    assert m["samples"][0] == 8
    ds.to_folder(tmp_path / "ds")
    back = harmonid.Dataset.from_folder(tmp_path / "ds")
    assert back.measurements == ds.measurements
    assert "std,samples" in (tmp_path / "ds" / "up.csv").read_text().splitlines()[0]
    # A direction the steps contradict is refused; levels for some steps only too.
    with pytest.raises(harmonid.DatasetError):
        harmonid.Dataset.from_arrays({}, sweeps=[{"name": "d", "direction": "down", "steps": steps}])
    partial = [dict(s) for s in steps]
    del partial[1]["drive_levels_v"], partial[1]["drive_phases_rad"]
    with pytest.raises(harmonid.DatasetError, match="some steps only"):
        harmonid.Dataset.from_arrays({}, sweeps=[{"name": "p", "steps": partial}])
