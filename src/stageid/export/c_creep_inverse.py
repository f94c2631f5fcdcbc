"""C99 compensator of a classical PI hysteresis with a creep term, as :class:`CreepInverse` runs it.

The creep term adds first-order lags of the drive to the output,
``y_c(k) = sum_j c_j s_j(k)``, ``s_j(k) = a_j s_j(k-1) + (1 - a_j) u(k)``
(:mod:`stageid.hysteresis.models.creep`).  Per sample its memory ``h = sum_j c_j a_j s_j(k-1)`` is
known before the drive, and the rest is ``g u(k)`` with ``g = sum_j c_j (1 - a_j) >= 0``: folded
into the weight of the PI model's linear operator (threshold 0), the drive is the closed-form
inverse of that folded PI model at ``y_ref - h`` (:func:`.c_inverse.pi_inverse_fields`), then the
lags advance with it.  Exact in one pass; no iteration, so the per-sample cost is the PI
compensator's plus the lags.

The first sample differs: the package takes the creep at rest at that sample's (unknown) drive,
so its whole static gain ``G = sum_j c_j`` joins the linear operator there.  That sample runs the
closed-form inverse of the PI model folded with ``G`` from its own constant tables, and hands the
operator state over to the ``g``-folded compensator through the forward state (both inverse
states are the same forward state in the weights of their models, by the duality of
:func:`stageid.hysteresis.inverse.closed_form.inverse_state`).  A creep term stored with its lags'
state starts from them instead, without the first-sample step.

Not exported: a modified PI hysteresis with creep (the input warp leaves a remainder
``g (u - x(u))`` that the package resolves by fixed-point iteration) and a PI model whose first
threshold is not 0 (no linear operator to fold into; the package iterates there too).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from .._errors import ModelError
from .c_writer import CType, array, define, fill, literal

__all__ = ["creep_inverse_fields", "check_creep_inverse"]

_TARGET = "    const ${T} target = in[0] - ${p}_OUTPUT_OFFSET;"

_FIRST = """\
/* The first sample (creep at rest at its drive: gain G joins the linear operator): the drive of
   the G-folded inverse PI model, and the operator state handed to the g-folded one through the
   forward state (in double: the duality sums cancel). */
static ${T} ${p}_creep_first(${p}_state *s, ${T} y)
{
    const double target = (double)y - ${p}_CREEP_G_STATIC * ${p}_CREEP_EXCESS0 - (double)${p}_OUTPUT_OFFSET;
    double zi[${p}_N_OPERATORS], zf[${p}_N_OPERATORS], x = 0.0, tail = 0.0;
    int i;
    for (i = 0; i < ${p}_N_OPERATORS; ++i) {  /* the G-folded inverse PI model: a play sum */
        const double lo = target - ${p}_first_r_inv[i], hi = target + ${p}_first_r_inv[i];
        const double v = ${p}_first_z0[i] < hi ? ${p}_first_z0[i] : hi;
        zi[i] = v > lo ? v : lo;
        x += ${p}_first_w_inv[i] * zi[i];
    }
${clip}    for (i = ${p}_N_OPERATORS - 1; i >= 0; --i) {  /* forward state: z_j = W'_j z'_j + sum_{k>j} w'_k z'_k */
        const double wz = ${p}_first_w_inv[i] * zi[i];
        zf[i] = ${p}_first_W_inv[i] * zi[i] + tail;
        tail = i == ${p}_N_OPERATORS - 1 ? wz : tail + wz;
    }
${replay}    tail = 0.0;
    for (i = ${p}_N_OPERATORS - 1; i >= 0; --i) {  /* the g-folded inverse state of that forward state */
        const double wz = ${p}_fold_w[i] * zf[i];
        s->z[i] = (${T})(${p}_fold_W[i] * zf[i] + tail);
        tail = i == ${p}_N_OPERATORS - 1 ? wz : tail + wz;
    }
    return (${T})(x + (double)${p}_INPUT_OFFSET);
}
"""

# a clipped first drive: the forward state is the model's, moved by one play update at the limit
_FIRST_CLIP = """\
    const int clipped = x < (double)${p}_LOW || x > (double)${p}_HIGH;
    if (clipped) x = x < (double)${p}_LOW ? (double)${p}_LOW : (double)${p}_HIGH;
