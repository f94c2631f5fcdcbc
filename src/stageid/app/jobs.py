"""Jobs of ``stageid serve``: every fit and export runs off the request thread, cancellable.

A command job runs the ``stageid`` command line in a child process with the session's
workspace as its folder: the model it writes is the command's own output (byte for byte),
its one-line error is the command's own message, and cancelling it ends the process, which a
thread running compiled code could not offer.  A function job runs a short in-process
computation (the singular values of a Hankel matrix) in a thread; cancelling it discards its
result.  The page polls a job for its state and elapsed time.
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["Job", "start_command", "start_function", "command_text"]

_POLL_S = 0.05


def command_text(args: list[str]) -> str:
    """The shell line a user would type for ``stageid`` with ``args``."""
    return shlex.join(["stageid", *args])


class Job:
    """One running or finished job; its public state is :meth:`state` (a JSON-ready dict).

    ``status`` goes ``running`` -> ``done`` | ``failed`` | ``cancelled``; ``error`` is the one
    line a failed job reports; ``result`` is what its finishing step returned.
    """

    def __init__(self, key: str, title: str, cli: str = "", python: str = "") -> None:
        self.key = key
        self.title = title
        self.cli = cli
        self.python = python
        self.status = "running"
        self.error = ""
        self.result: dict[str, Any] = {}
        self.started = time.monotonic()
        self.ended: float | None = None
        self._cancel = threading.Event()
        self._process: subprocess.Popen | None = None

    def cancel(self) -> None:
        """Stop the job: its process is terminated; a function job's result is dropped."""
        self._cancel.set()
        process = self._process
        if process is not None and process.poll() is None:
            process.terminate()
        elif process is None and self.status == "running":
            self.finish("cancelled")  # a thread cannot be stopped: its result will be dropped

    def state(self) -> dict[str, Any]:
        end = self.ended if self.ended is not None else time.monotonic()
        return {
            "id": self.key,
            "title": self.title,
            "status": self.status,
            "elapsed": round(end - self.started, 2),
            "error": self.error,
            "cli": self.cli,
            "python": self.python,
            "result": self.result if self.status == "done" else {},
        }

    def finish(self, status: str, error: str = "", result: dict[str, Any] | None = None) -> None:
        if self.status == "cancelled":
            return
        if self._cancel.is_set():
            status, error, result = "cancelled", "cancelled", None
        self.error = error
        self.result = result or {}
        self.ended = time.monotonic()
        self.status = status


def _finish_step(job: Job, then: Callable[[], dict[str, Any]]) -> None:
    """Run a job's finishing step; a failure there is the job's failure, in one line."""
    from .._errors import StageIdError

    try:
        job.finish("done", result=then())
    except (StageIdError, OSError, ValueError) as exc:
        job.finish("failed", error=f"stageid: error: {' '.join(str(exc).split())}")


def _child_environment() -> dict[str, str]:
    """The environment of a command: the child imports the same stageid as this server."""
    import stageid

    env = dict(os.environ)
    here = str(Path(stageid.__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (here, env.get("PYTHONPATH", "")) if p)
    return env


def _run_command(job: Job, args: list[str], cwd: Path, then: Callable[[], dict[str, Any]]) -> None:
    err_path = cwd / f"{job.key}.stderr"
    command = [sys.executable, "-m", "stageid", *args]
    with open(err_path, "wb") as err, open(cwd / f"{job.key}.stdout", "wb") as out:
        job._process = subprocess.Popen(command, cwd=cwd, stdout=out, stderr=err, env=_child_environment())
        while job._process.poll() is None:
            if job._cancel.wait(_POLL_S):
                job._process.terminate()
                job._process.wait()
    if job._process.returncode != 0:
        lines = [line for line in err_path.read_text(errors="replace").splitlines() if line.strip()]
        job.finish("failed", error=lines[-1] if lines else f"stageid ended with code {job._process.returncode}")
        return
    _finish_step(job, then)


def start_command(job: Job, args: list[str], cwd: Path, then: Callable[[], dict[str, Any]], wait: bool = False) -> Job:
    """Run ``stageid args`` in ``cwd`` in a child process; ``then()`` builds the result when it succeeded."""
    job.cli = job.cli or command_text(args)
    thread = threading.Thread(target=_run_command, args=(job, args, cwd, then), daemon=True)
    thread.start()
    if wait:
        thread.join()
    return job


def start_function(job: Job, work: Callable[[], dict[str, Any]]) -> Job:
    """Run ``work()`` in a thread; its dict is the job's result."""
    threading.Thread(target=_finish_step, args=(job, work), daemon=True).start()
    return job
