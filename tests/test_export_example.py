"""examples/realtime: identify -> export -> compile -> stream a CSV through the compensator, and
compare the drive with `stageid compensate` on the same reference."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stageid.cli.main import main
from stageid.data import read_table, write_csv
from stageid.export.host import find_compiler
from stageid.hysteresis import ModifiedPIModel
from stageid.models import save_model

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "realtime"
pytestmark = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (gcc, clang or cc) on PATH")


def test_stream_example_builds_and_matches_compensate(tmp_path):
    rng = np.random.default_rng(0)
    r = np.r_[0.0, np.sort(rng.uniform(1, 40, 11))]
    model = ModifiedPIModel(
        r=r, rc=0.6 * r, ra=1.4 * r, rb=0.9 * r, weights=np.r_[0.8, rng.uniform(0, 0.2, 11)], input_offset=2.0,
        output_offset=0.5, input_limits=(-60.0, 70.0),
    )  # fmt: skip
    save_model(model, tmp_path / "hyst.json")
    t = np.arange(3000) * 1e-3
    write_csv(
        tmp_path / "ref.csv", {"y_ref": model.simulate(80 * np.sin(2 * np.pi * 2 * t) * (1 - t / 4))[:, 0]}, dt=1e-3
    )
    build = tmp_path / "build"
    cc = find_compiler()
    if shutil.which("make"):
        cmd = ["make", "-C", str(EXAMPLE), f"MODEL={tmp_path / 'hyst.json'}", f"BUILD={build}", f"CC={cc}"]
        cmd.append(f"STAGEID={sys.executable} -m stageid")
        res = subprocess.run(cmd, capture_output=True, text=True, check=False)
        assert res.returncode == 0, res.stderr
    else:  # the build line of stream.c's header
        assert (
            main(["export", "c", str(tmp_path / "hyst.json"), "--prefix", "comp", "--inverse", "-o", str(build)]) == 0
        )
        flags = ["-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-O2", f"-I{build}"]
        subprocess.run(
            [cc, *flags, str(EXAMPLE / "stream.c"), str(build / "comp.c"), "-o", str(build / "stream"), "-lm"],
            check=True,
        )
    with open(tmp_path / "ref.csv") as stdin, open(tmp_path / "drive_c.csv", "w") as stdout:
        subprocess.run([str(build / "stream"), "V"], stdin=stdin, stdout=stdout, check=True)
    assert main(["compensate", str(tmp_path / "hyst.json"), str(tmp_path / "ref.csv"), "--column", "y_ref",
                 "-o", str(tmp_path / "drive.csv")]) == 0  # fmt: skip
    ours, theirs = read_table(tmp_path / "drive_c.csv"), read_table(tmp_path / "drive.csv")
    assert ours.dt == pytest.approx(theirs.dt, rel=1e-12) and ours.t0 == theirs.t0  # the time axis passes through
    u_c, u = ours.column("V"), theirs.column("V")
    assert u_c.shape == u.shape == (3000,)
    assert np.max(np.abs(u_c - u)) <= 1e-12 * np.max(np.abs(u))  # %.17g text both ways: exact doubles
    assert u.min() == -60.0  # the limits are part of the exported compensator
