"""The covariance grid's placement against a dense reference (issue 20, session 9).

For each case and seed the model is identified once and ``realised_response_uncertainty`` is
evaluated with the exact covariance on (a) the former even grid at ``MAX_OVERLAP_COLUMNS``,
(b) the mode placement (``grid="modes"``, :mod:`stageid.subspace.covariance_grid`) at the same
cap (and at the further caps of ``--modes-caps=48,36``) and (c) an even grid at ``--ref=N``
columns (default 144; ``--ref=100000``: every frequency of the fit, its own sum), the reference.  Printed per case:
the median and the 90th percentile over points x entries x seeds of ``|std / std_ref - 1|``
(the error of the band's width), and the uncertainty's CPU time of (a) and (b).

    .venv/bin/python studies/uncertainty/grid_check.py [n_seeds] [case ...] [--ref=N] [--bias=none]
        [--modes-caps=48,36]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import run_study as rs  # noqa: E402

import stageid.subspace.uncertainty as unc  # noqa: E402


def std_of(res, grid: str, cap: int, bias: str):
    old = unc.MAX_OVERLAP_COLUMNS
    unc.MAX_OVERLAP_COLUMNS = cap
    try:
        t = time.process_time()
        fr = unc.realised_response_uncertainty(res, rs.FREQS, bias=bias, grid=grid)
        return fr.std, time.process_time() - t
    finally:
        unc.MAX_OVERLAP_COLUMNS = old


def main() -> None:
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    ref = 144
    bias = "local"
    extra: list[int] = []
    for a in sys.argv[1:]:
        if a.startswith("--modes-caps="):
            extra = [int(c) for c in a.split("=", 1)[1].split(",")]
        if a.startswith("--ref="):
            ref = int(a.split("=", 1)[1])
        if a.startswith("--bias="):
            bias = a.split("=", 1)[1]
    n = int(args[0]) if args else 5
    cases = args[1:] or ["random", "random-mimo", "random-3x2", "random-siso", "p558", "p558-channels"]
    cap = unc.MAX_OVERLAP_COLUMNS
    for case in cases:
        variants = [("even", cap), ("modes", cap)] + [("modes", c) for c in extra]
        err = {v: [] for v in variants}
        cpu = {v: [] for v in variants}
        for seed in range(n):
            _, res, _ = rs.CASES[case](seed)
            s_ref, _ = std_of(res, "even", ref, bias)
            for v in variants:
                s, c = std_of(res, v[0], v[1], bias)
                err[v].append(np.abs(s / s_ref - 1).ravel())
                cpu[v].append(c)
        line = [f"{case:14s} seeds {n}, ref {ref} cols:"]
        for v in variants:
            e = np.concatenate(err[v])
            line.append(
                f"{v[0]} {v[1]} cols: |std/ref-1| median {np.median(e):.3f}, p90 {np.quantile(e, 0.9):.3f}, "
                f"max {e.max():.2f}; cpu {np.median(cpu[v]):.3f} s;"
            )
        print(" ".join(line), flush=True)


if __name__ == "__main__":
    main()
