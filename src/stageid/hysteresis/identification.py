"""Identification of classical and modified PI models from input/output records.

Procedure (the letter's, made explicit):

1. **Thresholds** ``r_i = i R / n`` (``i = 0 .. n-1``), equally spaced over the half range
   ``R = (max u - min u) / 2`` of the identification input (20 operators over -500...500 V
   give 0, 25, ..., 475 V); ``r_0 = 0`` is the linear term.  The operators act on the input
   measured from the range centre ``xc``.
2. **Weights** by constrained linear least squares (the model is linear in the weights once
   the thresholds are fixed), with one output offset per record (sensor zeros differ between
   records):

   * classical PI: every initial-loading slope ``W_j = sum_{i<=j} w_i >= eps`` -- exactly the
     condition for the closed-form inverse to exist (solved as bounds on ``W``);
   * modified PI: ``w_0 + sum_{i>=1} min(w_i, 0) >= eps`` -- the slope of the output with
     respect to the input is at least that in every state, so the per-sample inversion always
     has a unique solution (solved as bounds after writing ``w_i = p_i - q_i``,
     ``w_0 = eps + s + sum q_i`` with ``s, p, q >= 0``, an exact reformulation).

   ``eps`` is ``min_slope_fraction`` times the mean slope ``range(y) / range(u)``.
3. **CP thresholds** (modified PI) by nonlinear optimisation on top (bounded Nelder-Mead on
   the weighted-least-squares residual, started from the classical model):
   ``rc_i = c_i r_i``, ``ra_i = a_i r_i``, ``rb_i = b_i ra_i`` with ratios linear in the
   operator index (``c_i = c0 + c1 t_i``, ``t_i = i/(n-1) - 1/2``, likewise ``a_i``, ``b_i``),
   clipped to ``0 <= c_i <= 1``, ``a_i >= 0``, ``0 <= b_i <= 1`` (the orderings eq. 3 needs),
   the centre ``xc`` and (our extension, ``input_warp=True``) the monotone quadratic input
   warp ``q`` of :class:`ModifiedPIModel`: eight parameters, searched on a coarse grid of the
   mean ratios and the warp and refined by Nelder-Mead; the classical model (all ratios 1, no
   warp) is among the candidates, so the modified fit is never worse than the classical one
   under the same constraint.
4. **Starting state** of every record: ``"zero"`` (the letter's ``x0 = z0 = 0``, then the
   first sample), ``"ascending"`` or ``"descending"`` (arrived at the first sample from far
   below / above, e.g. after an idle period at the minimum); ``"auto"`` takes ``"zero"`` for a
   record that starts at 0 input (within 1 % of the range: at rest, the letter's condition) and
   otherwise the kind with the smallest residual.

5. **Creep** (optional, ``creep_time_constants``; our extension): the lags
   ``lowpass_{tau_j}(u)`` of :mod:`.creep` (at rest at each record's first input) are extra
   columns of the same least-squares problem, with ``c_j >= 0``, so the weights, offsets and
   creep weights are fitted jointly and the threshold search of step 3 sees the creep.  The
   ``"auto"`` starting states are still chosen by the fit *without* creep: a lag at rest at
   the first sample can imitate the slowly released memory of an "ascending" start, and on
   the measured piezo records letting the creep take part in that choice picked a start and
   creep that fit the identification record better and other records far worse
   (``studies/hysteresis/RESULTS.md`` section 2).

The fitted model starts, like the letter's, from the zero state at 0 input (or at the nearest
end of the identified range), with the output offset of the first record; use
:func:`align_record` to compare it with another record (own offset and starting state).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._errors import DataError, IdentificationError, ModelError
from .._threads import single_blas_thread
from .pi import STATE_KINDS, ModifiedPIModel, PIModel

__all__ = ["PIIdentifier", "HysteresisFit", "align_record", "MODEL_KINDS"]

MODEL_KINDS = ("pi", "modified-pi")
_STATE_CHOICES = ("auto",) + STATE_KINDS
#: Largest ``n_operators`` per model kind (the modified PI refits all weights for every step of
#: its threshold search: 100 operators on 10000 samples already take about a minute).
MAX_OPERATORS = {"pi": 1000, "modified-pi": 100}
#: At least this many samples (summed over the records) per operator.
SAMPLES_PER_OPERATOR = 5


def _real(value: object) -> float | None:
    """``float(value)`` for a finite real number (not a bool or a string), else None."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        return None
    v = float(value)
    return v if np.isfinite(v) else None


def _is_int(value: object) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


