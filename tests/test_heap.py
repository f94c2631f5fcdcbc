"""The first fit of a process raises glibc's adaptive malloc thresholds (stageid._heap)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from stageid.runtime import heap as _heap
from stageid.runtime import threads as _threads

# a fit-like pattern: six 1 MB temporaries alive at once, then freed; the page faults of the
# last nine of ten rounds
_PROBE = """
import resource, numpy as np
from stageid._heap import prime_heap
prime_heap()
def work():
    return [np.ones(1 << 17) for _ in range(6)]
work()
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(9):
    work()
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""


def test_primes_once_per_process(monkeypatch):
    monkeypatch.delenv("STAGEID_HEAP_PRIMING", raising=False)
    monkeypatch.setattr(_heap, "_primed", False)
    assert _heap.prime_heap() is _heap._is_glibc()
    assert _heap.prime_heap() is False


def test_the_environment_switches_it_off(monkeypatch):
    monkeypatch.setenv("STAGEID_HEAP_PRIMING", "0")
    monkeypatch.setattr(_heap, "_primed", False)
    assert _heap.prime_heap() is False


def test_every_wrapped_fit_primes(monkeypatch):
    calls = []
    monkeypatch.setattr(_threads, "prime_heap", lambda: calls.append(1))
    _threads.single_blas_thread(lambda: None)()
    assert calls == [1]


def test_reading_a_table_primes_before_the_reader_allocates(monkeypatch, tmp_path):
    # the reader's freed arrays are what the fit after it reuses, so it must prime first
    from stageid.data import io, npz_format, write_npz

    events = []
    monkeypatch.setattr(io, "prime_heap", lambda: events.append("prime"))
    real = npz_format.read_npz
    monkeypatch.setattr(io, "read_npz", lambda *a, **k: events.append("read") or real(*a, **k))
    path = tmp_path / "r.npz"
    write_npz(path, {"u": [1.0, 2.0, 3.0], "y": [0.0, 1.0, 0.5]}, dt=0.1)
    io.read_table(path)
    assert events == ["prime", "read"]


@pytest.mark.skipif(not _heap._is_glibc(), reason="glibc's malloc thresholds only")
def test_primed_processes_reuse_freed_blocks_instead_of_faulting_them_in_again():
    def faults(priming: str) -> int:
        env = {"STAGEID_HEAP_PRIMING": priming, "PATH": ""}
        out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, env=env, check=True)
        return int(out.stdout.split()[-1])

    # unprimed: glibc's thresholds have only risen to ~1 MB (the largest block freed), so
    # the 6 MB freed at the top of the heap are returned to the kernel and faulted in again
    # (1 536 pages) every round
    assert faults("0") >= 9 * 1000
    # primed (thresholds 16 / 32 MB): the freed memory is kept and reused
    assert faults("1") < 9 * 100
