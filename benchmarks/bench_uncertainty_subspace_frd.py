"""Cost of ``response_uncertainty`` against the identification it follows (issue 20, point 5).

Alternating paired runs (the machine is shared): for each case, ``fit`` alone and ``fit`` then
``response_uncertainty`` on the default grid (200 log-spaced points over the identified
band), repeated; medians and the median of the per-pair ratios.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_uncertainty_subspace_frd.py [repeats]
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np

from stageid.frf import FRDIdentification, FrequencyResponse
from stageid.plants import piezo_stage as ps
from stageid.subspace import HankelMAP

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
sys.path.insert(0, str(Path(__file__).parents[1] / "studies" / "uncertainty"))
from run_study import two_mode_plant  # noqa: E402

from _subspace_systems import band_limited, record  # noqa: E402


def p558_direct():
    g = ps.model()
    exp = record(g, band_limited(20000, 3, g.dt, 1) * np.array([10.0, 100.0, 100.0]), 0.01, 1)
    return lambda: HankelMAP(order=15).fit(exp)


def p558_channels():
    exps = [ps.EXPERIMENTS[k](0) for k in ("chirp-z", "chirp-rx", "chirp-ry")]
    return lambda: HankelMAP(order=[7, 4, 4], per_channel=True).fit(exps)


def frd():
    g = two_mode_plant()
    f = np.linspace(1, 200, 300)
    Gt = g.frequency_response(f)
    sd = 0.02 * np.abs(Gt).max() * np.ones(Gt.shape)
    rng = np.random.default_rng(0)
    data = FrequencyResponse(f, Gt + sd * (rng.standard_normal(Gt.shape) + 1j * rng.standard_normal(Gt.shape)), sd)
    return lambda: FRDIdentification(order="auto", dt=g.dt).fit(data)


def band_of(res):
    if hasattr(res, "channels"):
        return min(c.band[0] for c in res.channels), max(c.band[1] for c in res.channels)
    return res.band


CASES = {"p558 direct (horizon auto, order 15)": p558_direct, "p558 per channel (auto horizon)": p558_channels,
         "frd 1x2 (order auto)": frd}  # fmt: skip


def main() -> None:
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    for name, make in CASES.items():
        fit = make()
        fit()  # warm-up (compilation, caches)
        alone, both, ratios = [], [], []
        for _ in range(repeats):
            t = time.perf_counter()
            fit()
            a = time.perf_counter() - t
            t = time.perf_counter()
            res = fit()
            lo, hi = band_of(res)
            res.response_uncertainty(np.geomspace(lo if lo > 0 else 1e-3 * hi, hi, 200))
            b = time.perf_counter() - t
            alone.append(a)
            both.append(b)
            ratios.append(b / a)
        print(
            f"{name}: fit {statistics.median(alone):.3f} s, fit + uncertainty {statistics.median(both):.3f} s, "
            f"ratio {statistics.median(ratios):.2f} (min {min(ratios):.2f}, max {max(ratios):.2f}), {repeats} pairs",
            flush=True,
        )


if __name__ == "__main__":
    main()
