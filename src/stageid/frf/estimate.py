"""The result every nonparametric FRF estimator returns (Welch, LPM, periodic averaging).

:class:`FRFResult` holds the measured response as its ``model`` (a
:class:`~stageid.models.frequency_response.FrequencyResponse`), a copy of the estimator it was
fitted with, and a few numbers that say how it was made (``diagnostics``): the shape of every
other result of stageid, so that a caller moves between estimators without learning a new one.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from ..base import Estimator
from ..frozen import FrozenMapping
from ..models.frequency_response import FrequencyResponse

__all__ = ["FRFResult"]


@dataclasses.dataclass(frozen=True, repr=False)
class FRFResult:
    """A nonparametric FRF estimate and how it was made (no training data kept).

    Attributes
    ----------
    model : FrequencyResponse
        The estimate, with its ``std`` and ``coherence``.
    estimator : Estimator
        A copy of the estimator's settings at the fit (changing the estimator afterwards
        changes nothing here).
    diagnostics : mapping of str to int or float
        What the method decided from the data (segments, window width, periods, lines kept).
    """

    model: FrequencyResponse
    estimator: Estimator
    diagnostics: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "diagnostics", FrozenMapping(self.diagnostics))

    def summary(self) -> str:
        """One line per fact: the estimator, the frequencies and the diagnostics."""
        frd = self.model
        lines = [
            f"{self.estimator!r}: {frd.n_freqs} lines, {frd.freqs[0]:g}-{frd.freqs[-1]:g} Hz, "
            f"inputs {list(frd.inputs)}, outputs {list(frd.outputs)}"
        ]
        lines += [f"  {name}: {value:g}" for name, value in self.diagnostics.items()]
        return "\n".join(lines)

    def __repr__(self) -> str:
        frd = self.model
        return f"FRFResult({self.estimator!r}, {frd.n_freqs} lines, {frd.freqs[0]:g}-{frd.freqs[-1]:g} Hz)"
