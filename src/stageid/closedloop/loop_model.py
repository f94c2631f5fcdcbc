"""The closed loop ``T`` identified pair by pair from the experiments (Shakir & Kim, sec. 3.2.1, eq. 11-17).

The paper excites one reference per experiment; every reference-to-output pair ``T_ij`` is then
a SISO prediction-error fit of output ``i`` on reference ``j`` over the experiments that excite
``j``, and the pairs are assembled into the discrete transfer matrix ``T``.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
import scipy.signal as ss

from .._errors import DataError
from ..data import Experiment, as_experiments
from ..models import TransferMatrix
from .covariance import model_orders
from .pem import pem
from .polynomial import FREE_ORDERS, PolynomialModel

__all__ = [
    "remembered",
    "excited_reference",
    "closed_loop_experiments",
    "group_by_reference",
    "at_rest",
    "start_levels",
    "level_and_numerator",
    "refit",
    "fit_with_levels",
    "level_loss",
    "identify_pairs",
    "assemble_loop",
]

#: passes of the rest-level estimate; the shift, as a share of the reference's RMS, below which it
#: has converged; and the share of the first fit's loss the level must reach to be kept: a step
#: the loop never saw dominates the residual, while a smaller gain is the model's own error,
#: which an offset would only hide
REST_PASSES = 8
REST_TOL = 1e-4
REST_KEEP = 0.5
#: fits of each pair to its outputs less the levels the previous fit gave (:func:`fit_with_levels`):
#: the first selects the order again, the others refit from the last
LEVEL_PASSES = 2

#: fit of one pair: (reference records, output records, dt) -> model
PairFit = Callable[[list[np.ndarray], list[np.ndarray], float], PolynomialModel]


def remembered(fit_pair: PairFit) -> PairFit:
    """``fit_pair`` fitting each set of records once: the rest-level search fits the diagonal
    pair at the levels it keeps, and :func:`identify_pairs` starts from the same records."""
    cache: dict[bytes, PolynomialModel] = {}

    def fit(r: list[np.ndarray], y: list[np.ndarray], dt: float) -> PolynomialModel:
        digest = hashlib.blake2b(np.float64(dt).tobytes())
        for a in (*r, *y):
            digest.update(np.ascontiguousarray(a, dtype=float).tobytes())
        key = digest.digest()
        if key not in cache:
            cache[key] = fit_pair(r, y, dt)
        return cache[key]

    return fit


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


def at_rest(groups: dict[int, list[Experiment]], fit_pair: PairFit) -> dict[int, list[Experiment]]:
    """The records as deviations from the loop at rest before their first sample.

    Outputs are taken relative to their first sample (the loop is strictly proper, so ``y[0]``
    is the rest output). The excited reference is taken relative to its rest level, which is
    its first sample only when the excitation starts from rest: a multisine starts at a
    non-zero value and oscillates about the level the loop rested at, and subtracting its first
    value would add a step the loop never saw. So the level search starts from whichever of the
    first sample and the record's mean the diagonal pair ``T_jj`` fits better (:func:`start_levels`);
    from there the step offset ``c`` that best explains the fit's residual (linear least squares
    on the pair's poles, :func:`level_shift`) is added and the pair refitted until the shift is below
    :data:`REST_TOL` of the reference's RMS or no longer lowers the loss; the level is kept only when the last fit's loss is
    below :data:`REST_KEEP` times the first sample's, else the first sample stays the rest level.
    """
    out = {}
    for j, group in groups.items():
        r = [e.u[:, j].astype(float) for e in group]
        y = [e.y[:, j] - e.y[0, j] for e in group]
        first = np.array([rk[0] for rk in r])
        dt = group[0].dt
        levels, loss0 = start_levels(r, y, dt, fit_pair)
        best, best_loss = levels, np.inf
        for _ in range(REST_PASSES):
            m = fit_pair([rk - lk for rk, lk in zip(r, levels)], y, dt)
            loss = _loss(m, r, y, levels)
            if not loss < best_loss:  # a shift that does not lower the loss ends the search
                break
            best, best_loss = levels, loss
            shift = level_shift(m, [rk - lk for rk, lk in zip(r, levels)], y)
            if all(abs(c) <= REST_TOL * rk.std() for c, rk in zip(shift, r)):
                break
            levels = levels + shift
        levels = best if best_loss < REST_KEEP * loss0 else first
        out[j] = [_deviations(e, j, lk) for e, lk in zip(group, levels)]
    return out


def start_levels(r: list[np.ndarray], y: list[np.ndarray], dt: float, fit_pair: PairFit) -> tuple[np.ndarray, float]:
    """The better start of the rest-level search, first samples or record means, by the pair's
    loss, and the loss with the first samples (the level every other estimate must beat).

    A level search started at the first sample of a multisine stays near it (measured: pair
    fits 72-76 % and 13-256 % errors on records whose loop rested at the mean, against 0.02-2 %
    from the mean).
    """
    first = np.array([rk[0] for rk in r])
    mean = np.array([rk.mean() for rk in r])
    losses = []
    for levels in (first, mean):
        m = fit_pair([rk - lk for rk, lk in zip(r, levels)], y, dt)
        losses.append(_loss(m, r, y, levels))
    return (first if losses[0] <= losses[1] else mean), losses[0]


def level_and_numerator(model: PolynomialModel, r: list[np.ndarray], y: list[np.ndarray]) -> np.ndarray:
    """Each record's output level ``d`` in ``y = q^-nk B / (A F) r + d``, solved with ``B`` by
    linear least squares with the denominator ``A F`` held."""
    den = np.convolve(model.A, model.F)
    num = np.concatenate([np.zeros(model.nk), [1.0]])
    nb, n_rec = model.B.size, len(r)
    rows = []
    for k, rk in enumerate(r):
        x = ss.lfilter(num, den, rk)
        Phi = np.column_stack([np.concatenate([np.zeros(i), x[: x.size - i]]) for i in range(nb)])
        ones = np.zeros((rk.size, n_rec))
        ones[:, k] = 1.0
        rows.append(np.hstack([Phi, ones]))
    X = np.vstack(rows)
    scale = np.maximum(np.linalg.norm(X, axis=0), 1e-300)
    theta = np.linalg.lstsq(X / scale, np.concatenate(y), rcond=None)[0] / scale
    return theta[nb:]


def _loss(model: PolynomialModel, r, y, levels) -> float:
    return sum(float(np.sum((yk - model.simulate(rk - lk)) ** 2)) for rk, yk, lk in zip(r, y, levels))


def level_shift(model: PolynomialModel, r: list[np.ndarray], y: list[np.ndarray]) -> np.ndarray:
    """Shift of each record's reference level under ``model``'s poles.

    With the denominator ``A F`` held, ``y = q^-nk B / (A F) (r - c)`` is linear in ``B`` and in
    ``c B`` taken as a free polynomial ``D`` per record (the response to a step at the first
    sample): one least-squares solve gives both, and ``c = -(D . B) / (B . B)``.
    """
    den = np.convolve(model.A, model.F)
    lead = np.zeros(model.nk)
    nb = model.B.size
    ys, n_rec = [], len(r)
    rows_r, rows_s = [], []
    for k, (rk, yk) in enumerate(zip(r, y)):
        xr = ss.lfilter(np.concatenate([lead, [1.0]]), den, rk)
        xs = ss.lfilter(np.concatenate([lead, [1.0]]), den, np.ones(rk.size))
        Phi = np.column_stack([np.concatenate([np.zeros(i), xr[: xr.size - i]]) for i in range(nb)])
        Psi = np.zeros((rk.size, nb * n_rec))
        for i in range(nb):
            Psi[i:, k * nb + i] = xs[: xs.size - i]
        rows_r.append(Phi)
        rows_s.append(Psi)
        ys.append(yk)
    X = np.hstack([np.vstack(rows_r), np.vstack(rows_s)])
    Y = np.concatenate(ys)
    scale = np.maximum(np.linalg.norm(X, axis=0), 1e-300)  # 1/(A F) swells the step columns by its DC gain
    theta = np.linalg.lstsq(X / scale, Y, rcond=None)[0] / scale
    b, d = theta[:nb], theta[nb:].reshape(n_rec, nb)
    return -(d @ b) / max(float(b @ b), 1e-300)


def _deviations(exp: Experiment, j: int, level: float) -> Experiment:
    u = exp.u - exp.u[0]
    u[:, j] = exp.u[:, j] - level
    return replace(exp, u=u, y=exp.y - exp.y[0])


def refit(model: PolynomialModel, r: list[np.ndarray], y: list[np.ndarray]) -> PolynomialModel:
    """``model``'s structure and orders fitted again by prediction error, started from it."""
    orders = {k: v for k, v in model_orders(model).items() if k in FREE_ORDERS[model.structure]}
    return pem(r, y, model.structure, orders, model.nk, model.dt, initial=model)


