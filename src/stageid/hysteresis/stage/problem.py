"""Step 2 of the stage identification: weights, creep and dynamics for fixed hysteresis thresholds.

``StageProblem`` holds every record's hysteresis columns and creep lags at full rate and solves
``y = o_j + G[Z_j w + L_j c]`` on masked rows (all rows, or the folds of the held-out choice):
the weights for fixed ``G``, output-error fits for ``G`` (:mod:`.dynamics`, and
:func:`refine_output_error` by variable projection), alternated.  What depends on the kind of
hysteresis is a strategy plugged into it (its ``columns``): :class:`~.pi_columns.PIColumns`
(play operators, the PI identification's invertibility constraint) or
:class:`~.preisach.PreisachColumns` (Preisach cells, non-negative smoothed weights).  It is a
step inside :class:`~.identification.StageIdentifier` (which is the estimator), not an
estimator itself, so its method is ``solve``, not ``fit``.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Protocol

import numpy as np

from ..._errors import IdentificationError
from ..models.creep import CreepTerm
from . import StageModel
from .dynamics import fit_hammerstein, fit_unit_gain_dynamics, transfer_to_statespace, unit_gain_filter
from .selection import simulation_score

__all__ = ["StageProblem", "HysteresisColumns", "refine_output_error"]


class HysteresisColumns(Protocol):
    """What :class:`StageProblem` asks of the hysteresis it fits the weights of.

    ``recs`` and ``kinds`` are the records and their starting states, ``Z`` per record the
    columns the output is linear in (n_samples, n_columns), ``live`` the columns fitted;
    ``n_alternations``, ``settle`` and ``max_rows`` set the alternation and its row stride.
    """

    recs: list
    kinds: list[str]
    Z: list[np.ndarray]
    live: np.ndarray
    n_alternations: int
    settle: float
    max_rows: int

    def search_columns(self, cols: list[np.ndarray], masks: list[np.ndarray], stride: int) -> list[np.ndarray]: ...

    def grid_starts(self, problem: Any, cols: list[np.ndarray], masks: list[np.ndarray], order: int) -> list: ...

    def solve_weights(
        self, cols: list[np.ndarray], masks: list[np.ndarray], nc: int, stride: int
    ) -> tuple[np.ndarray, np.ndarray]: ...

    def hysteresis(self, w, c, offset, taus, dt, in_name, out_name) -> tuple[Any, Any]: ...


class StageProblem:
    """The hysteresis and creep columns of every record (full rate) and the alternating fit of step 2.

    Parameters
    ----------
    columns : HysteresisColumns
        The hysteresis side: :class:`~.pi_columns.PIColumns` or :class:`~.preisach.PreisachColumns`.
    dt : float
        Sample time of the records, s.
    prefilter : (b, a), optional
        Fixed unit-DC-gain dynamics every column runs through before the fitted ``G`` (the modes
        found in the disturbance, :mod:`.disturbance_modes`); None: none.  An attribute: the
        identification tries the problem with and without it.
    """

    def __init__(self, columns: HysteresisColumns, dt: float, prefilter: tuple | None = None) -> None:
        self.hysteresis_columns = columns
        self.recs = columns.recs
        self.kinds = columns.kinds
        self.dt = dt
        self.prefilter = prefilter
        #: rounds of the alternation from each start, and the relative drop of the residual below
        #: which it stops early (0: never)
        self.n_alternations = columns.n_alternations
        self.settle = columns.settle
        self.stride = max(1, int(np.ceil(sum(u.size for u, _ in self.recs) / columns.max_rows)))
        # (creep time constants and prefilter, their columns): the last set asked for (see columns)
        self._columns: tuple[Any, list[np.ndarray]] = (None, [])

    def columns(self, taus: tuple[float, ...]) -> list[np.ndarray]:
        """Per record the live operator columns and the creep lags, C-ordered (the filter runs
        along the rows); kept for the last ``taus`` (``auto`` asks for each set many times)."""
        key = (tuple(taus), None if self.prefilter is None else tuple(map(tuple, self.prefilter)))
        if self._columns[0] != key:
            out = []
            live = self.hysteresis_columns.live
            for (u, _), z in zip(self.recs, self.hysteresis_columns.Z):
                cols = [z[:, live]]
                if taus:
                    term = CreepTerm(time_constants=taus, weights=np.zeros(len(taus)), sample_time=self.dt)
                    cols.append(term.lags(u))
                both = np.ascontiguousarray(np.hstack(cols))
                out.append(both if self.prefilter is None else unit_gain_filter(*self.prefilter, both))
            self._columns = (key, out)
        return self._columns[1]

    def filtered(self, ba, cols: list[np.ndarray], masks: list[np.ndarray]) -> list[np.ndarray]:
        """``G[cols]`` per record at rest; a record without fitted rows (a held-out fold) is
        passed through unfiltered, since none of its rows is read."""
        return [unit_gain_filter(ba[0], ba[1], c) if mk.any() else c for c, mk in zip(cols, masks)]

    def search_columns(self, cols: list[np.ndarray], masks: list[np.ndarray]) -> list[np.ndarray]:
        """Columns the searches for ``G`` run on (all of them, or a reduced set for many columns)."""
        return self.hysteresis_columns.search_columns(cols, masks, self.stride)

    def grid_starts(self, cols: list[np.ndarray], masks: list[np.ndarray], order: int) -> list:
        """Further ``(b, a)`` starts of the alternation, from the hysteresis side."""
        return self.hysteresis_columns.grid_starts(self, cols, masks, order)

    def solve_weights(self, cols: list[np.ndarray], masks: list[np.ndarray], nc: int) -> tuple[np.ndarray, np.ndarray]:
        """Weights (creep last) and one offset per record fitted to ``y`` on the masked rows of ``cols``."""
        return self.hysteresis_columns.solve_weights(cols, masks, nc, self.stride)

    def segments(self, masks: list[np.ndarray], order: int) -> list[tuple[int, int]]:
        """(record, end) of every record whose fitted rows are a prefix long enough for the dynamics."""
        out = []
        for j, mask in enumerate(masks):
            last = int(np.flatnonzero(mask)[-1]) + 1 if mask.any() else 0
            if last > 2 * order + 1 and mask[:last].all():
                out.append((j, last))
        if not out:
            raise IdentificationError("no record segment left to fit the dynamics on.")
        return out

    def sse(self, filtered, masks, wc, offsets) -> float:
        total = 0.0
        for (_, y), c, mask, off in zip(self.recs, filtered, masks, offsets):
            e = (y - c @ wc - off)[mask]
            total += float(e @ e)
        return total

    def solve(self, order: int, taus: tuple[float, ...], masks: list[np.ndarray]):
        """Weights, creep weights, offsets and ``(b, a)`` (None for order 0) fitted on the masked rows.

        Alternation from two starts -- the over-parametrised fit (:func:`fit_hammerstein`) and
        ``G = 1`` -- keeping the least residual seen, so the fit is never worse than without
        dynamics on the fitted rows.
        """
        cols = self.columns(taus)
        nc = len(taus)
        wc, offsets = self.solve_weights(cols, masks, nc)
        best = (self.sse(cols, masks, wc, offsets), wc, offsets, None)
        if order:
            segs = self.segments(masks, order)
            search = self.search_columns(cols, masks)
            starts = [None] + [ba for ba in (refine_output_error(self, search, masks, order),) if ba is not None]
            try:
                starts.append(fit_hammerstein([(search[j][:end], self.recs[j][1][:end]) for j, end in segs], order))
            except (IdentificationError, np.linalg.LinAlgError):
                pass
            starts += self.grid_starts(cols, masks, order)
            for ba in starts:
                w_cur, off_cur = wc, offsets
                prev = np.inf
                for _ in range(self.n_alternations):
                    if ba is None:
                        pairs = [(cols[j][:end] @ w_cur, self.recs[j][1][:end] - off_cur[j]) for j, end in segs]
                        try:
                            ba = fit_unit_gain_dynamics(pairs, order)
                        except (IdentificationError, np.linalg.LinAlgError):
                            break  # this start cannot go on (a regressor vanished); keep the best seen
                    filtered = self.filtered(ba, cols, masks)
                    w_cur, off_cur = self.solve_weights(filtered, masks, nc)
                    err = self.sse(filtered, masks, w_cur, off_cur)
                    if err < best[0]:
                        best = (err, w_cur, off_cur, ba)
                    if self.settle and err > prev * (1 - self.settle):
                        break
                    prev = err
                    ba = None
        _, wc, offsets, ba = best
        return wc[: wc.size - nc], wc[wc.size - nc :], offsets, ba

    def held_out_score(self, order: int, taus: tuple[float, ...]) -> float:
        """Summed RMS error (% of range) on held-out records (or the last 40 % of a single record)."""
        return simulation_score(self.held_out_residuals(order, taus))

    def held_out_residuals(self, order: int, taus: tuple[float, ...]) -> list | None:
        """Per fold ``(training residuals, [(held-out residual, record range), ...])`` of the fit of
        ``order`` and ``taus`` on the fold's rows (each record left out in turn, or the first 60 %
        of a single record), every residual with its own mean removed; None when a fold's fit fails."""
        J = len(self.recs)
        folds = []
        if J == 1:
            n = self.recs[0][0].size
            fit_mask = np.arange(n) < int(0.6 * n)
            folds.append(([fit_mask], [~fit_mask]))
        else:
            for k in range(J):
                fit = [np.full(u.size, j != k) for j, (u, _) in enumerate(self.recs)]
                test = [np.full(u.size, j == k) for j, (u, _) in enumerate(self.recs)]
                folds.append((fit, test))
        out = []
        for fit_masks, test_masks in folds:
            try:
                w, c, _, ba = self.solve(order, taus, fit_masks)
            except (IdentificationError, np.linalg.LinAlgError):
                return None
            train, tests = [], []
            for (_, y), fit_mask, test_mask, col in zip(self.recs, fit_masks, test_masks, self.columns(taus)):
                v = col @ np.r_[w, c]
                e = y - (v if ba is None else unit_gain_filter(ba[0], ba[1], v[:, None])[:, 0])
                # every record with its own offset
                if fit_mask.any():
                    train.append(e[fit_mask] - e[fit_mask].mean())
                if test_mask.any():
                    tests.append((e[test_mask] - e[test_mask].mean(), float(np.ptp(y))))
            out.append((train, tests))
        return out

    def build(self, w, c, offset, taus, ba, in_name, out_name) -> StageModel:
        """The stage model of fitted weights ``w``, creep weights ``c`` of ``taus``, the first
        record's ``offset`` and dynamics ``(b, a)`` (None: none), the prefilter in series."""
        h, creep = self.hysteresis_columns.hysteresis(w, c, offset, taus, self.dt, in_name, out_name)
        ba = self.with_prefilter(ba)
        dyn = None if ba is None else transfer_to_statespace(ba[0] / (np.sum(ba[0]) / np.sum(ba[1])), ba[1], self.dt)
        return StageModel(h, dyn, creep)

    def with_prefilter(self, ba):
        """The fitted ``(b, a)`` (or None) in series with the fixed prefilter."""
        if self.prefilter is None:
            return ba
        if ba is None:
            return self.prefilter
        return np.convolve(ba[0], self.prefilter[0]), np.convolve(ba[1], self.prefilter[1])

    def offsets_of(self, model: StageModel, recs: list) -> np.ndarray:
        """Each record's offset: the model's plus its mean residual."""
        out = []
        for (u, y), kind in zip(recs, self.kinds):
            h = model.hysteresis.with_state(model.hysteresis.consistent_state(u[0], kind))
            out.append(float(np.mean(y - model.with_hysteresis(h).simulate(u, self.dt)[:, 0])) + h.output_offset)
        return np.array(out)

    def residuals(self, model: StageModel, offsets) -> list[np.ndarray]:
        """Measured minus modelled output per record (own offset and starting state)."""
        out = []
        for (u, y), kind, off in zip(self.recs, self.kinds, offsets):
            h = model.hysteresis
            h = replace(h.with_state(h.consistent_state(u[0], kind)), output_offset=float(off))
            out.append(y - model.with_hysteresis(h).simulate(u, self.dt)[:, 0])
        return out

    def errors(self, model: StageModel, offsets) -> tuple[list[float], list[float]]:
        max_e, rms_e = [], []
        for (_, y), e in zip(self.recs, self.residuals(model, offsets)):
            max_e.append(float(100 * np.max(np.abs(e)) / np.ptp(y)))
            rms_e.append(float(100 * np.sqrt(np.mean(e**2)) / np.ptp(y)))
        return max_e, rms_e


