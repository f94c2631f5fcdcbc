"""The frozen result of the closed-loop routes that are not told the controller (direct, two-stage, joint)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._errors import DataError, IdentificationError
from ..base import Estimator
from ..frozen import FrozenMapping
from ..models import StateSpaceModel
from ..models.frequency_response import FrequencyResponse
from .innovation_pem import response_std
from .predictor_subspace import InnovationMatrices
from .unknown_checks import Check

__all__ = ["UnknownControllerResult", "unstable_pole_agreement"]


@dataclass(frozen=True, eq=False)
class UnknownControllerResult:
    """Plant, poles with bands, the assumptions made and what the records said about them.

    Attributes
    ----------
    method : str
        "direct", "two-stage" or "joint".
    model : StateSpaceModel
        The identified plant ``u -> y`` at the data's sample time (offsets removed).  Also
        :attr:`plant`, its former name.
    poles : ndarray of complex
        Continuous-time poles of ``model``, ``ln(z) / dt`` (rad/s), sorted by real part.
    order, horizon : int
        States of the fitted model and past horizon of the subspace start.
    dt : float
        Sample time of the data.
    assumptions : tuple of str
        What the route assumes, in words.
    checks : tuple of Check
        What the records could check about those assumptions.
    innovation : InnovationMatrices or None
        The fitted innovation form (direct: the plant with its noise model; two-stage: the
        second stage); None for the joint route, whose model maps the references.
    pole_std : ndarray or None
        ``sqrt(E|s_est - s|^2)`` of each pole (delta method), None without a covariance.
    parameter_covariance : ndarray or None
        Covariance of the innovation form's parameters (the bands' source).
    feedthrough : bool
        Whether ``D`` was fitted.
    diagnostics : mapping of str to float, int, bool or dict
        Read-only: the optimiser's account and route-specific figures (stage-1 fit, ...).
        Also :attr:`details`, its former name.
    estimator : Estimator or None
        A copy of the route's settings at the fit.
    """

    method: str
    model: StateSpaceModel
    poles: np.ndarray
    order: int
    horizon: int
    dt: float
    assumptions: tuple[str, ...]
    checks: tuple[Check, ...]
    innovation: InnovationMatrices | None = None
    pole_std: np.ndarray | None = None
    parameter_covariance: np.ndarray | None = None
    feedthrough: bool = False
    diagnostics: Mapping[str, Any] = field(default_factory=dict)
    estimator: Estimator | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "diagnostics", FrozenMapping(self.diagnostics))

    @property
    def plant(self) -> StateSpaceModel:
        """The identified plant: :attr:`model` under its former name."""
        return self.model

    @property
    def details(self) -> Mapping[str, Any]:
        """:attr:`diagnostics` under its former name."""
        return self.diagnostics

    @property
    def unstable_poles(self) -> np.ndarray:
        """Poles with a positive real part (rad/s)."""
        return self.poles[self.poles.real > 0]

    @property
    def unstable_pole_std(self) -> np.ndarray | None:
        """The std of each of :attr:`unstable_poles` (None without a covariance)."""
        return None if self.pole_std is None else self.pole_std[self.poles.real > 0]

    @property
    def passed(self) -> bool:
        """True when every check passed."""
        return all(c.passed for c in self.checks)

    def response_uncertainty(self, freqs_hz: Sequence[float] | np.ndarray) -> FrequencyResponse:
        """The plant's response at ``freqs_hz`` with its delta-method std per entry.

        Raises
        ------
        DataError
            Frequencies that are not finite, positive and below the Nyquist frequency.
        IdentificationError
            When the route gives no covariance (joint).
        """
        f = np.asarray(freqs_hz, dtype=float).reshape(-1)
        if f.size == 0 or not np.all(np.isfinite(f)) or f.min() <= 0 or f.max() > 0.5 / self.dt:
            raise DataError(f"frequencies must be finite, in (0, {0.5 / self.dt:g}] Hz; got {f.min():g}-{f.max():g}.")
        if self.parameter_covariance is None or self.innovation is None:
            raise IdentificationError(f"the {self.method} route gives no covariance for bands.")
        H, std = response_std(self.innovation, self.parameter_covariance, f, self.dt, self.feedthrough)
        return FrequencyResponse(f, H, std, inputs=self.model.inputs, outputs=self.model.outputs)

    def summary(self) -> str:
        """Plain text: route, order, unstable poles with bands, assumptions, checks."""
        lines = [f"closed-loop identification, controller unknown ({self.method} route), dt = {self.dt:g} s"]
        lines.append(f"  order {self.order}, past horizon {self.horizon}")
        std = self.unstable_pole_std
        poles = ", ".join(
            f"{p.real:.4g}{'' if abs(p.imag) < 1e-9 else f'{p.imag:+.3g}j'}"
            + ("" if std is None else f" +- {2 * s:.2g}")
            for p, s in zip(self.unstable_poles, std if std is not None else [0] * len(self.unstable_poles))
        )
        lines.append("  unstable poles [rad/s]" + (" (+- 2 std)" if std is not None else "") + ": " + (poles or "none"))
        lines.append("  assumptions:")
        lines += [f"    - {a}" for a in self.assumptions]
        lines.append("  checks:")
        lines += [f"    - {c.line()}" for c in self.checks]
        return "\n".join(lines)


def unstable_pole_agreement(results: Sequence[UnknownControllerResult], rtol: float = 0.02) -> Check:
    """Do the routes agree on the unstable poles?  The largest relative spread of matched poles.

    Poles are matched by sorting each route's unstable poles by modulus; a route with a
    different count fails the check (value ``inf``).
    """
    sets = [np.sort_complex(np.asarray(r.unstable_poles)[np.argsort(np.abs(r.unstable_poles))]) for r in results]
    sets = [s[np.argsort(np.abs(s))] for s in sets]
    names = ", ".join(r.method for r in results)
    if len(results) < 2 or len({s.size for s in sets}) != 1 or sets[0].size == 0:
        counts = ", ".join(f"{r.method} {s.size}" for r, s in zip(results, sets))
        return Check("pole_agreement", False, float("inf"), rtol, f"unstable poles found per route: {counts}")
    stacked = np.array(sets)
    spread = float(np.max(np.abs(stacked - stacked.mean(axis=0)) / np.abs(stacked.mean(axis=0))))
    return Check(
        "pole_agreement", spread <= rtol, spread, rtol, f"largest relative spread of the unstable poles over {names}"
    )