@dataclass(frozen=True)
class HysteresisFit:
    """Result of :meth:`PIIdentifier.fit` (no training data kept).

    Attributes
    ----------
    model : PIModel or ModifiedPIModel
        The identified model.
    max_error_percent, rms_error_percent : tuple of float
        Per identification record, in % of that record's output range.
    output_offsets : tuple of float
        Fitted output offset of each record.
    initial_states : tuple of str
        Starting-state kind of each record.
    n_evaluations : int
        Weight fits done by the nonlinear search (0 for the classical model).
    success : bool
        False when the nonlinear search stopped on its evaluation limit (the model is still the
        best found and never worse than the classical fit it started from).
    message : str
    """

    model: Any
    max_error_percent: tuple[float, ...]
    rms_error_percent: tuple[float, ...]
    output_offsets: tuple[float, ...]
    initial_states: tuple[str, ...]
    n_evaluations: int
    success: bool
    message: str

    def summary(self) -> str:
        """A short text report."""
        kind = self.model.kind
        lines = [f"{kind} model, {self.model.n_operators} operators; fit on {len(self.max_error_percent)} record(s)"]
        for i, (m, r, s) in enumerate(zip(self.max_error_percent, self.rms_error_percent, self.initial_states)):
            lines.append(f"  record {i}: max error {m:.3f} % of range, RMS {r:.3f} %, start {s}")
        if kind == "modified-pi":
            lines.append(
                f"  rc/r = {_ratio(self.model.rc, self.model.r):.4f}, ra/r = {_ratio(self.model.ra, self.model.r):.4f}, "
                f"rb/ra = {_ratio(self.model.rb, self.model.ra):.4f}, centre = {self.model.input_offset:.6g}, "
                f"input warp = {self.model.input_warp:.4f}"
            )
        creep = getattr(self.model, "creep", None)
        if creep is not None:
            lines.append(
                "  creep: " + ", ".join(f"{c:.4g} at {t:g} s" for t, c in zip(creep.time_constants, creep.weights))
            )
        lines.append(f"  {self.message}")
        return "\n".join(lines)


def _ratio(a: np.ndarray, b: np.ndarray) -> float:
    k = b > 0
    return float(np.median(a[k] / b[k])) if np.any(k) else float("nan")


def _records(
    data: Any, inputs: str | None, outputs: str | None
) -> tuple[list[tuple[np.ndarray, np.ndarray]], str, str]:
    from ..data import Experiment

    if isinstance(data, Experiment):
        data = [data]
    if isinstance(data, tuple) and len(data) == 2 and not isinstance(data[0], Experiment):
        data = [data]
    recs = []
    in_name, out_name = inputs or "V", outputs or "y"
    for k, item in enumerate(data):
        if isinstance(item, Experiment):
            if item.n_inputs != 1 or item.n_outputs != 1:
                raise DataError(
                    f"hysteresis identification needs one input and one output; record {k} has {item.n_inputs} and {item.n_outputs}."
                )
            u, y = item.u[:, 0], item.y[:, 0]
            if k == 0:
                in_name = inputs or item.input_names[0]
                out_name = outputs or item.output_names[0]
        else:
            try:
                pair = [np.asarray(item[0], dtype=float), np.asarray(item[1], dtype=float)]
            except (TypeError, ValueError, IndexError, KeyError):
                raise DataError(
                    f"record {k} must be an Experiment or a (u, y) pair of numeric arrays; got {type(item).__name__}."
                ) from None
            for j, what in enumerate(("input", "output")):
                a = pair[j]
                if a.ndim > 2 or (a.ndim == 2 and a.shape[1] != 1):
                    raise DataError(
                        f"record {k}: one {what} column expected (shape (n_samples,) or (n_samples, 1)); "
                        f"got shape {a.shape}."
                    )
            u, y = pair[0].reshape(-1), pair[1].reshape(-1)
            if u.shape != y.shape:
                raise DataError(f"record {k}: input and output must have equal length; got {u.size} and {y.size}.")
        label = f"record {k}" + (f" ('{item.name}')" if isinstance(item, Experiment) and item.name else "")
        if u.size < 10:
            raise DataError(f"{label} has {u.size} samples; hysteresis identification needs at least 10.")
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
            raise DataError(f"{label} has NaN or inf samples.")
        if not np.ptp(y) > 0:
            raise DataError(
                f"{label}: the output is constant ({y[0]:g}); every record's output must vary "
                "(errors are reported in % of each record's output range)."
            )
        recs.append((np.ascontiguousarray(u, dtype=float), np.ascontiguousarray(y, dtype=float)))
    if not recs:
        raise DataError("no records given; expected at least one Experiment.")
    return recs, in_name, out_name