"""

_FIRST_REPLAY = """\
    if (clipped) {
        for (i = 0; i < ${p}_N_OPERATORS; ++i) {
            const double hi = x + ${p}_fold_r[i], lo = x - ${p}_fold_r[i];
            const double v = ${p}_fwd_z0[i] < hi ? ${p}_fwd_z0[i] : hi;
            zf[i] = v > lo ? v : lo;
        }
    }
"""

_STEP_FRESH = """\
    if (s->creep_fresh) {  /* the first sample: creep at rest at this drive */
        const ${T} u0 = ${p}_creep_first(s, in[0]);
        int j;
        for (j = 0; j < ${p}_N_LAGS; ++j) s->lag[j] = u0;
        s->u_prev = u0;
        s->creep_fresh = 0;
        out[0] = u0;
        return;
    }
"""

_STEP_HEAD = """\
    {
    ${T} h = 0.0${f};
    int j;
    for (j = 0; j < ${p}_N_LAGS; ++j) h += ${p}_creep_ca[j] * s->lag[j];  /* the lags' memory */
    {
    /* the drive's offset, as the package computes it: u - (operator input of u) */
    const ${T} excess = s->u_prev - (s->u_prev - ${p}_INPUT_OFFSET);
    const ${T} y_creep = in[0] - h - ${p}_CREEP_G * excess;
"""

_STEP_TAIL = """\
    }
    for (j = 0; j < ${p}_N_LAGS; ++j) s->lag[j] = ${p}_creep_a[j] * s->lag[j] + ${p}_creep_b[j] * out[0];
    s->u_prev = out[0];
    }"""


def check_creep_inverse(hysteresis: Any) -> None:
    """Refuse, in one line, a creep model whose compensator has no C form (module notes)."""
    from ..hysteresis import PIModel

    if not isinstance(hysteresis, PIModel):
        raise ModelError(
            "`inverse=True` of a modified-PI hysteresis with creep has no C form (its input warp leaves a remainder "
            "the package solves iteratively per sample); compensate in Python, or use a classical PI model."
        )
    if hysteresis.r[0] != 0.0:
        raise ModelError(
            "`inverse=True` with creep folds the creep's instantaneous gain into the operator of threshold 0; "
            f"this model's first threshold is {float(hysteresis.r[0])!r}; compensate in Python instead."
        )


def _first_tables(model: Any, creep: Any, gain_g: float, p: str, clipped: bool) -> list[str]:
    """Double tables of the first sample: the G-folded inverse, its starting state, the g-folded
    forward weights the hand-over uses and, with drive limits, the forward state and thresholds a
    clipped drive replays (as :class:`CreepInverse` builds them)."""
    from ..hysteresis import OperatorState
    from ..hysteresis.inverse.closed_form import forward_state, inverse_state, pi_inverse

    double = CType("double")
    folded_g, folded_G = (_folded(model, gain) for gain in (gain_g, float(np.sum(creep.weights))))
    # the package's first compensator starts from the g-folded one's state, read back through its inverse
    start = inverse_state(folded_g, model.state)
    forward = forward_state(pi_inverse(folded_g), start)
    first_inv = pi_inverse(folded_G)
    z0 = inverse_state(folded_G, forward).z
    tables = {
        "first_r_inv": first_inv.r,
        "first_w_inv": first_inv.weights,
        "first_W_inv": np.cumsum(first_inv.weights),
        "first_z0": z0,
        "fold_w": folded_g.weights,
        "fold_W": np.cumsum(folded_g.weights),
    }
    if clipped:
        tables["fwd_z0"] = forward_state(first_inv, OperatorState(float(z0[0]), z0)).z
        tables["fold_r"] = folded_g.r
    return [f"static const double {p}_{k}[{p}_N_OPERATORS] = {array(v, double)};" for k, v in tables.items()]


def _folded(model: Any, gain: float) -> Any:
    """The PI model with ``gain`` added to its linear operator's weight (threshold 0), no creep."""
    w = np.array(model.weights, dtype=float)
    w[0] += gain
    return replace(model, weights=w, creep=None)


