"""Chunked statistics on a real Dask cluster (a scheduler and two workers on 127.0.0.1): the
same sums as here, computed on the workers, and nothing lost when a worker dies mid-way."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from _chunked_data import columns, slowed, write
from conftest import run_main
from stageid.data.chunked import open_chunked
from stageid.frf.welch_chunked import chunked_cross_spectra
from stageid.models import load_model
from stageid.runtime.cluster import dask_client
from stageid.subspace.statistics.chunked_statistics import column_moments, range_lag_sums

N = 12_011
IO = ("--inputs", "u1,u2", "--outputs", "y1,y2")


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    x = columns(N, seed=7)
    return open_chunked(write(tmp_path_factory.mktemp("rec"), "h5", x), ["u1", "u2"], ["y1", "y2"])


def _rel(a, b) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def test_statistics_on_the_cluster_equal_the_local_ones(dask_cluster, record):
    from distributed import get_task_stream

    mom = column_moments(record, 1000)
    shift, scale = mom.mean, mom.rms
    ranges = [(0, 4000), (4000, N)]
    local, local_power = range_lag_sums(record, ranges, 15, shift, scale, 701, spectrum=True)
    local_spectra = chunked_cross_spectra(record, 512, 0.5, chunk=900)
    with dask_client(dask_cluster.address) as client, get_task_stream(client) as stream:
        remote_mom = column_moments(record, 1000, client)
        remote, remote_power = range_lag_sums(record, ranges, 15, shift, scale, 701, client, spectrum=True)
        remote_spectra = chunked_cross_spectra(record, 512, 0.5, chunk=900, client=client)
    # the same sums, added in the order the tasks finished: equal to rounding
    np.testing.assert_allclose(remote_mom.mean, mom.mean, rtol=1e-13)
    np.testing.assert_allclose(remote_mom.m2, mom.m2, rtol=1e-12)
    for a, b in zip(remote, local):
        assert _rel(a, b) < 1e-12
    assert _rel(remote_power, local_power) < 1e-12
    assert _rel(remote_spectra.S, local_spectra.S) < 1e-12
    workers = {t["worker"] for t in stream.data}
    assert len(workers) == 2  # the tasks ran on both workers, not here
    assert sum(1 for t in stream.data if "lag_task" in t["key"]) == len(range(0, 4000, 701)) + len(range(4000, N, 701))


@pytest.fixture
def helpers_on_cluster_path(monkeypatch):
    """The scheduler and workers started after this can import the tests' helpers (SlowRecord)."""
    here = str(Path(__file__).resolve().parent)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [here, os.environ.get("PYTHONPATH")])))


def test_a_worker_killed_mid_computation_loses_nothing(helpers_on_cluster_path, dask_cluster, record):
    slow = slowed(record, 0.05)  # 87 tasks of >= 50 ms on two workers: ~2 s
    mom = column_moments(record, 1000)
    local, _ = range_lag_sums(record, [(0, N)], 15, mom.mean, mom.rms, 139)
    box = {}
    with dask_client(dask_cluster.address) as client:

        def compute():
            box["R"], _ = range_lag_sums(slow, [(0, N)], 15, mom.mean, mom.rms, 139, client)

        worker = threading.Thread(target=compute)
        worker.start()
        deadline = time.monotonic() + 30
        while not any(client.processing().values()) and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.4)  # some tasks done, others running on the worker about to die
        assert worker.is_alive()  # the computation is not over when the worker dies
        dask_cluster.kill_worker(0)
        worker.join(timeout=120)
        assert not worker.is_alive()
        assert len(client.scheduler_info()["workers"]) == 1
    assert _rel(box["R"][0], local[0]) < 1e-12


def test_identify_statespace_with_scheduler_equals_here(dask_cluster, record, tmp_path):
    args = ("identify", "statespace", record.path, *IO, "--order", "4", "--band", "0:450")
    rc, _, err = run_main(*args, "--scheduler", dask_cluster.address, "-o", tmp_path / "cluster.json")
    assert rc == 0, err
    rc, _, err = run_main(*args, "-o", tmp_path / "here.json")
    assert rc == 0, err
    f = np.linspace(1.0, 450.0, 40)
    got = load_model(tmp_path / "cluster.json")
    want = load_model(tmp_path / "here.json")
    assert got.inputs == want.inputs
    assert _rel(got.frequency_response(f), want.frequency_response(f)) < 1e-8
