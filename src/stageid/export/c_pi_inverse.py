"""C99 compensator of a classical Prandtl-Ishlinskii model: its closed-form inverse.

What the C computes is what :class:`stageid.hysteresis.Compensator` computes (see
:mod:`stageid.export.c_hysteresis`): the inverse PI model of
:func:`stageid.hysteresis.pi_inverse` (thresholds ``r'``, weights ``w'``, state ``z'``), step
for step; a drive outside the limits is clipped and the state rebuilt: forward state
``z_j = W'_j z'_j + sum_{i>j} w'_i z'_i``, one play update at the clipped drive, back with
``z'_j = W_j z_j + sum_{i>j} w_i z_i`` (``W = cumsum(w)``).  This rebuild runs in double
precision also in single-precision code: its sums cancel.  The modified PI model's per-sample
inversion is :mod:`.c_inverse`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from . import c_float_sums as fs
from .c_writer import CType, const_tables, define, fill, init_lines, limit_define

__all__ = ["pi_inverse_fields", "operator_limits"]

_PI_STEP = """\
    const ${T} target = in[0] - ${p}_OUTPUT_OFFSET;
    ${T} zn[${p}_N_OPERATORS];
    ${T} x = 0.0${f};
    int i;
    for (i = 0; i < ${p}_N_OPERATORS; ++i) {  /* the inverse PI model: a play sum */
        const ${T} v = ${p}_max(target - ${p}_r_inv[i], ${p}_min(target + ${p}_r_inv[i], s->z[i]));
        zn[i] = v;
        x += ${p}_w_inv[i] * v;
    }
${clip}    for (i = 0; i < ${p}_N_OPERATORS; ++i) s->z[i] = zn[i];
    out[0] = x + ${p}_INPUT_OFFSET;
"""

_PI_CLIP = """\
    if (x < ${p}_LOW || x > ${p}_HIGH) {  /* clipped drive: rebuild the state from it */
        x = ${p}_min(${p}_max(x, ${p}_LOW), ${p}_HIGH);
        ${p}_rebase(s->z, x, zn);
    }
"""

_PI_REBASE = """\
/* Dual state: out_j = W_j z_j + sum_{i>j} w_i z_i (W = cumsum(w)), summed from the last operator. */
static void ${p}_dual(const ${R} *W, const ${R} *w, const ${R} *z, ${R} *out)
{
    ${R} tail = 0.0;
    int i;
    for (i = ${p}_N_OPERATORS - 1; i >= 0; --i) {
        const ${R} wz = w[i] * z[i];
        out[i] = W[i] * z[i] + tail;
        tail = i == ${p}_N_OPERATORS - 1 ? wz : tail + wz;
    }
}

/* The inverse state after the forward model is driven to x from the inverse state z_inv
   (the package's rebuild: forward state by duality, one play update at x, back by duality). */
static void ${p}_rebase(const ${T} *z_inv, ${T} x, ${T} *out)
{
    ${R} zi[${p}_N_OPERATORS], zf[${p}_N_OPERATORS], zo[${p}_N_OPERATORS];
    int i;
    for (i = 0; i < ${p}_N_OPERATORS; ++i) zi[i] = z_inv[i];
    ${p}_dual(${p}_W_inv${d}, ${p}_w_inv${d}, zi, zf);
    for (i = 0; i < ${p}_N_OPERATORS; ++i) {  /* play update at x: min(x + r, z), then max(x - r, .) */
        const ${R} hi = x + ${p}_r${d}[i], lo = x - ${p}_r${d}[i];
        const ${R} v = zf[i] < hi ? zf[i] : hi;
        zf[i] = v > lo ? v : lo;
    }
    ${p}_dual(${p}_W${d}, ${p}_w${d}, zf, zo);
    for (i = 0; i < ${p}_N_OPERATORS; ++i) out[i] = (${T})zo[i];
}
"""


def operator_limits(model: Any, limits: tuple[float, float] | None) -> tuple[float, float]:
    """Drive ``limits`` (or None: unbounded) as the hysteresis operators' input."""
    if limits is None:
        return -np.inf, np.inf
    return float(model.to_operator_input(limits[0])), float(model.to_operator_input(limits[1]))


def pi_inverse_fields(model: Any, limits: tuple[float, float] | None, ctype: CType, prefix: str) -> dict[str, str]:
    """Fields of the closed-form inverse of a classical PI model (drive ``limits`` or None)."""
    from ..hysteresis import pi_inverse

    p, inv = prefix, pi_inverse(model)
    lo, hi = operator_limits(model, limits)
    consts = [f"#define {p}_N_OPERATORS {model.n_operators}"]
    consts += [define(p, "INPUT_OFFSET", model.input_offset, ctype)]
    consts += [define(p, "OUTPUT_OFFSET", model.output_offset, ctype)]
    consts += const_tables(p, ctype, r_inv=inv.r, w_inv=inv.weights)
    clip, helpers = "", ""
    snap_consts, snap = fs.pinned(limits, ctype, p)
    consts += snap_consts
    if limits is not None:
        consts += [limit_define(p, "LOW", lo, ctype), limit_define(p, "HIGH", hi, ctype)]
        # the rebuild runs in double even in single-precision code: the duality sums cancel (terms up to
        # sum|w| / w0 times the output), which cost single precision up to 6e-4 of the drive range
        rebuild, suffix = CType("double"), "_d" if ctype.is_float else ""
        tables = {"r": model.r, "w": model.weights, "W": np.cumsum(model.weights), "W_inv": np.cumsum(inv.weights)}
        if ctype.is_float:
            tables["w_inv"] = inv.weights
        consts += const_tables(p, rebuild, **{name + suffix: v for name, v in tables.items()})
        clip = fill(_PI_CLIP, ctype, p)
        helpers = "\n" + fill(_PI_REBASE, ctype, p, R="double", d=suffix)
    return {
        "title": "compensator of a classical Prandtl-Ishlinskii model (closed-form inverse)",
        "members": f"    {ctype.name} z[{model.n_operators}];  /* operator outputs of the inverse PI model */",
        "constants": "\n".join(consts) + "\n",
        "helpers": helpers,
        "includes": "#include <math.h>\n" if limits is not None and not (np.isfinite(lo) and np.isfinite(hi)) else "",
        "init_body": "\n".join(init_lines("z", inv.state.z, ctype)),
        "step_body": (fill(_PI_STEP, ctype, p, clip=clip) + snap).rstrip("\n"),
    }
