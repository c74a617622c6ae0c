"""Shared fixtures: the repository, the `harmonid` command line, and a tolerant comparison.

Every binding is checked against the command line's own output on the shipped examples: same
strings, same numbers to 1e-12 relative.
"""

import json
import math
import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
MODEL_2 = "examples/nanostring_2mode/model.hb"
DATA_2 = "examples/nanostring_2mode/data"
MODEL_5 = "examples/nanostring_5mode/model.hb"


def _cli_path():
    exe = os.environ.get("HARMONID_CLI")
    if exe:
        return Path(exe)
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    return target / "release" / "harmonid"


@pytest.fixture(scope="session")
def cli():
    """Runs `harmonid ARGS` in the repository root and returns its standard output."""
    exe = _cli_path()
    if not exe.exists():
        subprocess.run(
            ["cargo", "build", "--release", "--quiet", "--bin", "harmonid"], cwd=REPO, check=True
        )

    def run(*args):
        out = subprocess.run(
            [str(exe), *map(str, args)], cwd=REPO, check=True, capture_output=True, text=True
        )
        return out.stdout

    return run


@pytest.fixture(autouse=True)
def _in_repo(monkeypatch):
    """Relative example paths resolve as they do for the command line run in the repository."""
    monkeypatch.chdir(REPO)


def assert_close(got, want, rel=1e-12, path="result"):
    """Recursive equality of JSON-like values; floats to `rel` relative (NaN equals NaN)."""
    if isinstance(want, dict):
        assert isinstance(got, dict), f"{path}: {got!r} is not a dict"
        assert set(got) == set(want), f"{path}: keys {sorted(got)} != {sorted(want)}"
        for k in want:
            assert_close(got[k], want[k], rel, f"{path}.{k}")
    elif isinstance(want, (list, tuple)):
        assert len(got) == len(want), f"{path}: length {len(got)} != {len(want)}"
        for i, (g, w) in enumerate(zip(got, want)):
            assert_close(g, w, rel, f"{path}[{i}]")
    elif isinstance(want, float) and not isinstance(want, bool):
        g = float(got)
        if math.isnan(want):
            assert math.isnan(g), f"{path}: {g} != NaN"
        else:
            assert abs(g - want) <= rel * max(abs(want), 1e-300), f"{path}: {g!r} != {want!r}"
    else:
        assert got == want, f"{path}: {got!r} != {want!r}"


def load_json(text):
    return json.loads(text)
