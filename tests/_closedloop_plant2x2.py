"""A 2x2 levitated test plant of our own (not the paper's maglev), shared by the closed-loop tests.

Two unstable axes ``k / ((s - a)(s + b))`` with third-order stable couplings, stabilised by
a decentralised [2, 2] lead-lag per axis (110 Hz crossover, Tustin at 5 kHz).
"""

from __future__ import annotations

import numpy as np

from stageid.models import TransferMatrix
from stageid.plants.maglev import lead_lag

DT = 2e-4
UNSTABLE = (45.0, 70.0)


def plant() -> TransferMatrix:
    num = [[[2.5], [30.0]], [[60.0], [2.0]]]
    den = [
        [np.poly([45.0, -70.0]), np.real(np.poly([-20.0, -150 + 1200j, -150 - 1200j]))],
        [np.real(np.poly([-90.0, -100 + 900j, -100 - 900j])), np.poly([70.0, -60.0])],
    ]
    return TransferMatrix(num, den, None, ("F1", "F2"), ("y1", "y2"))


def controller():
    m1 = lead_lag(2.5, 45.0, 70.0, 110.0)
    m2 = lead_lag(2.0, 70.0, 60.0, 110.0)
    K = TransferMatrix(
        [[m1[0], [0.0]], [[0.0], m2[0]]], [[m1[1], [1.0]], [[1.0], m2[1]]], None, ("e1", "e2"), ("F1", "F2")
    )
    return K.to_statespace(minimal=False).c2d(DT, "tustin")


def chirp_experiments(seeds: tuple[int, int], snr_db: float = 70.0, duration: float = 2.0) -> list:
    """One 1 um chirp (0-2.5 kHz) per reference axis, simulated in the loop at ``snr_db``; the
    record of axis ``j`` draws its noise from ``seeds[j]``."""
    from stageid.closedloop import simulate_closed_loop
    from stageid.data import Experiment
    from stageid.signals import chirp

    r = chirp(0.0, 2500.0, duration=duration, dt=DT, amplitude=1e-6)
    exps = []
    for j in range(2):
        R = np.zeros((r.size, 2))
        R[:, j] = r
        y, _ = simulate_closed_loop(plant(), controller(), R, DT, snr_db, seed=seeds[j])
        exps.append(Experiment(R, y, DT, ("r1", "r2"), ("y1", "y2")))
    return exps