def fit_with_levels(
    r: list[np.ndarray], y: list[np.ndarray], dt: float, fit_pair: PairFit
) -> tuple[PolynomialModel, np.ndarray]:
    """One pair ``T_ij`` and each record's output level ``d`` (``y = T_ij r + d``).

    A first fit to ``y`` gives the levels (:func:`level_and_numerator`); the order is selected
    again on ``y - d`` (a pair whose order was selected on outputs still carrying the offset
    stays in a higher minimum: PEM seed 4's coupling (1, 0) at 2.0x the noise floor, 0.95x
    selected again), and the levels are solved again and the pair refitted from where it was
    until :data:`LEVEL_PASSES` fits to corrected outputs are done.  Of all these fits the one
    with the lowest loss under its own best levels (:func:`level_loss`) is kept: a later stage
    can end in a worse minimum than an earlier one (PEM seed 12's T_00: 1.08x the floor after the
    first fit, 1.46x after the refit).
    """
    fits = [fit_pair(r, y, dt)]
    d = level_and_numerator(fits[0], r, y)
    fits.append(fit_pair(r, [yk - dk for yk, dk in zip(y, d)], dt))
    for _ in range(LEVEL_PASSES - 1):
        d = level_and_numerator(fits[-1], r, y)
        fits.append(refit(fits[-1], r, [yk - dk for yk, dk in zip(y, d)]))
    best = min(fits, key=lambda m: level_loss(m, r, y))
    return best, np.array([float(np.mean(yk - best.simulate(rk))) for rk, yk in zip(r, y)])


