"""Fits run with one BLAS thread and restore the caller's thread pool afterwards."""

from __future__ import annotations

import os

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from stageid.runtime.threads import single_blas_thread


def _blas_threads() -> list[int]:
    return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]


@pytest.fixture
def blas():
    if not _blas_threads():
        pytest.skip("no BLAS thread pool visible to threadpoolctl")


def test_fit_runs_single_threaded_and_restores(blas, monkeypatch):
    monkeypatch.delenv("STAGEID_BLAS_THREADS", raising=False)
    seen = []

    @single_blas_thread
    def fit():
        seen.extend(_blas_threads())
        return np.linalg.solve(np.eye(3) * 2.0, np.ones(3))

    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        np.testing.assert_allclose(fit(), 0.5)
        assert _blas_threads() == before
    assert seen and set(seen) == {1}


def test_environment_overrides(blas, monkeypatch):
    seen = []

    @single_blas_thread
    def fit():
        seen.extend(_blas_threads())

    with threadpool_limits(limits=2, user_api="blas"):
        monkeypatch.setenv("STAGEID_BLAS_THREADS", "0")  # leave the pool as it is
        fit()
        assert set(seen) == {2}
    seen.clear()
    if (os.cpu_count() or 1) < 2:
        pytest.skip("a BLAS pool of 2 threads needs 2 cores")
    # outer limit 1, asked for 2: "use 2" and "leave the pool alone" now give different counts
    with threadpool_limits(limits=1, user_api="blas"):
        monkeypatch.setenv("STAGEID_BLAS_THREADS", "2")
        fit()
        assert set(seen) == {2}
        assert set(_blas_threads()) == {1}  # and the caller's limit is back afterwards


def test_estimators_are_wrapped():
    from stageid.closedloop import ClosedLoopIdentification
    from stageid.hysteresis import PIIdentifier
    from stageid.subspace import HankelMAP

    for fn in (HankelMAP.fit, ClosedLoopIdentification.fit, PIIdentifier.fit):
        assert getattr(fn, "__wrapped__", None) is not None, fn


def test_the_controller_is_rebuilt_when_scipy_arrives(monkeypatch):
    import sys

    from stageid.runtime import threads as _threads

    monkeypatch.setattr(_threads, "_controller", None)
    first = _threads._blas_controller()
    assert _threads._blas_controller() is first  # kept while nothing new is loaded
    monkeypatch.setitem(sys.modules, "scipy.linalg", sys.modules.get("scipy.linalg", object()))
    monkeypatch.setattr(_threads, "_controller", (False, first))
    assert _threads._blas_controller() is not first  # scipy arrived: scanned again


def test_map_in_threads_keeps_item_order_and_raises_the_first_failing_item_after_all_ran():
    import threading

    from stageid.runtime.threads import map_in_threads

    seen, names = [], set()

    def fn(i):
        seen.append(i)
        names.add(threading.current_thread().name)
        if i in (5, 3):
            raise ValueError(f"item {i}")
        return i * i

    assert map_in_threads(lambda i: i * i, 20, 3) == [i * i for i in range(20)]
    with pytest.raises(ValueError, match="item 3"):
        map_in_threads(fn, 12, 3)
    assert sorted(seen) == list(range(12))  # every item ran, the failing ones included
    assert map_in_threads(fn, 0, 4) == []
    names.clear()
    with pytest.raises(ValueError, match="item 3"):
        map_in_threads(fn, 6, 1)
    assert names == {threading.current_thread().name}  # one thread: the caller's own


def test_stageid_threads_sets_the_default_thread_count(monkeypatch):
    from stageid.runtime.threads import default_threads

    monkeypatch.setenv("STAGEID_THREADS", "3")
    assert default_threads() == 3
    for raw in ("0", "-2", "many", ""):
        monkeypatch.setenv("STAGEID_THREADS", raw)
        assert default_threads() == 1
    monkeypatch.delenv("STAGEID_THREADS")
    assert default_threads() == 1
