"""`run_batch` on an in-process Dask client with a stand-in task: the state a batch keeps for
jobs a manifest drops and takes back, and the output a failed job must not leave behind."""

from __future__ import annotations

import contextlib
import json

import pytest

from stageid.batch.commands import Job
from stageid.batch.runner import run_batch
from stageid.batch.state import STATE_FILE

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def client():
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=None) as running:
        yield running


def task(argv, suffix):
    """Stands in for a worker running a command: the input file's text, upper-cased, or a failure."""
    text = open(argv[0]).read()
    if text.startswith("bad"):
        return {"ok": False, "seconds": 0.01, "worker": "w", "error": "DataError: bad record", "data": b""}
    return {"ok": True, "seconds": 0.01, "worker": "w", "error": "", "data": text.upper().encode()}


class _Bar:
    def update(self, n):
        pass

    def close(self):
        pass


def _job(name: str, path) -> Job:
    return Job(name, f"simulate {path.name}", "simulate", (str(path),), ((path.name, str(path)),), ".csv")


def _run(client, jobs, out) -> dict[str, str]:
    outcomes = run_batch(jobs, out, task, lambda: contextlib.nullcontext(client), "1.0", lambda n: _Bar())
    return {o.name: o.status for o in outcomes}


def test_a_job_dropped_from_the_manifest_and_taken_back_is_still_up_to_date(client, tmp_path):
    paths = [tmp_path / f"{n}.txt" for n in "abc"]
    for p in paths:
        p.write_text(f"record {p.stem}\n")
    a, b, c = (_job(p.stem, p) for p in paths)
    out = tmp_path / "out"
    assert _run(client, [a, b, c], out) == {"a": "ok", "b": "ok", "c": "ok"}
    assert _run(client, [a], out) == {"a": "skipped"}  # the manifest shrinks...
    recorded = json.loads((out / STATE_FILE).read_text())["jobs"]
    assert set(recorded) == {"a", "b", "c"}  # ...and the records of b and c stay
    assert _run(client, [a, b, c], out) == {"a": "skipped", "b": "skipped", "c": "skipped"}  # ...and grows back
    paths[1].write_text("record b, new\n")
    assert _run(client, [c, b], out) == {"c": "skipped", "b": "ok"}
    assert (out / "b.csv").read_text() == "RECORD B, NEW\n"


def test_a_job_that_fails_now_leaves_no_output_of_its_earlier_success(client, tmp_path):
    good, other = tmp_path / "good.txt", tmp_path / "other.txt"
    good.write_text("fine\n")
    other.write_text("also fine\n")
    jobs = [_job("good", good), _job("other", other)]
    out = tmp_path / "out"
    assert _run(client, jobs, out) == {"good": "ok", "other": "ok"}
    assert (out / "good.csv").read_text() == "FINE\n"
    good.write_text("bad now\n")
    assert _run(client, jobs, out) == {"good": "failed", "other": "skipped"}
    assert not (out / "good.csv").exists()  # a stale output would pass for the failed job's result
    assert "good" not in json.loads((out / STATE_FILE).read_text())["jobs"]
    assert (out / "other.csv").read_text() == "ALSO FINE\n"
    good.write_text("fine again\n")
    assert _run(client, jobs, out) == {"good": "ok", "other": "skipped"}
    assert (out / "good.csv").read_text() == "FINE AGAIN\n"