class PIIdentifier:
    """Identify a classical (``"pi"``) or modified (``"modified-pi"``) PI model.

    Parameters
    ----------
    model : {"pi", "modified-pi"}, default "pi"
    n_operators : int, default 20
        Number of operators, including the linear term (``r_0 = 0``); 2 at least and at most
        ``MAX_OPERATORS[model]`` (1000 for ``"pi"``, 100 for ``"modified-pi"``), at most one
        operator per ``SAMPLES_PER_OPERATOR`` (5) samples summed over the records, and at most
        the number of distinct input values (checked by :meth:`fit`).
    input_range : (float, float), optional
        Range ``(low, high)``, ``low < high``, the thresholds cover; default the range of the
        identification input.
    initial_state : {"auto", "zero", "ascending", "descending"}, default "auto"
        Starting state of each record (see module notes).
    min_slope_fraction : float, default 0.02
        ``eps`` of the invertibility constraint relative to the mean slope, in (0, 1).
    max_rows : int, default 20000
        The least-squares problems use at most this many (evenly strided) samples, >= 10; the
        operators always run over every sample.
    max_evaluations : int, optional
        Limit of the nonlinear search (modified PI: weight fits), >= 1; default 1000 with the
        input warp (its search runs a second, chained simplex) and 500 without.
    input_warp : bool, default True
        Also search the monotone quadratic input warp ``q`` of :class:`ModifiedPIModel` (our
        extension; ``False`` gives the letter's model exactly).
    creep_time_constants : sequence of float, optional
        Time constants [s] of a linear creep term (:class:`~stageid.hysteresis.creep.CreepTerm`)
        fitted jointly with the weights (``c_j >= 0``); default none (rate independent).
    sample_time : float, optional
        Sampling period [s] for ``(u, y)`` records when creep is fitted (Experiments carry
        their own ``dt``; all records must share one).
    ridge : float, default 1e-6
        Tikhonov penalty (>= 0) on the CP weights of the modified PI, relative to the mean diagonal of
        the normal matrix (keeps barely-moving operators from getting huge weights that blow up
        outside the identified input range; changes the fit by < 0.1 % of range on the data we
        tried).

    Notes
    -----
    The identified model's ``input_limits`` are the identified input range (the least and
    largest input sample over the records), so a :class:`~stageid.hysteresis.Compensator`
    clips its drive to that range by default (pass ``limits`` to extrapolate).

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis import PIModel, PIIdentifier
    >>> from stageid.signals import decaying_triangle
    >>> u = decaying_triangle(1.0, 8, 1e-3, amplitude=10.0)
    >>> true = PIModel(r=[0.0, 2.5, 5.0, 7.5], weights=[1.0, 0.4, 0.2, 0.1])
    >>> fit = PIIdentifier("pi", n_operators=4).fit((u, true.simulate(u)))
    >>> bool(fit.max_error_percent[0] < 1e-6)
    True
    """

    def __init__(
        self,
        model: str = "pi",
        n_operators: int = 20,
        input_range: tuple[float, float] | None = None,
        initial_state: str = "auto",
        min_slope_fraction: float = 0.02,
        max_rows: int = 20000,
        max_evaluations: int | None = None,
        ridge: float = 1e-6,
        input_warp: bool = True,
        creep_time_constants: Sequence[float] | None = None,
        sample_time: float | None = None,
    ) -> None:
        self.model = model
        self.n_operators = n_operators
        self.input_range = input_range
        self.initial_state = initial_state
        self.min_slope_fraction = min_slope_fraction
        self.max_rows = max_rows
        self.max_evaluations = max_evaluations
        self.ridge = ridge
        self.input_warp = input_warp
        self.creep_time_constants = creep_time_constants
        self.sample_time = sample_time

    # ------------------------------------------------------------------ checks
    def _check(self) -> None:
        if self.model not in MODEL_KINDS:
            raise IdentificationError(
                f"`model` of PIIdentifier must be one of {', '.join(MODEL_KINDS)}; got {self.model!r}."
            )
        if not _is_int(self.n_operators) or self.n_operators < 2:
            raise IdentificationError(
                f"`n_operators` of PIIdentifier must be an integer >= 2; got {self.n_operators!r}."
            )
        cap = MAX_OPERATORS[self.model]
        if self.n_operators > cap:
            raise IdentificationError(
                f"`n_operators` of PIIdentifier must be at most {cap} for a {self.model} model; got {self.n_operators}."
            )
        if self.initial_state not in _STATE_CHOICES:
            raise IdentificationError(
                f"`initial_state` of PIIdentifier must be one of {', '.join(_STATE_CHOICES)}; got {self.initial_state!r}."
            )
        msf = _real(self.min_slope_fraction)
        if msf is None or not 0 < msf < 1:
            raise IdentificationError(
                f"`min_slope_fraction` of PIIdentifier must be a number in (0, 1); got {self.min_slope_fraction!r}."
            )
        if not _is_int(self.max_rows) or self.max_rows < 10:
            raise IdentificationError(f"`max_rows` of PIIdentifier must be an integer >= 10; got {self.max_rows!r}.")
        if self.max_evaluations is not None and (not _is_int(self.max_evaluations) or self.max_evaluations < 1):
            raise IdentificationError(
                f"`max_evaluations` of PIIdentifier must be an integer >= 1; got {self.max_evaluations!r}."
            )
        ridge = _real(self.ridge)
        if ridge is None or ridge < 0:
            raise IdentificationError(f"`ridge` of PIIdentifier must be a number >= 0; got {self.ridge!r}.")
        if not isinstance(self.input_warp, (bool, np.bool_)):
            raise IdentificationError(f"`input_warp` of PIIdentifier must be True or False; got {self.input_warp!r}.")
        if self.input_range is not None:
            try:
                lo, hi = (_real(v) for v in self.input_range)
            except (TypeError, ValueError):
                lo = hi = None
            if lo is None or hi is None or not lo < hi:
                raise IdentificationError(
                    f"`input_range` of PIIdentifier must be (low, high) with finite low < high; "
                    f"got {self.input_range!r}."
                )
        if self.sample_time is not None:
            ts = _real(self.sample_time)
            if ts is None or ts <= 0:
                raise IdentificationError(
                    f"`sample_time` of PIIdentifier must be a positive number of seconds; got {self.sample_time!r}."
                )
        if self.creep_time_constants is not None:
            taus = np.asarray(self.creep_time_constants, dtype=float).reshape(-1)
            if taus.size == 0 or not np.all(np.isfinite(taus)) or np.any(taus <= 0):
                raise IdentificationError(
                    f"`creep_time_constants` of PIIdentifier must be positive seconds; got {self.creep_time_constants!r}."
                )

    # ------------------------------------------------------------------ fit
    @single_blas_thread
    def fit(self, data: Any, inputs: str | None = None, outputs: str | None = None) -> HysteresisFit:
        """Identify the model from one or several records.

        Parameters
        ----------
        data : Experiment, sequence of Experiment, or (u, y) tuple(s)
            Single-input single-output records, arrays of shape (n_samples,) or (n_samples, 1).
        inputs, outputs : str, optional
            Channel names for the model (default: the first Experiment's, else "V", "y").

        Returns
        -------
        HysteresisFit

        Raises
        ------
        DataError
            Malformed records (more than one input or output column, NaN/inf, fewer than 10
            samples), an input that does not move, or a record whose output is constant.
        IdentificationError
            Bad hyper-parameters (also ``n_operators`` beyond the bounds the class docstring
            gives for these records) or a singular least-squares problem.
        """
        self._check()
        recs, in_name, out_name = _records(data, inputs, outputs)
        u_lo = min(float(u.min()) for u, _ in recs)
        u_hi = max(float(u.max()) for u, _ in recs)
        if not u_hi > u_lo:
            raise DataError(f"the identification input must vary; got a constant {u_lo:g}.")
        n_total = sum(u.size for u, _ in recs)
        n_levels = int(np.unique(np.concatenate([u for u, _ in recs])).size)
        bound = min(n_total // SAMPLES_PER_OPERATOR, n_levels)
        if self.n_operators > bound:
            raise IdentificationError(
                f"`n_operators` of PIIdentifier must be at most {bound} for these records (one operator per "
                f"{SAMPLES_PER_OPERATOR} of their {n_total} samples, no more than their {n_levels} distinct input "
                f"values); got {self.n_operators}."
            )
        creep = None
        if self.creep_time_constants is not None:
            creep = (
                np.asarray(self.creep_time_constants, dtype=float).reshape(-1),
                _creep_sample_time(data, self.sample_time),
            )
        if self.input_range is not None:
            lo, hi = (float(v) for v in self.input_range)
        else:
            lo, hi = u_lo, u_hi
        n = int(self.n_operators)
        R = 0.5 * (hi - lo)
        r = np.arange(n) * R / n
        yr = max(float(np.ptp(y)) for _, y in recs)  # > 0: _records refuses a constant output
        eps = float(self.min_slope_fraction) * yr / (hi - lo)
        stride = max(1, int(np.ceil(sum(u.size for u, _ in recs) / int(self.max_rows))))
        ctx = _Context(recs, r, eps, stride, self.model, float(self.ridge), R, creep)

        # classical fit and starting-state choice
        theta0 = np.array([1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.5 * (lo + hi), 0.0])
        kinds = ["zero"] * len(recs) if self.initial_state == "auto" else [self.initial_state] * len(recs)
        at_rest = [abs(u[0]) <= 0.01 * (hi - lo) for u, _ in recs]
        if self.initial_state == "auto":
            for j in range(len(recs)):
                if at_rest[j]:
                    continue  # starts at 0 input: the letter's x0 = z0 = 0
                best = None
                for kind in STATE_KINDS:
                    trial = kinds.copy()
                    trial[j] = kind
                    sse = ctx.solve(theta0, trial, classical=self.model == "pi", creep=False)[0]
                    if best is None or sse < best[0]:
                        best = (sse, kind)
                kinds[j] = best[1]
        n_eval = 0
        success, message = True, "classical PI: constrained least squares."
        theta = theta0
        if self.model == "modified-pi":
            theta, n_eval, success, message = self._search(ctx, theta0, kinds, R, lo, hi)
            if self.initial_state == "auto":  # re-check the starting states with the final thresholds
                for j in range(len(recs)):
                    if at_rest[j]:
                        continue
                    best = None
                    for kind in STATE_KINDS:
                        trial = kinds.copy()
                        trial[j] = kind
                        sse = ctx.solve(theta, trial, classical=False, creep=False)[0]
                        if best is None or sse < best[0]:
                            best = (sse, kind)
                    kinds[j] = best[1]
        sse, w, offsets = ctx.solve(theta, kinds, classical=self.model == "pi")
        model = ctx.build(theta, w, offsets[0], in_name, out_name, lo, hi, (u_lo, u_hi))
        if creep is not None:
            from dataclasses import replace

            from .creep import CreepTerm

            c = ctx.solve_creep(theta, kinds, classical=self.model == "pi")[3]
            model = replace(
                model, creep=CreepTerm(time_constants=creep[0], weights=np.maximum(c, 0.0), sample_time=creep[1])
            )
        max_e, rms_e = [], []
        for j, (u, y) in enumerate(recs):
            m_j = model.with_state(model.consistent_state(u[0], kinds[j]))
            m_j = _replace_offset(m_j, offsets[j])
            yh = m_j.simulate(u)[:, 0]
            e = y - yh
            max_e.append(float(100 * np.max(np.abs(e)) / np.ptp(y)))
            rms_e.append(float(100 * np.sqrt(np.mean(e**2)) / np.ptp(y)))
        return HysteresisFit(
            model=model,
            max_error_percent=tuple(max_e),
            rms_error_percent=tuple(rms_e),
            output_offsets=tuple(float(v) for v in offsets),
            initial_states=tuple(kinds),
            n_evaluations=n_eval,
            success=success,
            message=message,
        )

    def _search(self, ctx: _Context, theta0: np.ndarray, kinds: list[str], R: float, lo: float, hi: float):
        from scipy.optimize import minimize

        centre = 0.5 * (lo + hi)
        qmax = 0.4 if self.input_warp else 0.0
        lower = np.array([0.0, -1.0, 0.05, -2.0, 0.0, -1.0, centre - 0.25 * (hi - lo), -qmax])
        upper = np.array([1.0, 1.0, 3.0, 2.0, 1.0, 1.0, centre + 0.25 * (hi - lo), qmax])
        scale = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, R, 1.0])
        active = np.flatnonzero(upper > lower)
        count = [0]
        cache: dict[tuple, float] = {}
        budget = int(self.max_evaluations) if self.max_evaluations is not None else (1000 if self.input_warp else 500)

        def full(v: np.ndarray) -> np.ndarray:
            th = np.array(theta0, dtype=float)
            th[active] = np.asarray(v) * scale[active]
            return np.clip(th, lower, upper)

        def objective(v: np.ndarray) -> float:
            th = full(v)
            key = tuple(np.round(th, 12))
            if key not in cache:
                count[0] += 1
                cache[key] = ctx.solve(th, kinds, classical=False)[0]
            return cache[key]

        classical = np.array(theta0, dtype=float)
        f_classical = objective(classical[active] / scale[active])
        # coarse grid over the mean ratios (thresholds proportional to r) and the warp,
        # then Nelder-Mead on all parameters from the two best grid points
        grid = []
        for q in (-0.2, 0.0, 0.2) if self.input_warp else (0.0,):
            for c0 in (0.2, 0.5, 0.8, 1.0):
                for a0 in (0.7, 1.0, 1.4, 2.0):
                    for b0 in (0.4, 0.7, 1.0):
                        th = np.array([c0, 0.0, a0, 0.0, b0, 0.0, centre, q])
                        grid.append((objective(th[active] / scale[active]), th))
        grid.sort(key=lambda item: item[0])
        best_f, best_th = grid[0]
        if f_classical < best_f:
            best_f, best_th = f_classical, classical
        steps_all = np.array([0.1, 0.2, 0.15, 0.3, 0.1, 0.2, 0.05, 0.05])

        def descend(
            th_start: np.ndarray, f_start: float, free: np.ndarray, maxfev: int
        ) -> tuple[float, np.ndarray, bool]:
            """Nelder-Mead over the parameters ``free`` (indices into theta) from ``th_start``."""
            base = np.array(th_start, dtype=float)

            def sub(v: np.ndarray) -> float:
                th = base.copy()
                th[free] = np.asarray(v) * scale[free]
                return objective(th[active] / scale[active])

            x0 = base[free] / scale[free]
            lb, ub = lower[free] / scale[free], upper[free] / scale[free]
            steps = steps_all[free]
            k = free.size
            simplex = np.vstack(
                [x0] + [x0 + np.eye(k)[i] * steps[i] * (1 if x0[i] + steps[i] <= ub[i] else -1) for i in range(k)]
            )
            res = minimize(
                sub,
                x0,
                method="Nelder-Mead",
                bounds=list(zip(lb, ub)),
                options={"maxfev": maxfev, "initial_simplex": simplex, "xatol": 1e-5, "fatol": 1e-10 * f_start},
            )
            th = base.copy()
            th[free] = res.x * scale[free]
            return float(res.fun), np.clip(th, lower, upper), res.nfev < maxfev

        # 1. the simplex on every parameter from the best grid point, with half the budget left;
        # 2. with the warp, the other half chains two simplexes: the best unwarped grid point
        #    searched without the warp, then the warp released from there.  A warped fit can then
        #    not end above the unwarped optimum the search finds (a plain 8-parameter simplex
        #    from warped grid points stalled above it on asymmetric Bouc-Wen data).
        remaining = budget - count[0]
        if remaining > 20:
            f_new, th_new, converged = descend(
                best_th, best_f, active, remaining // 2 if self.input_warp else remaining
            )
            success = converged
            if f_new < best_f:
                best_f, best_th = f_new, th_new
        else:
            success = False
        if self.input_warp:
            f0, th0 = min(((f, th) for f, th in grid if th[7] == 0.0), key=lambda item: item[0])
            remaining = budget - count[0]
            if remaining > 40:
                f0, th0, _ = descend(th0, f0, active[active != 7], remaining // 2)
                f_new, th_new, converged = descend(th0, f0, active, budget - count[0])
                success = success and converged
                for f_c, th_c in ((f0, th0), (f_new, th_new)):
                    if f_c < best_f:
                        best_f, best_th = f_c, th_c
            else:
                success = False
        msg = (
            f"modified PI: {count[0]} weight fits in the threshold search; RMS residual "
            f"{np.sqrt(best_f / max(f_classical, 1e-300)):.3g} of the classical start's."
        )
        return best_th, count[0], success, msg


def _creep_sample_time(data: Any, sample_time: float | None) -> float:
    """The one sampling period of the records (Experiment.dt, else ``sample_time``)."""
    from ..data import Experiment

    items = (
        [data]
        if isinstance(data, Experiment)
        else (
            [data] if isinstance(data, tuple) and len(data) == 2 and not isinstance(data[0], Experiment) else list(data)
        )
    )
    dts = {float(e.dt) for e in items if isinstance(e, Experiment)}
    if any(not isinstance(e, Experiment) for e in items):
        if sample_time is None:
            raise IdentificationError(
                "fitting creep needs the sampling period: pass `sample_time` for (u, y) records; got None."
            )
        dts.add(float(sample_time))
    elif sample_time is not None and dts != {float(sample_time)}:
        raise IdentificationError(f"`sample_time` {sample_time!r} differs from the records' dt {sorted(dts)}.")
    if len(dts) != 1:
        raise IdentificationError(f"fitting creep needs one sampling period for all records; got {sorted(dts)}.")
    dt = dts.pop()
    if not (np.isfinite(dt) and dt > 0):
        raise IdentificationError(f"the sampling period must be positive; got {dt!r}.")
    return dt


def _replace_offset(model, offset: float):
    from dataclasses import replace

    return replace(model, output_offset=float(offset))


class _Context:
    """Operator matrices and the constrained least-squares weight fit for fixed thresholds."""

    def __init__(self, recs, r, eps, stride, kind, ridge=0.0, R=1.0, creep=None):
        self.lags = None
        if creep is not None:  # creep lag columns (independent of the thresholds), per record
            from .creep import CreepTerm

            term = CreepTerm(time_constants=creep[0], weights=np.zeros(creep[0].size), sample_time=creep[1])
            self.lags = [np.ascontiguousarray(term.lags(u)[np.arange(0, u.size, stride)]) for u, _ in recs]
        self.ridge = ridge
        self.R = R
        self.recs = recs
        self.r = r
        self.eps = eps
        self.stride = stride
        self.kind = kind
        self.y = np.concatenate([y[::stride] for _, y in recs])
        self.rows = [np.arange(0, u.size, stride) for u, _ in recs]

    def thresholds(self, theta: np.ndarray, classical: bool):
        r = self.r
        if classical:
            return r, r, r, r, float(theta[6])
        t = np.arange(r.size) / max(r.size - 1, 1) - 0.5
        c = np.clip(theta[0] + theta[1] * t, 0.0, 1.0)
        a = np.clip(theta[2] + theta[3] * t, 0.0, None)
        b = np.clip(theta[4] + theta[5] * t, 0.0, 1.0)
        ra = a * r
        return r, c * r, ra, b * ra, float(theta[6])

    def warp(self, theta, classical):
        return 0.0 if classical or len(theta) < 8 else float(theta[7])

    def matrix(self, theta, kinds, classical):
        from . import kernels

        r, rc, ra, rb, xc = self.thresholds(theta, classical)
        q = self.warp(theta, classical)
        blocks = []
        for (u, _), kind, rows in zip(self.recs, kinds, self.rows):
            x = u - xc
            if q != 0.0:
                t = np.abs(x) / self.R
                x = x + q * self.R * np.where(t <= 1.0, t * t, 2.0 * t - 1.0)
            up = np.maximum(x[0] - r, np.minimum(x[0] - rc, 0.0))
            down = np.minimum(x[0] + ra, np.maximum(x[0] + rb, 0.0))
            z0 = up if kind == "ascending" else down if kind == "descending" else np.maximum(up, np.minimum(down, 0.0))
            # the state before the first sample: z0 is already consistent with x[0]
            Z, _ = kernels.cp_bank(np.ascontiguousarray(x), r, rc, ra, rb, np.ascontiguousarray(z0))
            blocks.append(Z[rows])
        return blocks

    def _live(self, blocks) -> np.ndarray:
        """Columns of the operators that move: one that (almost) never moves gets no weight
        (its weight would be unbounded); the linear term always counts."""
        motion = np.max([np.ptp(b, axis=0) for b in blocks], axis=0)
        live = motion > 1e-3 * max(float(self.r[-1]), 1e-300)
        live[0] = True
        return np.flatnonzero(live)

    def _normal_equations(self, columns, m: int, classical: bool):
        """``(G, G_fit, g, y'y)`` of the least-squares fit of ``y`` by the per-record column
        blocks plus one offset per record; ``G`` adds the ridge on the CP weights ``1 .. m-1``
        (not the linear term, creep weights or offsets: a CP operator whose thresholds leave it
        almost still over the data would otherwise get a huge weight that explodes outside the
        identified range), ``G_fit`` is without it."""
        from . import kernels

        y = self.y
        p = columns[0].shape[1]
        J = len(columns)
        G = np.zeros((p + J, p + J))
        g = np.zeros(p + J)
        start = 0
        for j, c in enumerate(columns):
            yb = np.ascontiguousarray(y[start : start + c.shape[0]])
            Gb, gb, sb = kernels.gram(np.ascontiguousarray(c), yb)
            G[:p, :p] += Gb
            G[:p, p + j] = sb
            G[p + j, :p] = sb
            G[p + j, p + j] = c.shape[0]
            g[:p] += gb
            g[p + j] = yb.sum()
            start += c.shape[0]
        Gfit = G
        if self.ridge > 0 and not classical:
            G = G.copy()
            lam = self.ridge * float(np.mean(np.diag(G)[:m]))
            G[np.arange(1, m), np.arange(1, m)] += lam
        return G, Gfit, g, float(y @ y)

    def solve(self, theta, kinds, classical, creep=True):
        """SSE, weights (n,), offsets (n_records,) of the constrained fit (Gram-matrix based);
        with the creep columns when there are any and ``creep`` is true."""
        if self.lags is not None and creep:
            return self.solve_creep(theta, kinds, classical)[:3]

        blocks = self.matrix(theta, kinds, classical)
        n = self.r.size
        J = len(blocks)
        idx = self._live(blocks)
        m = idx.size
        G, Gfit, g, yy = self._normal_equations([b[:, idx] for b in blocks], m, classical)
        if classical:
            # w = D W with W the cumulative sums (over the live operators), bounds W >= eps
            T = np.eye(m + J)
            for i in range(m - 1):
                T[i + 1, i] = -1.0
            lb = np.concatenate([np.full(m, self.eps), np.full(J, -np.inf)])
            v = _bounded_gram_lsq(T.T @ G @ T, T.T @ g, lb)
            sol = T @ v
        else:
            sol = _gram_solve(G, g)
            wl = sol[:m]
            if not (wl[0] + np.sum(np.minimum(wl[1:], 0.0)) >= self.eps):
                # w0 = eps + s + sum q, w_i = p_i - q_i (i >= 1), s, p, q >= 0: v = (s, p, q, offsets)
                k = m - 1
                T = np.zeros((m + J, 1 + 2 * k + J))
                T[0, 0] = 1.0
                T[0, 1 + k : 1 + 2 * k] = 1.0
                T[1:m, 1 : 1 + k] = np.eye(k)
                T[1:m, 1 + k : 1 + 2 * k] = -np.eye(k)
                T[m:, 1 + 2 * k :] = np.eye(J)
                shift = np.zeros(m + J)
                shift[0] = self.eps
                g2 = T.T @ (g - G @ shift)
                lb = np.concatenate([np.zeros(1 + 2 * k), np.full(J, -np.inf)])
                v = _bounded_gram_lsq(T.T @ G @ T, g2, lb)
                sol = T @ v + shift
        w = np.zeros(n)
        w[idx] = sol[:m]
        offs = sol[m:]
        sse = yy - 2.0 * float(sol @ g) + float(sol @ Gfit @ sol)
        if self.ridge > 0 and not classical:
            sse += float(sol @ (G - Gfit) @ sol)
        return max(sse, 0.0), w, offs

    def solve_creep(self, theta, kinds, classical):
        """As :meth:`solve` with the creep lag columns (weights ``c >= 0``); also returns c."""
        blocks = self.matrix(theta, kinds, classical)
        n = self.r.size
        J = len(blocks)
        nc = self.lags[0].shape[1]
        idx = self._live(blocks)
        m = idx.size
        p = m + nc  # operator weights, creep weights, then one offset per record
        G, Gfit, g, yy = self._normal_equations(
            [np.hstack([b[:, idx], self.lags[j]]) for j, b in enumerate(blocks)], m, classical
        )
        sol = _gram_solve(G, g)
        wl, cl = sol[:m], sol[m:p]
        if classical:
            ok = bool(np.all(np.cumsum(wl) >= self.eps))
        else:
            ok = bool(wl[0] + np.sum(np.minimum(wl[1:], 0.0)) >= self.eps)
        if not (ok and np.all(cl >= 0)):
            shift = np.zeros(p + J)
            if classical:
                # w = D W (cumulative sums, W >= eps), c >= 0, offsets free
                T = np.eye(p + J)
                for i in range(m - 1):
                    T[i + 1, i] = -1.0
                lb = np.concatenate([np.full(m, self.eps), np.zeros(nc), np.full(J, -np.inf)])
            else:
                # w0 = eps + s + sum q, w_i = p_i - q_i, c >= 0: v = (s, p, q, c, offsets)
                k = m - 1
                T = np.zeros((p + J, 1 + 2 * k + nc + J))
                T[0, 0] = 1.0
                T[0, 1 + k : 1 + 2 * k] = 1.0
                T[1:m, 1 : 1 + k] = np.eye(k)
                T[1:m, 1 + k : 1 + 2 * k] = -np.eye(k)
                T[m:, 1 + 2 * k :] = np.eye(nc + J)
                shift[0] = self.eps
                lb = np.concatenate([np.zeros(1 + 2 * k + nc), np.full(J, -np.inf)])
            v = _bounded_gram_lsq(T.T @ G @ T, T.T @ (g - G @ shift), lb)
            sol = T @ v + shift
        w = np.zeros(n)
        w[idx] = sol[:m]
        c = np.maximum(sol[m:p], 0.0)
        offs = sol[p:]
        sse = yy - 2.0 * float(sol @ g) + float(sol @ Gfit @ sol)
        if self.ridge > 0 and not classical:
            sse += float(sol @ (G - Gfit) @ sol)
        return max(sse, 0.0), w, offs, c

    def build(self, theta, w, offset, in_name, out_name, lo, hi, identified):
        classical = self.kind == "pi"
        r, rc, ra, rb, xc = self.thresholds(theta, classical)
        # input_limits: the identified input range (the compensator's default drive limits)
        common = dict(
            weights=w,
            input_offset=xc,
            output_offset=float(offset),
            inputs=(in_name,),
            outputs=(out_name,),
            input_limits=identified,
        )
        if classical:
            model = PIModel(r=r, **common)
        else:
            model = ModifiedPIModel(
                r=r, rc=rc, ra=ra, rb=rb, input_warp=self.warp(theta, False), warp_scale=self.R, **common
            )
        u_rest = min(max(0.0, lo), hi)
        return model.with_state(model.consistent_state(u_rest, "zero"))


def _gram_solve(G: np.ndarray, g: np.ndarray) -> np.ndarray:
    d = np.sqrt(np.maximum(np.diag(G), 1e-300))
    Gs = G / np.outer(d, d)
    try:
        v = np.linalg.solve(Gs + 1e-12 * np.eye(G.shape[0]), g / d)
    except np.linalg.LinAlgError:
        v = np.linalg.lstsq(Gs, g / d, rcond=None)[0]
    return v / d


def _bounded_gram_lsq(G: np.ndarray, g: np.ndarray, lb: np.ndarray) -> np.ndarray:
    """min v'Gv - 2 g'v subject to v >= lb, as a bounded least-squares problem on chol(G)."""
    from scipy.optimize import lsq_linear

    d = np.sqrt(np.maximum(np.diag(G), 1e-300))
    Gs = G / np.outer(d, d)
    try:
        Rm = np.linalg.cholesky(Gs + 1e-10 * np.eye(G.shape[0])).T
        qy = np.linalg.solve(Rm.T, g / d)
    except np.linalg.LinAlgError:
        # collinear columns (e.g. operators that never move when ``input_range`` is wider than
        # the data, or an operator constant like the offset): Gs is singular to rounding, so use
        # its symmetric square root with the eigenvalues floored instead of the Cholesky factor
        s, V = np.linalg.eigh(0.5 * (Gs + Gs.T))
        s = np.maximum(s, 1e-10 * max(float(s.max()), 1e-300))
        Rm = np.sqrt(s)[:, None] * V.T
        qy = (V.T @ (g / d)) / np.sqrt(s)
    lbs = np.where(np.isfinite(lb), lb * d, -np.inf)
    res = lsq_linear(Rm, qy, bounds=(lbs, np.full_like(lbs, np.inf)), method="bvls", tol=1e-12, max_iter=2000)
    if not np.all(np.isfinite(res.x)):
        raise IdentificationError("the constrained least-squares weight fit failed (non-finite solution).")
    return res.x / d


def align_record(
    model: PIModel | ModifiedPIModel, u: object, y: object, initial_state: str = "auto", fit_offset: bool = True
) -> tuple[Any, np.ndarray]:
    """Fit a record's own output offset and starting state, then simulate the model on it.

    Records taken at other times have other sensor zeros and start from unknown hysteretic
    states; this estimates only those two nuisance quantities (the mean residual and the best
    of the starting-state kinds) -- the model's thresholds and weights are untouched.

    Parameters
    ----------
    model : PIModel or ModifiedPIModel
    u, y : array_like of shape (n_samples,) or (n_samples, 1)
    initial_state : {"auto", "zero", "ascending", "descending", "model"}
        ``"model"`` keeps the model's own state.
    fit_offset : bool, default True

    Returns
    -------
    model : the model with that record's state and offset
    y_model : ndarray of shape (n_samples, 1)

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis import PIModel, align_record
    >>> m = PIModel(r=[0.0, 1.0], weights=[1.0, 0.5])
    >>> u = np.array([0.0, 2.0, -1.0, 1.0])
    >>> _, yh = align_record(m, u, m.simulate(u) + 3.0)
    >>> bool(np.allclose(yh, m.simulate(u) + 3.0))
    True
    """
    uu = np.asarray(u, dtype=float).reshape(-1)
    yy = np.asarray(y, dtype=float).reshape(-1)
    if uu.shape != yy.shape:
        raise DataError(f"input and output must have equal length; got {uu.size} and {yy.size}.")
    choices = STATE_KINDS if initial_state == "auto" else (initial_state,)
    if initial_state not in _STATE_CHOICES + ("model",):
        raise ModelError(
            f"`initial_state` must be one of auto, zero, ascending, descending, model; got {initial_state!r}."
        )
    best = None
    for kind in choices:
        m = model if kind == "model" else model.with_state(model.consistent_state(uu[0], kind))
        yh = m.simulate(uu)[:, 0]
        off = float(np.mean(yy - yh)) if fit_offset else 0.0
        sse = float(np.sum((yy - yh - off) ** 2))
        if best is None or sse < best[0]:
            best = (sse, _replace_offset(m, m.output_offset + off), (yh + off)[:, None])
    return best[1], best[2]
