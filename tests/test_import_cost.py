"""Start-up cost of the default commands: heavy modules load only where they are used.

The LPM's numba kernels, loaded through the `stageid.frf` package by every estimator that
reports a response with its std, once doubled the whole-process time of `identify statespace`
(benchmarks/RESULTS-subspace.md).  A structural check, not a timing: which modules a fresh
interpreter has after the import.
"""

from __future__ import annotations

import subprocess
import sys

import pytest


@pytest.mark.parametrize(
    ("module", "absent"),
    [
        ("stageid.subspace", ("numba", "dask", "distributed", "zarr")),
        ("stageid.cli.main", ("numba", "dask", "distributed", "zarr", "scipy", "matplotlib")),
        ("stageid.frf.frd", ("numba", "stageid.frf.lpm")),
    ],
)
def test_import_does_not_load(module, absent):
    code = f"import sys, {module}; print(','.join(m for m in {absent!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "", f"importing {module} loaded {out}"


def test_frf_names_still_import_from_the_package():
    import stageid.frf as frf

    for name in frf.__all__:
        assert getattr(frf, name).__name__ == name
    with pytest.raises(AttributeError):
        frf.no_such_name  # noqa: B018
