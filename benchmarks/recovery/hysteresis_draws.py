"""Draws shared by the hysteresis recovery cases (PI, modified PI, Preisach): identification
records and a held-out input, noise, the fit through the command line, and the comparisons.

Every record starts at rest at the centre of the input range (the zero state of every model
class here) and reaches both ends of ``[-A, A]``, so the grid the command line lays over the
records' range is the grid of the true model.  Errors are prediction RMS on the held-out input
in % of the truth's output range there, up to the output offset (a per-record nuisance that
every fit estimates from its own record).  The training cost of a model is its SSE on the
noisy records with the best offset per record, the cost every hysteresis fit minimises.
"""

from __future__ import annotations

import json
import math
import pathlib

import numpy as np
from common import TIME_STYLES, CliFailure, Row, run_cli, write_record

__all__ = [
    "RECOVERED_PERCENT",
    "REFERENCE_FACTOR",
    "forc_input",
    "sine_input",
    "draw_records",
    "fit_cli",
    "noisy",
    "failed",
    "held_out_error",
    "training_cost",
    "verdict",
    "run",
]

#: A draw counts as recovered when its held-out error is within this % of range, or within
#: ``REFERENCE_FACTOR`` times the reference fit's error (the best the noisy records allow).
RECOVERED_PERCENT = 0.3
REFERENCE_FACTOR = 1.5


def forc_input(amplitude: float, n_peaks: int, samples_per_leg: int) -> np.ndarray:
    """First-order reversal curves from the centre: up to +A, down to -A, then triangles from
    -A to peaks rising in equal steps to +A and back (the staircase of the FORC records)."""
    A = amplitude
    legs = [np.linspace(0.0, A, samples_per_leg), np.linspace(A, -A, 2 * samples_per_leg)]
    for p in np.linspace(-A, A, n_peaks + 1)[1:]:
        k = max(3, int(round(samples_per_leg * (p + A) / (2 * A))))
        legs += [np.linspace(-A, p, k)[1:], np.linspace(p, -A, k)[1:]]
    return np.concatenate(legs)


def sine_input(amplitude: float, n: int, cycles: float, final_fraction: float, phase: float) -> np.ndarray:
    """``n`` samples from the centre: to +A, to -A, back, then a sine decaying to
    ``final_fraction`` of A (nested minor loops)."""
    A = amplitude
    lead = np.r_[np.linspace(0.0, A, n // 20), np.linspace(A, -A, n // 10)[1:], np.linspace(-A, 0.0, n // 20)[1:]]
    t = np.arange(n - lead.size) / (n - lead.size)
    return np.r_[lead, A * final_fraction**t * np.sin(2 * np.pi * cycles * t + phase)]


def draw_records(
    rng: np.random.Generator, amplitude: float, n_cells: int
) -> tuple[list[np.ndarray], np.ndarray, float]:
    """Training inputs (a FORC staircase and a decaying sine, 2000-5000 samples each), a
    held-out input (another decaying sine), and the sampling rate."""
    fs = float(rng.choice([1000.0, 2000.0, 5000.0, 10000.0]))
    n_forc = int(rng.integers(2000, 5000))
    # legs of the staircase: 3 at full swing, 2 per peak at half the swing on average
    forc = forc_input(amplitude, 2 * n_cells, max(8, n_forc // (3 + 2 * n_cells)))
    n_sine = int(rng.integers(2000, 5000))  # records of one case differ in length, as logged
    sine = sine_input(amplitude, n_sine, float(rng.uniform(4, 9)), float(rng.uniform(0.1, 0.4)), 0.0)
    held = sine_input(0.95 * amplitude, 3000, float(rng.uniform(3, 7)), 0.3, float(rng.uniform(0, 6)))
    return [forc, sine], held, fs


def fit_cli(
    workdir: pathlib.Path, seed: int, inputs: list[np.ndarray], outputs: list[np.ndarray], fs: float, extra: list[str]
) -> dict:
    """Write the records with a logger's time column (style from the seed) and identify through
    the command line; the model file's JSON."""
    rng = np.random.default_rng([seed, 7])
    style = TIME_STYLES[seed % len(TIME_STYLES)]
    paths = []
    for k, (u, y) in enumerate(zip(inputs, outputs)):
        paths.append(write_record(workdir / f"rec{k}.csv", {"V": u, "y": y}, fs, style, rng))
    out = workdir / "model.json"
    run_cli(["identify", "hysteresis", *paths, "--input", "V", "--output", "y", "-o", out, "--quiet", *extra])
    return json.loads(out.read_text())


def noisy(rng: np.random.Generator, ys: list[np.ndarray], noise: float) -> list[np.ndarray]:
    """Outputs with white noise of ``noise`` times each output's RMS about its mean."""
    return [y + noise * float(np.std(y)) * rng.standard_normal(y.size) for y in ys]


def training_cost(predictions: list[np.ndarray], outputs: list[np.ndarray]) -> float:
    """SSE with the best output offset per record."""
    return float(sum(np.sum((p - y - np.mean(p - y)) ** 2) for p, y in zip(predictions, outputs)))


def held_out_error(prediction: np.ndarray, truth: np.ndarray) -> float:
    """RMS of the prediction error up to the offset, in % of the truth's range."""
    e = prediction - truth
    return 100.0 * float(np.sqrt(np.mean((e - e.mean()) ** 2))) / float(np.ptp(truth))


def run(model, u: np.ndarray) -> np.ndarray:
    """Output from the zero (demagnetised) state at the first sample: the records start at rest."""
    return model.with_state(model.consistent_state(u[0], "zero")).simulate(u)[:, 0]


def verdict(seed: int, noise: float, models: tuple, held: np.ndarray, cost_ratio: float, detail: str) -> Row:
    """The row of a draw from ``(truth, fit, reference)`` models and the held-out input."""
    truth, fitted, ref = models
    y_held = run(truth, held)
    error, reference_error = held_out_error(run(fitted, held), y_held), held_out_error(run(ref, held), y_held)
    recovered = error <= max(RECOVERED_PERCENT, REFERENCE_FACTOR * reference_error)
    return Row(
        seed=seed,
        recovered=bool(recovered),
        error=error,
        unit="% of range (held-out RMS)",
        reference_error=reference_error,
        cost_ratio=cost_ratio,
        noise=noise,
        detail=detail,
    )


def failed(seed: int, noise: float, exc: CliFailure, detail: str) -> Row:
    return Row(seed=seed, recovered=False, error=math.nan, noise=noise, detail=detail, failed=str(exc.args[0]))
