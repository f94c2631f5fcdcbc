"""Calibration of the closed-loop uncertainty bands (issue 20, point 3).

For each noise seed: simulate the closed-loop experiments, identify the plant once
(``ClosedLoopIdentification``, the demo's settings), compute the pair covariances both ways
("sandwich" and "white"), and compare ``|G_est - G_true|`` with ``1.73 std`` of
:meth:`ClosedLoopResult.response_uncertainty` over the band (200 log-spaced points) and
outside it.  For a circular complex Gaussian error of variance ``std^2``, ``|err| <= 1.73 std``
holds 95 % of the time and ``E|err|^2 / std^2 = 1``.

Plants: the maglev reference of Shakir & Kim (3x3, 80 dB SNR per channel, one 2 s chirp per
axis: the demo) and the 2x2 levitated plant of tests/_closedloop_plant2x2.py (70 dB, as the
CLI acceptance test), which the method was not tuned on.

    .venv/bin/python studies/uncertainty_closedloop/run_study.py [n_seeds] [plant ...]

Per-seed numbers go to ``output/<plant>.json``; RESULTS.md summarises them.
"""

from __future__ import annotations

import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

from stageid.closedloop import ClosedLoopIdentification, simulate_closed_loop
from stageid.closedloop.covariance import closed_loop_covariance
from stageid.closedloop.loop_model import group_by_reference
from stageid.data import Experiment
from stageid.plants import maglev
from stageid.signals import chirp

sys.path.insert(0, str(Path(__file__).parents[2] / "tests"))
import _closedloop_plant2x2 as plant2x2  # noqa: E402

OUT = Path(__file__).parent / "output"
BAND = (20.0, 300.0)
GRIDS = {"band": np.geomspace(*BAND, 200), "below": np.geomspace(2.0, 19.0, 40), "above": np.geomspace(320, 1500, 40)}


def maglev_experiments(seed: int) -> list[Experiment]:
    refs = [f"r_{o}" for o in maglev.OUTPUTS]
    tables = [maglev.simulate_chirp(a, seed=100 * seed + k) for k, a in enumerate(maglev.OUTPUTS)]
    return [t.experiment(refs, list(maglev.OUTPUTS), name=f"chirp-{a}") for t, a in zip(tables, maglev.OUTPUTS)]


def plant2x2_experiments(seed: int) -> list[Experiment]:
    r = chirp(0.0, 2500.0, duration=2.0, dt=plant2x2.DT, amplitude=1e-6)
    exps = []
    for j in range(2):
        R = np.zeros((r.size, 2))
        R[:, j] = r
        y, _ = simulate_closed_loop(plant2x2.plant(), plant2x2.controller(), R, plant2x2.DT, 70.0, 100 * seed + j)
        exps.append(Experiment(R, y, plant2x2.DT, ("r1", "r2"), ("y1", "y2")))
    return exps


PLANTS = {
    "maglev": (maglev_experiments, maglev.controller, maglev.model),
    "plant2x2": (plant2x2_experiments, plant2x2.controller, plant2x2.plant),
}


def one_seed(name: str, seed: int) -> dict:
    make, controller, truth = PLANTS[name]
    exps = make(seed)
    t0 = time.perf_counter()
    res = ClosedLoopIdentification(controller(), band=BAND, covariance="none").fit(exps)
    t_fit = time.perf_counter() - t0
    groups = group_by_reference(exps)
    f_band = np.geomspace(*BAND, 120)  # the estimator's reduction grid
    out: dict = {
        "seed": seed,
        "t_fit": t_fit,
        "orders": {f"{i}{j}": m.F.size - 1 for (i, j), m in res.pem_models.items()},
    }
    for method in ("sandwich", "white"):
        t1 = time.perf_counter()
        cov = closed_loop_covariance(groups, res.pem_models, f_band, None, method)
        r = dataclasses.replace(res, covariance=cov)
        t_cov = time.perf_counter() - t1
        for grid_name, f in GRIDS.items():
            t2 = time.perf_counter()
            fr = r.response_uncertainty(f)
            t_prop = time.perf_counter() - t2
            err = np.abs(fr.response - truth().frequency_response(f))
            z = err / fr.std
            out[f"{method}/{grid_name}"] = {
                "hits": (z <= 1.73).tolist(),  # (n_freqs, p, p)
                "z2": (z**2).tolist(),
                "rel_std": (fr.std / np.abs(fr.response)).tolist(),
            }
            if grid_name == "band":
                out[f"{method}/t_cov"], out[f"{method}/t_prop"] = t_cov, t_prop
    return out


def summarise(name: str, runs: list[dict]) -> None:
    print(f"== {name}: {len(runs)} seeds, fit median {np.median([r['t_fit'] for r in runs]):.1f} s")
    for method in ("sandwich", "white"):
        print(
            f"  {method}: covariance {np.median([r[f'{method}/t_cov'] for r in runs]):.2f} s, "
            f"propagation {np.median([r[f'{method}/t_prop'] for r in runs]):.2f} s (medians)"
        )
        for grid_name in GRIDS:
            hits = np.array([r[f"{method}/{grid_name}"]["hits"] for r in runs], dtype=float)
            z2 = np.array([r[f"{method}/{grid_name}"]["z2"] for r in runs])
            per_seed = hits.mean(axis=(1, 2, 3))
            print(
                f"    {grid_name:6s}: coverage {100 * hits.mean():.1f} % (per seed {100 * per_seed.min():.0f}-"
                f"{100 * per_seed.max():.0f} %), mean |err|^2/std^2 {z2.mean():.2f}, median {np.median(z2):.2f}"
            )
            if grid_name == "band":
                print("      per entry coverage %:\n" + _matrix(100 * hits.mean(axis=(0, 1))))
                print("      per entry mean |err|^2/std^2:\n" + _matrix(z2.mean(axis=(0, 1))))
                thirds = np.array_split(np.arange(hits.shape[1]), 4)
                fb = GRIDS["band"]
                print(
                    "      coverage by quarter of the band: "
                    + ", ".join(f"{fb[k[0]]:.0f}-{fb[k[-1]]:.0f} Hz {100 * hits[:, k].mean():.1f} %" for k in thirds)
                )


def _matrix(a: np.ndarray) -> str:
    return "\n".join("        " + "  ".join(f"{v:7.2f}" for v in row) for row in a)


def main() -> None:
    n_seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    names = sys.argv[2:] or list(PLANTS)
    OUT.mkdir(exist_ok=True)
    for name in names:
        path = OUT / f"{name}.json"
        runs = json.loads(path.read_text()) if path.exists() else []
        done = {r["seed"] for r in runs}
        for seed in range(n_seeds):
            if seed in done:
                continue
            runs.append(one_seed(name, seed))
            path.write_text(json.dumps(runs))
            print(f"{name} seed {seed}: fit {runs[-1]['t_fit']:.1f} s", flush=True)
        summarise(name, [r for r in runs if r["seed"] < n_seeds])


if __name__ == "__main__":
    main()
