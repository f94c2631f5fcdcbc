"""The direct route on the paper's maglev reference (Shakir & Kim eq. 22-24, 3x3, unstable poles
54.62, 82.21 and 86.73 rad/s) under its lead-lag controller, which the fit is not told: the three
chirp experiments of :mod:`stageid.plants.maglev` (80 dB SNR, 10 000 samples each at 5 kHz), plant
inputs Fx, Fy, Tphi and outputs x, y, phi, the order chosen by BIC over 2-24.  Printed: time, the
unstable poles, the FRF error of every entry over 20-300 Hz relative to that entry's peak, and the
checks that failed.  Takes about ten minutes on the shared machine.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_direct_maglev_reference.py
"""

from __future__ import annotations

import time

import numpy as np

from stageid.closedloop import DirectPredictionError
from stageid.plants import maglev


def main() -> None:
    names = ("chirp-x", "chirp-y", "chirp-phi")
    exps = [maglev.EXPERIMENTS[k](seed=0).experiment(["Fx", "Fy", "Tphi"], ["x", "y", "phi"]) for k in names]
    f = np.geomspace(20, 300, 100)
    true = maglev.model().frequency_response(f)
    t = time.perf_counter()
    res = DirectPredictionError(order="auto", order_range=range(2, 25, 2), horizon=20).fit(exps)
    err = np.abs(res.plant.frequency_response(f) - true).max(axis=0) / np.abs(true).max(axis=0)
    print(f"order {res.order}, {time.perf_counter() - t:.0f} s")
    print("unstable poles [rad/s]:", np.round(np.sort(res.unstable_poles.real), 2), "true", maglev.UNSTABLE_POLES)
    print("FRF error, % of each entry's peak over 20-300 Hz:\n", np.round(100 * err, 2))
    print("failed checks:", [c.name for c in res.checks if not c.passed])


if __name__ == "__main__":
    main()
