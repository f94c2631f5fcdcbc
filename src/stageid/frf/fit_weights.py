"""How the FRD fit weighs the frequencies and judges its error.

:func:`frequency_weights`: per-frequency weights of the output-error fit from the response's
std (``1 / std^2``), its coherence (``gamma^2 / (1 - gamma^2)``) or none;
:func:`column_errors`: the largest miss of each input column over its peak; and
:func:`warn_large_error`: a :class:`~stageid.FitWarning` when the fit misses by more than
``LARGE_ERROR`` beyond the data's own noise.
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError, FitWarning
from ..models.frequency_response import FrequencyResponse
from ..validation.order_choice import poor_order_message

__all__ = ["frequency_weights", "column_errors", "warn_large_error", "LARGE_ERROR"]


#: A fit whose largest column error exceeds this fraction of the column's peak is warned about.
LARGE_ERROR = 0.10


def warn_large_error(
    response: np.ndarray, G: np.ndarray, std: np.ndarray | None, order: int, order_errors: tuple
) -> None:
    """Warn (:class:`FitWarning`) when the fit misses the response by more than ``LARGE_ERROR``
    of a column's peak beyond 3 std of the data (when it has one): a low order chosen on a
    held-out plateau must not pass silently, a miss within the data's own noise is no miss."""
    import warnings

    gap = np.abs(response - G) if std is None else np.maximum(np.abs(response - G) - 3.0 * std, 0.0)
    peak = np.max(np.abs(G), axis=(0, 1))
    worst = float(np.max(np.max(gap, axis=(0, 1)) / np.where(peak > 0, peak, 1.0)))
    if worst <= LARGE_ERROR:
        return
    beyond = "" if std is None else " beyond 3 std of the data"
    message = poor_order_message(
        "FRDIdentification",
        order,
        [n for n, _ in order_errors],
        f"misses the response by up to {100 * worst:.3g} % of a column's peak{beyond}",
        f"at most {100 * LARGE_ERROR:g} %",
        "give a higher `order`, or a band (`fmin`, `fmax`) the model can follow.",
    )
    warnings.warn(message, FitWarning, stacklevel=3)


def frequency_weights(frd: FrequencyResponse, weight: str, scale: np.ndarray) -> tuple[str, np.ndarray]:
    """Per-frequency weights of the output-error fit, normalised to mean 1, and their kind.

    ``std``: ``1 / mean_ij (std_ij / scale_j)^2`` (the columns as scaled for the fit), from the
    total std (noise and nonlinear distortion of a best linear approximation) when the
    response has one - the kind is then ``"total-std"`` - else from the noise std;
    ``coherence``: ``mean_i gamma_i^2 / (1 - gamma_i^2)`` capped at 1e6; ``none``: ones.
    """
    has_std = frd.std is not None or frd.total_std is not None
    if weight == "auto":
        weight = "std" if has_std else ("coherence" if frd.coherence is not None else "none")
    if weight == "std":
        if not has_std:
            raise DataError("`weight='std'` needs std_<out>_<in> columns in the frequency response; it has none.")
        std = frd.total_std if frd.total_std is not None else frd.std
        weight = "total-std" if frd.total_std is not None else "std"
        var = np.mean((std / scale[None, None, :]) ** 2, axis=(1, 2))
        if not var.max() > 0:  # an exact (computed) response: every line alike
            var = np.ones_like(var)
        floor = 1e-12 * float(var.max())  # a zero std would give one frequency all the weight
        w = 1.0 / np.maximum(var, floor)
    elif weight == "coherence":
        if frd.coherence is None:
            raise DataError("`weight='coherence'` needs coh_<out> columns in the frequency response; it has none.")
        c = np.clip(frd.coherence, 0.0, 1.0 - 1e-6)
        w = np.mean(c / (1.0 - c), axis=1)
    else:
        w = np.ones(frd.n_freqs)
    if not np.any(w > 0):
        raise DataError(f"the {weight} weights are zero at every frequency; use `weight='none'`.")
    return weight, w / np.mean(w)


def column_errors(model_response: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Max over frequencies and outputs of ``|model - G|`` per input column, over the column's peak."""
    peak = np.max(np.abs(G), axis=(0, 1))
    return np.max(np.abs(model_response - G), axis=(0, 1)) / np.where(peak > 0, peak, 1.0)
