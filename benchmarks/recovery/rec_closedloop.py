"""Recovery of random open-loop-unstable stages by ``stageid identify closed-loop`` with the
controller known (Shakir & Kim: closed loop by prediction error, plant deduced as
``G = T (M - M T)^-1``, spurious pairs cancelled, each entry reduced to the paper's structure
over the band keeping its unstable poles). The draws are described in :mod:`loop_draws`; the
command runs with its defaults (paper structure, band 20-300 Hz, output error).

Error: the largest plant frequency-response error over the band, each entry's error as a
percentage of that entry's peak in the band, the worst entry. Poles: every true unstable pole
matched by one of the fit's within 2 %, and no other unstable pole.
No cost ratio: the reduced plant minimises a band error against the deduced response, a cost
the truth does not share (the prediction-error cost of the loop is the PEM case's,
:mod:`rec_pem`); the reference is the truth itself.
Recovered when the unstable poles are within 2 % and the band error is at most 10 %.
"""

from __future__ import annotations

import pathlib

import numpy as np
from common import Row
from loop_draws import BAND, SALT, draw_and_fit

ESTIMATOR = "Closed loop"
SHARED_DRAW = "loop"  # one command run per truth gives T (the PEM case) and G (this case)


def unstable_entry_poles(fit) -> np.ndarray:
    """The distinct right-half-plane poles of the entries of a continuous transfer matrix (an
    unstable pole shared by several entries counted once: within 0.5 % of one another)."""
    found: list[complex] = []
    for i in range(fit.n_outputs):
        for j in range(fit.n_inputs):
            for p in fit.entry_poles(i, j):
                if p.real > 0 and all(abs(p - q) > 5e-3 * abs(q) for q in found):
                    found.append(complex(p))
    return np.array(found)


def unstable_pole_error(true_poles: np.ndarray, fit_unstable: np.ndarray) -> float:
    """Largest relative distance (%) from a true unstable pole to the nearest unstable pole of the
    fit; infinite when the fit has a different number of unstable poles."""
    if fit_unstable.size != true_poles.size:
        return float("inf")
    return float(max(100 * np.abs(fit_unstable - p).min() / abs(p) for p in true_poles))


def band_error(fit, truth, f: np.ndarray) -> float:
    """Worst entry's max error over ``f`` as % of that entry's peak."""
    g_true, g_fit = truth.frequency_response(f), fit.frequency_response(f)
    return float((100 * np.abs(g_fit - g_true).max(0) / np.abs(g_true).max(0)).max())


def case(seed: int, workdir: pathlib.Path, noise: float, salt: int = SALT) -> Row:
    from stageid.models import load_model

    draw = draw_and_fit(seed, workdir, noise, salt)
    if draw.failed:
        return Row(seed, False, float("nan"), noise=noise, detail=draw.detail, failed=draw.failed)
    fit = load_model(workdir / "G.json")
    f = np.linspace(*BAND, 400)
    error = band_error(fit, draw.plant, f)
    pole_error = unstable_pole_error(draw.unstable, unstable_entry_poles(fit))
    detail = draw.detail + f", unstable poles {pole_error:.3g} % off"
    recovered = pole_error <= 2.0 and error <= 10.0
    return Row(seed, recovered, error, "% of entry peak", float("nan"), float("nan"), noise, detail)
