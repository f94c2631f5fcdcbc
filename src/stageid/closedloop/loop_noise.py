"""A closed-loop pair refined with a noise model: the loop's measurement noise is not white at its outputs.

A sensor's noise ``n`` enters the loop it closes: the controller acts on ``y + n``, so the
recorded output is ``y_m = T r + (I - T) n`` (:func:`stageid.models.feedback`), the noise
shaped by the sensitivity ``I - T``.  Below the crossover the sensitivity is small (the loop
gain is high), so there the records tell ``T`` very precisely; an output-error fit weighs every
frequency alike and lets ``T`` drift there by as much as it costs on the white-noise reading.
Those frequencies are where the plant deduction ``G = T (M - M T)^-1`` is most sensitive to ``T``
(:mod:`~stageid.closedloop.reliability`) and where the unstable poles, the zeros of
``M (I - T)``, lie.  An output-error pair is therefore refined as a Box-Jenkins model
``y = B/F r + C/D e`` (Ljung 1999, sec. 4.2) with the same ``B, F`` orders and a
:data:`NOISE_ORDER` noise model: the prediction error whitens the noise, so the fit counts each
frequency by how precisely the records give it.  The estimator refines every pair it fits, so the
records' rest and output levels (:mod:`~stageid.closedloop.loop_model`), which trade against a
pair's low-frequency gain, are estimated with the refined pairs too.
"""

from __future__ import annotations

import numpy as np

from .._errors import IdentificationError
from .pem import pem
from .polynomial import PolynomialModel

__all__ = ["NOISE_ORDER", "with_noise_model"]

#: order of the noise model's ``C`` and ``D``: enough for the sensitivity's high-pass shape
#: below the crossover (the loop gain rises as a power of ``1 / f`` there)
NOISE_ORDER = 2


def with_noise_model(
    model: PolynomialModel, r: list[np.ndarray], y: list[np.ndarray], max_nfev: int = 200
) -> PolynomialModel:
    """``model``'s orders with a :data:`NOISE_ORDER` noise model, by prediction error on ``(r, y)``
    from ``model`` and from the linear start, the lower loss kept.

    From the output-error optimum alone the search can stay near its low-frequency drift
    (measured on a 2x2 loop's diagonal pair: loss 1.1669e-17 and ``|dT|`` 4.1e-3 at 1 Hz; from
    the linear start 1.1579e-17 and 3.6e-4).  A pair whose refinements both fail is returned as
    it came; a pair that already has a noise model too.

    Parameters
    ----------
    model : PolynomialModel
        An output-error pair fitted to ``(r, y)``.
    r, y : list of ndarray of shape (n_samples,)
        The records' references and outputs.
    max_nfev : int
        Evaluation limit of each refinement.
    """
    if model.structure != "oe":
        return model
    orders = {"nb": model.B.size, "nf": model.F.size - 1, "nc": NOISE_ORDER, "nd": NOISE_ORDER}
    fits = []
    for initial in (model, None):
        try:
            fits.append(pem(r, y, "bj", orders, model.nk, model.dt, max_nfev=max_nfev, initial=initial))
        except IdentificationError:  # a refinement that fails leaves the other (or the output-error fit)
            continue
    return min(fits, key=lambda m: m.loss) if fits else model
