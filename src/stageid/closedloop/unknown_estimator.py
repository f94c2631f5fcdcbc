"""The common base of the closed-loop routes that are not told the controller: settings and the result."""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from ..base import Boolean, Estimator, Interval, Options, Satisfies
from ..checks import is_integer
from ..models import StateSpaceModel
from .innovation_fit import InnovationResult
from .innovation_pem import pole_std
from .unknown_checks import ASSUMPTIONS, Check
from .unknown_result import UnknownControllerResult

__all__ = ["UnknownControllerEstimator", "pem_account"]


def _is_order_range(value: object) -> bool:
    return (
        isinstance(value, (Sequence, np.ndarray, range))
        and not isinstance(value, str)
        and len(value) > 0
        and all(is_integer(n) and n >= 1 for n in value)
    )


def _is_names(value: object) -> bool:
    return isinstance(value, (list, tuple)) and len(value) > 0 and all(isinstance(n, str) for n in value)


def pem_account(fit: InnovationResult) -> dict:
    """The optimiser's account of a fit (empty for a subspace estimate without refinement)."""
    if fit.pem is None:
        return {}
    return {
        "nfev": fit.pem.nfev,
        "converged": fit.pem.converged,
        "cost_start": fit.pem.cost_start,
        "cost": fit.pem.cost,
    }


class UnknownControllerEstimator(Estimator):
    """Settings shared by :class:`DirectPredictionError`, :class:`TwoStageProjection` and :class:`JointInputOutput`."""

    abstract: ClassVar[bool] = True
    method_name: ClassVar[str] = ""

    def __init__(
        self,
        *,
        order: int | str = "auto",
        order_range: Sequence[int] = tuple(range(1, 13)),
        horizon: int | str = "auto",
        feedthrough: bool = False,
        max_nfev: int = 100,
        references: Sequence[str] | None = None,
    ) -> None:
        self.order = order
        self.order_range = order_range
        self.horizon = horizon
        self.feedthrough = feedthrough
        self.max_nfev = max_nfev
        self.references = references

    parameter_constraints = {
        "order": [Options("auto"), Interval(int, 1, None)],
        "order_range": [Satisfies(_is_order_range, "a non-empty sequence of integers >= 1")],
        "horizon": [Options("auto"), Interval(int, 1, None)],
        "feedthrough": [Boolean()],
        "max_nfev": [Interval(int, 1, None)],
        "references": [Satisfies(_is_names, "a non-empty list of input column names"), None],
    }

    def plant_result(
        self,
        fit: InnovationResult,
        dt: float,
        names: tuple[tuple[str, ...], tuple[str, ...]],
        checks: list[Check],
        **details,
    ) -> UnknownControllerResult:
        """The frozen result of a route whose plant is the deterministic part of ``fit``."""
        m = fit.matrices
        plant = StateSpaceModel(m.A, m.B, m.C, m.D, dt, names[0], names[1])
        s, std = pole_std(m, fit.covariance, dt) if fit.covariance is not None else (None, None)
        if s is None:
            s = np.log(np.linalg.eigvals(m.A).astype(complex)) / dt
        order = np.argsort(-s.real, kind="stable")[::-1]
        return self.route_result(
            plant,
            s[order],
            (fit.order, fit.horizon),
            checks,
            {**pem_account(fit), **details},
            innovation=m,
            pole_std=None if std is None else std[order],
            parameter_covariance=fit.covariance,
            feedthrough=bool(self.feedthrough),
        )

    def route_result(
        self,
        plant: StateSpaceModel,
        poles: np.ndarray,
        order_horizon: tuple[int, int],
        checks: list[Check],
        diagnostics: dict,
        **bands,
    ) -> UnknownControllerResult:
        """The frozen result of this route: its plant and poles, its assumptions and what the records say of them.

        ``bands`` are the fields a route with a parameter covariance fills (``innovation``,
        ``pole_std``, ``parameter_covariance``, ``feedthrough``).
        """
        return UnknownControllerResult(
            method=self.method_name,
            model=plant,
            poles=poles,
            order=order_horizon[0],
            horizon=order_horizon[1],
            dt=plant.dt,
            assumptions=ASSUMPTIONS[self.method_name],
            checks=tuple(checks),
            diagnostics=diagnostics,
            estimator=self.clone(),
            **bands,
        )
