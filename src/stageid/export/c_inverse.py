"""C99 streaming compensators: closed-form inverse PI and per-sample modified-PI inversion.

The C mirrors :class:`stageid.hysteresis.Compensator` step for step (see
:mod:`stageid.export.c_hysteresis`):

* classical PI -- the inverse PI model of :func:`stageid.hysteresis.pi_inverse` (thresholds
  ``r'``, weights ``w'``, state ``z'``); a drive outside the limits is clipped and the state
  rebuilt: forward state ``z_j = W'_j z'_j + sum_{i>j} w'_i z'_i``, one play update at the
  clipped drive, back with ``z'_j = W_j z_j + sum_{i>j} w_i z_i`` (``W = cumsum(w)``);
* modified PI -- ``F(x) = sum_i w_i CP_i(x; z_i)`` is piecewise linear and nondecreasing with
  slope at least ``smin``; each sample brackets the solution of ``F(x) = y_ref - y0`` from the
  last input and refines it by Newton steps on the pieces (regula falsi / bisection inside the
  bracket as safeguards) to ``|F(x) - target| <= tol``, then updates the operators at ``x``.

In single precision the tolerance and the bracket width are those a ``float`` can resolve.
"""

from __future__ import annotations

from string import Template
from typing import Any

import numpy as np

from .c_writer import CType, array, literal

__all__ = ["pi_inverse_fields", "modified_pi_inverse"]

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
static void ${p}_dual(const ${T} *W, const ${T} *w, const ${T} *z, ${T} *out)
{
    ${T} tail = 0.0${f};
    int i;
    for (i = ${p}_N_OPERATORS - 1; i >= 0; --i) {
        const ${T} wz = w[i] * z[i];
        out[i] = W[i] * z[i] + tail;
        tail = i == ${p}_N_OPERATORS - 1 ? wz : tail + wz;
    }
}

/* The inverse state after the forward model is driven to x from the inverse state z_inv. */
static void ${p}_rebase(const ${T} *z_inv, ${T} x, ${T} *out)
{
    ${T} zf[${p}_N_OPERATORS];
    int i;
    ${p}_dual(${p}_W_inv, ${p}_w_inv, z_inv, zf);
    for (i = 0; i < ${p}_N_OPERATORS; ++i) zf[i] = ${p}_max(x - ${p}_r[i], ${p}_min(x + ${p}_r[i], zf[i]));
    ${p}_dual(${p}_W, ${p}_w, zf, out);
}
"""

_CP_EVAL = """\
/* F(x) = sum_i w_i CP_i(x; z_i) and its slopes on the pieces right (sp) and left (sm) of x. */
static ${T} ${p}_eval(${T} x, const ${T} *z, ${T} *sp_out, ${T} *sm_out)
{
    ${T} f = 0.0${f}, sp = 0.0${f}, sm = 0.0${f};
    int i;
    for (i = 0; i < ${p}_N_OPERATORS; ++i) {
        const ${T} a = x - ${p}_r[i], b = x - ${p}_rc[i], c = x + ${p}_ra[i], d = x + ${p}_rb[i];
        const ${T} lo = ${p}_min(b, 0.0${f}), hi = ${p}_max(d, 0.0${f});
        const ${T} up = a > lo ? a : lo, down = c < hi ? c : hi;
        const int up_sp = a >= 0.0${f} || b < 0.0${f};  /* 0/1 slopes of the branches */
        const int up_sm = a > 0.0${f} || b <= 0.0${f};
        const int dn_sp = c < 0.0${f} || d >= 0.0${f};
        const int dn_sm = c <= 0.0${f} || d > 0.0${f};
        const ${T} zi = z[i];
        ${T} inner, v;
        int in_sp, in_sm, v_sp, v_sm;
        if (down < zi) {
            inner = down; in_sp = dn_sp; in_sm = dn_sm;
        } else if (down > zi) {
            inner = zi; in_sp = 0; in_sm = 0;
        } else {
            inner = zi; in_sp = 0; in_sm = dn_sm;
        }
        if (up > inner) {
            v = up; v_sp = up_sp; v_sm = up_sm;
        } else if (up < inner) {
            v = inner; v_sp = in_sp; v_sm = in_sm;
        } else {
            v = up; v_sp = up_sp | in_sp; v_sm = up_sm & in_sm;
        }
        f += ${p}_w[i] * v;
        if (v_sp) sp += ${p}_w[i];  /* (int flags, not 0/1 doubles: gcc 12 -O2 crashed vectorising those) */
        if (v_sm) sm += ${p}_w[i];
    }
    *sp_out = sp;
    *sm_out = sm;
    return f;
}

static ${T} ${p}_abs(${T} v) { return v < 0.0${f} ? -v : v; }

