"""C99 code for PI and modified-PI hysteresis models: forward model and streaming compensator.

Forward (``stageid simulate``)
    Every operator is updated at every sample with the formula of the plain-Python references
    of :mod:`stageid.hysteresis` -- the play ``max(x - r, min(x + r, z))`` (eq. 1) or the
    coupled play ``max(gamma_up(x), min(gamma_down(x), z))`` (eq. 3 in the package's consistent
    reading) -- and the weighted sum (eq. 4) is taken in operator order.  The input warp of a
    modified PI model and a creep term (first-order lags as :func:`scipy.signal.lfilter` runs
    them, at rest at the first input unless the term stores a state) follow the same
    arithmetic as the Python model.

Inverse (``stageid compensate``, eq. 5 and Fig. 9)
    A classical PI model runs its closed-form inverse PI model (a play sum); when the drive
    leaves its limits it is clipped and the operator state is rebuilt from the clipped drive
    through the duality formula, as :class:`stageid.hysteresis.Compensator` does.  A modified
    PI model finds the exact root of ``F(x) = y_ref`` per sample, as the package does, by its
    own safeguarded Newton iteration on the piecewise-linear output (:mod:`.c_inverse`), then
    updates the operators with that input.  Only rate-independent models have an exported
    inverse.

Every constant is emitted exactly (:mod:`stageid.export.c_writer`); the forward steps and the
classical-PI compensator keep the package's order of operations, so double-precision code
reproduces the Python results to rounding (bit for bit where the package evaluates in the same
order); the modified-PI compensator agrees to rounding because both return the exact root.
"""

from __future__ import annotations

from typing import Any

from .._errors import ModelError
from .c_writer import CType, array, define, fill, init_lines

__all__ = ["forward_fields", "inverse_fields"]

_MINMAX = """\
static ${T} ${p}_max(${T} a, ${T} b) { return a > b ? a : b; }
static ${T} ${p}_min(${T} a, ${T} b) { return a < b ? a : b; }
"""

_PLAY_LOOP = """\
    for (i = 0; i < ${p}_N_OPERATORS; ++i) {  /* play operators, eq. 1 */
        const ${T} v = ${p}_max(x - ${p}_r[i], ${p}_min(x + ${p}_r[i], s->z[i]));
        s->z[i] = v;
        y += ${p}_w[i] * v;
    }
"""

_CP_LOOP = """\
    for (i = 0; i < ${p}_N_OPERATORS; ++i) {  /* coupled-play operators, eq. 3 */
        const ${T} up = ${p}_max(x - ${p}_r[i], ${p}_min(x - ${p}_rc[i], 0.0${f}));
        const ${T} down = ${p}_min(x + ${p}_ra[i], ${p}_max(x + ${p}_rb[i], 0.0${f}));
        const ${T} v = ${p}_max(up, ${p}_min(down, s->z[i]));
        s->z[i] = v;
        y += ${p}_w[i] * v;
    }
"""

_WARP = """\
    {   /* input warp x = d + q R phi(d / R) */
        const ${T} t = d / ${p}_WARP_SCALE;
        const ${T} a = t < 0.0${f} ? -t : t;
        const ${T} phi = a <= 1.0${f} ? t * t : 2.0${f} * a - 1.0${f};
        x = d + ${p}_WARP_QR * phi;
    }
"""

_CREEP = """\
    if (s->creep_at_rest) {  /* creep lags at rest at the first input */
        for (j = 0; j < ${p}_N_LAGS; ++j) s->lag[j] = ${p}_lag_pole[j] * u;
        s->creep_at_rest = 0;
    }
    creep = 0.0${f};
    for (j = 0; j < ${p}_N_LAGS; ++j) {  /* s_j = a_j s_j + (1 - a_j) u; lag[j] holds a_j s_j */
        const ${T} lag = s->lag[j] + ${p}_lag_gain[j] * u;
        s->lag[j] = ${p}_lag_pole[j] * lag;
        creep += ${p}_creep_w[j] * lag;
    }
    y = y + creep;
"""


def _table(prefix: str, name: str, values: object, ctype: CType, size: str) -> str:
    return f"static const {ctype.name} {prefix}_{name}[{size}] = {array(values, ctype)};"


def _names(model: Any) -> dict[str, str]:
    return {
        "n_inputs": "1",
        "n_outputs": "1",
        "input_names": model.inputs[0],
        "output_names": model.outputs[0],
    }


