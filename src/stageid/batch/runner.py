"""Run a batch of jobs on a Dask cluster: skip what is up to date, collect, write, summarise.

The client does all the writing into DIR: a worker runs one job's command into a private
temporary folder and sends the output's bytes back, and the client writes ``DIR/<name>.ext``
atomically the moment the job completes.  So a worker that dies mid-write leaves nothing in
DIR, Dask can rerun a lost job on another worker without two writers racing, and an
interrupted batch leaves only whole files (the jobs finished so far, and their state).
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import signal
import threading
import time
import uuid
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..display import html_repr, short_repr
from .commands import Job
from .state import fingerprint, load_state, save_state, write_now

__all__ = ["Outcome", "job_result", "SUMMARY_FILE", "SUMMARY_COLUMNS", "run_batch", "summary_text", "up_to_date"]

SUMMARY_FILE = "summary.csv"
SUMMARY_COLUMNS = ("name", "status", "seconds", "worker", "error")
#: Seconds between two saves of the state while jobs complete (and once at the end).
_STATE_EVERY = 2.0


@dataclass(frozen=True)
class Outcome:
    """One row of ``summary.csv``: status ``ok``, ``failed`` or ``skipped``; seconds the job ran
    on its worker (None when skipped or lost); a one-line error for a failure."""

    name: str
    status: str
    seconds: float | None = None
    worker: str = ""
    error: str = ""

    def __repr__(self) -> str:
        return short_repr(self)

    def _repr_html_(self) -> str:
        return html_repr(self)


def up_to_date(job: Job, recorded: dict | None, current: dict, folder: Path) -> bool:
    """True when ``job`` succeeded before with the same fingerprint and its output is untouched."""
    if not recorded or any(recorded.get(k) != v for k, v in current.items()):
        return False
    if any(digest is None for _, digest in current["inputs"]):
        return False
    try:
        data = (folder / job.output_name).read_bytes()
    except OSError:
        return False
    return recorded.get("output") == hashlib.sha256(data).hexdigest()


def run_batch(
    jobs: Sequence[Job],
    folder: Path,
    task: Callable[..., dict],
    connect: Callable[[], AbstractContextManager[Any]],
    version: str,
    progress: Callable[[int], Any],
) -> list[Outcome]:
    """Run ``jobs`` (those not up to date) with ``task`` on the client ``connect()`` gives.

    ``task(argv, suffix)`` runs on a worker and returns ``{"ok", "seconds", "worker",
    "error", "data"}``; ``progress(total)`` returns a tqdm-like bar.
    ``folder`` is created (its parent must exist) once the cluster is up; the cluster is
    started only when some job has to run.  Returns one outcome per job, in
    the order of ``jobs``; ``summary.csv`` is written when every job has one.
    """
    state = load_state(folder)
    prints = {job.name: fingerprint(job.command, job.inputs, version) for job in jobs}
    outcomes = {
        job.name: Outcome(job.name, "skipped")
        for job in jobs
        if up_to_date(job, state.get(job.name), prints[job.name], folder)
    }
    state = {name: state[name] for name in outcomes} | {
        name: entry for name, entry in state.items() if name not in prints
    }  # jobs no longer in the manifest keep their record
    pending = [job for job in jobs if job.name not in outcomes]
    if pending:
        with connect() as client, contextlib.closing(progress(len(pending))) as bar:
            folder.mkdir(exist_ok=True)  # after the cluster is up: an unreachable one writes nothing
            _collect(client, pending, task, folder, prints, state, outcomes, bar)
    save_state(folder, state)
    ordered = [outcomes[job.name] for job in jobs]
    write_now(folder / SUMMARY_FILE, summary_text(ordered).encode())
    return ordered


def _collect(client, pending, task, folder: Path, prints, state, outcomes, bar) -> None:
    """Submit every pending job; write each output, record each outcome as its job completes."""
    from distributed import as_completed

    token = uuid.uuid4().hex[:8]
    futures = {
        client.submit(task, job.argv, job.suffix, key=f"stageid-batch-{token}-{i}", pure=False): job
        for i, job in enumerate(pending)
    }
    saved = time.monotonic()
    done = as_completed(futures, loop=client.loop)
    try:
        with _deferred_interrupt() as interrupted:
            while not done.is_empty():
                if interrupted.is_set():  # Ctrl-C, taken here between jobs
                    raise KeyboardInterrupt
                ready = done.next_batch(block=False)
                if not ready:
                    time.sleep(0.05)
                for future in ready:
                    job = futures.pop(future)
                    outcomes[job.name] = _finish(job, future, folder, prints[job.name], state)
                    bar.update(1)
                if time.monotonic() - saved > _STATE_EVERY:
                    save_state(folder, state)
                    saved = time.monotonic()
    finally:  # an interrupt: stop what still runs, keep the state of what finished
        client.cancel(list(futures))
        save_state(folder, state)


@contextlib.contextmanager
def _deferred_interrupt():
    """SIGINT sets an event instead of raising wherever Python happens to be.

    Raised asynchronously, the KeyboardInterrupt can land in a Dask finaliser (``Future.__del__``),
    which prints "Exception ignored" and swallows it, and the batch then runs to the end.
    """
    event = threading.Event()
    try:
        previous = signal.signal(signal.SIGINT, lambda *_: event.set())
    except ValueError:  # not the main thread: leave signals alone
        yield event
        return
    try:
        yield event
    finally:
        signal.signal(signal.SIGINT, previous)


def _finish(job: Job, future, folder: Path, current: dict, state: dict) -> Outcome:
    """The outcome of a completed future; its output written (ok) or a stale one removed (failed)."""
    target = folder / job.output_name
    result = job_result(future)
    if result["ok"]:
        write_now(target, result["data"])
        state[job.name] = {**current, "output": hashlib.sha256(result["data"]).hexdigest()}
        return Outcome(job.name, "ok", result["seconds"], result["worker"])
    state.pop(job.name, None)
    with contextlib.suppress(FileNotFoundError):
        target.unlink()  # DIR/<name> exists only for jobs that are ok now
    error = " ".join(str(result["error"]).split())
    for given, absolute in job.inputs:  # the paths as the manifest gives them, as the direct command says
        error = error.replace(absolute, given)
    return Outcome(job.name, "failed", result["seconds"], result["worker"], error)


def job_result(future) -> dict:
    """The task's result dict, or a failed one carrying the exception the task raised.

    Asks for the result rather than reading ``future.status`` first: a future that completed
    on a worker that died before the client fetched its bytes goes back to pending and is
    recomputed elsewhere, and its ``exception()`` is then None, not an error.
    """
    try:
        return future.result()
    except Exception as exc:  # the task itself raised, or its workers kept dying (KilledWorker)
        return {"ok": False, "seconds": None, "worker": "", "error": f"{type(exc).__name__}: {exc}"}


def summary_text(outcomes: Sequence[Outcome]) -> str:
    """``summary.csv``: ``name,status,seconds,worker,error``, one row per job in manifest order."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(SUMMARY_COLUMNS)
    for o in outcomes:
        seconds = "" if o.seconds is None else f"{o.seconds:.3f}"
        writer.writerow([o.name, o.status, seconds, o.worker, o.error])
    return buffer.getvalue()
