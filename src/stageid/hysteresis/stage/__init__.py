"""Rate-dependent stage model: drive -> hysteresis -> creep -> unit-DC-gain linear dynamics.

``y = y0 + G[h(u) + creep(u) - y0]`` where ``h`` is a PI or modified-PI model (its optional
:class:`~stageid.hysteresis.models.creep.CreepTerm` is the creep stage) or a Preisach model (which
is rate independent: the stage holds its creep term), ``y0`` its output offset and
``G`` a discrete SISO :class:`~stageid.models.StateSpaceModel` with ``G(1) = 1`` (amplifier and
mechanics), at rest at the first sample.  The unit DC gain keeps the hysteresis in the output's
units: at slow drive the stage is its hysteresis model.

JSON (``stageid.hysteresis/1``)::

    {"format": "stageid.hysteresis/1", "kind": "stage",
     "hysteresis": {... a pi / modified-pi model, creep included, or a preisach model ...},
     "dynamics": {... a stageid.lti/1 statespace model, discrete ...} | null,
     "creep": {... see stageid.hysteresis.models.creep ...},   # optional; preisach hysteresis only
     "disturbance_modes": [{"frequency_hz": f, "damping": z}, ...]}   # optional, see below

``disturbance_modes`` records which modes of ``dynamics`` the identification took from the
records' disturbance spectrum (:mod:`.disturbance_modes`); they are part of ``dynamics``
already, the list is a record of where they came from.

The object composes with :mod:`stageid.models`: :attr:`StageModel.dynamics` is a plain
``StateSpaceModel`` (poles, frequency response, python-control conversion), and
:meth:`StageModel.linear_response` runs it on any hysteresis output.

This package, the rate-dependent stage (our extension of the letter):

=============================  ==============================================================
module                         what it holds
=============================  ==============================================================
``__init__`` (here)            ``StageModel`` (kind ``stage`` of the JSON format)
:mod:`.dynamics`               unit-DC-gain discrete dynamics: fits and filtering
:mod:`.disturbance_modes`      lightly damped modes from the records' disturbance spectrum
:mod:`.disturbance_spectrum`   that spectrum: each residual's Welch PSD, drive harmonics out
:mod:`.mode_proposals`         which fits' residuals propose the modes to the held-out test
:mod:`.identification`         ``StageIdentifier``: hysteresis first, then weights / creep /
                               dynamics alternated; auto order and creep
:mod:`.result`                 ``StageResult``: the model, its errors, the candidates' scores
:mod:`.problem`                ``StageProblem``: that alternation for fixed thresholds (step 2),
                               the hysteresis side plugged in as a strategy
:mod:`.pi_columns`             step 2's PI side: operator columns, the invertible weight fit
:mod:`.preisach`               step 2's Preisach side: cell states, the smoothed NNLS fit
:mod:`.selection`              held-out evidence for the order, the creep and the modes
:mod:`.validation`             a stage model on a record that starts mid-history
:mod:`.inverse`                offline stage feedforward (stable inversion, then the
                               hysteresis inverse): ``stage_feedforward``
=============================  ==============================================================
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..._errors import ModelError, ModelFormatError
from ...checks import shown
from ...data.sampling import PERIOD_RTOL, same_period, seconds
from ...display import html_repr, short_repr
from ..models.common import as_input
from ..models.creep import CreepTerm
from ..models.pi import HYSTERESIS_FORMAT, ModifiedPIModel, PIModel
from ..models.preisach import PreisachModel
from .dynamics import statespace_to_transfer, unit_gain_filter

__all__ = ["StageModel", "STAGE_KIND"]

STAGE_KIND = "stage"
#: Relative tolerance on the dynamics' DC gain (1 within rounding of the fitted coefficients).
DC_GAIN_TOLERANCE = 1e-6


@dataclass(frozen=True, eq=False)
class StageModel:
    """Hysteresis (PI, modified PI or Preisach), creep, then unit-DC-gain discrete dynamics.

    Parameters
    ----------
    hysteresis : PIModel, ModifiedPIModel or PreisachModel
        The rate-independent part (a PI model's ``creep`` term, if any, is the creep stage).
    dynamics : StateSpaceModel or None
        Discrete SISO model with DC gain 1 and poles inside the unit circle; ``None``: the
        stage is its hysteresis model.
    creep : CreepTerm or None
        The creep stage of a Preisach hysteresis (a PI model carries its own); at rest at the
        first sample of every simulation.

    Raises
    ------
    ModelError
        Dynamics that are continuous, not SISO, unstable, or of DC gain other than 1; a
        sample time that differs from the creep term's.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.hysteresis import PIModel
    >>> from stageid.hysteresis.stage import StageModel
    >>> from stageid.models import StateSpaceModel
    >>> g = StateSpaceModel([[0.5]], [[1.0]], [[0.5]], [[0.0]], dt=1e-3)
    >>> s = StageModel(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]), g)
    >>> np.round(s.simulate(np.r_[0.0, 2.0, 2.0, 2.0])[:, 0], 3).tolist()
    [0.0, 0.0, 1.25, 1.875]
    """

    hysteresis: Any
    dynamics: Any = None
    creep: CreepTerm | None = None
    disturbance_modes: tuple[tuple[float, float], ...] = ()

    kind = STAGE_KIND

    def __repr__(self) -> str:
        return short_repr(self)

    def _repr_html_(self) -> str:
        return html_repr(self)

    def __post_init__(self) -> None:
        if not isinstance(self.hysteresis, (PIModel, ModifiedPIModel, PreisachModel)):
            raise ModelError(
                f"`hysteresis` must be a PIModel, ModifiedPIModel or PreisachModel; got {type(self.hysteresis).__name__}."
            )
        modes = tuple(tuple(float(v) for v in m) for m in self.disturbance_modes)
        if any(len(m) != 2 or not all(np.isfinite(m)) or min(m) <= 0 for m in modes):
            raise ModelError(f"`disturbance_modes` must be (frequency Hz, damping) pairs > 0; got {modes}.")
        object.__setattr__(self, "disturbance_modes", modes)
        if modes and self.dynamics is None:
            raise ModelError("`disturbance_modes` name modes of the dynamics; this stage has none.")
        if self.creep is not None:
            if not isinstance(self.creep, CreepTerm):
                raise ModelError(f"`creep` must be a CreepTerm or None; got {type(self.creep).__name__}.")
            if not isinstance(self.hysteresis, PreisachModel):
                raise ModelError("a PI hysteresis carries its own creep term; `creep` is for a Preisach hysteresis.")
        g = self.dynamics
        if g is None:
            return
        from ...models import StateSpaceModel

        if not isinstance(g, StateSpaceModel):
            raise ModelError(f"`dynamics` must be a StateSpaceModel or None; got {type(g).__name__}.")
        if g.dt is None or g.n_inputs != 1 or g.n_outputs != 1:
            raise ModelError(
                f"`dynamics` must be discrete with one input and one output; got dt={g.dt}, {g.n_inputs}x{g.n_outputs}."
            )
        if g.n_states and not g.is_stable():
            raise ModelError(f"`dynamics` must be stable; got poles {np.round(g.poles(), 6).tolist()}.")
        dc = float(np.real(g.dc_gain()[0, 0]))
        if not abs(dc - 1.0) <= DC_GAIN_TOLERANCE:
            raise ModelError(f"`dynamics` must have DC gain 1 (the hysteresis keeps the output's units); got {dc:.9g}.")
        creep = self.creep_term
        if creep is not None and not same_period(creep.sample_time, g.dt):
            raise ModelError(
                f"the dynamics' dt {seconds(g.dt)} s differs from the creep term's {seconds(creep.sample_time)} s "
                f"(tolerance {PERIOD_RTOL:g} relative)."
            )

    # ------------------------------------------------------------------ the hysteresis' face
    @property
    def inputs(self) -> tuple[str, ...]:
        return self.hysteresis.inputs

    @property
    def outputs(self) -> tuple[str, ...]:
        return self.hysteresis.outputs

    @property
    def input_limits(self) -> tuple[float, float] | None:
        return self.hysteresis.input_limits

    @property
    def output_offset(self) -> float:
        return self.hysteresis.output_offset

    @property
    def creep_term(self) -> CreepTerm | None:
        """The creep stage: the stage's own (Preisach) or the PI model's."""
        return self.creep if self.creep is not None else getattr(self.hysteresis, "creep", None)

    @property
    def dt(self) -> float | None:
        """Sample time [s] of the dynamics (else of the creep term; None when rate independent)."""
        if self.dynamics is not None:
            return float(self.dynamics.dt)
        creep = self.creep_term
        return None if creep is None else float(creep.sample_time)

    @property
    def n_operators(self) -> int:
        return self.hysteresis.n_operators

    @property
    def dynamics_order(self) -> int:
        """Order ``n`` of the linear dynamics (0 without)."""
        return 0 if self.dynamics is None else int(self.dynamics.n_states)

    def transfer(self) -> tuple[np.ndarray, np.ndarray]:
        """``(b, a)`` of the dynamics in powers of ``z^-1`` (``([1], [1])`` without dynamics)."""
        if self.dynamics is None or self.dynamics.n_states == 0:
            d = 1.0 if self.dynamics is None else float(self.dynamics.D[0, 0])
            return np.array([d]), np.array([1.0])
        return statespace_to_transfer(self.dynamics)

    def with_hysteresis(self, hysteresis: Any) -> StageModel:
        """A copy with another hysteresis part (e.g. another starting state or offset)."""
        return replace(self, hysteresis=hysteresis)

    def with_state(self, state: Any) -> StageModel:
        """Hysteresis started from ``state``; the dynamics always start at rest."""
        return replace(self, hysteresis=self.hysteresis.with_state(state))

    def consistent_state(self, u0: float, kind: str = "zero") -> Any:
        return self.hysteresis.consistent_state(u0, kind)

    # ------------------------------------------------------------------ simulation
    def linear_response(self, v: object) -> np.ndarray:
        """``y0 + G[v - y0]`` at rest at ``v[0]``: the dynamics applied to a hysteresis output, shape (n_samples,)."""
        vv = np.asarray(v, dtype=float).reshape(-1)
        if self.dynamics is None:
            return vv.copy()
        b, a = self.transfer()
        return unit_gain_filter(b, a, vv[:, None])[:, 0]

    def simulate(self, u: object, dt: float | None = None) -> np.ndarray:
        """Stage output for an input record, shape (n_samples, 1).

        Parameters
        ----------
        u : array_like of shape (n_samples, 1) or (n_samples,)
        dt : float, optional
            Sampling period [s]; must equal the model's :attr:`dt` when it has dynamics.

        Raises
        ------
        ModelError
            Bad input, or a ``dt`` that differs from the dynamics' sample time.
        """
        u_in = as_input(u, self.inputs[0])
        step = self.dt
        if dt is not None and step is not None and self.dynamics is not None and not same_period(dt, step):
            raise ModelError(
                f"the input's sample time {seconds(dt)} s differs from the stage dynamics' {seconds(step)} s "
                f"(tolerance {PERIOD_RTOL:g} relative)."
            )
        v = self.hysteresis.simulate(u_in, dt if dt is not None else step)[:, 0]
        if self.creep is not None:
            v = v + self.creep.run(u_in, dt if dt is not None else step)[0]
        return self.linear_response(v)[:, None]

    # ------------------------------------------------------------------ serialisation
    def to_dict(self) -> dict[str, Any]:
        """The ``stageid.hysteresis/1`` dictionary of kind ``"stage"``."""
        d = {
            "format": HYSTERESIS_FORMAT,
            "kind": STAGE_KIND,
            "hysteresis": self.hysteresis.to_dict(),
            "dynamics": None if self.dynamics is None else self.dynamics.to_dict(),
        }
        if self.creep is not None:  # absent otherwise: PI stage files stay as they were
            d["creep"] = self.creep.to_dict()
        if self.disturbance_modes:  # which modes of `dynamics` came from the disturbance spectrum
            d["disturbance_modes"] = [{"frequency_hz": f, "damping": z} for f, z in self.disturbance_modes]
        return d

    @classmethod
    def from_dict(cls, d: Any) -> StageModel:
        """Inverse of :meth:`to_dict`; :class:`ModelFormatError` names the malformed field."""
        from ...models.serialization import lti_from_dict
        from ..models.serialization import model_from_dict

        keys = {"format", "kind", "hysteresis", "dynamics", "creep", "disturbance_modes"}
        if not isinstance(d, dict) or set(d) - keys or "hysteresis" not in d or "dynamics" not in d:
            raise ModelFormatError(
                f"a stage model needs `hysteresis`, `dynamics` and optionally `creep`; got {shown(d)}."
            )
        hyst = d["hysteresis"]
        if not isinstance(hyst, dict) or hyst.get("kind") not in ("pi", "modified-pi", "preisach"):
            raise ModelFormatError(
                f"`hysteresis` of a stage model must be a pi, modified-pi or preisach model; got {shown(hyst)}."
            )
        h = PreisachModel.from_dict(hyst) if hyst.get("kind") == "preisach" else model_from_dict(hyst)
        creep = None if d.get("creep") is None else CreepTerm.from_dict(d["creep"])
        g = d.get("dynamics")
        dyn = None
        if g is not None:
            if not isinstance(g, dict) or g.get("kind") != "statespace":
                raise ModelFormatError(f"`dynamics` must be a stageid.lti/1 statespace model or null; got {shown(g)}.")
            dyn = lti_from_dict(g)
        modes = d.get("disturbance_modes", [])
        if not isinstance(modes, list) or not all(
            isinstance(m, dict) and set(m) == {"frequency_hz", "damping"} for m in modes
        ):
            raise ModelFormatError(
                f"`disturbance_modes` must be a list of {{frequency_hz, damping}}; got {shown(modes)}."
            )
        try:
            pairs = tuple((m["frequency_hz"], m["damping"]) for m in modes)
            return cls(hysteresis=h, dynamics=dyn, creep=creep, disturbance_modes=pairs)
        except ModelError as exc:
            raise ModelFormatError(str(exc)) from None