def level_loss(model: PolynomialModel, r: list[np.ndarray], y: list[np.ndarray]) -> float:
    """The summed squared output error of ``model`` with each record's output level at its best
    (the mean of that record's residual)."""
    loss = 0.0
    for rk, yk in zip(r, y):
        e = yk - model.simulate(rk)
        loss += float(np.sum((e - e.mean()) ** 2))
    return loss


def identify_pairs(
    groups: dict[int, list[Experiment]], fit_pair: PairFit
) -> tuple[TransferMatrix, dict[tuple[int, int], PolynomialModel], np.ndarray, dict[int, list[Experiment]]]:
    """Every pair ``T_ij`` fitted by ``fit_pair`` on the records that excite ``j`` (eq. 11-14),
    each output's rest level estimated with it.

    The records are deviations from the loop at rest (:func:`at_rest`), every output taken
    relative to its first sample, which carries one sample of the noise into the whole record;
    a pair fitted to that bends its DC gain to follow the offset wherever the reference has a
    mean (measured on chirps from DC: the identified loop 2.6-4.5x the noise floor on the
    records, all of it a constant). So each output of each record gets the constant ``d`` of
    ``y = T r + d``, solved jointly with a numerator under the loop's poles
    (:func:`level_and_numerator`; the DC gain and ``d`` are nearly interchangeable, so solving
    them one after the other would not move them), the order selected again on ``y - d`` and the
    pair refitted from where it was (:func:`fit_with_levels`).

    Returns
    -------
    (T, models, fits, groups)
        The discrete closed loop (references to outputs), ``{(i, j): PolynomialModel}``, the
        simulation fit in percent of each pair on its records, shape (p, p), and the records
        with the estimated output levels removed (those the pairs were fitted to).
    """
    p = next(iter(groups.values()))[0].n_outputs
    models: dict[tuple[int, int], PolynomialModel] = {}
    shifted_groups = {}
    for j, group in groups.items():
        r = [e.u[:, j] for e in group]
        shifted = [e.y.copy() for e in group]
        for i in range(p):
            models[(i, j)], d = fit_with_levels(r, [e.y[:, i] for e in group], group[0].dt, fit_pair)
            for yk, dk in zip(shifted, d):
                yk[:, i] -= dk
        shifted_groups[j] = [replace(e, y=yk) for e, yk in zip(group, shifted)]
    T, fits = assemble_loop(models, shifted_groups)
    return T, models, fits, shifted_groups


def assemble_loop(
    models: dict[tuple[int, int], PolynomialModel], groups: dict[int, list[Experiment]]
) -> tuple[TransferMatrix, np.ndarray]:
    """The discrete closed loop ``T`` of the pairs ``models`` and each pair's simulation fit in
    percent on ``groups`` (records with the output levels removed), shape (p, p)."""
    first = next(iter(groups.values()))[0]
    p = first.n_outputs
    fits = np.zeros((p, p))
    num = [[None] * p for _ in range(p)]
    den = [[None] * p for _ in range(p)]
    for j, group in groups.items():
        for i in range(p):
            m = models[(i, j)]
            sim = np.concatenate([m.simulate(e.u[:, j]) for e in group])
            yy = np.concatenate([e.y[:, i] for e in group])
            fits[i, j] = 100.0 * (1.0 - np.linalg.norm(yy - sim) / max(np.linalg.norm(yy - yy.mean()), 1e-300))
            num[i][j], den[i][j] = m.plant_polynomials()
    T = TransferMatrix(num, den, first.dt, first.input_names, first.output_names)
    return T, fits