def forward_fields(
    model: Any, ctype: CType, prefix: str, dt: float | None = None, output: str = "out[0]"
) -> dict[str, str]:
    """Template fields of the forward model (``stageid simulate``); ``dt`` [s] for a creep term
    (default its ``sample_time``); ``output`` receives the model's output at the step's end
    (a stage model declares a local there and filters it, :mod:`.c_stage`)."""
    from ..hysteresis import PIModel

    p, m = prefix, model.n_operators
    classical = isinstance(model, PIModel)
    consts = [f"#define {p}_N_OPERATORS {m}", define(p, "INPUT_OFFSET", model.input_offset, ctype)]
    consts.append(define(p, "OUTPUT_OFFSET", model.output_offset, ctype))
    consts.append(_table(p, "r", model.r, ctype, f"{p}_N_OPERATORS"))
    if not classical:
        for name in ("rc", "ra", "rb"):
            consts.append(_table(p, name, getattr(model, name), ctype, f"{p}_N_OPERATORS"))
    consts.append(_table(p, "w", model.weights, ctype, f"{p}_N_OPERATORS"))
    warp = not classical and model.input_warp != 0.0
    if warp:
        consts.append(define(p, "WARP_SCALE", model.warp_scale, ctype))
        consts.append(define(p, "WARP_QR", model.input_warp * model.warp_scale, ctype))
    members = [f"    {ctype.name} z[{m}];  /* operator outputs */"]
    init = init_lines("z", model.state.z, ctype)
    body = [f"    const {ctype.name} u = in[0];", f"    const {ctype.name} d = u - {p}_INPUT_OFFSET;"]
    body += [f"    {ctype.name} x = d;", f"    {ctype.name} y = 0.0{'f' if ctype.is_float else ''};", "    int i;"]
    creep = model.creep
    if creep is not None:
        body[-1] = "    int i, j;"
        body.append(f"    {ctype.name} creep;")
        poles = creep.poles(dt)
        consts.append(f"#define {p}_N_LAGS {creep.n_lags}")
        consts.append(_table(p, "lag_pole", poles, ctype, f"{p}_N_LAGS"))
        consts.append(_table(p, "lag_gain", [1.0 - a for a in poles], ctype, f"{p}_N_LAGS"))
        consts.append(_table(p, "creep_w", creep.weights, ctype, f"{p}_N_LAGS"))
        members.append(f"    {ctype.name} lag[{creep.n_lags}];  /* a_j s_j of the creep lags */")
        members.append("    int creep_at_rest;  /* 1 until the first sample */")
        if creep.state is None:
            init.append("    s->creep_at_rest = 1;")
            init += [f"    s->lag[{j}] = 0.0{'f' if ctype.is_float else ''};" for j in range(creep.n_lags)]
        else:
            init.append("    s->creep_at_rest = 0;")
            init += init_lines("lag", poles * creep.state, ctype)
    if warp:
        body.append(fill(_WARP, ctype, p).rstrip("\n"))
    body.append(fill(_PLAY_LOOP if classical else _CP_LOOP, ctype, p).rstrip("\n"))
    if creep is not None:
        body.append(fill(_CREEP, ctype, p).rstrip("\n"))
    body.append(f"    {output} = y + {p}_OUTPUT_OFFSET;")
    rate = "" if creep is None else f", creep lags at dt = {float(dt or creep.sample_time)!r} s"
    return {
        **_names(model),
        "title": f"{'classical' if classical else 'modified'} Prandtl-Ishlinskii model (forward)",
        "summary": f"{m} {'play' if classical else 'coupled-play'} operators{rate}.",
        "members": "\n".join(members),
        "init_doc": "to the model's stored operator state, where `stageid simulate` starts",
        "constants": "\n".join(consts) + "\n",
        "helpers": fill(_MINMAX, ctype, p),
        "init_body": "\n".join(init),
        "step_body": "\n".join(body),
    }


def inverse_fields(model: Any, ctype: CType, prefix: str, limits: tuple[float, float] | None = None) -> dict[str, str]:
    """Template fields of the streaming compensator (``stageid compensate``).

    ``limits`` as :class:`~stageid.hysteresis.Compensator` takes them (default the model's
    ``input_limits``).  Raises :class:`ModelError` for a model without an exported causal
    inverse: a creep term (rate dependent) or a non-invertible model.
    """
    from ..hysteresis import Compensator, PIModel

    if model.creep is not None:
        raise ModelError(
            "`inverse=True` exports the compensator of rate-independent models; got a model with a creep term "
            "(its drive depends on the sampling rate: use `stageid compensate`)."
        )
    comp = Compensator(model, limits)  # the package's own checks: invertible, limits well formed
    from .c_inverse import modified_pi_inverse
    from .c_pi_inverse import pi_inverse_fields

    fields = (pi_inverse_fields if isinstance(model, PIModel) else modified_pi_inverse)(
        model, comp.limits, ctype, prefix
    )
    lim = "unlimited drive" if comp.limits is None else f"drive limited to [{comp.limits[0]!r}, {comp.limits[1]!r}]"
    fields.update(_names(model))
    fields["input_names"], fields["output_names"] = model.outputs[0] + " (desired output)", model.inputs[0] + " (drive)"
    fields["summary"] = f"{model.n_operators} operators, {lim}."
    fields["init_doc"] = "to the model's stored operator state, where `stageid compensate` starts"
    fields["helpers"] = fill(_MINMAX, ctype, prefix) + fields.get("helpers", "")
    return fields
