"""C99 code for rate-dependent stage models: hysteresis, creep, then the unit-DC-gain dynamics.

Forward (``stageid simulate``)
    Every sample runs the PI / modified-PI forward step of :mod:`.c_hysteresis` (play or
    coupled-play operators, the input warp, the creep lags) to the hysteresis output ``v``, then
    the dynamics ``y = v0 + G[v - v0]`` at rest at the first sample's ``v0``
    (:class:`stageid.hysteresis.stage.StageModel`).  In double precision ``G`` runs as the
    transposed direct-form-II state space of its transfer function -- the coefficients and
    order of operations of the package's filter (:func:`stageid.hysteresis.dynamics.unit_gain_filter`),
    so the C agrees with :meth:`StageModel.simulate` to rounding.  In single precision a stable
    minimal ``G`` runs in balanced coordinates instead (rounded polynomial coefficients move slow
    poles, see :mod:`.c_lti`).

Inverse (``inverse=True``)
    Only the causal part has a real-time form: the streaming compensator of the stage's
    rate-independent hysteresis (:func:`.c_hysteresis.inverse_fields`).  ``stageid compensate``
    inverts the dynamics by stable inversion over the whole reference (preview of future
    samples, :mod:`stageid.hysteresis.stage_inverse`), which a per-sample loop cannot do, so the
    exported compensator omits the dynamics (:data:`STAGE_INVERSE_NOTE`).  The creep of a
    classical PI hysteresis is included (its lags' memory known before each drive, the rest
    folded into the linear operator: :mod:`.c_creep_inverse`); a modified PI hysteresis with
    creep (its per-sample inverse iterates, :class:`stageid.hysteresis.compensator.CreepInverse`)
    and a Preisach hysteresis have no C form yet: both are refused with one line.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._errors import ModelError
from .c_hysteresis import forward_fields, inverse_fields
from .c_lti import balanced_realisation, weighted_sum
from .c_writer import CType, array, literal

__all__ = ["stage_fields", "stage_inverse_fields", "STAGE_INVERSE_NOTE"]

#: What the exported compensator of a stage with dynamics leaves out (header and CLI say it).
STAGE_INVERSE_NOTE = (
    "the compensator inverts the hysteresis only; the stage's dynamics are not inverted "
    "(`stageid compensate` inverts them offline by non-causal stable inversion, which has no per-sample form)"
)


def _check_kind(model: Any) -> None:
    from ..hysteresis import PreisachModel

    if isinstance(model.hysteresis, PreisachModel):
        raise ModelError(
            "a stage with a Preisach hysteresis has no C export; export stages of PI or modified-PI hysteresis."
        )


def _lag_dt(model: Any, dt: float | None) -> float | None:
    """The sample time the creep lags run at: the stage's (its dynamics', as
    :meth:`StageModel.simulate` runs them), which ``dt`` may only repeat."""
    if dt is None or model.dt is None:
        return model.dt if dt is None else dt
    if not np.isclose(dt, model.dt, rtol=1e-9, atol=0.0):
        raise ModelError(f"the stage model runs at dt = {model.dt!r} s; `dt={dt!r}` differs (it cannot be resampled).")
    return model.dt


def _df2t_lines(b: np.ndarray, a: np.ndarray, ctype: CType, p: str) -> tuple[list[str], list[str]]:
    """Constant tables and step lines of ``yd = G[x]`` as the package's filter runs it."""
    t, m = ctype.name, b.size
    consts = [f"static const {t} {p}_dyn_b[{m}] = {array(b, ctype)};"]
    consts.append(f"static const {t} {p}_dyn_a[{m}] = {array(a, ctype)};")
    lines = [f"        const {t} yd = s->dyn[0] + {p}_dyn_b[0] * x;"]
    if m > 2:
        lines.append("        int k;")
        lines.append(f"        for (k = 0; k < {m - 2}; ++k)")
        lines.append(f"            s->dyn[k] = s->dyn[k + 1] + x * {p}_dyn_b[k + 1] - yd * {p}_dyn_a[k + 1];")
    lines.append(f"        s->dyn[{m - 2}] = x * {p}_dyn_b[{m - 1}] - yd * {p}_dyn_a[{m - 1}];")
    return consts, lines


def _balanced_lines(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: float, ctype: CType) -> list[str]:
    """Step lines of ``yd = G[x]`` in a state space (x_{k+1} = A x_k + B x, yd = C x_k + D x)."""
    n = A.shape[0]
    names = [f"d{i}" for i in range(n)] + ["x"]
    lines = [f"        const {ctype.name} d{i} = s->dyn[{i}];" for i in range(n)]
    lines.append(f"        const {ctype.name} yd = {weighted_sum(np.r_[C[0], D], names, ctype)};")
    AB = np.hstack([A, B])
    lines += [f"        s->dyn[{i}] = {weighted_sum(AB[i], names, ctype)};" for i in range(n)]
    return lines


