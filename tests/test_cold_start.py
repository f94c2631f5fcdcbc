"""Cold start: nothing is compiled before a command needs it, and the kernels' own sorts.

Timings are in ``benchmarks/bench_cold_start.py`` (``benchmarks/RESULTS-cold-start.md``); these
are structural checks: an empty kernel cache stays empty through imports and ``--help``, and no
kernel has a compiled signature after its module is imported.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from stageid.hysteresis.kernels.ordering import RUN, SMALL, quick_argsort, stable_argsort

KERNEL_MODULES = (
    "stageid.hysteresis.kernels",
    "stageid.hysteresis.kernels.filters",
    "stageid.hysteresis.kernels.preisach",
    "stageid.subspace.map_kernels",
    "stageid.frf.lpm_kernels",
    "stageid.frf.lpm_lanes",
)


def _run(args: list[str], cache) -> subprocess.CompletedProcess:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env, timeout=300)


def _cache_files(cache) -> list[str]:
    return [os.path.join(d, f) for d, _, files in os.walk(cache) for f in files]


@pytest.mark.parametrize(
    "args",
    [["-m", "stageid.cli.main", "--help"], ["-m", "stageid.cli.main", "identify", "hysteresis", "--help"]],
)
def test_help_compiles_no_kernel(tmp_path, args):
    cache = tmp_path / "cache"
    cache.mkdir()
    proc = _run(args, cache)
    assert proc.returncode == 0, proc.stderr
    assert _cache_files(cache) == []


def test_importing_the_kernel_modules_compiles_nothing(tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    code = (
        "import importlib, sys\n"
        "from numba.core.registry import CPUDispatcher\n"
        f"mods = [importlib.import_module(m) for m in {KERNEL_MODULES!r}]\n"
        "found = [(m.__name__, n) for m in mods for n, f in vars(m).items() if isinstance(f, CPUDispatcher)]\n"
        "compiled = [(m.__name__, n) for m in mods for n, f in vars(m).items()\n"
        "            if isinstance(f, CPUDispatcher) and f.signatures]\n"
        "print(len(found), compiled)\n"
    )
    proc = _run(["-c", code], cache)
    assert proc.returncode == 0, proc.stderr
    n_found, compiled = proc.stdout.split(" ", 1)
    assert int(n_found) > 20  # the check sees the kernels
    assert compiled.strip() == "[]"
    assert _cache_files(cache) == []


@pytest.mark.parametrize("n", [0, 1, 2, RUN - 1, RUN, RUN + 1, 2 * RUN, 61, 300, 1001])
def test_stable_argsort_is_numpys_stable_order(n):
    rng = np.random.default_rng(n)
    for keys in (rng.standard_normal(n), rng.integers(0, 4, n).astype(float), np.zeros(n), -np.arange(n, dtype=float)):
        np.testing.assert_array_equal(stable_argsort(keys), np.argsort(keys, kind="stable"))


def _key_sets(n, rng):
    return (
        rng.standard_normal(n),
        rng.integers(0, 4, n).astype(float),
        np.zeros(n),
        np.sort(rng.integers(0, 9, n)).astype(float),
        -np.arange(n, dtype=float),
    )


@pytest.mark.parametrize("n", [0, 1, 2, SMALL - 1, SMALL, SMALL + 1, 2 * SMALL + 1, 60, 61, 300, 1001])
def test_quick_argsort_is_numbas_argsort_ties_included(n):
    import numba

    numbas = numba.njit(lambda keys: np.argsort(keys))  # the order the event sums had before
    rng = np.random.default_rng(n)
    for keys in _key_sets(n, rng):
        np.testing.assert_array_equal(quick_argsort(keys), numbas(keys))
