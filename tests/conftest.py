"""Helpers shared by the test files: running the command line, the failure contract, snapshots.

Test files import them (``from conftest import run_main``): pytest puts this folder on
``sys.path`` (the default "prepend" import mode), as it does for ``_subspace_systems.py``.

- :func:`run_main` runs ``stageid`` in this process (fast; sees the CLI's own stderr);
- :func:`run_cli` runs the real ``stageid`` process, optionally under an address-space
  limit, for hostile inputs whose missing guard must fail the test instead of the machine;
- :func:`assert_one_line_error` is the failure contract (docs/guide/bad-input.md) for one command;
- :func:`snapshot` captures a folder's files so "unchanged" is a plain equality.
"""

from __future__ import annotations

import contextlib
import io
import os
import resource
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

#: Address space of a child running a hostile input: numpy, scipy, numba and h5py loaded take
#: about 1.5 GB of address space; an allocation of many GB must fail there, not swap here.
AS_LIMIT = 3 * 2**30


def run_main(*args: object, cwd: Path | None = None, warnings_as_errors: bool = False) -> tuple[int, str, str]:
    """Run ``stageid`` in this process: (exit code, stdout, stderr).

    ``warnings_as_errors`` turns any warning leaking out of the command into an error, so a
    raw ``RuntimeWarning`` before a one-line error breaks the contract visibly.
    """
    out, err = io.StringIO(), io.StringIO()
    old = os.getcwd()
    from stageid.cli.main import main

    with warnings.catch_warnings(), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        if warnings_as_errors:
            warnings.simplefilter("error")
        if cwd is not None:
            os.chdir(cwd)
        try:
            rc = main([str(a) for a in args])
        finally:
            os.chdir(old)
    return rc, out.getvalue(), err.getvalue()


def run_cli(
    *args: object,
    cwd: Path | None = None,
    env: dict[str, str] | None = None,
    memory_limit: int | None = None,
    timeout: float = 120,
) -> tuple[int, str, str]:
    """Run the real ``stageid`` process: (exit code, stdout, stderr).

    ``memory_limit`` (bytes, e.g. :data:`AS_LIMIT`) caps the child's address space
    (``RLIMIT_AS``); ``env`` adds to this process's environment (one BLAS thread always).
    """

    def limit() -> None:
        if memory_limit is not None:
            resource.setrlimit(resource.RLIMIT_AS, (memory_limit, memory_limit))

    full_env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", **(env or {}))
    proc = subprocess.run(
        [sys.executable, "-m", "stageid", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=full_env,
        timeout=timeout,
        preexec_fn=limit,
    )
    return proc.returncode, proc.stdout, proc.stderr


def assert_one_line_error(rc: int, err: str, *fragments: str) -> None:
    """Exit code 2 and exactly one stderr line, ``stageid: error: ...``, holding ``fragments``."""
    assert rc == 2, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("stageid: error: "), err
    assert "Traceback" not in err
    for fragment in fragments:
        assert fragment in err, err


@pytest.fixture
def drawn(monkeypatch):
    """The figures a report draws, ``[(figure, caption)]``, kept open (``Report.figure`` renders
    them to PNG and forgets them)."""
    from stageid.report import html as report_html

    figs = []
    real = report_html.Report.figure

    def keep(self, fig, caption, dpi=110):
        figs.append((fig, caption))
        return real(self, fig, caption, dpi)

    monkeypatch.setattr(report_html.Report, "figure", keep)
    return figs


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (names relative) with its bytes: "unchanged" is equality."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture
def dask_cluster():
    """A real scheduler and two workers on 127.0.0.1 (see tests/dask_cluster.py); torn down after."""
    from dask_cluster import TestCluster

    with TestCluster(n_workers=2) as cluster:
        yield cluster
