"""HankelMAP refuses a horizon, order or frequency count that would not fit in memory.

`stageid identify statespace ... --horizon 2400` on a 3x3 record was killed by the kernel at
23.7 GB.  Now the memory is estimated before anything is allocated and the request is refused
with one line naming the need and what is available.  Every hostile case runs in a child
process under an address-space limit (``RLIMIT_AS``), so a guard that fails cannot take the
test machine's memory: the child then dies with a MemoryError instead, and the test fails.
"""

import os
import resource
import subprocess
import sys
import textwrap

import numpy as np

from stageid.data import Experiment, write_npz

LIMIT = 3 * 2**30  # address space of the child: numpy, scipy and a normal fit fit well inside


def _limited():
    resource.setrlimit(resource.RLIMIT_AS, (LIMIT, LIMIT))


def _run(args, tmp_path):
    env = {**os.environ, "STAGEID_MEMORY_LIMIT": "2G", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    return subprocess.run(args, capture_output=True, text=True, env=env, cwd=tmp_path, preexec_fn=_limited, timeout=300)


def _record(tmp_path, n=6000):
    rng = np.random.default_rng(0)
    u = rng.standard_normal((n, 3))
    y = np.cumsum(u, axis=0) * 0.01 + 0.01 * rng.standard_normal((n, 3))
    path = tmp_path / "run.npz"
    write_npz(path, Experiment(u, y, 0.002, ("Z", "Rx", "Ry"), ("z", "rx", "ry")))
    return path


def _cli(tmp_path, data, *options):
    args = ["identify", "statespace", str(data), "--inputs", "Z,Rx,Ry", "--outputs", "z,rx,ry", *options]
    return _run([sys.executable, "-m", "stageid", *args, "-o", str(tmp_path / "m.json")], tmp_path)


def test_cli_refuses_a_horizon_that_would_not_fit_in_memory(tmp_path):
    data = _record(tmp_path)
    proc = _cli(tmp_path, data, "--horizon", "2400", "--order", "4")
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "horizon 2400" in lines[0] and "would need about" in lines[0] and "is available" in lines[0], lines[0]
    assert not (tmp_path / "m.json").exists()
    # the same record and limits with an ordinary horizon: the guard does not refuse real work
    proc = _cli(tmp_path, data, "--horizon", "10", "--order", "4")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "m.json").exists()


def test_estimator_refuses_horizon_order_and_frequency_counts_beyond_memory(tmp_path):
    script = textwrap.dedent(
        """
        import numpy as np
        from stageid import ResourceError
        from stageid.data import Experiment
        from stageid.subspace import HankelMAP

        u = np.random.default_rng(0).standard_normal((6000, 3))
        exp = Experiment(u, np.cumsum(u, axis=0) * 0.01, 0.002)
        for settings in [dict(horizon=2400, order=4), dict(horizon=10, order=400), dict(horizon=10, order=4, n_frequencies=10**8)]:
            try:
                HankelMAP(**settings).fit(exp)
            except ResourceError as exc:
                print("refused:", exc)
            else:
                print("fitted:", settings)
        """
    )
    proc = _run([sys.executable, "-c", script], tmp_path)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert len(lines) == 3 and all(line.startswith("refused: HankelMAP with horizon") for line in lines), proc.stdout
    assert "would need about" in lines[0] and "of memory;" in lines[0]
