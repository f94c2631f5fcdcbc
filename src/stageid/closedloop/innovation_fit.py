"""The innovation form fitted to records: centring and scaling, horizon and order, PBSID start, PEM.

Shared by the three routes that are not told the controller (direct, two-stage, joint): each
hands :func:`fit_innovation` the input and output records of the model it needs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._errors import DataError, IdentificationError
from ..data import Experiment
from .innovation_pem import PemResult, predictor_residuals, refine, transient_length
from .predictor_subspace import InnovationMatrices, choose_horizon, order_by_bic, pbsid, varx

__all__ = ["InnovationResult", "InnovationFit", "fit_innovation", "as_records", "split_references", "HORIZONS"]

#: Past horizons tried when ``horizon="auto"`` (BIC of the VARX predictor).
HORIZONS = (5, 10, 15, 20, 30, 40)


@dataclass(frozen=True)
class InnovationResult:
    """The fitted innovation form in the data's units and what the fit saw (records are not kept)."""

    matrices: InnovationMatrices
    covariance: np.ndarray | None
    order: int
    horizon: int
    rcond: float
    pem: PemResult | None
    residuals: tuple[np.ndarray, ...]
    burn: int


InnovationFit = InnovationResult  # its former name


def as_records(data: Experiment | Sequence[Experiment]) -> list[Experiment]:
    """One experiment or a non-empty sequence of them with the same channels and sample time."""
    exps = [data] if isinstance(data, Experiment) else list(data) if isinstance(data, (list, tuple)) else None
    if not exps or not all(isinstance(e, Experiment) for e in exps):
        raise DataError(f"expected an Experiment or a non-empty list of them; got {type(data).__name__}.")
    first = exps[0]
    for e in exps[1:]:
        if e.input_names != first.input_names or e.output_names != first.output_names:
            raise DataError(f"every record must have the channels of the first; '{e.name}' differs.")
        if abs(e.dt - first.dt) > 1e-9 * first.dt:
            raise DataError(f"every record must have the sample time {first.dt:g} s; '{e.name}' has {e.dt:g} s.")
    return exps


def _unscale(m: InnovationMatrices, cov: np.ndarray | None, su, sy, feedthrough: bool):
    """Matrices and parameter covariance of unit-RMS data back in the data's units."""
    n = m.A.shape[0]
    A, B, C, K = m.A, m.B / su, m.C * sy[:, None], m.K / sy
    D = m.D * sy[:, None] / su
    d0 = None if m.output_offset is None else m.output_offset * sy
    out = InnovationMatrices(A, B, C, D, K, m.noise_cov * np.outer(sy, sy), m.state_offset, d0)
    if cov is None:
        return out, None
    t = [np.ones(n * n), np.tile(1 / su, n), np.repeat(sy, n), np.tile(1 / sy, n)]
    if feedthrough:
        t.append((sy[:, None] / su).ravel())
    t += [np.ones(n), sy]
    T = np.concatenate(t)
    return out, cov * np.outer(T, T)


def fit_innovation(
    inputs: Sequence[np.ndarray],
    outputs: Sequence[np.ndarray],
    order: int | str,
    order_range: Sequence[int],
    horizon: int | str,
    feedthrough: bool,
    max_nfev: int,
    refine_start: bool = True,
) -> InnovationResult:
    """Centre and scale the records, pick horizon and order, start by PBSID, refine by PEM.

    ``refine_start=False`` keeps the (consistent) subspace estimate: no covariance, no bands.

    Raises
    ------
    IdentificationError
        Records too short for the horizon, no stable predictor, or a channel that never moves.
    """
    su = np.sqrt(np.mean(np.vstack([u - u.mean(axis=0) for u in inputs]) ** 2, axis=0))
    sy = np.sqrt(np.mean(np.vstack([y - y.mean(axis=0) for y in outputs]) ** 2, axis=0))
    if np.any(su == 0) or np.any(sy == 0):
        raise IdentificationError("every input and output channel must vary; one is constant.")
    records = [((u - u.mean(axis=0)) / su, (y - y.mean(axis=0)) / sy) for u, y in zip(inputs, outputs)]
    p = choose_horizon(records, HORIZONS, feedthrough) if horizon == "auto" else int(horizon)
    rcond = varx(records, p, feedthrough)[4]

    shortest = min(u.shape[0] for u, _ in records)

    def pooled(mats: InnovationMatrices) -> np.ndarray:
        burn = transient_length(mats, p, shortest // 4)
        return np.vstack([e[burn:] for e in predictor_residuals(mats, records)])

    n = order_by_bic(records, p, order_range, feedthrough, pooled) if order == "auto" else int(order)
    start = pbsid(records, n, p, feedthrough)
    if not refine_start:
        burn = transient_length(start, p, shortest // 4)
        mats, _ = _unscale(start, None, su, sy, feedthrough)
        res = tuple(e[burn:] * sy for e in predictor_residuals(start, records))
        return InnovationResult(mats, None, n, p, rcond, None, res, burn)
    fit = refine(records, start, feedthrough, p, max_nfev)
    mats, cov = _unscale(fit.matrices, fit.covariance, su, sy, feedthrough)
    residuals = tuple(e * sy for e in predictor_residuals(fit.matrices, records))
    return InnovationResult(mats, cov, n, p, rcond, fit, tuple(e[fit.burn :] for e in residuals), fit.burn)


def split_references(
    exps: Sequence[Experiment], references: Sequence[str] | None, required: bool, owner: str
) -> tuple[list[np.ndarray] | None, list[np.ndarray], tuple[str, ...]]:
    """``(r records or None, u records, plant-input names)``: input columns named in ``references`` are r."""
    names = exps[0].input_names
    refs = tuple(references or ())
    missing = [r for r in refs if r not in names]
    if missing:
        raise DataError(
            f"reference column '{missing[0]}' of {owner} is not an input; expected one of {', '.join(names)}."
        )
    if required and not refs:
        raise DataError(f"{owner} needs recorded references: name them in `references`.")
    plant_in = [i for i, n in enumerate(names) if n not in refs]
    if not plant_in:
        raise DataError(f"{owner} needs plant-input columns besides the references; got only {', '.join(names)}.")
    ref_idx = [names.index(r) for r in refs]
    r = [np.array(e.u[:, ref_idx]) for e in exps] if refs else None
    return r, [np.array(e.u[:, plant_in]) for e in exps], tuple(names[i] for i in plant_in)
