"""harmonid.io: sweeps of several passes, and rows where nothing was measured (NaN)."""

import warnings

import pytest

import harmonid
import harmonid.io

LOOPS = [100.0, 101.0, 102.0, 101.0, 100.0, 101.0, 102.0, 101.0, 100.0]


def sweeper(tmp_path, drives, nan=()):
    """A LabOne sweeper CSV; rows `nan` (0-based) as a sweep stopped early writes them."""
    lines = ["grid;x;y;xstddev;ystddev;count"]
    for k, f in enumerate(drives):
        if k in nan:
            lines.append(f"{f!r};nan;nan;nan;nan;0")
        else:
            lines.append(f"{f!r};{1e-3 * (k + 1)!r};{-1e-4 * k!r};1e-6;1e-6;100")
    p = tmp_path / "sweep_demod0.csv"
    p.write_text("\n".join(lines) + "\n")
    return p


def read(p, **kw):
    return harmonid.io.read_zi_sweeper(
        [p], amplitude="rms", quadrature="x+iy", metres_per_unit=None, drive_level=0.1, **kw
    )


def test_two_loops_are_four_ordered_passes(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing dropped: no warning
        ds = read(sweeper(tmp_path, LOOPS))
    sweeps = ds.manifest["sweep"]
    assert [s["name"] for s in sweeps] == ["sweep_up", "sweep_down", "sweep_up_2", "sweep_down_2"]
    assert [s["direction"] for s in sweeps] == ["up", "down", "up", "down"]
    assert any("4 passes" in n for n in ds.notes)


def test_a_sweep_stopped_early_drops_its_tail_with_a_warning(tmp_path):
    p = sweeper(tmp_path, LOOPS, nan=(8,))
    with pytest.warns(UserWarning, match=r"sweep_demod0.csv: 1 row \(row 10\) at the end"):
        ds = read(p)
    assert len(ds.measurements) == 8
    assert [s["name"] for s in ds.manifest["sweep"]][-1] == "sweep_down_2"


def test_a_gap_is_refused_unless_asked(tmp_path):
    p = sweeper(tmp_path, LOOPS, nan=(1,))
    with pytest.raises(harmonid.DatasetError, match=r"row 3.*drop_nan_rows=True"):
        read(p)
    with pytest.warns(UserWarning, match="inside sweep"):
        ds = read(p, drop_nan_rows=True)
    assert len(ds.measurements) == 8


def test_read_table_drops_a_gap_when_asked(tmp_path):
    data = tmp_path / "hyst.txt"
    rows = [f"{f} {1e-3 * (k + 1)} 1e-4 0.1" for k, f in enumerate(LOOPS)]
    rows[1] = f"{LOOPS[1]} NaN NaN 0.1"
    data.write_text("# f X Y level\n" + "\n".join(rows) + "\n")
    mapping = tmp_path / "map.toml"
    mapping.write_text(
        "[columns]\nfreq_hz = 1\nx = 2\ny = 3\ndrive_level = 4\n"
        '[conventions]\namplitude = "rms"\nquadrature = "x+iy"\ndisplacement_unit = "V"\n'
    )
    with pytest.raises(harmonid.DatasetError, match="row 3"):
        harmonid.io.read_table([data], mapping)
    with pytest.warns(UserWarning, match="1 row"):
        ds = harmonid.io.read_table([data], mapping, drop_nan_rows=True)
    assert len(ds.measurements) == 8
