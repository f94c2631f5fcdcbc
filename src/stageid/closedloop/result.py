"""The frozen result of :class:`~stageid.closedloop.ClosedLoopIdentification`: plant, closed loop, diagnostics."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..base import Estimator
from ..display import html_repr, short_repr
from ..frozen import FrozenMapping
from ..models import StateSpaceModel, TransferMatrix
from ..models.frequency_response import FrequencyResponse
from .cancellation import CancelledPair, EntryPoleZero, z_to_s
from .covariance import ClosedLoopCovariance
from .deduction import plant_response
from .uncertainty import plant_uncertainty

__all__ = ["ClosedLoopResult"]


@dataclass(frozen=True, eq=False)
class ClosedLoopResult:
    """Frozen result of :meth:`ClosedLoopIdentification.fit` (no training data kept).

    Attributes
    ----------
    model : TransferMatrix
        The identified plant in the requested structure (continuous unless
        ``continuous=False``); inputs named after the controller's outputs.  Also
        :attr:`plant`, its former name.
    plant_full : StateSpaceModel
        The full-order discrete deduction of eq. 18 (with its spurious pairs).
    plant_cancelled : TransferMatrix
        The discrete deduction after cancelling pole-zero pairs closer than ``cancel_tol``.
    closed_loop : TransferMatrix
        The identified discrete ``T`` (references to outputs).
    controller : StateSpaceModel
        The controller used, discrete at the data's sample time.
    unstable_poles : ndarray
        Continuous-time (rad/s) unstable poles of the deduced plant, ``ln(z) / dt``.
    cancellations : tuple of CancelledPair
        Every cancelled pair with its ``s``-plane distance.
    entries : tuple of EntryPoleZero
        Per-entry poles/zeros before and after cancellation (for pole-zero maps).
    reduced : dict
        ``(i, j) -> ReducedEntry`` for the fixed-structure fits (empty for ``"full"``).
    band : (float, float)
        Band of the reduction and of the errors, Hz.
    band_error : ndarray of shape (p, p)
        The paper's ``eps = max | |P_i| - |P_r| | / |P_i|`` over the band, per entry.
    band_error_complex : ndarray of shape (p, p)
        ``max |P_i - P_r| / |P_i|`` over the band.
    band_error_median : ndarray of shape (p, p) or None
        The median over the band of ``|P_i - P_r| / |P_i|`` (None for the "full" structure).
    pem_models : dict
        ``(i, j) -> PolynomialModel`` of each closed-loop pair.
    closed_loop_fit : ndarray of shape (p, p)
        Simulation fit (percent) of each ``T_ij`` on its experiment(s).
    dt : float
        Sample time of the data.
    structure : str
        "paper", "full" or "custom" (a dict of orders).
    diagnostics : mapping of str to float
        Named figures of the fit, read-only: the worst closed-loop fit of a pair [%], the
        largest band error ``eps``, the number of cancelled pole-zero pairs and of unstable
        poles.
    covariance : ClosedLoopCovariance or None
        The pairs' parameter covariances for :meth:`response_uncertainty` (None when fitted
        with ``covariance="none"``).
    estimator : ClosedLoopIdentification or None
        A copy of the settings it was fitted with (changing the estimator afterwards changes
        nothing here).
    """

    model: TransferMatrix
    plant_full: StateSpaceModel
    plant_cancelled: TransferMatrix
    closed_loop: TransferMatrix
    controller: StateSpaceModel
    unstable_poles: np.ndarray
    cancellations: tuple[CancelledPair, ...]
    entries: tuple[EntryPoleZero, ...]
    reduced: dict
    band: tuple[float, float]
    band_error: np.ndarray
    band_error_complex: np.ndarray
    pem_models: dict
    closed_loop_fit: np.ndarray
    dt: float
    structure: str = "paper"
    diagnostics: Mapping[str, Any] = field(default_factory=dict)
    covariance: ClosedLoopCovariance | None = None
    band_error_median: np.ndarray | None = None
    estimator: Estimator | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "diagnostics", FrozenMapping({**self.diagnostics, **self._figures()}))

    @property
    def plant(self) -> TransferMatrix:
        """The identified plant: :attr:`model` under its former name."""
        return self.model

    def _figures(self) -> dict[str, float]:
        """The named figures :attr:`diagnostics` holds, from the result's own fields (so they always agree)."""
        return {
            "closed_loop_fit_min_percent": float(np.min(self.closed_loop_fit)),
            "band_error_max": float(np.max(self.band_error)),
            "cancelled_pairs": len(self.cancellations),
            "unstable_poles": len(self.unstable_poles),
        }

    def __repr__(self) -> str:
        return short_repr(self)

    def _repr_html_(self) -> str:
        return html_repr(self)

    def response_uncertainty(self, freqs_hz: Sequence[float] | np.ndarray) -> FrequencyResponse:
        """The returned plant's response with ``std = sqrt(E|G_est - G|^2)`` per entry.

        The PEM parameter covariance propagated through eq. 18 and the reduction by the delta
        method, the reduction's bias included (:mod:`~stageid.closedloop.uncertainty`).

        Parameters
        ----------
        freqs_hz : array_like of shape (n_freqs,)
            Finite, positive, strictly increasing frequencies in Hz.

        Returns
        -------
        FrequencyResponse
            ``response`` of :attr:`plant`, ``std`` beside it, the plant's channel names.

        Raises
        ------
        DataError
            A bad grid, or one that hits a pole of the plant.
        IdentificationError
            When the result was fitted with ``covariance="none"``.
        """
        return plant_uncertainty(self, freqs_hz)

    def deduced_response(self, freqs_hz: Sequence[float] | np.ndarray) -> np.ndarray:
        """Full-order deduced plant response (eq. 18) at ``freqs_hz``, shape (n_freqs, p, p)."""
        return plant_response(self.closed_loop, self.controller, None, np.asarray(freqs_hz, dtype=float))

    @property
    def plant_unstable_poles(self) -> np.ndarray:
        """Right-half-plane poles of the returned plant's entries (rad/s; duplicates merged)."""
        poles: list[complex] = []
        for row in self.model.den:
            for d in row:
                r = np.roots(d)
                if self.model.dt is not None:
                    r = z_to_s(r, self.model.dt)
                for q in r[r.real > 0]:
                    if not any(abs(q - o) <= 1e-9 * max(1.0, abs(q)) for o in poles):
                        poles.append(complex(q))
        return np.array(sorted(poles, key=lambda q: (q.real, q.imag)), dtype=complex)

    def summary(self) -> str:
        """A plain-text summary: orders, fits, unstable poles, band errors, cancellations."""
        p = self.closed_loop.n_outputs
        lines = [
            f"closed-loop identification ({self.structure} structure), dt = {self.dt:g} s, band {self.band[0]:g}-{self.band[1]:g} Hz"
        ]
        for (i, j), m in sorted(self.pem_models.items()):
            lines.append(
                f"  T[{self.closed_loop.outputs[i]}<-{self.closed_loop.inputs[j]}]: {m.structure} order {m.F.size - 1 + m.A.size - 1}, "
                f"fit {self.closed_loop_fit[i, j]:.2f} %"
            )
        lines.append("  unstable poles of M (I - T) [rad/s]: " + ", ".join(f"{p_:.4g}" for p_ in self.unstable_poles))
        lines.append(
            "  unstable poles of the plant returned [rad/s]: "
            + ", ".join(f"{p_:.4g}" for p_ in self.plant_unstable_poles)
        )
        for i in range(p):
            for j in range(p):
                lines.append(
                    f"  G[{self.model.outputs[i]}<-{self.model.inputs[j]}]: eps = {100 * self.band_error[i, j]:.3f} % "
                    f"(complex {100 * self.band_error_complex[i, j]:.3f} %)"
                )
        lines.append(
            f"  {len(self.cancellations)} pole-zero pairs cancelled; largest distance "
            f"{max((c.distance for c in self.cancellations), default=0.0):.2e}"
        )
        return "\n".join(lines)
