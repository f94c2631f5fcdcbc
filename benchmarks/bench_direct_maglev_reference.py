"""The direct route on the paper's maglev reference (Shakir & Kim eq. 22-24, 3x3, unstable poles
54.62, 82.21 and 86.73 rad/s) under its lead-lag controller, which the fit is not told: the three
chirp experiments of :mod:`stageid.plants.maglev` (80 dB SNR, 10 000 samples each at 5 kHz), plant
inputs Fx, Fy, Tphi and outputs x, y, phi.

The records are the continuous plant sampled under a zero-order hold, so the truth of a discrete
fit is the ZOH-sampled plant.  Against the continuous plant a perfect discrete model still
differs by the hold's half-sample delay, ``|1 - exp(-j w dt / 2)| ~ w dt / 2``: 1.3 % at 20 Hz,
where the diagonal entries peak.  Both errors are printed per entry over 20-300 Hz, relative
to the entry's peak, beside the fit's own band (two standard deviations, relative to the same
peak) and the entry's share of its output in the records: the RMS of ``G_ij u_j`` over the RMS of
the measurement noise (how far above the noise an entry shows; couplings only, the diagonal
entries are unstable and cannot be run open loop).  One round takes about 12 minutes of CPU.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_direct_maglev_reference.py \
        [--order auto] [--horizon 40] [--rounds 1]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from stageid.closedloop import DirectPredictionError
from stageid.plants import maglev

NAMES = ("chirp-x", "chirp-y", "chirp-phi")
BAND = np.geomspace(20, 300, 100)
SNR_DB = 80.0  # the experiments' output SNR (maglev.simulate_chirp's default)


def records():
    tables = [maglev.EXPERIMENTS[k](seed=0) for k in NAMES]
    return [t.experiment(["Fx", "Fy", "Tphi"], ["x", "y", "phi"]) for t in tables]


def coupling_snr(exps) -> np.ndarray:
    """RMS of ``G_ij u_j`` over the RMS of output ``i``'s noise, pooled over the records (NaN on the diagonal)."""
    G = maglev.model().c2d(maglev.DT)
    out = np.full((3, 3), np.nan)
    noise = np.array([[10 ** (-SNR_DB / 20) * np.std(e.y[:, i]) for i in range(3)] for e in exps])
    for i in range(3):
        for j in range(3):
            if i == j:
                continue
            part = [G.entry(i, j).simulate(e.u[:, [j]])[:, 0] for e in exps]
            out[i, j] = np.sqrt(np.mean(np.concatenate(part) ** 2) / np.mean(noise[:, i] ** 2))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--order", default="auto")
    ap.add_argument("--horizon", type=int, default=40)
    ap.add_argument("--rounds", type=int, default=1)
    args = ap.parse_args()
    exps = records()
    order = args.order if args.order == "auto" else int(args.order)
    times, cpu = [], []
    for _ in range(args.rounds):
        t, c = time.perf_counter(), time.process_time()
        res = DirectPredictionError(order=order, order_range=range(2, 25, 2), horizon=args.horizon).fit(exps)
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    sampled = maglev.model().c2d(maglev.DT).frequency_response(BAND)
    continuous = maglev.model().frequency_response(BAND)
    fr = res.response_uncertainty(BAND)
    peak = np.abs(sampled).max(axis=0)
    print(
        f"order {res.order}, horizon {res.horizon}: median of {args.rounds} {statistics.median(times):.1f} s "
        f"({statistics.median(cpu):.1f} s CPU)"
    )
    print(f"optimiser: {res.details}")
    print("unstable poles [rad/s]:", np.round(np.sort(res.unstable_poles.real), 2), "true", maglev.UNSTABLE_POLES)
    rows = {
        "error vs the ZOH-sampled plant": np.abs(fr.response - sampled).max(axis=0) / peak,
        "error vs the continuous plant": np.abs(fr.response - continuous).max(axis=0) / np.abs(continuous).max(axis=0),
        "band, 2 std": 2 * fr.std.max(axis=0) / peak,
    }
    for name, value in rows.items():
        print(f"{name}, % of each entry's peak over 20-300 Hz:\n", np.round(100 * value, 2).tolist())
    print("coupling RMS / noise RMS in the records:\n", np.round(coupling_snr(exps), 2).tolist())
    print("failed checks:", [c.name for c in res.checks if not c.passed])


if __name__ == "__main__":
    main()