/* The input x with F(x) = target (to TOL), starting from the last input x_prev. */
static ${T} ${p}_solve(const ${T} *z, ${T} x_prev, ${T} target)
{
    ${T} sp, sm, s1, s2, a, b, fa, fb, xc, fc, sc;
    const ${T} f = ${p}_eval(x_prev, z, &sp, &sm);
    ${T} x = x_prev;
    int it;
    if (${p}_abs(f - target) <= ${p}_TOL) return x_prev;
    if (target > f) {  /* bracket [x_prev, x_prev + (target - f) / smin] */
        a = x_prev; fa = f;
        b = x_prev + (target - f) / ${p}_SMIN;
        if (b > ${p}_HIGH) b = ${p}_HIGH;
        fb = ${p}_eval(b, z, &s1, &s2);
        if (fb <= target) { x = b; fa = fb; a = b; }
    } else {
        b = x_prev; fb = f;
        a = x_prev - (f - target) / ${p}_SMIN;
        if (a < ${p}_LOW) a = ${p}_LOW;
        fa = ${p}_eval(a, z, &s1, &s2);
        if (fa >= target) { x = a; fb = fa; b = a; }
    }
    if (!(a < b)) return x;
    if (target > f) { xc = a; fc = fa; sc = sp; } else { xc = b; fc = fb; sc = sm; }
    for (it = 0; it < 200; ++it) {  /* Newton on the pieces, safeguarded inside [a, b] */
        ${T} xn = sc > 0.0${f} ? xc + (target - fc) / sc : 0.5${f} * (a + b);
        ${T} fn, snp, snm;
        if (!(xn > a && xn < b)) {
            if (fb > fa) xn = a + (target - fa) * (b - a) / (fb - fa);
            if (!(xn > a && xn < b)) xn = 0.5${f} * (a + b);
        }
        fn = ${p}_eval(xn, z, &snp, &snm);
        x = xn;
        if (${p}_abs(fn - target) <= ${p}_TOL) break;
        if (fn < target) { a = xn; fa = fn; xc = xn; fc = fn; sc = snp; }
        else { b = xn; fb = fn; xc = xn; fc = fn; sc = snm; }
        if (b - a <= ${p}_BRACKET * (1.0${f} + ${p}_abs(a) + ${p}_abs(b))) break;
    }
    return x;
}
"""

_CP_STEP = """\
    const ${T} x = ${p}_solve(s->z, s->x, in[0] - ${p}_OUTPUT_OFFSET);
    int i;
    for (i = 0; i < ${p}_N_OPERATORS; ++i) {  /* operators follow the chosen input, eq. 3 */
        const ${T} up = ${p}_max(x - ${p}_r[i], ${p}_min(x - ${p}_rc[i], 0.0${f}));
        const ${T} down = ${p}_min(x + ${p}_ra[i], ${p}_max(x + ${p}_rb[i], 0.0${f}));
        s->z[i] = ${p}_max(up, ${p}_min(down, s->z[i]));
    }
    s->x = x;
${drive}"""

_UNWARP = """\
    {   /* drive from the operator input: inverse of the input warp */
        const ${T} tp = x / ${p}_WARP_SCALE;
        const ${T} inner = 2.0${f} * tp / (1.0${f} + sqrt${fn}(${p}_max(1.0${f} + ${p}_WARP_4Q * tp, 0.0${f})));
        const ${T} t = tp > ${p}_WARP_UP ? (tp + ${p}_WARP_Q) / ${p}_WARP_UP_SLOPE
                     : (tp < ${p}_WARP_DOWN ? (tp + ${p}_WARP_Q) / ${p}_WARP_DOWN_SLOPE : inner);
        out[0] = t * ${p}_WARP_SCALE + ${p}_INPUT_OFFSET;
    }