def refine_output_error(problem: StageProblem, cols: list, masks: list, order: int):
    """``(b, a)`` minimising the output error with the weights projected out (variable projection).

    Parameters ``(a_1..a_n, b_1..b_n)``, ``b_0 = sum a - sum b_i`` (``G(1) = 1``); the inner fit
    is unconstrained least squares of the weights and offsets on strided rows; an unstable
    ``A`` scores a large residual.  Started from ``n`` poles at 0.5 and a numerator spread over
    the delays (a stage's sub-millisecond lag and delay at 10 kHz).
    """
    from scipy.optimize import least_squares

    n = int(order)
    rows = [np.flatnonzero(m)[:: problem.stride] for m in masks]
    J = len(cols)
    y = np.concatenate([problem.recs[j][1][rows[j]] for j in range(J)])
    big = float(np.linalg.norm(y)) + 1.0

    def residual(theta):
        a = np.r_[1.0, theta[:n]]
        if np.any(np.abs(np.roots(a)) >= 0.9995):
            return np.full(y.size, big / np.sqrt(y.size))
        b = np.r_[np.sum(a) - np.sum(theta[n:]), theta[n:]]
        blocks = []
        for j, c in enumerate(cols):
            if rows[j].size == 0:
                continue
            f = unit_gain_filter(b, a, c)[rows[j]]
            E = np.zeros((rows[j].size, J))
            E[:, j] = 1.0
            blocks.append(np.hstack([f, E]))
        X = np.vstack(blocks)
        sol = np.linalg.lstsq(X, y, rcond=None)[0]
        return y - X @ sol

    a0 = np.poly(np.full(n, 0.5))
    b_tail = np.full(n, np.sum(a0) / (n + 1))
    try:
        res = least_squares(residual, np.r_[a0[1:], b_tail], method="trf", diff_step=1e-6, max_nfev=60 * n)
    except (ValueError, np.linalg.LinAlgError):
        return None
    a = np.r_[1.0, res.x[:n]]
    if np.any(np.abs(np.roots(a)) >= 0.9995):
        return None
    return np.r_[np.sum(a) - np.sum(res.x[n:]), res.x[n:]], a
