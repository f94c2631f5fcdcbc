"""Recovery of the closed loop by prediction error (Shakir & Kim, eq. 12-14), through
``stageid identify closed-loop --closed-loop-output``.

Which estimator is "PEM": ``identify statespace`` offers no prediction-error route (its methods
are MAP and batch least squares on the Hankel-Toeplitz statistics), so the CLI's prediction-error
estimator is the first step of the closed-loop route: every reference-to-output pair ``T_ij``
fitted by output-error minimisation, the diagonal pairs then refitted through their outputs'
sensitivity noise model (prefiltered output error). Its estimate, the discrete closed loop ``T`` the command
writes with ``--closed-loop-output``, is compared here; the plant deduction and reduction that
follow are the closed-loop case's (:mod:`rec_closedloop`), but a refusal there fails the
command and so this draw too. The draws are described in :mod:`loop_draws`; they are the
closed-loop case's truths, and run together (``SHARED_DRAW``) one command run serves both.

Error: the largest error of the closed-loop response ``T`` over 5 Hz - 1 kHz as a percentage of
its peak there. Reference: the true loop; its output-error cost on the records is the noise
floor, which the cost's optimum started from the truth can undercut only by the fitted
parameters' share of the samples. Cost ratio = summed squared output error of the identified
loop driven by the recorded references (the cost output-error PEM minimises, from rest) / the
true loop's.
Recovered when the error is at most 2 % of the peak and the cost ratio at most 1.1 (or, noise-free,
the error at most 0.5 %).
"""

from __future__ import annotations

import pathlib

import numpy as np
from common import Row
from loop_draws import SALT, closed_loop_response, draw_and_fit, loop_cost

ESTIMATOR = "PEM"
SHARED_DRAW = "loop"  # one command run per truth gives T (this case) and G (the closed-loop case)


def case(seed: int, workdir: pathlib.Path, noise: float, salt: int = SALT) -> Row:
    from stageid.models import load_model

    draw = draw_and_fit(seed, workdir, noise, salt)
    if draw.failed:
        return Row(seed, False, float("nan"), noise=noise, detail=draw.detail, failed=draw.failed)
    T_fit = load_model(workdir / "T.json")
    f = np.geomspace(5.0, 1000.0, 400)
    T_true = closed_loop_response(draw.plant, draw.controller, f)
    error = float(100 * np.abs(T_fit.frequency_response(f) - T_true).max() / np.abs(T_true).max())
    ref_cost = loop_cost(draw.plant, draw.controller, draw.records)
    fit_cost = sum(float(np.sum((y - T_fit.simulate(R)) ** 2)) for R, y in draw.records)
    energy = sum(float(np.sum(y**2)) for _, y in draw.records)
    # noise-free draws: the truth's cost is at rounding level, where a ratio says nothing
    ratio = fit_cost / ref_cost if ref_cost > 1e-12 * energy else float("nan")
    recovered = error <= 2.0 and ratio <= 1.1 if np.isfinite(ratio) else error <= 0.5
    return Row(seed, bool(recovered), error, "% of peak", float("nan"), ratio, noise, draw.detail)
