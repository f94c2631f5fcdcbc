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
   mean ratios and the warp; with ``max_evaluations`` given, refined by Nelder-Mead within it;
   otherwise the best eight grid points are each taken to the bottom of their valley by
   Gauss-Newton on the projected residual and settled by rounds of Powell's method and the
   simplex until the residual stops falling (the residual has several valleys); the
   classical model (all ratios 1, no warp) is among the candidates, so the modified fit is never
   worse than the classical one under the same constraint.
4. **Starting state** of every record: ``"zero"`` (the letter's ``x0 = z0 = 0``, then the
   first sample), ``"ascending"`` or ``"descending"`` (arrived at the first sample from far
   below / above, e.g. after an idle period at the minimum); ``"auto"`` takes ``"zero"`` for a
   record that starts at 0 input (within 1 % of the range: at rest, the letter's condition) and
   otherwise the kind with the smallest residual.

5. **Creep** (optional, ``creep``; our extension): the lags
   ``lowpass_{tau_j}(u)`` of :mod:`~stageid.hysteresis.models.creep` (at rest at each record's first input) are extra
   columns of the same least-squares problem, with ``c_j >= 0``, so the weights, offsets and
   creep weights are fitted jointly and the threshold search of step 3 sees the creep.  The
   ``"auto"`` starting states are still chosen by the fit *without* creep: a lag at rest at
   the first sample can imitate the slowly released memory of an "ascending" start, and on
   the measured piezo records letting the creep take part in that choice picked a start and
   creep that fit the identification record better and other records far worse
   (``studies/hysteresis/RESULTS.md`` section 2).

Modules: step 2 :mod:`.weights`, step 3 :mod:`.threshold_search`, steps 4 and the errors
:mod:`.records`; :meth:`PIIdentifier.fit` runs them in this order.

The fitted model starts, like the letter's, from the zero state at 0 input (or at the nearest
end of the identified range), with the output offset of the first record; use
:func:`align_record` to compare it with another record (own offset and starting state).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from ..._errors import DataError
from ...base import Boolean, Estimator, InstanceOf, Interval, Options, Satisfies
from ...checks import is_positive_sequence, is_real
from ...runtime.resources import require_memory, require_work
from ...runtime.threads import single_blas_thread
from ..models.creep import CreepTerm
from .records import (
    STATE_CHOICES,
    Records,
    align_record,
    choose_initial_states,
    error_percents,
    read_records,
    record_residuals,
    with_former_channels,
)
from .result import HysteresisFit, HysteresisResult
from .threshold_search import search_thresholds
from .weight_uncertainty import UNCERTAINTY_METHODS, weight_uncertainty
from .weights import WeightProblem

__all__ = ["PIIdentifier", "HysteresisResult", "HysteresisFit", "align_record", "MODEL_KINDS"]

MODEL_KINDS = ("pi", "modified-pi")
#: Largest ``n_operators`` per model kind (the modified PI refits all weights for every step of
#: its threshold search).
MAX_OPERATORS = {"pi": 1000, "modified-pi": 100}
#: At least this many samples (summed over the records) per operator.
SAMPLES_PER_OPERATOR = 5
#: Most multiply-adds a fit may need (normal equations and bounded least squares of every
#: weight fit); a few minutes of work.  More (thousands of creep lags) is refused up front.
MAX_FIT_OPERATIONS = 3e11


def _is_range(value: Any) -> bool:
    return (
        isinstance(value, (tuple, list, np.ndarray))
        and len(value) == 2
        and all(is_real(v) for v in value)
        and float(value[0]) < float(value[1])
    )


class PIIdentifier(Estimator):
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
        Limit of the nonlinear search (modified PI: weight fits), >= 1: the grid, then
        Nelder-Mead (with the input warp, a second, chained simplex) within the limit.  Default:
        no limit; the best point of the grid and the next seven settled, each by Gauss-Newton
        on the projected residual and then rounds of Powell's method and a simplex until a round
        lowers the residual by less than 1e-4 (relative; at most 20000 weight fits in all); a
        start that Gauss-Newton leaves more than 1 % above a start settled before is dropped.
    input_warp : bool, default True
        Also search the monotone quadratic input warp ``q`` of :class:`ModifiedPIModel` (our
        extension; ``False`` gives the letter's model exactly).
    creep : sequence of float, optional
        Time constants [s] of a linear creep term (:class:`~stageid.hysteresis.models.creep.CreepTerm`)
        fitted jointly with the weights (``c_j >= 0``); default none (rate independent).
        Formerly ``creep_time_constants`` (still accepted, with a DeprecationWarning).
    sample_time : float, optional
        Sampling period [s] for ``(u, y)`` records when creep is fitted (Experiments carry
        their own ``dt``; all records must share one).
    ridge : float, default 1e-6
        Tikhonov penalty (>= 0) on the CP weights of the modified PI, relative to the mean diagonal of
        the normal matrix (keeps barely-moving operators from getting huge weights that blow up
        outside the identified input range; changes the fit by < 0.1 % of range on the data we
        tried).
    weight_uncertainty : {"none", "auto", "sandwich", "bootstrap"}, default "none"
        Covariance of the weights on the result (:mod:`~stageid.hysteresis.identify.weight_uncertainty`):
        "auto" is the block-robust sandwich unless a bound is active, then 200 bootstrap refits.
    inputs, outputs : str, optional
        The input and output channel: of Experiments with several, the column of that name; the
        model's channel names (default: the first Experiment's, else "V" and "y").

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

    parameter_constraints = {
        "model": [Options(*MODEL_KINDS)],
        "n_operators": [Interval(int, 2, None, closed="left")],
        "input_range": [Satisfies(_is_range, "(low, high) with finite low < high"), None],
        "initial_state": [Options(*STATE_CHOICES)],
        "min_slope_fraction": [Interval(float, 0, 1, closed="neither")],
        "max_rows": [Interval(int, 10, None, closed="left")],
        "max_evaluations": [Interval(int, 1, None, closed="left"), None],
        "ridge": [Interval(float, 0, None, closed="left")],
        "input_warp": [Boolean()],
        "creep": [Satisfies(is_positive_sequence, "a non-empty sequence of positive seconds"), None],
        "sample_time": [Interval(float, 0, None, closed="neither"), None],
        "weight_uncertainty": [Options("none", *UNCERTAINTY_METHODS)],
        "inputs": [InstanceOf(str, "a channel name"), None],
        "outputs": [InstanceOf(str, "a channel name"), None],
    }
    renamed_parameters = {"creep_time_constants": "creep"}

    def check_together(self) -> None:
        cap = MAX_OPERATORS[self.model]
        if self.n_operators > cap:
            raise self.invalid("n_operators", f"at most {cap} for a {self.model} model")

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
        creep: Sequence[float] | None = None,
        sample_time: float | None = None,
        weight_uncertainty: str = "none",
        inputs: str | None = None,
        outputs: str | None = None,
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
        self.creep = creep
        self.sample_time = sample_time
        self.weight_uncertainty = weight_uncertainty
        self.inputs = inputs
        self.outputs = outputs

    @with_former_channels
    def fit(self, data: Any) -> HysteresisResult:
        """Identify the model from one or several records.

        Parameters
        ----------
        data : Experiment, sequence of Experiment, or (u, y) tuple(s)
            Single-input single-output records (or Experiments whose channel ``inputs`` and
            ``outputs`` name), arrays of shape (n_samples,) or (n_samples, 1).

        Returns
        -------
        HysteresisResult

        Raises
        ------
        DataError
            Malformed records (more than one input or output column, NaN/inf, fewer than 10
            samples), an input that does not move, or a record whose output is constant.
        ParameterError
            Bad hyper-parameters (also ``n_operators`` beyond the bounds the class docstring
            gives for these records, or no ``sample_time`` for creep on (u, y) records).
        ResourceError
            When the fit would need more memory than is available or more than
            ``MAX_FIT_OPERATIONS`` operations (many creep time constants, before any work).
        IdentificationError
            A failed least-squares problem.

        Notes
        -----
        The former call ``fit(data, inputs, outputs)`` still works, with a DeprecationWarning.
        """
        self.validate_params()
        return self.fit_records(read_records(data, self.inputs, self.outputs))

    @single_blas_thread
    def fit_records(self, records: Records) -> HysteresisResult:
        """:meth:`fit` on records already read (:func:`~.records.read_records`), as a fit that
        holds them (the stage identification) hands them down: they are not read again."""
        self.validate_params()
        recs = records.recs
        u_lo, u_hi = self._check_records(recs)
        creep = self._creep_lags(records)
        lo, hi = (float(v) for v in self.input_range) if self.input_range is not None else (u_lo, u_hi)
        classical = self.model == "pi"
        self._check_cost(recs, creep)
        # step 1: thresholds equally spaced over the half range, the linear term r_0 = 0
        n = int(self.n_operators)
        R = 0.5 * (hi - lo)
        r = np.arange(n) * R / n
        yr = max(float(np.ptp(y)) for _, y in recs)  # > 0: read_records refuses a constant output
        eps = float(self.min_slope_fraction) * yr / (hi - lo)
        problem = WeightProblem(recs, r, eps, self._stride(recs), self.model, float(self.ridge), R, creep)
        # step 4 (for the classical thresholds): the starting state of every record
        theta = np.array([1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.5 * (lo + hi), 0.0])
        kinds = ["zero" if self.initial_state == "auto" else self.initial_state] * len(recs)
        at_rest = [abs(u[0]) <= 0.01 * (hi - lo) for u, _ in recs]
        if self.initial_state == "auto":
            kinds = choose_initial_states(problem, theta, kinds, at_rest, classical)
        n_eval, success, message = 0, True, "classical PI: constrained least squares."
        if not classical:  # step 3: the CP thresholds, then the starting states again
            # no limit given: the search goes on past its first budget until the residual settles
            settle = self.max_evaluations is None
            found = search_thresholds(problem, theta, kinds, R, lo, hi, bool(self.input_warp), self._budget(), settle)
            theta, n_eval, success, message = found.theta, found.n_evaluations, found.success, found.message
            if self.initial_state == "auto":
                kinds = choose_initial_states(problem, theta, kinds, at_rest, False)
        # step 2 for the final thresholds (and step 5, the creep weights, jointly)
        sse, w, offsets = problem.solve(theta, kinds, classical=classical)
        model = problem.build(theta, w, offsets[0], records.input_name, records.output_name, lo, hi, (u_lo, u_hi))
        if creep is not None:
            c = problem.solve_creep(theta, kinds, classical=classical)[3]
            model = replace(
                model, creep=CreepTerm(time_constants=creep[0], weights=np.maximum(c, 0.0), sample_time=creep[1])
            )
        residuals = record_residuals(model, recs, kinds, offsets)
        max_e, rms_e = error_percents(recs, residuals)
        return HysteresisResult(
            model=model,
            max_error_percent=tuple(max_e),
            rms_error_percent=tuple(rms_e),
            output_offsets=tuple(float(v) for v in offsets),
            initial_states=tuple(kinds),
            n_evaluations=n_eval,
            success=success,
            message=message,
            weight_uncertainty=self._weight_uncertainty(problem, theta, kinds, classical, model, w, offsets),
            edge_errors=records.edges(residuals),
            estimator=self.clone(),
        )

    def _weight_uncertainty(self, problem, theta, kinds, classical, model, w, offsets):
        """The weights' covariance (``weight_uncertainty`` setting), None when not asked for."""
        if self.weight_uncertainty == "none":
            return None
        creep_weights = getattr(getattr(model, "creep", None), "weights", None)
        return weight_uncertainty(
            problem, theta, kinds, classical, self.weight_uncertainty, (w, offsets, creep_weights)
        )

    # ------------------------------------------------------------------ steps of fit
    def _check_records(self, recs: list) -> tuple[float, float]:
        """The identified input range; ParameterError when ``n_operators`` exceeds what the
        records support (one operator per 5 samples, no more than their distinct inputs)."""
        u_lo = min(float(u.min()) for u, _ in recs)
        u_hi = max(float(u.max()) for u, _ in recs)
        if not u_hi > u_lo:
            raise DataError(f"the identification input must vary; got a constant {u_lo:g}.")
        n_total = sum(u.size for u, _ in recs)
        n_levels = int(np.unique(np.concatenate([u for u, _ in recs])).size)
        bound = min(n_total // SAMPLES_PER_OPERATOR, n_levels)
        if self.n_operators > bound:
            raise self.invalid(
                "n_operators",
                f"at most {bound} for these records (one operator per {SAMPLES_PER_OPERATOR} of their "
                f"{n_total} samples, no more than their {n_levels} distinct input values)",
            )
        return u_lo, u_hi

    def _creep_lags(self, records: Records) -> tuple[np.ndarray, float] | None:
        """(time constants, sampling period) of the creep term to fit, or None."""
        if self.creep is None:
            return None
        dt = records.sample_time(self.sample_time)
        if dt is None:
            raise self.invalid("sample_time", "the sampling period in seconds when creep is fitted to (u, y) records")
        return np.asarray(self.creep, dtype=float).reshape(-1), dt

    def _stride(self, recs: list) -> int:
        """Sample stride of the least-squares rows (at most ``max_rows`` rows)."""
        return max(1, int(np.ceil(sum(u.size for u, _ in recs) / int(self.max_rows))))

    def _budget(self) -> int:
        if self.max_evaluations is not None:
            return int(self.max_evaluations)
        return 1000 if self.input_warp else 500

    def _check_cost(self, recs: list, creep: tuple[np.ndarray, float] | None) -> None:
        """Refuse, before any work, a fit that needs too much memory or time.

        Every weight fit forms the normal equations of ``rows x p`` columns (``p`` operators
        plus creep lags) and solves a bounded problem of size ``p``; the modified PI does one
        per step of its search, the classical about one per record and starting state.  The
        operator and lag outputs of the longest record are held in memory.
        """
        n_lags = 0 if creep is None else creep[0].size
        p = int(self.n_operators) + n_lags + len(recs)
        rows = sum(u.size for u, _ in recs) / self._stride(recs)
        n_fits = 3 * len(recs) + 2 + (0 if self.model == "pi" else self._budget())
        longest = max(u.size for u, _ in recs)
        what = f"a {self.model} fit with {self.n_operators} operators" + (f" and {n_lags} creep lags" if n_lags else "")
        require_memory(8.0 * longest * (int(self.n_operators) + n_lags) * 2, what)
        require_work(
            n_fits * (rows * p * p / 2 + p**3),
            MAX_FIT_OPERATIONS,
            what,
            "use fewer creep time constants (a few per decade) or fewer operators",
        )
