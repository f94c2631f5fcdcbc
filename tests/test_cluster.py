"""stageid.cluster: connecting to a real scheduler, the one-line error for a missing one."""

from __future__ import annotations

import socket
import time

import pytest

from stageid._errors import ClusterError, ParameterError
from stageid.runtime.cluster import check_scheduler_address, dask_client


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_client_on_a_running_cluster_runs_on_its_workers(dask_cluster):
    with dask_client(dask_cluster.address) as client:
        assert client.submit(sum, [1, 2, 3]).result() == 6
        assert len(client.scheduler_info()["workers"]) == 2


def test_unreachable_scheduler_is_a_prompt_cluster_error():
    start = time.monotonic()
    with pytest.raises(ClusterError, match="cannot reach the Dask scheduler"):
        with dask_client(f"tcp://127.0.0.1:{_free_port()}"):
            pass
    assert time.monotonic() - start < 10


@pytest.mark.parametrize("bad", ["127.0.0.1:8786", "http://x:1", "", "tcp://"])
def test_malformed_address_is_a_parameter_error(bad):
    with pytest.raises(ParameterError, match="tcp://HOST:PORT"):
        check_scheduler_address(bad)


def test_local_cluster_starts_and_closes():
    with dask_client(n_workers=1) as client:
        assert client.submit(pow, 2, 10).result() == 1024
