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

    .venv/bin/python studies/uncertainty_closedloop/run_study.py [n_seeds] [plant ...] [--cached]

Fitted seeds are cached in ``output/<plant>_seed<k>.pkl`` (fit and covariances, timed), per-seed\ncoverage goes to ``output/<plant>.json``; RESULTS.md summarises them.
"""

from __future__ import annotations

import dataclasses
import json
import pickle
import sys
import time
from pathlib import Path

import numpy as np

from stageid.closedloop import ClosedLoopIdentification
from stageid.closedloop.covariance import closed_loop_covariance
from stageid.closedloop.loop_model import group_by_reference
from stageid.closedloop.uncertainty import BIAS_RULES, plant_uncertainty
from stageid.data import Experiment
from stageid.plants import maglev

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
    return plant2x2.chirp_experiments((100 * seed, 100 * seed + 1))


PLANTS = {
    "maglev": (maglev_experiments, maglev.controller, maglev.model),
    "plant2x2": (plant2x2_experiments, plant2x2.controller, plant2x2.plant),
}


def fit_seed(name: str, seed: int) -> dict:
    """Fit one seed and both covariances; cached in ``output/`` (the evaluation is re-run cheaply)."""
    path = OUT / f"{name}_seed{seed}.pkl"
    if path.exists():
        return pickle.loads(path.read_bytes())
    make, controller, _ = PLANTS[name]
    exps = make(seed)
    t0 = time.perf_counter()
    res = ClosedLoopIdentification(controller(), band=BAND, covariance="none").fit(exps)
    out = {"seed": seed, "t_fit": time.perf_counter() - t0, "result": res}
    groups = group_by_reference(exps)
    f_band = np.geomspace(*BAND, 120)  # the estimator's reduction grid
    for method in ("sandwich", "white"):
        t1 = time.perf_counter()
        out[method] = closed_loop_covariance(groups, res.pem_models, f_band, None, method)
        out[f"t_cov/{method}"] = time.perf_counter() - t1
    path.write_bytes(pickle.dumps(out))
    return out


def evaluate(name: str, fitted: dict) -> dict:
    """Coverage numbers of one fitted seed with the current propagation code, every variant."""
    truth = PLANTS[name][2]()
    out: dict = {"seed": fitted["seed"], "t_fit": fitted["t_fit"]}
    for method in ("sandwich", "white"):
        r = dataclasses.replace(fitted["result"], covariance=fitted[method])
        out[f"t_cov/{method}"] = fitted[f"t_cov/{method}"]
        for bias in BIAS_RULES:
            for grid_name, f in GRIDS.items():
                t2 = time.perf_counter()
                fr = plant_uncertainty(r, f, bias)
                if grid_name == "band":
                    out[f"t_prop/{method}/{bias}"] = time.perf_counter() - t2
                z = np.abs(fr.response - truth.frequency_response(f)) / fr.std
                out[f"{method}/{bias}/{grid_name}"] = {"hits": (z <= 1.73).tolist(), "z2": (z**2).tolist()}
    return out


def summarise(name: str, runs: list[dict]) -> None:
    print(f"== {name}: {len(runs)} seeds, fit median {np.median([r['t_fit'] for r in runs]):.1f} s")
    for method in ("sandwich", "white"):
        print(
            f"  {method}: covariance {np.median([r[f't_cov/{method}'] for r in runs]):.2f} s, "
            f"propagation {np.median([r[f't_prop/{method}/flat'] for r in runs]):.2f} s (medians)"
        )
        for bias in BIAS_RULES:
            print(f"   bias rule {bias}:")
            for grid_name in GRIDS:
                hits = np.array([r[f"{method}/{bias}/{grid_name}"]["hits"] for r in runs], dtype=float)
                z2 = np.array([r[f"{method}/{bias}/{grid_name}"]["z2"] for r in runs])
                per_seed = hits.mean(axis=(1, 2, 3))
                print(
                    f"    {grid_name:6s}: coverage {100 * hits.mean():.1f} % (per seed {100 * per_seed.min():.0f}-"
                    f"{100 * per_seed.max():.0f} %), mean |err|^2/std^2 {z2.mean():.2f}, median {np.median(z2):.2f}"
                )
                if grid_name == "band" and bias in ("flat", "local"):
                    print("      per entry coverage %:\n" + _matrix(100 * hits.mean(axis=(0, 1))))
                    print("      per entry mean |err|^2/std^2:\n" + _matrix(z2.mean(axis=(0, 1))))
                    quarters = np.array_split(np.arange(hits.shape[1]), 4)
                    fb = GRIDS["band"]
                    print(
                        "      coverage by quarter of the band: "
                        + ", ".join(
                            f"{fb[k[0]]:.0f}-{fb[k[-1]]:.0f} Hz {100 * hits[:, k].mean():.1f} %" for k in quarters
                        )
                    )


def _matrix(a: np.ndarray) -> str:
    return "\n".join("        " + "  ".join(f"{v:7.2f}" for v in row) for row in a)


def main() -> None:
    n_seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    names = [a for a in sys.argv[2:] if not a.startswith("--")] or list(PLANTS)
    cached_only = "--cached" in sys.argv  # evaluate the seeds fitted so far, fit nothing
    OUT.mkdir(exist_ok=True)
    for name in names:
        runs = []
        for seed in range(n_seeds):
            if cached_only and not (OUT / f"{name}_seed{seed}.pkl").exists():
                continue
            fitted = fit_seed(name, seed)
            runs.append(evaluate(name, fitted))
            print(f"{name} seed {seed}: fit {fitted['t_fit']:.1f} s", flush=True)
        (OUT / f"{name}.json").write_text(json.dumps(runs))
        summarise(name, runs)


if __name__ == "__main__":
    main()
