"""Cost of the uncertainty (issue 20, point 5): an identify with and without it, paired runs.

* closed loop: ``ClosedLoopIdentification`` on the demo's maglev chirps with
  ``covariance="none"`` against the default ``"sandwich"`` plus
  ``response_uncertainty`` on 200 points over the band (what ``identify closed-loop
  --uncertainty`` adds);
* hysteresis: ``PIIdentifier`` (classical and modified PI, 20 operators) on the piezo
  actuator's decaying triangle with ``weight_uncertainty="none"`` against ``"auto"`` plus the loop band on
  the record.

Runs alternate (without, with, without, ...) so that the load of a shared machine hits both
alike; the medians and the median of the per-pair ratios are printed.

    .venv/bin/python benchmarks/bench_uncertainty.py [--pairs 3] [closedloop] [hysteresis]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from stageid.closedloop import ClosedLoopIdentification
from stageid.hysteresis import PIIdentifier
from stageid.plants import maglev
from stageid.plants.piezo_actuator import EXPERIMENTS


def closed_loop_runs():
    refs = [f"r_{o}" for o in maglev.OUTPUTS]
    tables = [maglev.simulate_chirp(a, seed=k) for k, a in enumerate(maglev.OUTPUTS)]  # the demo's records
    exps = [t.experiment(refs, list(maglev.OUTPUTS), name=f"chirp-{a}") for t, a in zip(tables, maglev.OUTPUTS)]
    f = np.geomspace(20.0, 300.0, 200)

    def without():
        ClosedLoopIdentification(maglev.controller(), band=(20.0, 300.0), covariance="none").fit(exps)

    def with_():
        res = ClosedLoopIdentification(maglev.controller(), band=(20.0, 300.0)).fit(exps)
        res.response_uncertainty(f)

    return without, with_


def hysteresis_runs(kind: str):
    ident = EXPERIMENTS["decaying-triangle"](seed=0)

    def without():
        PIIdentifier(kind, n_operators=20).fit(ident)

    def with_():
        fit = PIIdentifier(kind, n_operators=20, weight_uncertainty="auto").fit(ident)
        fit.weight_uncertainty.output_band(fit.model, ident.u)

    return without, with_


def paired(without, with_, pairs: int) -> tuple[float, float, float]:
    t0, t1, ratios = [], [], []
    for _ in range(pairs):
        a = time.perf_counter()
        without()
        b = time.perf_counter()
        with_()
        c = time.perf_counter()
        t0.append(b - a)
        t1.append(c - b)
        ratios.append((c - b) / (b - a))
    return float(np.median(t0)), float(np.median(t1)), float(np.median(ratios))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("what", nargs="*", default=["closedloop", "hysteresis"])
    args = ap.parse_args()
    cases = {}
    if "closedloop" in args.what:
        cases["maglev closed loop (sandwich + 200-point band)"] = closed_loop_runs()
    if "hysteresis" in args.what:
        cases["classical PI, 20 operators (auto + loop band)"] = hysteresis_runs("pi")
        cases["modified PI, 20 operators (auto + loop band)"] = hysteresis_runs("modified-pi")
    print(f"| case | without [s] | with [s] | ratio (median of {args.pairs} pairs) |")
    print("|---|---|---|---|")
    for name, (without, with_) in cases.items():
        without()  # warm-up: numba compilation and imports count for neither
        t0, t1, r = paired(without, with_, args.pairs)
        print(f"| {name} | {t0:.2f} | {t1:.2f} | {r:.2f} |", flush=True)


if __name__ == "__main__":
    main()
