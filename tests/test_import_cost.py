"""Start-up cost of the default commands: heavy modules load only where they are used.

The LPM's numba kernels, loaded through the `stageid.frf` package by every estimator that
reports a response with its std, once doubled the whole-process time of `identify statespace`
(benchmarks/RESULTS-subspace.md).  A structural check, not a timing: which modules a fresh
interpreter has after the import.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
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


def _fresh(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()


@pytest.mark.parametrize(
    ("module", "absent"),
    [
        # a measured response (the BLA's result) needs no LTI class and so no scipy.linalg
        ("stageid.frf.bla", ("scipy", "matplotlib", "tqdm", "numba", "stageid.models.lti")),
        ("stageid.models.frequency_response", ("scipy", "stageid.models.lti")),
        # sub-commands load when they run; the moved-paths finder needs no importlib.abc
        ("stageid.cli.main", ("stageid.cli.frf", "stageid.cli.serve", "stageid.validation", "numpy")),
        ("stageid", ("importlib.resources",)),
    ],
)
def test_start_up_loads_only_what_is_used(module, absent):
    out = _fresh(f"import sys, {module}; print(','.join(m for m in {absent!r} if m in sys.modules))")
    assert out == "", f"importing {module} loaded {out}"


def test_model_names_still_import_from_the_package():
    import stageid.models as models

    for name in models.__all__:
        value = getattr(models, name)
        assert value == "stageid.lti/1" if name == "LTI_FORMAT" else value.__name__ == name
    with pytest.raises(AttributeError):
        models.no_such_name  # noqa: B018
    assert _fresh("import stageid.frf as f, stageid.models as m; print('welch_frf' in dir(f), 'c2d' in dir(m))") == (
        "True True"  # listed before they load
    )
    assert _fresh("from stageid.models import *; print(StateSpaceModel.__name__, LTI_FORMAT)") == (
        "StateSpaceModel stageid.lti/1"
    )


def test_a_command_loads_its_own_module_only():
    code = (
        "import sys, click; from stageid.cli.main import cli; ctx = click.Context(cli); "
        "names = cli.list_commands(ctx); frf = cli.get_command(ctx, 'frf'); "
        "ident = cli.get_command(ctx, 'identify'); both = ident.list_commands(click.Context(ident)); "
        "print(' '.join(names)); print(frf.name, 'stageid.cli.frf' in sys.modules, 'stageid.cli.serve' in sys.modules); "
        "print(' '.join(both), ident.get_command(ctx, 'closedloop') is ident.get_command(ctx, 'closed-loop'))"
    )
    names, frf, identify = _fresh(code).splitlines()
    assert names.split() == sorted(
        "batch compensate demo export freqresp frf identify plants report serve signal simulate validate".split()
    )
    assert frf == "frf True False"
    assert identify == "closed-loop closedloop frd hysteresis statespace True"


def test_frf_bla_run_loads_no_plotting_fitting_or_progress_modules(tmp_path):
    from stageid.signals import multisine

    for r in range(2):
        u = multisine(1024, 1e-3, 5.0, 100.0, seed=1, realisation=r, n_periods=4, lines="odd")
        y = np.convolve(u, [0.0, 1.0, 0.5])[: u.size] + 0.1 * u**3
        np.savez(tmp_path / f"r{r}.npz", t=np.arange(u.size) * 1e-3, u=u, y=y)
    # numpy.ma: np.median imports it, a fifth of numpy's own import time
    absent = ("scipy", "matplotlib", "tqdm", "numba", "dask", "stageid.models.lti", "stageid.cli.serve", "numpy.ma")
    args = ["frf", str(tmp_path / "r0.npz"), str(tmp_path / "r1.npz"), "--inputs", "u", "--outputs", "y"]
    args += ["--method", "bla", "--periods", "4", "-o", str(tmp_path / "bla.npz")]
    code = (
        f"import sys; from stageid.cli.main import main; rc = main({args!r}); "
        f"print(rc, ','.join(m for m in {absent!r} if m in sys.modules) or 'none')"
    )
    assert _fresh(code).splitlines()[-1] == "0 none", "the BLA run failed or loaded a module it does not use"
    assert (tmp_path / "bla.npz").exists()
