"""One Jacobian of the direct route's prediction-error cost on the maglev reference: the sensitivity
system against forward differences, in CPU time.

The three chirp experiments of :mod:`stageid.plants.maglev` (3 x 10 000 samples, plant inputs
Fx, Fy, Tphi, outputs x, y, phi), centred and scaled as the fit does, at the PBSID start of each
``order/horizon`` pair.  Printed per pair: the parameters, the cost's rows, the CPU time of each
Jacobian (``time.process_time``, one BLAS thread) and the largest difference between the two
relative to each column's size (forward differences are the inexact side: see the unit test
against central differences).

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_innovation_jacobian.py [14/20 21/40 ...]
"""

from __future__ import annotations

import sys
import time

import numpy as np

from stageid.closedloop.innovation_pem import (
    difference_jacobian,
    pack,
    stacked_residuals,
    transient_length,
    unpack,
    weighted_jacobian,
)
from stageid.closedloop.predictor_subspace import pbsid
from stageid.plants import maglev


def scaled_records() -> list[tuple[np.ndarray, np.ndarray]]:
    names = ("chirp-x", "chirp-y", "chirp-phi")
    exps = [maglev.EXPERIMENTS[k](seed=0).experiment(["Fx", "Fy", "Tphi"], ["x", "y", "phi"]) for k in names]
    su = np.sqrt(np.mean(np.vstack([e.u - e.u.mean(axis=0) for e in exps]) ** 2, axis=0))
    sy = np.sqrt(np.mean(np.vstack([e.y - e.y.mean(axis=0) for e in exps]) ** 2, axis=0))
    return [((e.u - e.u.mean(axis=0)) / su, (e.y - e.y.mean(axis=0)) / sy) for e in exps]


def one_pair(records, stacked, n: int, horizon: int) -> str:
    """Both Jacobians at the PBSID start of order ``n``, past horizon ``horizon``: the printed line."""
    start = pbsid(records, n, horizon, False)
    W = np.linalg.inv(np.linalg.cholesky(start.noise_cov))
    burn = transient_length(start, horizon, 2500)
    theta = pack(start, False)

    def cost(t: np.ndarray) -> np.ndarray:
        mats = unpack(t, n, 3, 3, False, start.noise_cov)
        return np.concatenate([(e[burn:] @ W.T).ravel() for e in stacked_residuals(mats, stacked)])

    weighted_jacobian(start, stacked, W, burn, False)  # compile and warm up
    c = time.process_time()
    J = weighted_jacobian(start, stacked, W, burn, False)
    t_analytic = time.process_time() - c
    c = time.process_time()
    J_fd = difference_jacobian(cost, theta, np.zeros(0))
    t_fd = time.process_time() - c
    diff = np.abs(J - J_fd).max(axis=0) / np.abs(J_fd).max(axis=0)
    return (
        f"order {n}, horizon {horizon}: {theta.size} parameters, {J.shape[0]} rows; analytic {t_analytic:.2f} s"
        f" CPU, forward differences {t_fd:.2f} s CPU, ratio {t_fd / t_analytic:.1f}; column difference"
        f" median {np.median(diff):.1e}, largest {diff.max():.1e}"
    )


def main(pairs: list[str]) -> None:
    records = scaled_records()
    stacked = [np.hstack([u, np.ones((u.shape[0], 1)), y]) for u, y in records]
    for pair in pairs:
        n, horizon = (int(x) for x in pair.split("/"))
        print(one_pair(records, stacked, n, horizon), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:] or ["14/20", "21/40"])
