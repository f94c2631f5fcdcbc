"""A real Dask cluster for the tests that need one: a scheduler and workers on 127.0.0.1.

Started as separate processes (``python -m distributed.cli.dask_scheduler`` / ``dask_worker``,
no nanny), so a test can kill a worker outright and see what Dask does about it.  Use the
``dask_cluster`` fixture (tests/conftest.py) or :class:`TestCluster` as a context manager.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path


class TestCluster:
    """A scheduler plus ``n_workers`` single-threaded workers, all on 127.0.0.1."""

    __test__ = False  # not a test class, despite the name

    def __init__(self, n_workers: int = 2, startup_timeout: float = 60.0):
        self.n_workers = n_workers
        self.startup_timeout = startup_timeout
        self.folder = Path(tempfile.mkdtemp(prefix="stageid-dask-"))
        self.scheduler_file = self.folder / "scheduler.json"
        self.scheduler: subprocess.Popen | None = None
        self.workers: list[subprocess.Popen] = []
        self.address = ""

    def _spawn(self, module: str, *args: str) -> subprocess.Popen:
        env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
        log = open(self.folder / f"{module.rsplit('.', 1)[-1]}-{len(self.workers)}.log", "w")
        return subprocess.Popen(
            [sys.executable, "-m", module, *args],
            stdout=log,
            stderr=subprocess.STDOUT,
            env=env,
            start_new_session=True,
        )

    def start(self) -> TestCluster:
        self.scheduler = self._spawn(
            "distributed.cli.dask_scheduler",
            "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
            "--scheduler-file", str(self.scheduler_file),
        )  # fmt: skip
        deadline = time.monotonic() + self.startup_timeout
        while not self.scheduler_file.exists():
            if time.monotonic() > deadline or self.scheduler.poll() is not None:
                self.close()
                raise RuntimeError(f"the Dask scheduler did not start; see {self.folder}")
            time.sleep(0.1)
        time.sleep(0.2)  # the file is written before it is complete on a slow machine
        self.address = json.loads(self.scheduler_file.read_text())["address"]
        for _ in range(self.n_workers):
            self.add_worker()
        self.wait_for_workers(self.n_workers, deadline)
        return self

    def add_worker(self) -> subprocess.Popen:
        worker = self._spawn(
            "distributed.cli.dask_worker",
            "--nthreads", "1", "--no-nanny", "--no-dashboard", "--host", "127.0.0.1",
            "--name", f"w{len(self.workers)}", "--scheduler-file", str(self.scheduler_file),
        )  # fmt: skip
        self.workers.append(worker)
        return worker

    def wait_for_workers(self, n: int, deadline: float) -> None:
        from distributed import Client

        with Client(self.address, timeout="30s", set_as_default=False) as client:
            while len(client.scheduler_info()["workers"]) < n:
                if time.monotonic() > deadline:
                    self.close()
                    raise RuntimeError(f"only {len(client.scheduler_info()['workers'])} of {n} workers came up")
                time.sleep(0.1)

    def worker_address(self, index: int) -> str:
        """The address of worker ``index`` (in start order; workers are named w0, w1, ...)."""
        from distributed import Client

        with Client(self.address, timeout="30s", set_as_default=False) as client:
            workers = client.scheduler_info(n_workers=-1)["workers"]
        return next(addr for addr, info in workers.items() if info.get("name") == f"w{index}")

    def kill_worker(self, index: int = 0) -> None:
        """SIGKILL one worker process: no goodbye to the scheduler, its tasks are simply lost."""
        os.killpg(self.workers[index].pid, signal.SIGKILL)
        self.workers[index].wait(timeout=30)

    def close(self) -> None:
        for proc in [*self.workers, self.scheduler]:
            if proc is not None and proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(timeout=30)

    def __enter__(self) -> TestCluster:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()
