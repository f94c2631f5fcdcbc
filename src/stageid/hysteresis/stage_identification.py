"""Joint identification of a rate-dependent stage: hysteresis -> creep -> unit-DC-gain dynamics.

Procedure (:meth:`StageIdentifier.fit`):

1. **Hysteresis thresholds** by :class:`~stageid.hysteresis.PIIdentifier` (rate independent,
   no creep): thresholds (and for the modified PI the CP thresholds and warp), every record's
   starting state and output offset.
2. **Alternation** with the thresholds fixed.  The model output is
   ``y = o_j + G[Z_j w + L_j c]`` (``Z_j`` operator outputs, ``L_j`` creep lags of record
   ``j``, ``o_j`` its offset); ``G`` is linear, so for fixed ``G`` the output is linear in
   ``(w, c, o)``: the filtered columns ``G[Z_j], G[L_j]`` go into the constrained least squares
   of step 2 of the PI identification (same invertibility constraint, ``c >= 0``).  For fixed
   weights ``G`` is an output-error fit of ``v = Z w + L c`` to ``y - o``
   (:func:`~.dynamics.fit_unit_gain_dynamics`).  ``N_ALTERNATIONS`` rounds, each of both steps.
3. **auto** (``dynamics="auto"``, ``creep="auto"``): every candidate (orders
   ``AUTO_ORDERS``, creep sets ``AUTO_CREEP``) is fitted on all records but one and scored by
   its RMS error on the one left out (own offset), summed over the records; with a single
   record the first 60 % of it is fitted and the rest scored.  The best candidate is then
   fitted on all records.

The result's model is a :class:`~.stage.StageModel` that starts like the PI identification's
model (zero state, first record's offset).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .._errors import DataError, IdentificationError
from .._threads import single_blas_thread
from ..base import Boolean, Estimator, Interval, Options, Satisfies
from ..checks import is_real
from .creep import CreepTerm
from .dynamics import fit_hammerstein, fit_unit_gain_dynamics, transfer_to_statespace, unit_gain_filter
from .identification import MODEL_KINDS, PIIdentifier
from .records import STATE_CHOICES, read_records, sampling_period
from .stage import StageModel
from .stage_inverse import invert_dynamics

__all__ = ["StageIdentifier", "StageFit", "AUTO_ORDERS", "AUTO_CREEP"]

N_ALTERNATIONS = 4
AUTO_ORDERS = (0, 1, 2, 3, 4)
AUTO_CREEP = ((), (0.05,), (0.01, 0.1, 1.0), (0.005, 0.05, 0.5, 5.0))
#: Relative margin within which ``auto`` prefers the candidate with fewer parameters.
AUTO_TOLERANCE = 0.02
#: At least this many samples per dynamics coefficient (2n + 1 of them) in every record.
SAMPLES_PER_COEFFICIENT = 50
#: Least-squares rows per fit (evenly strided); the filters always run over every sample.
MAX_ROWS = 40000


def _dynamics_ok(value: Any) -> bool:
    return value is None or value == "auto" or (isinstance(value, int) and not isinstance(value, bool) and value >= 1)


def _creep_ok(value: Any) -> bool:
    if value is None or value == "auto":
        return True
    return (
        isinstance(value, (tuple, list, np.ndarray))
        and np.ndim(value) == 1
        and len(value) > 0
        and all(is_real(v) and v > 0 for v in value)
    )


@dataclass(frozen=True)
class StageFit:
    """Result of :meth:`StageIdentifier.fit` (no training data kept).

    Attributes
    ----------
    model : StageModel
    max_error_percent, rms_error_percent : tuple of float
        Per record, in % of that record's output range (own offset and starting state).
    output_offsets : tuple of float
    initial_states : tuple of str
    dynamics_order : int
        0: no dynamics.
    creep_time_constants : tuple of float
        Empty: no creep.
    held_out : tuple of (int, tuple of float, float)
        ``(order, creep time constants, held-out RMS % summed over folds)`` per candidate when
        something was ``"auto"``; empty otherwise.
    message : str
    """

    model: StageModel
    max_error_percent: tuple[float, ...]
    rms_error_percent: tuple[float, ...]
    output_offsets: tuple[float, ...]
    initial_states: tuple[str, ...]
    dynamics_order: int
    creep_time_constants: tuple[float, ...]
    held_out: tuple[tuple[int, tuple[float, ...], float], ...]
    message: str

    def summary(self) -> str:
        """A short text report."""
        h = self.model.hysteresis
        lines = [
            f"stage model: {h.kind} hysteresis, {h.n_operators} operators; creep "
            + (", ".join(f"{t:g} s" for t in self.creep_time_constants) or "none")
            + f"; dynamics order {self.dynamics_order}; fit on {len(self.max_error_percent)} record(s)"
        ]
        for i, (m, r, s) in enumerate(zip(self.max_error_percent, self.rms_error_percent, self.initial_states)):
            lines.append(f"  record {i}: max error {m:.3f} % of range, RMS {r:.3f} %, start {s}")
        if self.model.dynamics is not None:
            poles = self.model.dynamics.poles()
            hz = np.abs(np.log(poles.astype(complex))) / (2 * np.pi * self.model.dt)
            lines.append("  dynamics poles at " + ", ".join(f"{f:.4g} Hz" for f in sorted(hz)))
        for order, taus, score in self.held_out:
            lines.append(f"  candidate order {order}, creep {list(taus)}: held-out RMS {score:.3f} %")
        lines.append(f"  {self.message}")
        return "\n".join(lines)


class StageIdentifier(Estimator):
    """Identify a stage model: PI / modified-PI hysteresis, creep lags and unit-DC-gain dynamics.

    Parameters
    ----------
    model : {"pi", "modified-pi"}, default "modified-pi"
    n_operators : int, default 20
        As in :class:`~stageid.hysteresis.PIIdentifier`.
    dynamics : int >= 1, "auto" or None, default "auto"
        Order of the linear dynamics; ``None``: none; ``"auto"``: picked from ``AUTO_ORDERS``
        (0-4) by held-out error.
    creep : sequence of positive seconds, "auto" or None, default "auto"
        Creep time constants; ``"auto"``: picked from ``AUTO_CREEP`` by held-out error.
    initial_state : {"auto", "zero", "ascending", "descending"}, default "auto"
    input_warp : bool, default True
        Modified PI only (see :class:`~stageid.hysteresis.PIIdentifier`).
    sample_time : float, optional
        Sampling period [s] for ``(u, y)`` records (Experiments carry their own).

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis import PIModel
    >>> from stageid.hysteresis.stage import StageModel
    >>> from stageid.hysteresis.stage_identification import StageIdentifier
    >>> from stageid.models import StateSpaceModel
    >>> from stageid.signals import decaying_triangle
    >>> u = decaying_triangle(20.0, 8, 1e-4, amplitude=10.0)
    >>> true = StageModel(PIModel(r=[0.0, 2.5, 5.0, 7.5], weights=[1.0, 0.4, 0.2, 0.1]),
    ...                   StateSpaceModel([[0.9]], [[1.0]], [[0.1]], [[0.0]], dt=1e-4))
    >>> fit = StageIdentifier("pi", n_operators=4, dynamics=1, creep=None, sample_time=1e-4).fit(
    ...     (u, true.simulate(u)))
    >>> bool(fit.max_error_percent[0] < 0.1)
    True
    """

    parameter_constraints = {
        "model": [Options(*MODEL_KINDS)],
        "n_operators": [Interval(int, 2, None, closed="left")],
        "dynamics": [Satisfies(_dynamics_ok, 'a positive integer order, "auto" or None')],
        "creep": [Satisfies(_creep_ok, 'a non-empty sequence of positive seconds, "auto" or None')],
        "initial_state": [Options(*STATE_CHOICES)],
        "input_warp": [Boolean()],
        "sample_time": [Interval(float, 0, None, closed="neither"), None],
    }

    def __init__(
        self,
        model: str = "modified-pi",
        n_operators: int = 20,
        dynamics: int | str | None = "auto",
        creep: Sequence[float] | str | None = "auto",
        initial_state: str = "auto",
        input_warp: bool = True,
        sample_time: float | None = None,
    ) -> None:
        self.model = model
        self.n_operators = n_operators
        self.dynamics = dynamics
        self.creep = creep
        self.initial_state = initial_state
        self.input_warp = input_warp
        self.sample_time = sample_time

    @single_blas_thread
    def fit(self, data: Any, inputs: str | None = None, outputs: str | None = None) -> StageFit:
        """Identify the stage from one or several records (several rates are the normal input).

        Raises
        ------
        ParameterError
            Bad settings; no sampling period for (u, y) records; a dynamics order the records
            cannot support (fewer than ``SAMPLES_PER_COEFFICIENT`` samples per coefficient).
        DataError, IdentificationError
            As :meth:`PIIdentifier.fit`, or a dynamics fit that fails.
        """
        self.validate_params()
        recs, in_name, out_name = read_records(data, inputs, outputs)
        names = (in_name, out_name)
        dt = sampling_period(data, self.sample_time)
        if dt is None:
            raise self.invalid("sample_time", "the sampling period in seconds for dynamics and creep on (u, y) records")
        orders = AUTO_ORDERS if self.dynamics == "auto" else (0 if self.dynamics is None else int(self.dynamics),)
        creeps = AUTO_CREEP if self.creep == "auto" else (() if self.creep is None else tuple(map(float, self.creep)),)
        shortest = min(u.size for u, _ in recs)
        need = SAMPLES_PER_COEFFICIENT * (2 * max(orders) + 1)
        if self.dynamics not in (None, "auto") and shortest < need:
            raise self.invalid(
                "dynamics", f"an order these records support: order {max(orders)} needs {need} samples per record, "
                f"the shortest has {shortest}"
            )
        orders = tuple(n for n in orders if SAMPLES_PER_COEFFICIENT * (2 * n + 1) <= shortest)
        base = PIIdentifier(
            self.model, n_operators=self.n_operators, initial_state=self.initial_state, input_warp=self.input_warp
        ).fit(data, inputs, outputs)
        kinds = list(base.initial_states)
        problem = _StageProblem(base.model, recs, kinds, dt)
        held_out: list[tuple[int, tuple[float, ...], float]] = []
        if len(orders) * len(creeps) > 1:
            for taus in creeps:
                for n in orders:
                    held_out.append((n, taus, problem.held_out_score(n, taus)))
            # the simplest candidate within AUTO_TOLERANCE of the best held-out error
            best = min(c[2] for c in held_out)
            simple = sorted(held_out, key=lambda c: (c[0] + len(c[1]), c[0]))
            order, taus, _ = next(c for c in simple if c[2] <= best * (1 + AUTO_TOLERANCE) + 1e-3)
        else:
            order, taus = orders[0], creeps[0]
        everything = [np.ones(u.size, bool) for u, _ in recs]
        w, c, offsets, ba = problem.fit(order, taus, everything)
        model = problem.build(w, c, offsets[0], taus, ba, *names)
        if model.dynamics is not None:  # step 4: thresholds again, on the outputs with G inverted
            problem, model, offsets = self._second_pass(problem, model, recs, kinds, dt, order, taus, names)
        max_e, rms_e = problem.errors(model, offsets)
        return StageFit(
            model=model,
            max_error_percent=tuple(max_e),
            rms_error_percent=tuple(rms_e),
            output_offsets=tuple(float(v) for v in offsets),
            initial_states=tuple(kinds),
            dynamics_order=model.dynamics_order,
            creep_time_constants=tuple(taus),
            held_out=tuple(held_out),
            message=f"hysteresis by PIIdentifier ({base.message.rstrip('.')}); weights, creep and dynamics "
            f"alternated {N_ALTERNATIONS} times"
            + ("." if model.dynamics_order == order else f"; order-{order} dynamics did not lower the residual: none."),
        )

    def _second_pass(self, problem, model, recs, kinds, dt, order, taus, names):
        """Thresholds refitted on ``G^-1[y]`` (stable inversion), then step 2 again; kept when
        the residual on the records is smaller (the first pass saw the dynamics as hysteresis)."""
        unfiltered = [(u, invert_dynamics(model, y)) for u, y in recs]
        base = PIIdentifier(
            self.model, n_operators=self.n_operators, initial_state=self.initial_state, input_warp=self.input_warp
        ).fit(unfiltered)
        everything = [np.ones(u.size, bool) for u, _ in recs]
        second = _StageProblem(base.model, recs, kinds, dt)
        w, c, offsets2, ba = second.fit(order, taus, everything)
        model2 = second.build(w, c, offsets2[0], taus, ba, *names)
        old = problem.errors(model, problem.offsets_of(model, recs))[1]
        new = second.errors(model2, offsets2)[1]
        if sum(new) < sum(old):
            return second, model2, offsets2
        return problem, model, problem.offsets_of(model, recs)


class _StageProblem:
    """Operator and creep columns of every record (full rate) and the alternating fit of step 2."""

    def __init__(self, hysteresis: Any, recs: list, kinds: list[str], dt: float) -> None:
        self.h = hysteresis
        self.recs = recs
        self.kinds = kinds
        self.dt = dt
        self.Z = []
        for (u, _), kind in zip(recs, kinds):
            m = hysteresis.with_state(hysteresis.consistent_state(u[0], kind))
            self.Z.append(m.operator_outputs(u)[0])
        r = hysteresis.r
        self.live = np.flatnonzero(np.max([np.ptp(z, axis=0) for z in self.Z], axis=0) > 1e-3 * max(r[-1], 1e-300))
        self.live = np.union1d(self.live, [0])
        self.classical = hysteresis.kind == "pi"
        yr = max(float(np.ptp(y)) for _, y in recs)
        ur = max(float(np.ptp(u)) for u, _ in recs)
        self.eps = 0.02 * yr / ur  # PIIdentifier's default min_slope_fraction, slope in operator units
        self.stride = max(1, int(np.ceil(sum(u.size for u, _ in recs) / MAX_ROWS)))

    def columns(self, taus: tuple[float, ...]) -> list[np.ndarray]:
        out = []
        for (u, _), z in zip(self.recs, self.Z):
            cols = [z[:, self.live]]
            if taus:
                term = CreepTerm(time_constants=taus, weights=np.zeros(len(taus)), sample_time=self.dt)
                cols.append(term.lags(u))
            out.append(np.hstack(cols))
        return out

    def solve_weights(self, cols: list[np.ndarray], masks: list[np.ndarray], nc: int) -> tuple[np.ndarray, np.ndarray]:
        """Constrained LS of ``y`` by ``cols`` plus one offset per record: (weights incl. creep, offsets)."""
        from scipy.optimize import lsq_linear

        J = len(cols)
        p = cols[0].shape[1]
        m = p - nc
        rows_X, rows_y = [], []
        for j, ((_, y), c, mask) in enumerate(zip(self.recs, cols, masks)):
            idx = np.flatnonzero(mask)[:: self.stride]
            if idx.size == 0:
                continue
            E = np.zeros((idx.size, J))
            E[:, j] = 1.0
            rows_X.append(np.hstack([c[idx], E]))
            rows_y.append(y[idx])
        X = np.vstack(rows_X)
        t = np.concatenate(rows_y)
        # v = (operator variables, creep, offsets); w = T v + shift keeps the model invertible
        T, shift, lb = _constraint_map(m, nc, J, self.eps, self.classical)
        scale = np.linalg.norm(X @ T, axis=0)
        scale[scale == 0] = 1.0
        res = lsq_linear((X @ T) / scale, t - X @ shift, bounds=(lb * scale, np.full(lb.size, np.inf)), method="bvls")
        sol = T @ (res.x / scale) + shift
        return sol[:p], sol[p:]

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

    def fit(self, order: int, taus: tuple[float, ...], masks: list[np.ndarray]):
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
            starts = [None] + [ba for ba in (refine_output_error(self, cols, masks, order),) if ba is not None]
            try:
                starts.append(fit_hammerstein([(cols[j][:end], self.recs[j][1][:end]) for j, end in segs], order))
            except (IdentificationError, np.linalg.LinAlgError):
                pass
            for ba in starts:
                w_cur, off_cur = wc, offsets
                for _ in range(N_ALTERNATIONS):
                    if ba is None:
                        pairs = [(cols[j][:end] @ w_cur, self.recs[j][1][:end] - off_cur[j]) for j, end in segs]
                        ba = fit_unit_gain_dynamics(pairs, order)
                    filtered = [unit_gain_filter(ba[0], ba[1], c) for c in cols]
                    w_cur, off_cur = self.solve_weights(filtered, masks, nc)
                    err = self.sse(filtered, masks, w_cur, off_cur)
                    if err < best[0]:
                        best = (err, w_cur, off_cur, ba)
                    ba = None
        _, wc, offsets, ba = best
        return wc[: wc.size - nc], wc[wc.size - nc :], offsets, ba

    def held_out_score(self, order: int, taus: tuple[float, ...]) -> float:
        """Summed RMS error (% of range) on held-out records (or the last 40 % of a single record)."""
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
        score = 0.0
        for fit_masks, test_masks in folds:
            try:
                w, c, _, ba = self.fit(order, taus, fit_masks)
            except (IdentificationError, np.linalg.LinAlgError):
                return float("inf")
            for (_, y), cols_mask, col in zip(self.recs, test_masks, self.columns(taus)):
                if not cols_mask.any():
                    continue
                v = col @ np.r_[w, c]
                yh = v if ba is None else unit_gain_filter(ba[0], ba[1], v[:, None])[:, 0]
                e = (y - yh)[cols_mask]
                e = e - e.mean()  # the held-out record's own offset
                score += float(100 * np.sqrt(np.mean(e**2)) / np.ptp(y))
        return score

    def build(self, w, c, offset, taus, ba, in_name, out_name) -> StageModel:
        weights = np.zeros(self.h.n_operators)
        weights[self.live] = w
        h = replace(self.h, weights=weights, output_offset=float(offset), inputs=(in_name,), outputs=(out_name,))
        if taus:
            h = replace(h, creep=CreepTerm(time_constants=taus, weights=np.maximum(c, 0.0), sample_time=self.dt))
        dyn = None if ba is None else transfer_to_statespace(ba[0] / (np.sum(ba[0]) / np.sum(ba[1])), ba[1], self.dt)
        return StageModel(h, dyn)

    def offsets_of(self, model: StageModel, recs: list) -> np.ndarray:
        """Each record's offset: the model's plus its mean residual."""
        out = []
        for (u, y), kind in zip(recs, self.kinds):
            h = model.hysteresis.with_state(model.hysteresis.consistent_state(u[0], kind))
            out.append(float(np.mean(y - model.with_hysteresis(h).simulate(u, self.dt)[:, 0])) + h.output_offset)
        return np.array(out)

    def errors(self, model: StageModel, offsets) -> tuple[list[float], list[float]]:
        max_e, rms_e = [], []
        for (u, y), kind, off in zip(self.recs, self.kinds, offsets):
            h = model.hysteresis
            h = replace(h.with_state(h.consistent_state(u[0], kind)), output_offset=float(off))
            e = y - model.with_hysteresis(h).simulate(u, self.dt)[:, 0]
            max_e.append(float(100 * np.max(np.abs(e)) / np.ptp(y)))
            rms_e.append(float(100 * np.sqrt(np.mean(e**2)) / np.ptp(y)))
        return max_e, rms_e


def refine_output_error(problem: _StageProblem, cols: list, masks: list, order: int):
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


def _constraint_map(m: int, nc: int, J: int, eps: float, classical: bool):
    """``(T, shift, lb)`` with ``x = T v + shift``, ``v >= lb``: the invertibility constraint of
    the PI identification (classical: cumulative weights ``>= eps``; modified: ``w_0 = eps + s +
    sum q``, ``w_i = p_i - q_i``), creep weights ``>= 0``, offsets free."""
    tail = nc + J
    shift = np.zeros(m + tail)
    if classical:
        T = np.zeros((m + tail, m + tail))
        T[:m, :m] = np.eye(m) - np.eye(m, k=-1)  # w = D W
        T[m:, m:] = np.eye(tail)
        lb = np.concatenate([np.full(m, eps), np.zeros(nc), np.full(J, -np.inf)])
        return T, shift, lb
    k = m - 1
    T = np.zeros((m + tail, 1 + 2 * k + tail))
    T[0, 0] = 1.0
    T[0, 1 + k : 1 + 2 * k] = 1.0
    T[1:m, 1 : 1 + k] = np.eye(k)
    T[1:m, 1 + k : 1 + 2 * k] = -np.eye(k)
    T[m:, 1 + 2 * k :] = np.eye(tail)
    shift[0] = eps
    lb = np.concatenate([np.zeros(1 + 2 * k + nc), np.full(J, -np.inf)])
    return T, shift, lb


def check_records_have_time(data: Any) -> None:
    """DataError unless the records carry a sampling period (for the CLI's messages)."""
    if sampling_period(data, None) is None:
        raise DataError("dynamics and creep need a time axis: give the records a `t` column or pass --ts.")
