"""The Bode figure of a measured frequency response: its +-2 std band, a model over it, its coherence.

:func:`frf_figure` is what :meth:`~stageid.models.frequency_response.FrequencyResponse.plot`
draws: the data and the model as responses of the one Bode figure (:func:`.bode.bode_figure`),
the std as the data's band, the coherence as its last row.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .bode import bode_figure

__all__ = ["frf_figure", "N_STD"]

#: Half-width of the shaded band in standard deviations.
N_STD = 2.0


def frf_figure(
    frd: Any,
    model: Any = None,
    fit_band: tuple[float, float] | None = None,
    input_units: Sequence[str] = (),
    output_units: Sequence[str] = (),
    ax: Any = None,
):
    """A :class:`~stageid.frf.FrequencyResponse` as magnitude (with ``|H| +- 2 std`` shaded when the
    FRF has ``std``), phase, and coherence when the FRF has it.

    One panel per entry; ``model`` (anything with ``frequency_response(freqs)`` and the same
    channels) is drawn dashed.  ``fit_band`` ``(f_low, f_high)`` greys the frequencies a fit
    left out (they stay drawn).  Every magnitude axis is labelled with its unit
    (``input_units``/``output_units``, else ``output/input``) and shows its lines' peak down to
    a millionth of it, so a band whose lower edge ``|H| - 2 std`` is below zero runs to the
    bottom of the axis instead of to 1e-300.  The legend names every drawn artist (data, model,
    std band, coherence, unfitted band).  ``ax``: the axes to draw in instead of a new figure
    (see :func:`~stageid.plots.style.axes_grid`).  Returns the figure.
    """
    responses = {"data": frd.response}
    if model is not None:
        responses["model"] = model.frequency_response(frd.freqs)
    bands = None
    if frd.std is not None:
        mag, spread = np.abs(frd.response), N_STD * frd.std
        bands = {"data": (mag - spread, mag + spread)}
    return bode_figure(
        frd.freqs,
        responses,
        frd.inputs,
        frd.outputs,
        bands=bands,
        styles={"model": "k--"},
        input_units=input_units,
        output_units=output_units,
        band_label=f"+-{N_STD:g} std",
        coherence=frd.coherence,
        fit_band=fit_band,
        ax=ax,
    )