def creep_inverse_fields(
    hysteresis: Any, ctype: CType, prefix: str, limits: tuple[float, float] | None, dt: float
) -> dict[str, str]:
    """Template fields of the compensator of a classical PI model with creep, lags at ``dt`` [s].

    The fields of :func:`.c_hysteresis.inverse_fields` for the ``g``-folded model, its target
    moved by the creep's memory, and the first sample and the lags around it (module notes).
    Raises :class:`ModelError` for a model it cannot export (:func:`check_creep_inverse`).
    """
    from .c_hysteresis import inverse_fields

    check_creep_inverse(hysteresis)
    creep, p = hysteresis.creep, prefix
    a = creep.poles(dt)
    g = creep.instantaneous_gain(dt)
    folded = _folded(hysteresis, g)
    fields = inverse_fields(folded, ctype, p, limits if limits is not None else hysteresis.input_limits)
    clipped = (limits if limits is not None else hysteresis.input_limits) is not None
    body = fields["step_body"]
    target = fill(_TARGET, ctype, p)
    if body.count(target) != 1:  # the inverse's step names its target once; anything else is a bug here
        raise AssertionError("the PI compensator's step does not read its target as expected")
    body = body.replace(target, target.replace("in[0]", "y_creep"))
    consts = [f"#define {p}_N_LAGS {creep.n_lags}", define(p, "CREEP_G", g, ctype)]
    consts.append(f"static const {ctype.name} {p}_creep_a[{p}_N_LAGS] = {array(a, ctype)};")
    consts.append(f"static const {ctype.name} {p}_creep_b[{p}_N_LAGS] = {array(1.0 - a, ctype)};")
    consts.append(f"static const {ctype.name} {p}_creep_ca[{p}_N_LAGS] = {array(creep.weights * a, ctype)};")
    members = [f"    {ctype.name} lag[{creep.n_lags}];  /* creep lag outputs s_j */"]
    members.append(f"    {ctype.name} u_prev;  /* the last drive */")
    members.append("    int creep_fresh;  /* 1: the creep is at rest at the first drive */")
    u0 = float(hysteresis.from_operator_input(hysteresis.state.x))
    init = [f"    s->u_prev = {literal(u0, ctype)};", f"    s->creep_fresh = {int(creep.state is None)};"]
    lags = np.full(creep.n_lags, u0) if creep.state is None else creep.state
    init += [f"    s->lag[{j}] = {literal(v, ctype)};" for j, v in enumerate(lags)]
    head = fill(_STEP_HEAD, ctype, p)
    helpers = ""
    if creep.state is None:
        G = float(np.sum(creep.weights))
        consts += [define(p, "CREEP_G_STATIC", G, CType("double"))]
        consts += [define(p, "CREEP_EXCESS0", u0 - float(hysteresis.to_operator_input(u0)), CType("double"))]
        consts += _first_tables(hysteresis, creep, g, p, clipped)
        head = fill(_STEP_FRESH, ctype, p) + head
        helpers = "\n" + fill(
            _FIRST, ctype, p, clip=fill(_FIRST_CLIP, ctype, p) if clipped else "",
            replay=fill(_FIRST_REPLAY, ctype, p) if clipped else "",
        )  # fmt: skip
    fields["members"] += "\n" + "\n".join(members)
    fields["init_body"] += "\n" + "\n".join(init)
    fields["constants"] += "\n".join(consts) + "\n"
    fields["helpers"] += helpers
    fields["step_body"] = head + body + "\n" + fill(_STEP_TAIL, ctype, p)
    fields["summary"] += (
        f" Creep: {creep.n_lags} first-order lags at {dt!r} s folded into the linear operator "
        f"(instantaneous gain {g:.6g}, static gain {float(np.sum(creep.weights)):.6g})."
    )
    return fields
