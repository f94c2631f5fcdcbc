"""`stageid batch` when things go wrong on the cluster: a worker killed mid-batch loses no job,
and an interrupted batch leaves only whole files (a real scheduler and workers on 127.0.0.1)."""

from __future__ import annotations

import json
import os
import shlex
import signal
import subprocess
import sys
import time

import pytest

from _batch_records import read_summary, write_manifest, write_record
from conftest import run_main
from dask_cluster import TestCluster

# auto order and horizon: ~1-2 s per job here, long enough to be caught running
IDENTIFY_AUTO = "identify statespace {} --inputs Z --outputs z"
N_JOBS = 8


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    """Records, the manifest, and each job's command run directly: the bytes every batch output must equal."""
    data = tmp_path_factory.mktemp("data")
    direct = tmp_path_factory.mktemp("direct")
    jobs, expected = [], {}
    for i in range(N_JOBS):
        write_record(data, f"unit{i}.csv", "chirp-z", seed=i)
        name, command = f"unit{i}", IDENTIFY_AUTO.format(f"unit{i}.csv")
        rc, _, err = run_main(*shlex.split(command), "-o", direct / f"{name}.json", cwd=data)
        assert rc == 0, err
        jobs.append((name, command))
        expected[name] = (direct / f"{name}.json").read_bytes()
    return write_manifest(data / "fleet.csv", jobs), jobs, expected


def _start_batch(manifest, out, address) -> subprocess.Popen:
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    return subprocess.Popen(
        [sys.executable, "-m", "stageid", "batch", str(manifest), "--out", str(out), "--scheduler", address],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )


def _wait_for(condition, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def test_a_worker_killed_mid_batch_loses_no_job(fleet, tmp_path):
    from distributed import Client

    manifest, jobs, expected = fleet
    out = tmp_path / "out"
    with TestCluster(n_workers=2) as cluster, Client(cluster.address, set_as_default=False) as client:
        victim = cluster.worker_address(0)
        batch = _start_batch(manifest, out, cluster.address)
        try:
            # the victim has finished a job (imports paid) and holds another one when it dies
            _wait_for(lambda: out.is_dir() and any(out.glob("unit*.json")), 240, "a first output")
            _wait_for(lambda: client.processing().get(victim), 120, "a job on worker 0")
            lost = set(client.processing()[victim])
            cluster.kill_worker(0)
            stdout, stderr = batch.communicate(timeout=600)
        finally:
            if batch.poll() is None:
                batch.kill()
    rows = read_summary(out)
    assert batch.returncode == 0, (stdout, stderr, rows)
    assert f"{N_JOBS} ok, 0 skipped, 0 failed" in stdout
    assert [r["status"] for r in rows] == ["ok"] * N_JOBS
    assert lost  # a job really was on the killed worker ...
    for key in lost:  # ... and it finished elsewhere
        assert rows[int(str(key).rsplit("-", 1)[1])]["worker"] not in ("", victim)
    for name, _ in jobs:
        assert (out / f"{name}.json").read_bytes() == expected[name], name


def test_an_interrupted_batch_leaves_whole_files_and_the_rerun_finishes_it(fleet, tmp_path):
    manifest, jobs, expected = fleet
    out = tmp_path / "out"
    with TestCluster(n_workers=2) as cluster:
        batch = _start_batch(manifest, out, cluster.address)
        try:
            _wait_for(lambda: out.is_dir() and any(out.glob("unit*.json")), 240, "a first output")
            batch.send_signal(signal.SIGINT)  # Ctrl-C
            _, stderr = batch.communicate(timeout=120)
        finally:
            if batch.poll() is None:
                batch.kill()
        assert batch.returncode == 130, stderr
        assert stderr.strip().splitlines()[-1] == "stageid: interrupted"
        files = sorted(p.name for p in out.iterdir())
        done = [name for name, _ in jobs if f"{name}.json" in files]
        assert set(files) <= {".stageid-batch.json", *(f"{name}.json" for name, _ in jobs)}  # no temporaries
        assert 1 <= len(done) < N_JOBS
        for name in done:  # whole files, each the direct command's output
            assert (out / f"{name}.json").read_bytes() == expected[name]
        state = json.loads((out / ".stageid-batch.json").read_text())
        assert set(state["jobs"]) <= set(done)
        rc, stdout, err = run_main("batch", manifest, "--out", out, "--scheduler", cluster.address)
    assert rc == 0, err
    statuses = {r["name"]: r["status"] for r in read_summary(out)}
    assert {n for n, s in statuses.items() if s == "skipped"} == set(state["jobs"])
    for name, _ in jobs:
        assert (out / f"{name}.json").read_bytes() == expected[name]


class _RecomputedFuture:
    """A future whose worker died after it finished and before its bytes were fetched: Dask
    reset it to pending, recomputed it elsewhere, and ``exception()`` is None, not an error."""

    status = "lost"

    def result(self):
        return {"ok": True, "seconds": 1.0, "worker": "tcp://127.0.0.1:2", "error": "", "data": b"{}"}

    def exception(self):
        return None


class _RaisingFuture:
    status = "error"

    def result(self):
        raise ValueError("bad record")

    def exception(self):
        return ValueError("bad record")


def test_a_result_lost_with_its_worker_is_taken_once_recomputed():
    from stageid.batch.runner import job_result

    assert job_result(_RecomputedFuture())["ok"]
    failed = job_result(_RaisingFuture())
    assert not failed["ok"] and failed["error"] == "ValueError: bad record"
