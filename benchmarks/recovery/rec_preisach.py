"""Recovery case: discrete Preisach model (``identify hysteresis --model preisach``).

True model of the class the command line fits: a grid of ``n`` levels (6-14) over the
records' input range ``[-A, A]`` with a smooth non-negative density (one to three Gaussian
bumps below the diagonal, the wide loops of a piezo actuator, plus a reversible part on the
diagonal).  Reference: the fit's own cost (least squares with one offset per record plus the
smoothness penalty ``lambda ||D w||^2``, ``w >= 0``; the identifier's default ``lambda``)
minimised by scipy's L-BFGS-B started from the true weights.
"""

from __future__ import annotations

import pathlib

import numpy as np
from common import CliFailure, Row
from hysteresis_draws import draw_records, failed, fit_cli, noisy, run, verdict

ESTIMATOR = "Preisach"


def draw_weights(rng: np.random.Generator, n: int) -> np.ndarray:
    i, j = np.tril_indices(n)
    a, b = (i + 0.5) / n, (j + 0.5) / n  # cell centres in [0, 1]
    w = np.zeros(i.size)
    for _ in range(int(rng.integers(1, 4))):
        ca, cb = rng.uniform(0.3, 1.0), rng.uniform(0.0, 0.7)
        sa, sb = rng.uniform(0.15, 0.5, 2)
        w += rng.uniform(0.3, 1.0) * np.exp(-(((a - ca) / sa) ** 2) - ((b - cb) / sb) ** 2)
    w += (i == j) * rng.uniform(0.5, 2.0) * w.max()  # reversible part
    return w * float(rng.uniform(0.01, 1.0)) / w.sum()


def cost_terms(inputs: list[np.ndarray], outputs: list[np.ndarray], input_range: tuple, n: int):
    """``(A, b, lam D)``: centred cell states and outputs of all records, and the penalty rows."""
    from stageid.hysteresis.identify.preisach import cell_regressors, second_differences

    blocks = [cell_regressors(u, input_range, n) for u in inputs]
    A = np.vstack([P - P.mean(axis=0) for P in blocks])
    b = np.concatenate([y - y.mean() for y in outputs])
    lam = 1e-4 * float(np.mean(np.sum(A**2, axis=0)))  # the identifier's default smoothing
    return A, b, np.sqrt(lam) * second_differences(n)


def cost(w: np.ndarray, A: np.ndarray, b: np.ndarray, D: np.ndarray) -> float:
    return float(np.sum((A @ w - b) ** 2) + np.sum((D @ w) ** 2))


def reference(w0: np.ndarray, A: np.ndarray, b: np.ndarray, D: np.ndarray) -> np.ndarray:
    from scipy.optimize import minimize

    G, g = A.T @ A + D.T @ D, A.T @ b
    res = minimize(
        lambda w: (float(w @ G @ w - 2 * g @ w), 2 * (G @ w - g)),
        w0,
        jac=True,
        method="L-BFGS-B",
        bounds=[(0.0, None)] * w0.size,
        options={"maxiter": 20000, "ftol": 1e-15, "gtol": 1e-14},
    )
    return res.x


def case(seed: int, workdir: pathlib.Path, noise: float) -> Row:
    from stageid.hysteresis.models.preisach import PreisachModel
    from stageid.models.serialization import model_from_dict

    rng = np.random.default_rng([seed, 303])
    amplitude = float(rng.uniform(50.0, 500.0))
    n = int(rng.integers(6, 15))
    truth = PreisachModel((-amplitude, amplitude), draw_weights(rng, n))
    inputs, held, fs = draw_records(rng, amplitude, n)
    outputs = noisy(rng, [run(truth, u) for u in inputs], noise)
    detail = f"{n} levels, A {amplitude:.0f} V, {fs:.0f} Hz, {inputs[0].size} samples"
    try:
        fitted = model_from_dict(
            fit_cli(workdir, seed, inputs, outputs, fs, ["--model", "preisach", "--levels", str(n)])
        )
    except CliFailure as exc:
        return failed(seed, noise, exc, detail)
    A, b, D = cost_terms(inputs, outputs, fitted.input_range, n)
    w_ref = reference(truth.weights, A, b, D)
    ref = PreisachModel(fitted.input_range, w_ref)
    ratio = cost(fitted.weights, A, b, D) / cost(w_ref, A, b, D)
    return verdict(seed, noise, (truth, fitted, ref), held, ratio, detail)
