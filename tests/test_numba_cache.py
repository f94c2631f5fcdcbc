"""A read-only install still runs its compiled kernels.

numba refuses to define a ``cache=True`` kernel when neither the package folder nor the
user's cache folder is writable.  The test installs a copy of the package on a read-only
bind mount inside a private mount namespace (``unshare -m``, root only), with a read-only
``$HOME``; once with a writable temporary folder (the cache moves there) and once with the
temporary folders read-only too (the kernels run uncached).  Both runs must print nothing
but the result.
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import stageid
from stageid.runtime import numba_cache

CODE = (
    "import numpy as np, os, stageid\n"
    "from stageid.hysteresis import PIModel\n"
    "m = PIModel(r=[0.0, 1.0], weights=[1.0, 0.5])\n"
    "print(float(np.ravel(m.simulate(np.linspace(0, 2, 50)))[-1]), os.environ.get('NUMBA_CACHE_DIR'))\n"
)


def _can_unshare() -> bool:
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        return False
    probe = subprocess.run(["unshare", "-m", "true"], capture_output=True)
    return probe.returncode == 0


needs_namespace = pytest.mark.skipif(not _can_unshare(), reason="needs root and `unshare -m` for read-only mounts")


def _run_read_only(tmp_path: Path, extra_read_only: list[str]) -> subprocess.CompletedProcess:
    src = tmp_path / "install"
    shutil.copytree(Path(stageid.__file__).parent, src / "stageid", ignore=shutil.ignore_patterns("__pycache__"))
    home = tmp_path / "home"
    home.mkdir()
    mounts = [str(src), str(home), *extra_read_only]
    script = "".join(f"mount --bind {m} {m} && mount -o remount,bind,ro {m} || exit 97\n" for m in mounts)
    script += f'cd {src} && exec "{sys.executable}" -c "$1"\n'
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME", "PYTHONPATH")}
    env.update(HOME=str(home), PYTHONPATH=str(src), TMPDIR=str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    return subprocess.run(
        ["unshare", "-m", "sh", "-c", script, "sh", CODE], env=env, capture_output=True, text=True, timeout=300
    )


@needs_namespace
@pytest.mark.slow
def test_read_only_install_caches_in_the_temporary_folder(tmp_path):
    p = _run_read_only(tmp_path, [])
    assert p.returncode == 0, p.stderr[-500:]
    assert p.stderr == ""
    value, cache = p.stdout.split()
    assert float(value) == 2.5  # 2 * 1.0 + 0.5 * (2 - 1): the play operator's closed form
    assert cache.startswith(str(tmp_path / "tmp"))
    assert any((tmp_path / "tmp").rglob("*.nbi"))  # the kernels were cached there


@needs_namespace
@pytest.mark.slow
def test_nothing_writable_runs_uncached(tmp_path):
    p = _run_read_only(tmp_path, [str(tmp_path / "tmp"), "/tmp", "/var/tmp"])
    assert p.returncode == 0, p.stderr[-500:]
    assert p.stderr == ""
    assert p.stdout.split() == ["2.5", "None"]


def test_writable_checks_really_write(tmp_path):
    assert numba_cache.writable(str(tmp_path / "a" / "b"))
    (tmp_path / "file").write_text("")
    assert not numba_cache.writable(str(tmp_path / "file" / "sub"))  # a file is in the way
