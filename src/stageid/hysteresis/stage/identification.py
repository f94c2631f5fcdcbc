"""Joint identification of a rate-dependent stage: hysteresis -> creep -> unit-DC-gain dynamics.

Procedure (:meth:`StageIdentifier.fit`):

1. **Hysteresis thresholds** by :class:`~stageid.hysteresis.PIIdentifier` (rate independent,
   no creep): thresholds (and for the modified PI the CP thresholds and warp), every record's
   starting state and output offset.  A Preisach hysteresis has a fixed grid instead: the
   rate-independent :class:`~stageid.hysteresis.PreisachIdentifier` checks that the records
   resolve it and gives each record's starting state (the best of the three kinds).
2. **Alternation** with the thresholds fixed.  The model output is
   ``y = o_j + G[Z_j w + L_j c]`` (``Z_j`` operator outputs, ``L_j`` creep lags of record
   ``j``, ``o_j`` its offset); ``G`` is linear, so for fixed ``G`` the output is linear in
   ``(w, c, o)``: the filtered columns ``G[Z_j], G[L_j]`` go into the constrained least squares
   of step 2 of the PI identification (same invertibility constraint, ``c >= 0``; for a
   Preisach hysteresis ``Z_j`` are the cell states and the weights are non-negative with the
   smoothness penalty, :mod:`.stage_preisach`).  For fixed
   weights ``G`` is an output-error fit of ``v = Z w + L c`` to ``y - o``
   (:func:`~.dynamics.fit_unit_gain_dynamics`).  ``N_ALTERNATIONS`` rounds, each of both steps,
   from three starts (``G = 1``; the over-parametrised fit :func:`~.dynamics.fit_hammerstein`;
   the variable-projection fit :func:`~.problem.refine_output_error`), keeping the least
   residual: never worse than no dynamics on the fitted rows.
3. **Order and creep by held-out evidence** (:mod:`.stage_selection`): every candidate is
   fitted on all records but one and scored by its RMS error on the one left out (own
   offset), summed over the records; with a single record the first 60 % of it is fitted and
   the rest scored.  ``auto`` (orders ``AUTO_ORDERS``, creep sets ``AUTO_CREEP``) takes the
   simplest candidate within ``AUTO_TOLERANCE`` of the best.  A fixed order ``N`` is kept
   only when its held-out error is below that of no dynamics (same creep); otherwise the
   model has none and the summary says so, so ``dynamics=N`` is never worse held out than
   no dynamics.  The choice is then fitted on all records.
4. **Thresholds again** when dynamics were found: step 1 on the outputs with ``G`` stably
   inverted (:func:`~.stage_inverse.invert_dynamics`; the first pass saw the dynamics as
   hysteresis), then step 2; kept only when the summed RMS error on the records drops.  (PI
   only: a Preisach grid has no thresholds to search.)
5. **Modes from the disturbance** (``disturbance_modes`` not None, with any dynamics but
   ``None``): the residual of the fit of steps 2-4 on every record goes to
   :func:`~.disturbance_modes.disturbance_modes`, whose rule (in that module) finds the
   lightly damped modes a broadband disturbance rings in every record, which the drives
   themselves do not excite, above a floor that is never below numerical precision; when it
   shows none, the residuals of the held-out fits of step 3's orders at the chosen creep
   propose them (:func:`~.mode_proposals.proposed_modes`: a fit can hide the ring).  Found
   modes become a fixed unit-DC-gain resonance filter in series with ``G``
   (:func:`~.disturbance_modes.resonance_filter`); with ``auto`` order or creep, step 3 runs
   again with the modes in place, and step 2 is fitted again (weights, creep, offsets and the
   low-order ``G`` jointly, the modes fixed).  ``"auto"`` (the default) keeps the modes only
   when the held-out one-step prediction error with them (a noise model with the modes' poles,
   :func:`~.stage_selection.prediction_score`) is below that of the choice without them and
   that of no dynamics, and says in the summary which way it went; ``"spectrum"`` keeps them
   on the spectral evidence alone.

The result's model is a :class:`~.stage.StageModel` that starts like the PI identification's
model (zero state, first record's offset).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from functools import partial
from typing import Any

import numpy as np

from ...base import Boolean, Estimator, InstanceOf, Interval, Options, Satisfies
from ...checks import is_positive_sequence
from ...runtime.threads import single_blas_thread
from ..identify.pi import MODEL_KINDS, PIIdentifier
from ..identify.preisach import PreisachIdentifier
from ..identify.records import STATE_CHOICES, Records, error_percents, read_records, with_former_channels
from .disturbance_modes import DisturbanceMode, resonance_filter
from .inverse import invert_dynamics
from .mode_proposals import proposed_modes
from .pi_columns import N_ALTERNATIONS, PIColumns
from .preisach import PreisachColumns, best_start_kinds
from .problem import StageProblem
from .result import SUMMARY_CANDIDATES, StageFit, StageResult
from .selection import choose_candidate, fixed_order, modes_improve, prediction_score, simulation_score

__all__ = [
    "StageIdentifier",
    "StageResult",
    "StageFit",
    "choose_candidate",
    "AUTO_ORDERS",
    "AUTO_CREEP",
    "SUMMARY_CANDIDATES",
]

AUTO_ORDERS = (0, 1, 2, 3, 4)
AUTO_CREEP = ((), (0.05,), (0.01, 0.1, 1.0), (0.005, 0.05, 0.5, 5.0))
#: At least this many samples per dynamics coefficient (2n + 1 of them) in every record.
SAMPLES_PER_COEFFICIENT = 50
#: ``progress(step, done, total)`` of :meth:`StageIdentifier.fit`.
Progress = Callable[[str, int, int], None]


def _silent(step: str, done: int, total: int) -> None:
    """The progress callback of a fit nobody watches."""


def _dynamics_ok(value: Any) -> bool:
    return value is None or value == "auto" or (isinstance(value, int) and not isinstance(value, bool) and value >= 0)


def _creep_ok(value: Any) -> bool:
    return value is None or (isinstance(value, str) and value == "auto") or is_positive_sequence(value)


class StageIdentifier(Estimator):
    """Identify a stage model: PI / modified-PI / Preisach hysteresis, creep lags and unit-DC-gain dynamics.

    Parameters
    ----------
    model : {"pi", "modified-pi", "preisach"}, default "modified-pi"
    n_operators : int, default 20
        As in :class:`~stageid.hysteresis.PIIdentifier` (PI kinds).
    dynamics : int >= 0, "auto" or None, default "auto"
        Order of the linear dynamics (0: none, one of ``auto``'s candidates); ``None``: none and no
        disturbance modes; ``"auto"``: picked from ``AUTO_ORDERS``
        (0-4) by held-out error.  An order ``N`` is kept only when it lowers the held-out
        error below that of no dynamics (step 3).
    creep : sequence of positive seconds, "auto" or None, default "auto"
        Creep time constants; ``"auto"``: picked from ``AUTO_CREEP`` by held-out error.
    initial_state : {"auto", "zero", "ascending", "descending"}, default "auto"
    input_warp : bool, default True
        Modified PI only (see :class:`~stageid.hysteresis.PIIdentifier`).
    sample_time : float, optional
        Sampling period [s] for ``(u, y)`` records (Experiments carry their own).
    n_levels : int, default 20
        Preisach only: cells per axis of the grid (as :class:`~stageid.hysteresis.PreisachIdentifier`).
    smoothing : float, default 1e-4
        Preisach only: weight of the smoothness penalty (as :class:`~stageid.hysteresis.PreisachIdentifier`).
    disturbance_modes : {"auto", "spectrum"} or None, default "auto"
        Lightly damped modes found in the records' disturbance spectrum are put in the dynamics
        (step 5; only when ``dynamics`` is not None): ``"auto"`` when they lower the held-out
        error, ``"spectrum"`` whenever found; ``None``: never.
    inputs, outputs : str, optional
        The input and output channel: of Experiments with several, the column of that name; the
        model's channel names (default: the first Experiment's, else "V" and "y").

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis import PIModel, StageIdentifier, StageModel
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
        "model": [Options(*MODEL_KINDS, "preisach")],
        "n_operators": [Interval(int, 2, None, closed="left")],
        "dynamics": [Satisfies(_dynamics_ok, 'an integer order >= 0, "auto" or None')],
        "creep": [Satisfies(_creep_ok, 'a non-empty sequence of positive seconds, "auto" or None')],
        "initial_state": [Options(*STATE_CHOICES)],
        "input_warp": [Boolean()],
        "sample_time": [Interval(float, 0, None, closed="neither"), None],
        "n_levels": [Interval(int, 2, None, closed="left")],
        "smoothing": [Interval(float, 0, None, closed="left")],
        "disturbance_modes": [Options("auto", "spectrum"), None],
        "inputs": [InstanceOf(str, "a channel name"), None],
        "outputs": [InstanceOf(str, "a channel name"), None],
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
        n_levels: int = 20,
        smoothing: float = 1e-4,
        disturbance_modes: str | None = "auto",
        inputs: str | None = None,
        outputs: str | None = None,
    ) -> None:
        self.model = model
        self.n_operators = n_operators
        self.dynamics = dynamics
        self.creep = creep
        self.initial_state = initial_state
        self.input_warp = input_warp
        self.sample_time = sample_time
        self.n_levels = n_levels
        self.smoothing = smoothing
        self.disturbance_modes = disturbance_modes
        self.inputs = inputs
        self.outputs = outputs

    @with_former_channels
    @single_blas_thread
    def fit(self, data: Any, *, progress: Progress | None = None) -> StageResult:
        """Identify the stage from one or several records (several rates are the normal input).

        ``data``: Experiments or (u, y) pairs, as :meth:`PIIdentifier.fit
        <stageid.hysteresis.PIIdentifier.fit>` takes them; they are read once and handed down
        to the hysteresis identification of step 1.  The former call ``fit(data, inputs,
        outputs)`` still works, with a DeprecationWarning.

        ``progress(step, done, total)``, when given, is told what the fit is doing: the step's
        name, and for the held-out candidates of ``auto`` how many of ``total`` are scored
        (``total`` 0: a step without a count).  The search over candidates is most of the time.

        Raises
        ------
        ParameterError
            Bad settings; no sampling period for (u, y) records; a dynamics order the records
            cannot support (fewer than ``SAMPLES_PER_COEFFICIENT`` samples per coefficient).
        DataError, IdentificationError
            As :meth:`PIIdentifier.fit`, or a dynamics fit that fails.
        """
        self.validate_params()
        records = read_records(data, self.inputs, self.outputs)
        recs, names = records.recs, (records.input_name, records.output_name)
        dt = records.sample_time(self.sample_time)
        if dt is None:
            raise self.invalid("sample_time", "the sampling period in seconds for dynamics and creep on (u, y) records")
        orders, creeps = self._candidates(min(u.size for u, _ in recs))
        tell = progress if progress is not None else _silent
        tell("hysteresis thresholds", 0, 0)
        problem, kinds, base_message = self._first_step(records, dt)
        notes: list[str] = []
        counted = partial(tell, "held-out candidates")
        if self.dynamics in (None, "auto"):
            order, taus, held_out = choose_candidate(problem, orders, creeps, counted)
        else:  # a fixed order is kept only with held-out evidence (never worse than none)
            _, taus, scores = choose_candidate(problem, orders, creeps, counted)
            order, held_out, note = fixed_order(problem, orders[0], taus, scores)
            notes += [note] if note else []
        chosen = (order, tuple(taus))
        tell("fit of the chosen candidate on all records", 0, 0)
        problem, model, offsets = self._fit_chosen(problem, records, kinds, dt, order, taus)
        modes: tuple[DisturbanceMode, ...] = ()
        if self.disturbance_modes is not None and self.dynamics is not None:  # step 5
            found = proposed_modes(problem, model, offsets, orders, taus)
            if found:
                orders_m = orders if self.dynamics == "auto" else (order,)
                outcome = self._with_modes(problem, found, orders_m, creeps, order, taus, names, tell)
                if outcome[0]:
                    _, order, taus, held_out, model, offsets, note = outcome
                    chosen = (order, tuple(taus))
                    modes = found
                    notes += [note] if note else []
                else:
                    notes.append(outcome[1])
        residuals = problem.residuals(model, offsets)
        max_e, rms_e = error_percents(problem.recs, residuals)
        fitted = "alternated " + (f"{N_ALTERNATIONS} times" if problem.settle == 0 else "until settled")
        if model.dynamics_order != order + 2 * len(modes):
            notes.append(f"order-{order} dynamics did not lower the residual: none")
        return StageResult(
            model=model,
            max_error_percent=tuple(max_e),
            rms_error_percent=tuple(rms_e),
            output_offsets=tuple(float(v) for v in offsets),
            initial_states=tuple(kinds),
            dynamics_order=model.dynamics_order,
            creep_time_constants=tuple(taus),
            held_out=tuple(held_out),
            modes=modes,
            edge_errors=records.edges(residuals),
            chosen=chosen,
            message=f"{base_message}; weights, creep and dynamics {fitted}" + "".join(f"; {n}" for n in notes) + ".",
            estimator=self.clone(),
        )

    def _candidates(self, shortest: int) -> tuple[tuple[int, ...], tuple]:
        """The orders and creep sets to try; a fixed order the records cannot support is refused,
        ``auto``'s orders are only those they can."""
        orders = AUTO_ORDERS if self.dynamics == "auto" else (0 if self.dynamics is None else int(self.dynamics),)
        creeps = AUTO_CREEP if self.creep == "auto" else (() if self.creep is None else tuple(map(float, self.creep)),)
        need = SAMPLES_PER_COEFFICIENT * (2 * max(orders) + 1)
        if self.dynamics not in (None, "auto") and shortest < need:
            raise self.invalid(
                "dynamics",
                f"an order these records support: order {max(orders)} needs {need} samples per record, "
                f"the shortest has {shortest}",
            )
        return tuple(n for n in orders if SAMPLES_PER_COEFFICIENT * (2 * n + 1) <= shortest), creeps

    def _fit_chosen(self, problem, records, kinds, dt, order, taus):
        """``(problem, model, offsets)`` of the chosen order and creep on all records (steps 2 and 4)."""
        names = (records.input_name, records.output_name)
        everything = [np.ones(u.size, bool) for u, _ in records.pairs]
        w, c, offsets, ba = problem.solve(order, taus, everything)
        model = problem.build(w, c, offsets[0], taus, ba, *names)
        if model.dynamics is not None and self.model != "preisach":  # step 4: thresholds again, G inverted
            return self._second_pass(problem, model, records, kinds, dt, order, taus)
        return problem, model, offsets

    def _with_modes(self, problem, modes, orders, creeps, order, taus, names, tell=None):
        """``(True, order, taus, held-out scores, model, offsets, note)`` with the modes in the
        dynamics when they lower the held-out one-step prediction error below that of the choice
        without them and that of no dynamics (``"spectrum"``: always); else ``(False, note)``."""
        evidence = self.disturbance_modes == "auto"
        without = np.nan
        if evidence:  # the choice without the modes, and no dynamics at all (never worse than either)
            without = min(prediction_score(problem.held_out_residuals(n, taus))[0] for n in {order, 0})
        problem.prefilter = resonance_filter(modes, problem.dt)
        # with auto order or creep both are chosen again (by simulation error) with the modes in place
        tell = tell if tell is not None else _silent
        counted = partial(tell, "held-out candidates with the disturbance modes")
        order_m, taus_m, held_out = choose_candidate(problem, orders, creeps, counted)
        with_modes = np.nan
        if evidence:
            folds = problem.held_out_residuals(order_m, taus_m)
            with_modes = prediction_score(folds, problem.prefilter[1])[0]
            if not held_out:
                held_out = [(order_m, taus_m, simulation_score(folds))]
        hz = ", ".join(f"{m.frequency_hz:.4g} Hz" for m in modes)
        if evidence and not modes_improve(without, with_modes):
            problem.prefilter = None
            return False, (
                f"modes at {hz} from the disturbance spectrum did not lower the held-out one-step "
                f"prediction error ({with_modes:.3f} % against {without:.3f} % without them): left out"
            )
        everything = [np.ones(u.size, bool) for u, _ in problem.recs]
        w, c, offsets, ba = problem.solve(order_m, taus_m, everything)
        model = problem.build(w, c, offsets[0], taus_m, ba, *names)
        model = replace(model, disturbance_modes=tuple((m.frequency_hz, m.damping) for m in modes))
        note = (
            ""
            if not evidence
            else (
                f"modes at {hz} lowered the held-out one-step prediction error ({with_modes:.3f} % against "
                f"{without:.3f} % without them)"
            )
        )
        return True, order_m, taus_m, held_out, model, offsets, note

    def _first_step(self, records: Records, dt: float):
        """Step 1: the rate-independent hysteresis, the records' starting states and the step-2 problem."""
        recs = records.recs
        if self.model == "preisach":
            base = PreisachIdentifier(n_levels=self.n_levels, smoothing=self.smoothing).fit_records(records)
            kinds = best_start_kinds(base.model, recs, self.initial_state)
            problem = StageProblem(PreisachColumns(base.model, recs, kinds, self.smoothing), dt)
            return problem, kinds, f"Preisach grid of {self.n_levels} levels (rate-independent start {base.summary()})"
        base = self._hysteresis_identifier().fit_records(records)
        kinds = list(base.initial_states)
        return (
            StageProblem(PIColumns(base.model, recs, kinds), dt),
            kinds,
            f"hysteresis by PIIdentifier ({base.message.rstrip('.')})",
        )

    def _hysteresis_identifier(self) -> PIIdentifier:
        """The rate-independent PI identification of steps 1 and 4 (no creep: step 2 fits it)."""
        return PIIdentifier(
            self.model, n_operators=self.n_operators, initial_state=self.initial_state, input_warp=self.input_warp
        )

    def _second_pass(self, problem, model, records, kinds, dt, order, taus):
        """Thresholds refitted on ``G^-1[y]`` (stable inversion), then step 2 again; kept when
        the residual on the records is smaller (the first pass saw the dynamics as hysteresis)."""
        recs, names = records.recs, (records.input_name, records.output_name)
        unfiltered = records.with_outputs([invert_dynamics(model, y) for _, y in recs])
        base = self._hysteresis_identifier().fit_records(unfiltered)
        everything = [np.ones(u.size, bool) for u, _ in recs]
        second = StageProblem(PIColumns(base.model, recs, kinds), dt)
        w, c, offsets2, ba = second.solve(order, taus, everything)
        model2 = second.build(w, c, offsets2[0], taus, ba, *names)
        old = problem.errors(model, problem.offsets_of(model, recs))[1]
        new = second.errors(model2, offsets2)[1]
        if sum(new) < sum(old):
            return second, model2, offsets2
        return problem, model, problem.offsets_of(model, recs)