def _dynamics(model: Any, ctype: CType, p: str) -> dict[str, Any]:
    """Members, init, constants and step lines that filter ``v`` through the dynamics."""
    from ..hysteresis.stage.dynamics import unit_gain_coefficients

    t = ctype.name
    b, a = unit_gain_coefficients(*model.transfer())
    g = model.dynamics
    bal = balanced_realisation(g.A, g.B, g.C) if ctype.is_float and g.n_states else None
    n = b.size - 1 if bal is None else bal[0].shape[0]
    members = [f"    {t} v0;  /* hysteresis output at the first sample: the dynamics rest there */"]
    members.append("    int dyn_at_rest;  /* 1 until the first sample */")
    init = [f"    s->v0 = {literal(0.0, ctype)};", "    s->dyn_at_rest = 1;"]
    step = ["    if (s->dyn_at_rest) {", "        s->v0 = v;", "        s->dyn_at_rest = 0;", "    }"]
    if n == 0:  # a static unit gain: y = v0 + (v - v0) b0, as the package computes it
        step.append(f"    out[0] = s->v0 + (v - s->v0) * {literal(b[0], ctype)};")
        return {"members": members, "init": init, "constants": [], "step": step, "form": "static gain"}
    members.append(f"    {t} dyn[{n}];  /* state of the dynamics */")
    init += [f"    s->dyn[{i}] = {literal(0.0, ctype)};" for i in range(n)]
    consts: list[str] = []
    if bal is None:
        consts, inner = _df2t_lines(b, a, ctype, p)
    else:
        inner = _balanced_lines(*bal, float(g.D[0, 0]), ctype)
    step += ["    {", f"        const {t} x = v - s->v0;", *inner, "        out[0] = s->v0 + yd;", "    }"]
    form = "direct form II transposed" if bal is None else "balanced state space"
    return {"members": members, "init": init, "constants": consts, "step": step, "form": form}


def stage_fields(model: Any, ctype: CType, prefix: str, dt: float | None = None) -> dict[str, str]:
    """Template fields of a :class:`~stageid.hysteresis.stage.StageModel`'s forward model.

    ``dt`` may only repeat the stage's sample time (or, without dynamics, set the creep lags'
    as for a hysteresis model).  Raises :class:`ModelError` for a Preisach hysteresis.
    """
    _check_kind(model)
    step = _lag_dt(model, dt)
    if model.dynamics is None:
        fields = forward_fields(model.hysteresis, ctype, prefix, step)
        fields["title"] = "stage model (forward): hysteresis and creep, no dynamics"
        return fields
    fields = forward_fields(model.hysteresis, ctype, prefix, step, output=f"const {ctype.name} v")
    dyn = _dynamics(model, ctype, prefix)
    fields["members"] += "\n" + "\n".join(dyn["members"])
    fields["init_body"] += "\n" + "\n".join(dyn["init"])
    fields["constants"] += "".join(line + "\n" for line in dyn["constants"])
    fields["step_body"] += "\n" + "\n".join(dyn["step"])
    fields["title"] = "stage model (forward): hysteresis, creep, unit-DC-gain dynamics"
    fields["summary"] += f" Dynamics: order {model.dynamics_order} ({dyn['form']}), sample time {model.dt!r} s."
    fields["init_doc"] += "; the dynamics at rest at the first sample's hysteresis output"
    return fields


def stage_inverse_fields(
    model: Any, ctype: CType, prefix: str, limits: tuple[float, float] | None = None
) -> dict[str, str]:
    """Template fields of the causal part of a stage's inverse: its hysteresis compensator, creep
    included for a classical PI hysteresis (:mod:`.c_creep_inverse`; module notes).  Raises
    :class:`ModelError` for a Preisach hysteresis, or a modified PI one with creep."""
    _check_kind(model)
    creep = model.hysteresis.creep
    if creep is not None:
        from .c_creep_inverse import creep_inverse_fields

        # the lags run at the creep term's sample time, as the package's compensator runs them
        fields = creep_inverse_fields(model.hysteresis, ctype, prefix, limits, creep.sample_time)
    else:
        fields = inverse_fields(model.hysteresis, ctype, prefix, limits)
    if model.dynamics is not None:
        fields["title"] = "stage model: compensator of the hysteresis (dynamics not inverted)"
        fields["summary"] += " Note: " + STAGE_INVERSE_NOTE + "."
    return fields
