"""The routes without a controller model against the truth, and against the known-controller route.

Truth: :mod:`stageid.plants.levitated_pair` (2x2, unstable poles 31.4 and 50 rad/s) under a
filtered PD the fits are not told: linear, saturated at half the noise-free run's largest
command, or acting one sample late; white measurement noise of 0.5, 1 and 2 % of each output's
std, fed back; 5000 samples at 1 kHz; seeds 0-2.  Printed per case: the largest relative error
of the unstable poles and the largest FRF error over 0.5-50 Hz relative to the FRF's peak (the
issue's targets: 2 % and 1 %), and whether every check passed.  The known-controller route
(:class:`~stageid.closedloop.ClosedLoopIdentification`) gets one experiment per excited
reference from the same loop and the controller itself.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_closedloop_unknown.py
"""

from __future__ import annotations

import time

import numpy as np

from stageid.closedloop import ClosedLoopIdentification, DirectPredictionError, JointInputOutput, TwoStageProjection
from stageid.data import Experiment
from stageid.plants import levitated_pair as lp

BAND = np.geomspace(0.5, 50.0, 100)
LOOPS = {"PD": {}, "PD + saturation": {"saturation": 0.5}, "PD + 1-sample delay": {"delay": 1}}
NAMES = ("r1", "r2", "u1", "u2")


def errors(plant) -> tuple[float, float]:
    s = np.log(plant.poles().astype(complex)) / lp.DT if plant.dt else plant.poles()
    found = np.sort(s[s.real > 0].real)
    true = np.array(lp.UNSTABLE_POLES)
    pole = float(np.max(np.abs(found - true) / true)) if found.size == 2 else np.inf
    H, Ht = plant.frequency_response(BAND), lp.model().frequency_response(BAND)
    return pole, float(np.abs(H - Ht).max() / np.abs(Ht).max())


def row(name: str, loop: str, noise: float, fits: list) -> str:
    poles = [errors(r.plant)[0] for r in fits]
    frfs = [errors(r.plant)[1] for r in fits]
    ok = sum(r.passed for r in fits)
    return (
        f"| {name} | {loop} | {100 * noise:.1f} | {100 * max(poles):.2f} | {100 * max(frfs):.2f} | {ok}/{len(fits)} |"
    )


def main() -> None:
    print("| route | loop | noise % | worst pole err % | worst FRF err % of peak | all checks passed |")
    print("|---|---|---|---|---|---|")
    seeds = (0, 1, 2)
    t0 = time.perf_counter()
    for loop, kw in LOOPS.items():
        for noise in (0.005, 0.01, 0.02):
            recs = [lp.record(5000, seed=s, noise=noise, **kw) for s in seeds]
            exps = [Experiment(np.hstack([r, u]), y, lp.DT, NAMES) for r, u, y in recs]
            direct = [DirectPredictionError(order=4, references=["r1", "r2"]).fit(e) for e in exps]
            print(row("direct", loop, noise, direct))
            if noise == 0.02:
                two = [TwoStageProjection(order=4, sensitivity_order=8, references=["r1", "r2"]).fit(e) for e in exps]
                print(row("two-stage", loop, noise, two))
                joint = [JointInputOutput(order=8, references=["r1", "r2"]).fit(e) for e in exps]
                print(row("joint", loop, noise, joint))
    print(f"\n(all fits: {time.perf_counter() - t0:.0f} s)")
    print("\nKnown-controller route, 2 % noise, linear PD, one excited reference per experiment:")
    for seed in seeds:
        exps = []
        for ax in (0, 1):
            r, u, y = lp.record(5000, seed=10 * seed + ax, noise=0.02, reference_axes=(ax,))
            exps.append(Experiment(r, y, lp.DT, ("r1", "r2"), ("x1", "x2")))
        direct = DirectPredictionError(order=4).fit(
            [
                Experiment(u, y, lp.DT)
                for u, y in (
                    lp.record(5000, seed=10 * seed + ax, noise=0.02, reference_axes=(ax,))[1:] for ax in (0, 1)
                )
            ]
        )
        try:
            known = ClosedLoopIdentification(
                lp.controller(), order_range=range(4, 11), band=(0.5, 50.0), continuous=False,
                structure={(i, j): (0, 2) for i in range(2) for j in range(2)}, covariance="none",
            ).fit(exps)  # fmt: skip
            kp, kf = errors(known.plant)
            known_text = f"pole err {100 * kp:.2f} %, FRF err {100 * kf:.2f} % of peak"
        except Exception as exc:  # noqa: BLE001 - the route's own message is the finding
            known_text = f"failed: {exc}"
        dp, df = errors(direct.plant)
        print(f"seed {seed}: known controller {known_text}; direct (same records) pole err {100 * dp:.2f} %, "
              f"FRF err {100 * df:.2f} %")  # fmt: skip


if __name__ == "__main__":
    main()
