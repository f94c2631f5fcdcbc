"""The first fit of a process raises glibc's adaptive malloc thresholds (stageid._heap)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from stageid import _heap, _threads

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