"""


def _sub(text: str, ctype: CType, prefix: str, **extra: str) -> str:
    f = "f" if ctype.is_float else ""
    return Template(text).substitute(T=ctype.name, f=f, fn=f, p=prefix, **extra)


def _define(prefix: str, name: str, value: float, ctype: CType) -> str:
    return f"#define {prefix}_{name} ({literal(value, ctype)})"


def _tables(prefix: str, ctype: CType, **tables: object) -> list[str]:
    return [
        f"static const {ctype.name} {prefix}_{name}[{prefix}_N_OPERATORS] = {array(v, ctype)};"
        for name, v in tables.items()
    ]


def _limits(model: Any, limits: tuple[float, float] | None) -> tuple[float, float]:
    if limits is None:
        return -np.inf, np.inf
    return float(model.to_operator_input(limits[0])), float(model.to_operator_input(limits[1]))


def _limit_define(prefix: str, name: str, value: float, ctype: CType) -> str:
    if np.isfinite(value):
        return _define(prefix, name, value, ctype)
    huge = "HUGE_VALF" if ctype.is_float else "HUGE_VAL"
    return f"#define {prefix}_{name} ({'-' if value < 0 else ''}{huge})"


def _init(name: str, values: object, ctype: CType) -> list[str]:
    return [f"    s->{name}[{i}] = {literal(v, ctype)};" for i, v in enumerate(np.asarray(values).reshape(-1))]


def pi_inverse_fields(model: Any, limits: tuple[float, float] | None, ctype: CType, prefix: str) -> dict[str, str]:
    """Fields of the closed-form inverse of a classical PI model (drive ``limits`` or None)."""
    from ..hysteresis import pi_inverse

    p, inv = prefix, pi_inverse(model)
    lo, hi = _limits(model, limits)
    consts = [f"#define {p}_N_OPERATORS {model.n_operators}"]
    consts += [_define(p, "INPUT_OFFSET", model.input_offset, ctype)]
    consts += [_define(p, "OUTPUT_OFFSET", model.output_offset, ctype)]
    consts += _tables(p, ctype, r_inv=inv.r, w_inv=inv.weights)
    clip, helpers = "", ""
    if limits is not None:
        consts += [_limit_define(p, "LOW", lo, ctype), _limit_define(p, "HIGH", hi, ctype)]
        consts += _tables(p, ctype, r=model.r, w=model.weights)
        consts += _tables(p, ctype, W=np.cumsum(model.weights), W_inv=np.cumsum(inv.weights))
        clip = _sub(_PI_CLIP, ctype, p)
        helpers = "\n" + _sub(_PI_REBASE, ctype, p)
    return {
        "title": "compensator of a classical Prandtl-Ishlinskii model (closed-form inverse)",
        "members": f"    {ctype.name} z[{model.n_operators}];  /* operator outputs of the inverse PI model */",
        "constants": "\n".join(consts) + "\n",
        "helpers": helpers,
        "includes": "#include <math.h>\n" if limits is not None and not (np.isfinite(lo) and np.isfinite(hi)) else "",
        "init_body": "\n".join(_init("z", inv.state.z, ctype)),
        "step_body": _sub(_PI_STEP, ctype, p, clip=clip).rstrip("\n"),
    }


def modified_pi_inverse(model: Any, limits: tuple[float, float] | None, ctype: CType, prefix: str) -> dict[str, str]:
    """Fields of the per-sample inversion of a modified PI model (drive ``limits`` or None)."""
    p = prefix
    lo, hi = _limits(model, limits)
    # tolerances of the package's inversion; a float resolves about 1e-7 of the output scale
    scale = float(np.sum(np.abs(model.weights)) * (1.0 + np.max(model.r)))
    tol = 1e-12 * max(scale, 1e-300)
    consts = [f"#define {p}_N_OPERATORS {model.n_operators}"]
    consts += [_define(p, "INPUT_OFFSET", model.input_offset, ctype)]
    consts += [_define(p, "OUTPUT_OFFSET", model.output_offset, ctype)]
    consts += [_define(p, "SMIN", model.min_slope(), ctype)]
    consts += [_define(p, "TOL", max(tol, 2e-7 * scale) if ctype.is_float else tol, ctype)]
    consts += [_define(p, "BRACKET", 1e-6 if ctype.is_float else 1e-15, ctype)]
    consts += [_limit_define(p, "LOW", lo, ctype), _limit_define(p, "HIGH", hi, ctype)]
    consts += _tables(p, ctype, r=model.r, rc=model.rc, ra=model.ra, rb=model.rb, w=model.weights)
    q = model.input_warp
    if q != 0.0:
        R = model.warp_scale
        consts += [_define(p, "WARP_SCALE", R, ctype), _define(p, "WARP_Q", q, ctype), _define(p, "WARP_4Q", 4.0 * q, ctype)]
        consts += [_define(p, "WARP_UP", 1.0 + q, ctype), _define(p, "WARP_DOWN", -1.0 + q, ctype)]
        consts += [_define(p, "WARP_UP_SLOPE", 1.0 + 2.0 * q, ctype), _define(p, "WARP_DOWN_SLOPE", 1.0 - 2.0 * q, ctype)]
        drive = _sub(_UNWARP, ctype, p)
        if limits is not None:
            consts += [_define(p, "DRIVE_LOW", limits[0], ctype), _define(p, "DRIVE_HIGH", limits[1], ctype)]
            drive += f"    out[0] = {p}_min({p}_max(out[0], {p}_DRIVE_LOW), {p}_DRIVE_HIGH);\n"
    else:
        drive = f"    out[0] = x + {p}_INPUT_OFFSET;\n"
    uses_math = q != 0.0 or not (np.isfinite(lo) and np.isfinite(hi))
    return {
        "title": "compensator of a modified Prandtl-Ishlinskii model (per-sample inversion)",
        "members": f"    {ctype.name} z[{model.n_operators}];  /* operator outputs */\n"
        f"    {ctype.name} x;  /* last operator input */",
        "constants": "\n".join(consts) + "\n",
        "helpers": "\n" + _sub(_CP_EVAL, ctype, p),
        "includes": "#include <math.h>\n" if uses_math else "",
        "init_body": "\n".join(_init("z", model.state.z, ctype) + [f"    s->x = {literal(model.state.x, ctype)};"]),
        "step_body": _sub(_CP_STEP, ctype, p, drive=drive).rstrip("\n"),
    }
