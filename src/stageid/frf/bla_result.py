"""The result of a best linear approximation: the BLA as an FRF with its noise and total std, and the
levels at the odd and even detection lines (see :mod:`stageid.frf.bla` for the estimate)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..frozen import FrozenMapping
from ..models.frequency_response import FrequencyResponse

__all__ = ["BLAResult", "DetectionLevels", "DETECTION_DB"]

#: A kind of nonlinearity is flagged when its detection lines stand this far above the noise.
DETECTION_DB = 3.0


@dataclasses.dataclass(frozen=True)
class DetectionLevels:
    """Output power at the unexcited lines of one kind (odd or even), averaged over realisations.

    Attributes
    ----------
    kind : {"odd", "even"}
    freqs : ndarray of shape (n_lines,)
    power : ndarray of shape (n_lines, n_outputs)
        Mean ``|Y|^2`` of the period-mean output spectrum (noise and nonlinear distortion).
    noise : ndarray of shape (n_lines, n_outputs)
        Mean noise variance of that period mean (from the period-to-period scatter).
    outputs : tuple of str
    floor : ndarray of shape (n_outputs,)
        The least noise variance a line is compared with: 1e-12 of the mean output power
        at the excited lines, so that noise-free records flag only real distortion.
    """

    kind: str
    freqs: np.ndarray
    power: np.ndarray
    noise: np.ndarray
    outputs: tuple[str, ...]
    floor: np.ndarray

    @property
    def level_db(self) -> np.ndarray:
        """Per output: total power over the lines relative to their noise, in dB."""
        noise = np.maximum(np.sum(self.noise, axis=0), self.freqs.size * self.floor)
        return 10.0 * np.log10(np.maximum(np.sum(self.power, axis=0), 1e-300) / np.maximum(noise, 1e-300))

    @property
    def detected(self) -> np.ndarray:
        """Per output: True when the level exceeds :data:`DETECTION_DB`."""
        return self.level_db > DETECTION_DB


@dataclasses.dataclass(frozen=True)
class BLAResult:
    """The BLA with its noise and total std (a :class:`FrequencyResponse`) and the distortion levels.

    Attributes
    ----------
    model : FrequencyResponse
        ``response`` the BLA at the excited lines; ``std`` its noise part; ``total_std`` noise
        and stochastic nonlinear distortion together (None from a single realisation).  Also
        readable as ``frd``, its former name.
    n_realisations : int
    n_periods : int
        Steady-state periods averaged (the fewest over the realisations).
    transient_periods : int
        Leading periods dropped (the most over the realisations).
    odd, even : DetectionLevels or None
        Levels at the odd / even detection lines (None when the excitation has none).
    odd_std, even_std : ndarray of shape (n_freqs, n_outputs, n_inputs) or None
        The BLA's std from odd / even distortions, interpolated from the detection lines.
    """

    model: FrequencyResponse
    n_realisations: int
    n_periods: int
    transient_periods: int
    odd: DetectionLevels | None = None
    even: DetectionLevels | None = None
    odd_std: np.ndarray | None = None
    even_std: np.ndarray | None = None
    transient: str = "drop"

    @property
    def frd(self) -> FrequencyResponse:
        """The BLA: :attr:`model` under its former name."""
        return self.model

    @property
    def diagnostics(self) -> Mapping[str, Any]:
        """How the BLA was made: realisations, steady-state periods, transient periods and how."""
        return FrozenMapping(
            {
                "n_realisations": self.n_realisations,
                "n_periods": self.n_periods,
                "transient_periods": self.transient_periods,
                "transient": self.transient,
            }
        )

    @property
    def distortion_std(self) -> np.ndarray | None:
        """``sqrt(max(total_std^2 - std^2, 0))``: the BLA's std from stochastic nonlinear distortions."""
        if self.model.total_std is None:
            return None
        return np.sqrt(np.maximum(self.model.total_std**2 - self.model.std**2, 0.0))

    @property
    def stochastic_variance(self) -> np.ndarray | None:
        """``var(G_S)`` of one realisation: ``M`` times the distortion variance of the BLA."""
        d = self.distortion_std
        return None if d is None else self.n_realisations * d**2

    def to_columns(self) -> dict[str, np.ndarray]:
        """The FRD columns (:mod:`stageid.models.frequency_response`, with ``stdtot_``) plus ``stdnl_``, ``stdodd_``, ``stdeven_``."""
        cols = self.model.to_columns()
        extra = (("stdnl_", self.distortion_std), ("stdodd_", self.odd_std), ("stdeven_", self.even_std))
        for prefix, value in extra:
            if value is None:
                continue
            for i, out in enumerate(self.model.outputs):
                for j, inp in enumerate(self.model.inputs):
                    cols[f"{prefix}{out}_{inp}"] = value[:, i, j]
        return cols

    def summary(self) -> str:
        """One line per finding: averaging, distortion above noise, odd/even detection per output."""
        f = self.model
        how = (
            "every period kept, the transient removed by the local polynomial method"
            if self.transient == "lpm"
            else f"{self.transient_periods} transient period(s) dropped"
        )
        lines = [
            f"bla: {self.n_realisations} realisation(s) x {self.n_periods} periods ({how}), "
            f"{f.n_freqs} excited lines {f.freqs[0]:g}-{f.freqs[-1]:g} Hz"
        ]
        if f.total_std is not None:
            ratio = _band_median(f.total_std**2 / np.maximum(f.std**2, 1e-300))
            for i, out in enumerate(f.outputs):
                parts = ", ".join(f"{inp} {10 * np.log10(ratio[i, j]):+.1f} dB" for j, inp in enumerate(f.inputs))
                lines.append(f"bla: {out}: total variance over noise variance (median over the band): {parts}")
        else:
            lines.append(
                "bla: one realisation: no total variance, so noise and nonlinear distortion are not told apart"
            )
        for levels in (self.odd, self.even):
            if levels is None:
                continue
            for i, out in enumerate(levels.outputs):
                found = "detected" if levels.detected[i] else "not detected"
                lines.append(
                    f"bla: {out}: {levels.kind} nonlinearity {found} "
                    f"({levels.level_db[i]:+.1f} dB over noise at {levels.freqs.size} {levels.kind} detection lines)"
                )
        return "\n".join(lines)

    def plot(self):
        """The classic figure: |BLA|, its noise and total std (and odd/even shares) vs frequency."""
        from .bla_figure import bla_figure

        return bla_figure(self.model, self.odd_std, self.even_std)


def _band_median(x: np.ndarray) -> np.ndarray:
    """``np.median(x, axis=0)``, NaN where a column holds one, without ``np.median``'s import of ``numpy.ma``."""
    s = np.sort(x, axis=0)  # NaNs sort last
    n = s.shape[0]
    mid = s[n // 2] if n % 2 else (s[n // 2 - 1] + s[n // 2]) / 2
    return np.where(np.isnan(s[-1]), np.nan, mid)
