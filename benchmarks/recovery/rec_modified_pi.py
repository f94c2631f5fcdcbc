"""Recovery case: the letter's modified PI model (``identify hysteresis --model modified-pi``).

True model of the class the command line fits: ``n`` coupled-play operators (6-16) with
``r_i = i A / n``, ratios ``rc/r = c0 + c1 t``, ``ra/r = a0 + a1 t``, ``rb/ra = b0 + b1 t``
linear in the operator index (``t = i/(n-1) - 1/2``; ranges around the reference actuator's
``c = 0.25-0.6``, ``a = 1.1-1.6``, ``b = 0.55-0.85``), a centre near the middle of the range,
the monotone quadratic input warp ``|q| <= 0.15``, a linear weight and positive decaying
weights.  Reference: the fit's own cost (the best weights for given thresholds, the weight
problem the identification solves) minimised by scipy's Nelder-Mead over the eight threshold
parameters, started from the true ones.
"""

from __future__ import annotations

import pathlib

import numpy as np
from common import CliFailure, Row
from hysteresis_draws import draw_records, failed, fit_cli, noisy, run, training_cost, verdict

ESTIMATOR = "Modified PI"


def draw_theta(rng: np.random.Generator, amplitude: float) -> np.ndarray:
    """``(c0, c1, a0, a1, b0, b1, xc, q)`` as the identification's threshold search writes them."""
    return np.array(
        [
            rng.uniform(0.25, 0.8),
            rng.uniform(-0.3, 0.3),
            rng.uniform(1.1, 1.8),
            rng.uniform(-0.4, 0.4),
            rng.uniform(0.5, 0.9),
            rng.uniform(-0.2, 0.2),
            rng.uniform(-0.05, 0.05) * amplitude,
            rng.uniform(-0.15, 0.15),
        ]
    )


def weight_problem(inputs: list[np.ndarray], outputs: list[np.ndarray], amplitude: float, n: int):
    """The identification's weight problem on these records (its defaults: slope floor 2 % of
    the mean slope, ridge 1e-6, every sample a row)."""
    from stageid.hysteresis.identify.weights import WeightProblem

    eps = 0.02 * max(float(np.ptp(y)) for y in outputs) / (2 * amplitude)
    recs = list(zip(inputs, outputs))
    return WeightProblem(recs, np.arange(n) * amplitude / n, eps, 1, "modified-pi", 1e-6, amplitude)


def build(problem, theta: np.ndarray, weights: np.ndarray):
    return problem.build(theta, weights, 0.0, "V", "y", -problem.R, problem.R, (-problem.R, problem.R))


def reference(problem, theta0: np.ndarray):
    """Nelder-Mead on the weight problem's SSE over the thresholds from ``theta0``; the model."""
    from scipy.optimize import minimize

    kinds = ["zero"] * len(problem.recs)
    scale = np.r_[np.ones(6), problem.R, 1.0]
    res = minimize(
        lambda v: problem.solve(v * scale, kinds, classical=False)[0],
        theta0 / scale,
        method="Nelder-Mead",
        options={"maxfev": 600, "xatol": 1e-6, "fatol": 1e-12},
    )
    theta = res.x * scale
    return build(problem, theta, problem.solve(theta, kinds, classical=False)[1])


def case(seed: int, workdir: pathlib.Path, noise: float) -> Row:
    from stageid.models.serialization import model_from_dict

    rng = np.random.default_rng([seed, 202])
    amplitude = float(rng.uniform(50.0, 500.0))
    n = int(rng.integers(6, 17))
    theta = draw_theta(rng, amplitude)
    t = np.arange(1, n) / n
    plays = np.exp(-float(rng.uniform(0.5, 3.0)) * t) * rng.uniform(0.5, 1.5, n - 1)
    weights = np.r_[1.0, plays * float(rng.uniform(0.5, 2.0)) / plays.sum()] * float(rng.uniform(0.002, 0.02))
    inputs, held, fs = draw_records(rng, amplitude, n)
    problem = weight_problem(inputs, [np.ones(u.size) for u in inputs], amplitude, n)
    truth = build(problem, theta, weights)
    outputs = noisy(rng, [run(truth, u) for u in inputs], noise)
    detail = f"{n} operators, A {amplitude:.0f} V, q {theta[7]:+.2f}, {fs:.0f} Hz, {inputs[0].size} samples"
    extra = ["--model", "modified-pi", "--operators", str(n)]
    try:
        fitted = model_from_dict(fit_cli(workdir, seed, inputs, outputs, fs, extra))
    except CliFailure as exc:
        return failed(seed, noise, exc, detail)
    ref = reference(weight_problem(inputs, outputs, amplitude, n), theta)
    cost = training_cost([run(fitted, u) for u in inputs], outputs)
    ref_cost = training_cost([run(ref, u) for u in inputs], outputs)
    return verdict(seed, noise, (truth, fitted, ref), held, cost / ref_cost, detail)
