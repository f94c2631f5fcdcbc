"""The closed loop ``T`` identified pair by pair from the experiments (Shakir & Kim, sec. 3.2.1, eq. 11-17).

The paper excites one reference per experiment; every reference-to-output pair ``T_ij`` is then
a SISO prediction-error fit of output ``i`` on reference ``j`` over the experiments that excite
``j``, and the pairs are assembled into the discrete transfer matrix ``T``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from .._errors import DataError
from ..data import Experiment, as_experiments
from ..models import TransferMatrix
from .polynomial import PolynomialModel

__all__ = ["excited_reference", "closed_loop_experiments", "group_by_reference", "identify_pairs"]

#: fit of one pair: (reference records, output records, dt) -> model
PairFit = Callable[[list[np.ndarray], list[np.ndarray], float], PolynomialModel]


def excited_reference(exp: Experiment, rel_threshold: float = 1e-3) -> int:
    """Index of the one excited reference column of ``exp`` (the paper excites one axis per run).

    Raises
    ------
    DataError
        When no reference or more than one reference carries a signal (RMS above
        ``rel_threshold`` times the largest).
    """
    rms = np.sqrt(np.mean((exp.u - exp.u.mean(axis=0)) ** 2, axis=0))
    if not np.any(rms > 0):
        raise DataError(
            f"experiment '{exp.name or 'unnamed'}' has no excited reference: every reference column is constant."
        )
    active = np.flatnonzero(rms > rel_threshold * rms.max())
    if active.size != 1:
        names = ", ".join(exp.input_names[k] for k in active)
        raise DataError(
            f"experiment '{exp.name or 'unnamed'}' excites {active.size} references ({names}); expected one reference per experiment."
        )
    return int(active[0])


def closed_loop_experiments(data: Experiment | Sequence[Experiment]) -> tuple[Experiment, ...]:
    """The experiments, checked: references ``r`` as inputs, as many as the outputs ``y``.

    Raises
    ------
    DataError
        Not experiments, or a reference count different from the output count.
    """
    if not isinstance(data, (Experiment, list, tuple)):
        raise DataError(
            f"ClosedLoopIdentification.fit needs an Experiment or a sequence of them; got {type(data).__name__}."
        )
    exps = as_experiments(data)
    first = exps[0]
    if first.n_inputs != first.n_outputs:
        raise DataError(
            f"closed-loop data need one reference per output; got {first.n_inputs} references and {first.n_outputs} outputs."
        )
    return tuple(exps)


def group_by_reference(exps: Sequence[Experiment]) -> dict[int, list[Experiment]]:
    """``{j: experiments exciting reference j}``; DataError when a reference is never excited."""
    groups: dict[int, list[Experiment]] = {}
    for e in exps:
        groups.setdefault(excited_reference(e), []).append(e)
    first = exps[0]
    missing = [first.input_names[j] for j in range(first.n_inputs) if j not in groups]
    if missing:
        raise DataError(f"every reference must be excited in some experiment; none excites {', '.join(missing)}.")
    return groups


def identify_pairs(
    groups: dict[int, list[Experiment]], fit_pair: PairFit
) -> tuple[TransferMatrix, dict[tuple[int, int], PolynomialModel], np.ndarray]:
    """Every pair ``T_ij`` fitted by ``fit_pair`` on the records that excite ``j`` (eq. 11-14).

    Records are taken relative to their first sample (the loop starts at rest around it).

    Returns
    -------
    (T, models, fits)
        The discrete closed loop (references to outputs), ``{(i, j): PolynomialModel}`` and
        the simulation fit in percent of each pair on its records, shape (p, p).
    """
    first = next(iter(groups.values()))[0]
    p, dt = first.n_outputs, first.dt
    models: dict[tuple[int, int], PolynomialModel] = {}
    fits = np.zeros((p, p))
    num = [[None] * p for _ in range(p)]
    den = [[None] * p for _ in range(p)]
    for j, group in groups.items():
        r = [e.u[:, j] - e.u[0, j] for e in group]
        for i in range(p):
            y = [e.y[:, i] - e.y[0, i] for e in group]
            m = fit_pair(r, y, dt)
            models[(i, j)] = m
            sim = np.concatenate([m.simulate(rk) for rk in r])
            yy = np.concatenate(y)
            fits[i, j] = 100.0 * (1.0 - np.linalg.norm(yy - sim) / max(np.linalg.norm(yy - yy.mean()), 1e-300))
            num[i][j], den[i][j] = m.plant_polynomials()
    return TransferMatrix(num, den, dt, first.input_names, first.output_names), models, fits
