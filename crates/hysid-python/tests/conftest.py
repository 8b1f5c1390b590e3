"""Shared fixtures: the repository's records and the `hysid` program."""

import os
import pathlib
import shutil
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]
PICK_AND_PLACE = REPO / "models" / "pick-and-place" / "headdata_1v6.mat"
HEAD_MODEL = REPO / "models" / "pick-and-place" / "head.toml"
BOTH_STOPS = REPO / "models" / "pick-and-place" / "simulated" / "both-saturations.csv"


def hysid_program():
    """The `hysid` program: $HYSID_BIN, else a build in the repository's
    target folder, else one on PATH; None when there is none."""
    given = os.environ.get("HYSID_BIN")
    if given:
        return given
    for profile in ("release", "debug"):
        p = REPO / "target" / profile / "hysid"
        if p.exists():
            return str(p)
    return shutil.which("hysid")


@pytest.fixture(scope="session")
def program():
    """Runs the `hysid` program; its tests are skipped only when no build
    exists and $HYSID_BIN is unset (CI sets it)."""
    exe = hysid_program()
    if exe is None:
        pytest.skip("no hysid program built (cargo build -p hysid-cli, or set HYSID_BIN)")

    def run(*args, check=True):
        r = subprocess.run([exe, *map(str, args)], capture_output=True, text=True)
        if check and r.returncode != 0:
            raise AssertionError(f"hysid {' '.join(map(str, args))} failed: {r.stderr}")
        return r

    return run


@pytest.fixture(scope="session")
def record():
    """The pick-and-place record at 400 Hz: (u, y, ts)."""
    import hysid

    return hysid.load(PICK_AND_PLACE, decimate=10)
