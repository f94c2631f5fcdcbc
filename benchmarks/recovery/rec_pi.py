"""Recovery case: classical Prandtl-Ishlinskii model (``identify hysteresis --model pi``).

True model: ``n`` play operators (8-24) with thresholds ``r_i = i A / n`` over the input
amplitude ``A`` (the grid the command line lays over the records' range, as the letter's 20
operators over +-500 V), a linear weight and positive decaying play weights (the letter's and
the reference actuator's shape), random amplitude and gain.  Reference: the weights are linear
for fixed thresholds, so the least-squares optimum at the true thresholds (unconstrained, one
offset per record) is the best any fit of the class reaches on these records.
"""

from __future__ import annotations

import pathlib

import numpy as np
from common import CliFailure, Row
from hysteresis_draws import draw_records, failed, fit_cli, noisy, run, training_cost, verdict

ESTIMATOR = "PI"


def draw_truth(rng: np.random.Generator, amplitude: float, n: int):
    from stageid.hysteresis import PIModel

    t = np.arange(1, n) / n
    plays = np.exp(-float(rng.uniform(0.5, 3.0)) * t) * rng.uniform(0.5, 1.5, n - 1)
    plays *= float(rng.uniform(0.5, 2.0)) / plays.sum()  # hysteresis weight relative to the linear part
    weights = np.r_[1.0, plays] * float(rng.uniform(0.002, 0.02))  # um/V
    return PIModel(r=np.arange(n) * amplitude / n, weights=weights)


def reference(truth, inputs: list[np.ndarray], outputs: list[np.ndarray]):
    """Least-squares weights at the true thresholds, one offset per record; the model and its SSE."""
    from dataclasses import replace

    blocks, rhs = [], []
    for u, y in zip(inputs, outputs):
        Z, _ = truth.with_state(truth.consistent_state(u[0], "zero")).operator_outputs(u)
        blocks.append(Z - Z.mean(axis=0))
        rhs.append(y - y.mean())
    w = np.linalg.lstsq(np.vstack(blocks), np.concatenate(rhs), rcond=None)[0]
    return replace(truth, weights=w)


def case(seed: int, workdir: pathlib.Path, noise: float) -> Row:
    from stageid.models.serialization import model_from_dict

    rng = np.random.default_rng([seed, 101])
    amplitude = float(rng.uniform(50.0, 500.0))
    n = int(rng.integers(8, 25))
    truth = draw_truth(rng, amplitude, n)
    inputs, held, fs = draw_records(rng, amplitude, n)
    outputs = noisy(rng, [run(truth, u) for u in inputs], noise)
    detail = f"{n} operators, A {amplitude:.0f} V, {fs:.0f} Hz, {inputs[0].size} samples"
    try:
        fitted = model_from_dict(fit_cli(workdir, seed, inputs, outputs, fs, ["--model", "pi", "--operators", str(n)]))
    except CliFailure as exc:
        return failed(seed, noise, exc, detail)
    ref = reference(truth, inputs, outputs)
    cost = training_cost([run(fitted, u) for u in inputs], outputs)
    ref_cost = training_cost([run(ref, u) for u in inputs], outputs)
    return verdict(seed, noise, (truth, fitted, ref), held, cost / ref_cost, detail)
