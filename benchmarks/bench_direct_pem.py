"""Direct prediction-error identification of a 3x3 unstable stage in closed loop, 20 000 samples,
side by side with SIPPY's closed-loop subspace method (PARSIM-K) when ``sippy_unipi`` is installed.

The stage: three magnetically levitated axes (negative springs, unstable poles at 31.4, 50 and
70 rad/s) with input coupling, sampled at 1 kHz, each axis under a filtered PD the fits are not
told; band-limited references on all axes, 2 % white measurement noise fed back.  Both fits get
the logged plant inputs and the measured outputs only, at the true order 6.  Printed: the median
wall time over ``--rounds`` (the machine is shared and noisy), the median CPU time of the process
(one BLAS thread; a loaded machine disturbs it less than the wall time), the ratio, the unstable
poles' largest relative error and the largest FRF error over 0.5-50 Hz relative to the peak.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_direct_pem.py [--samples 20000] [--rounds 3]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from scipy.signal import butter, lfilter

from stageid.closedloop import DirectPredictionError, simulate_feedback
from stageid.data import Experiment
from stageid.models import StateSpaceModel

DT = 1e-3
POLES = (2 * np.pi * 5.0, 50.0, 70.0)
COUPLING = np.array([[1.0, 0.2, 0.1], [0.15, 1.0, 0.1], [0.05, 0.1, 1.0]])
BAND = np.geomspace(0.5, 50.0, 100)


def plant() -> StateSpaceModel:
    A, B = np.zeros((6, 6)), np.zeros((6, 3))
    for k, a in enumerate(POLES):
        A[2 * k, 2 * k + 1], A[2 * k + 1, 2 * k] = 1.0, a * a
        B[2 * k + 1] = COUPLING[k]
    C = np.zeros((3, 6))
    C[[0, 1, 2], [0, 2, 4]] = 1.0
    return StateSpaceModel(A, B, C, np.zeros((3, 3))).c2d(DT, "zoh")


def controller() -> StateSpaceModel:
    w, tau = 2 * np.pi * 20.0, 1.0 / (2 * np.pi * 200.0)
    kp = np.array([w * w + a * a for a in POLES])
    kd = 2 * 0.7 * w
    K = StateSpaceModel(
        -np.eye(3) / tau, np.eye(3), -kd / tau**2 * np.eye(3), np.diag(kp + kd / tau)
    )  # kp + kd s / (tau s + 1) per axis
    return K.c2d(DT, "tustin")


def record(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    b, a = butter(2, 2 * 60.0 * DT)
    r = lfilter(b, a, rng.standard_normal((n, 3)), axis=0) * 1e-3
    G, K = plant(), controller()
    _, y0 = simulate_feedback(G, K, r)
    v = 0.02 * y0.std(axis=0) * rng.standard_normal((n, 3))
    return simulate_feedback(G, K, r, measurement_noise=v)


def accuracy(A, B, C, D) -> tuple[float, float]:
    G = StateSpaceModel(A, B, C, D, DT)
    s = np.log(G.poles().astype(complex)) / DT
    found = np.sort(s[s.real > 0].real)
    pole_err = np.inf if found.size != 3 else float(np.max(np.abs(found - np.array(POLES)) / np.array(POLES)))
    true = plant().frequency_response(BAND)
    frf_err = float(np.abs(G.frequency_response(BAND) - true).max() / np.abs(true).max())
    return pole_err, frf_err


def run_stageid(u, y):
    res = DirectPredictionError(order=6, horizon=20).fit(Experiment(u, y, DT))
    return res.plant.A, res.plant.B, res.plant.C, res.plant.D


def run_sippy(u, y):
    from sippy_unipi import system_identification

    sys_id = system_identification(y.T, u.T, "PARSIM-K", SS_fixed_order=6, SS_f=20, SS_p=20, tsample=DT)
    return sys_id.A, sys_id.B, sys_id.C, sys_id.D


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, default=20000)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    u, y = record(args.samples, seed=0)
    peers = {"stageid direct PEM": run_stageid}
    try:
        import sippy_unipi  # noqa: F401

        peers["SIPPY PARSIM-K"] = run_sippy
    except ImportError:
        print("sippy_unipi not installed: stageid alone")
    times: dict[str, list[float]] = {k: [] for k in peers}
    cpu: dict[str, list[float]] = {k: [] for k in peers}
    results = {}
    for _ in range(args.rounds):
        for name, fn in peers.items():  # alternate the peers within each round
            t, c = time.perf_counter(), time.process_time()
            results[name] = fn(u, y)
            times[name].append(time.perf_counter() - t)
            cpu[name].append(time.process_time() - c)
    base = statistics.median(times["stageid direct PEM"])
    print(f"3x3 unstable stage, {args.samples} samples, order 6, medians of {args.rounds} rounds")
    print(f"{'method':22s} {'time s':>8s} {'CPU s':>7s} {'ratio':>7s} {'pole err %':>11s} {'FRF err % peak':>15s}")
    for name in peers:
        med = statistics.median(times[name])
        pole_err, frf_err = accuracy(*results[name])
        print(
            f"{name:22s} {med:8.2f} {statistics.median(cpu[name]):7.2f} {med / base:7.2f} "
            f"{100 * pole_err:11.3f} {100 * frf_err:15.3f}"
        )


if __name__ == "__main__":
    main()
