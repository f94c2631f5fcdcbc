"""C99 streaming compensators: closed-form inverse PI and per-sample modified-PI inversion.

The C mirrors :class:`stageid.hysteresis.Compensator` step for step (see
:mod:`stageid.export.c_hysteresis`):

* classical PI -- the inverse PI model of :func:`stageid.hysteresis.pi_inverse` (thresholds
  ``r'``, weights ``w'``, state ``z'``); a drive outside the limits is clipped and the state
  rebuilt: forward state ``z_j = W'_j z'_j + sum_{i>j} w'_i z'_i``, one play update at the
  clipped drive, back with ``z'_j = W_j z_j + sum_{i>j} w_i z_i`` (``W = cumsum(w)``).  This
  rebuild runs in double precision also in single-precision code: its sums cancel;
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

_SLOPE = """\
static ${T} ${p}_slope_${side}(${T} x, const ${T} *z)
{
    ${T} s = 0.0${f};
    int i;
    for (i = 0; i < ${p}_N_OPERATORS; ++i) {
        const ${T} a = x - ${p}_r[i], b = x - ${p}_rc[i], c = x + ${p}_ra[i], d = x + ${p}_rb[i];
        const ${T} up = ${p}_max(a, ${p}_min(b, 0.0${f})), down = ${p}_min(c, ${p}_max(d, 0.0${f}));
        const ${T} inner = ${p}_min(down, z[i]);
${moves}
        s += moves ? ${p}_w[i] : 0.0${f};  /* w_i or 0: exactly what w_i * (0 or 1) adds */
    }
    return s;
}
"""

# which operators move right / left of x (the tie rules of the package's kernel)
_MOVES = {
    "right": """\
        const int up_moves = (a >= 0.0${f}) | (b < 0.0${f}), down_moves = (c < 0.0${f}) | (d >= 0.0${f});
        const int moves = ((up >= inner) & up_moves) | ((up <= inner) & (down < z[i]) & down_moves);""",
    "left": """\
        const int up_moves = (a > 0.0${f}) | (b <= 0.0${f});
        const int in_moves = (down <= z[i]) & ((c <= 0.0${f}) | (d > 0.0${f}));
        const int gt = up > inner, lt = up < inner;
        const int moves = (gt & up_moves) | (lt & in_moves) | (!gt & !lt & up_moves & in_moves);""",
}

_CP_FUNCTIONS = """\
static ${T} ${p}_abs(${T} v) { return v < 0.0${f} ? -v : v; }

/* F(x) = sum_i w_i CP_i(x; z_i), summed in operator order (the package's order); zn receives
   the operator outputs at x, the state should x be the answer (zn = z: the operators follow x). */
static ${T} ${p}_value(${T} x, const ${T} *z, ${T} *zn)
{
    ${T} f = 0.0${f};
    int i;
    for (i = 0; i < ${p}_N_OPERATORS; ++i) {
        const ${T} up = ${p}_max(x - ${p}_r[i], ${p}_min(x - ${p}_rc[i], 0.0${f}));
        const ${T} down = ${p}_min(x + ${p}_ra[i], ${p}_max(x + ${p}_rb[i], 0.0${f}));
        zn[i] = ${p}_max(up, ${p}_min(down, z[i]));
        f += ${p}_w[i] * zn[i];
    }
    return f;
}

/* Slopes of F on the pieces right and left of x: the sums, in operator order, of the weights
   of the operators that move there.  An operator's output max(up, min(down, z)) moves with x
   where the branch it sits on does: the ascending branch up (slope 1 except on its flat zero
   stretch rc <= x <= r) where up >= min(down, z), the descending branch down where down < z.
   At a tie between branches the rules of the package's kernel apply, so the sums are its sums. */
${slope_right}
${slope_left}
/* A bound of the rounding error of the computed F at x (see the module notes). */
static ${T} ${p}_error(${T} x) { return ${p}_ROUNDING * (${p}_abs(x) + ${p}_R_MAX); }

/* Where a solve leaves the operators: z points to their outputs at the answer and f to F there
   when the solve evaluated F at the answer (z = 0: not evaluated, the operators must follow). */
typedef struct {
    ${T} z_new[${p}_N_OPERATORS], z_far[${p}_N_OPERATORS], f;
    const ${T} *z;
} ${p}_next;

/* The input x with F(x) = target (to TOL), from the last input x_prev where F = f.  The package's
   iteration: the bracket [x_prev, x_prev + (target - f) / smin] (or its mirror); if F at its far
   end does not pass the target the far end is the answer (a drive limit), else Newton on the
   pieces from the near end, with regula falsi / bisection inside the bracket as safeguards.
   Work is done only where its result is used: slopes only for a Newton step, the far end only
   when it can matter -- F rises at least smin per unit, so once an iterate lands past the target
   by more than the rounding error allows, the far end cannot be the answer. */
static ${T} ${p}_solve(const ${T} *z, ${T} x_prev, ${T} f, ${T} target, ${p}_next *next)
{
    const int rising = target > f;
    ${T} a, b, fa = f, fb = f, xc = x_prev, fc = f, sc, x = x_prev, far;
    int known = 0, decided = 0, it;  /* far end: value computed / known not to be the answer */
    next->z = 0;
    if (${p}_abs(f - target) <= ${p}_TOL) return x_prev;
    if (rising) {
        a = x_prev;
        b = x_prev + (target - f) / ${p}_SMIN;
        if (b > ${p}_HIGH) b = ${p}_HIGH;
    } else {
        b = x_prev;
        a = x_prev - (f - target) / ${p}_SMIN;
        if (a < ${p}_LOW) a = ${p}_LOW;
    }
    far = rising ? b : a;
#define ${p}_FAR_END()                                                         \\
    do {                                                                        \\
        if (!known) {                                                           \\
            known = decided = 1;                                                \\
            if (rising) fb = ${p}_value(b, z, next->z_far);                     \\
            else fa = ${p}_value(a, z, next->z_far);                            \\
            if (rising ? fb <= target : fa >= target) {                         \\
                next->z = next->z_far;                                          \\
                next->f = rising ? fb : fa;                                     \\
                return rising ? b : a;                                          \\
            }                                                                   \\
        }                                                                       \\
    } while (0)
    if (!(a < b)) {
        ${p}_FAR_END();
        return x_prev;
    }
    sc = rising ? ${p}_slope_right(x_prev, z) : ${p}_slope_left(x_prev, z);
    for (it = 0; it < 200; ++it) {
        ${T} xn = sc > 0.0${f} ? xc + (target - fc) / sc : 0.5${f} * (a + b);
        ${T} fn;
        if (!(xn > a && xn < b)) {
            ${p}_FAR_END();
            if (fb > fa) xn = a + (target - fa) * (b - a) / (fb - fa);
            if (!(xn > a && xn < b)) xn = 0.5${f} * (a + b);
        }
        fn = ${p}_value(xn, z, next->z_new);
        x = xn;
        next->z = next->z_new;
        next->f = fn;
        if (!decided) {
            const ${T} gap = rising ? fn + ${p}_SMIN * (far - xn) - target : target - (fn - ${p}_SMIN * (xn - far));
            if (gap > ${p}_error(xn) + ${p}_error(far)) decided = 1;
        }
        if (${p}_abs(fn - target) <= ${p}_TOL) break;
        if (fn < target) { a = xn; fa = fn; }
        else { b = xn; fb = fn; }
        xc = xn;
        fc = fn;
        if (rising ? b != far : a != far) known = decided = 1;  /* the far end was replaced */
        if (b - a <= ${p}_BRACKET * (1.0${f} + ${p}_abs(a) + ${p}_abs(b))) break;
        sc = fn < target ? ${p}_slope_right(xn, z) : ${p}_slope_left(xn, z);
    }
    if (!decided) ${p}_FAR_END();
#undef ${p}_FAR_END
    return x;
}
"""

_CP_STEP = """\
    ${p}_next next;
    const ${T} x = ${p}_solve(s->z, s->x, s->f, in[0] - ${p}_OUTPUT_OFFSET, &next);
    if (next.z) {  /* F was evaluated at x: its operator outputs are the new state */
        int i;
        for (i = 0; i < ${p}_N_OPERATORS; ++i) s->z[i] = next.z[i];
        s->f = next.f;
    } else {
        s->f = ${p}_value(x, s->z, s->z);  /* operators follow x (eq. 3); F there starts the next sample */
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
        # the rebuild runs in double also with --float: the duality sums cancel (terms up to
        # sum|w| / w0 times the output), which cost single precision up to 6e-4 of the drive range
        rebuild, suffix = CType("double"), "_d" if ctype.is_float else ""
        tables = {"r": model.r, "w": model.weights, "W": np.cumsum(model.weights), "W_inv": np.cumsum(inv.weights)}
        if ctype.is_float:
            tables["w_inv"] = inv.weights
        consts += _tables(p, rebuild, **{name + suffix: v for name, v in tables.items()})
        clip = _sub(_PI_CLIP, ctype, p)
        helpers = "\n" + _sub(_PI_REBASE, ctype, p, R="double", d=suffix)
    return {
        "title": "compensator of a classical Prandtl-Ishlinskii model (closed-form inverse)",
        "members": f"    {ctype.name} z[{model.n_operators}];  /* operator outputs of the inverse PI model */",
        "constants": "\n".join(consts) + "\n",
        "helpers": helpers,
        "includes": "#include <math.h>\n" if limits is not None and not (np.isfinite(lo) and np.isfinite(hi)) else "",
        "init_body": "\n".join(_init("z", inv.state.z, ctype)),
        "step_body": _sub(_PI_STEP, ctype, p, clip=clip).rstrip("\n"),
    }


def _cp_functions(ctype: CType, prefix: str) -> str:
    """value, the two slopes (one template, two rules) and solve."""
    slopes = {
        f"slope_{side}": _sub(_SLOPE, ctype, prefix, side=side, moves=_sub(moves, ctype, prefix)).rstrip("\n")
        for side, moves in _MOVES.items()
    }
    return _sub(_CP_FUNCTIONS, ctype, prefix, **slopes)


def _drive(model: Any, limits: tuple[float, float] | None, ctype: CType, p: str) -> tuple[list[str], str]:
    """Constants and C lines that turn the operator input ``x`` into the drive ``out[0]``."""
    q = model.input_warp
    if q == 0.0:
        return [], f"    out[0] = x + {p}_INPUT_OFFSET;\n"
    consts = [_define(p, "WARP_SCALE", model.warp_scale, ctype), _define(p, "WARP_Q", q, ctype)]
    consts += [_define(p, "WARP_4Q", 4.0 * q, ctype), _define(p, "WARP_UP", 1.0 + q, ctype)]
    consts += [_define(p, "WARP_DOWN", -1.0 + q, ctype), _define(p, "WARP_UP_SLOPE", 1.0 + 2.0 * q, ctype)]
    consts += [_define(p, "WARP_DOWN_SLOPE", 1.0 - 2.0 * q, ctype)]
    drive = _sub(_UNWARP, ctype, p)
    if limits is not None:  # the warp's inverse may round a clipped value a hair outside
        consts += [_define(p, "DRIVE_LOW", limits[0], ctype), _define(p, "DRIVE_HIGH", limits[1], ctype)]
        drive += f"    out[0] = {p}_min({p}_max(out[0], {p}_DRIVE_LOW), {p}_DRIVE_HIGH);\n"
    return consts, drive


def modified_pi_inverse(model: Any, limits: tuple[float, float] | None, ctype: CType, prefix: str) -> dict[str, str]:
    """Fields of the per-sample inversion of a modified PI model (drive ``limits`` or None).

    Operators of weight 0 are left out: they add exactly 0 to F and its slopes, and their state
    is never seen.  The tolerance, ``smin`` and the bracket rules are the package's (in single
    precision those a ``float`` resolves); ``ROUNDING`` bounds the rounding error of the computed
    F, ``4 (m + 2) u sum|w| (|x| + max threshold)``, used only to prove the far end of a bracket
    is not the answer without evaluating it.
    """
    p = prefix
    lo, hi = _limits(model, limits)
    scale = float(np.sum(np.abs(model.weights)) * (1.0 + np.max(model.r)))
    tol = 1e-12 * max(scale, 1e-300)
    keep = model.weights != 0.0
    m = int(np.count_nonzero(keep))
    unit = 2.0**-24 if ctype.is_float else 2.0**-53
    consts = [f"#define {p}_N_OPERATORS {m}"]
    consts += [_define(p, "INPUT_OFFSET", model.input_offset, ctype)]
    consts += [_define(p, "OUTPUT_OFFSET", model.output_offset, ctype)]
    consts += [_define(p, "SMIN", model.min_slope(), ctype)]
    consts += [_define(p, "TOL", max(tol, 5e-8 * scale) if ctype.is_float else tol, ctype)]
    consts += [_define(p, "BRACKET", 1e-6 if ctype.is_float else 1e-15, ctype)]
    consts += [_define(p, "ROUNDING", 4.0 * (m + 2) * unit * float(np.sum(np.abs(model.weights))), ctype)]
    consts += [_define(p, "R_MAX", float(max(np.max(model.r), np.max(model.ra))), ctype)]
    consts += [_limit_define(p, "LOW", lo, ctype), _limit_define(p, "HIGH", hi, ctype)]
    tables = {k: getattr(model, k)[keep] for k in ("r", "rc", "ra", "rb")}
    consts += _tables(p, ctype, **tables, w=model.weights[keep])
    warp_consts, drive = _drive(model, limits, ctype, p)
    uses_math = model.input_warp != 0.0 or not (np.isfinite(lo) and np.isfinite(hi))
    return {
        "title": "compensator of a modified Prandtl-Ishlinskii model (per-sample inversion)",
        "members": f"    {ctype.name} z[{m}];  /* outputs of the operators of nonzero weight */\n"
        f"    {ctype.name} x;  /* last operator input */\n"
        f"    {ctype.name} f;  /* F(x) at this state */",
        "constants": "\n".join(consts + warp_consts) + "\n",
        "helpers": "\n" + _cp_functions(ctype, p),
        "includes": "#include <math.h>\n" if uses_math else "",
        "init_body": "\n".join(
            _init("z", model.state.z[keep], ctype)
            + [
                f"    s->x = {literal(model.state.x, ctype)};",
                f"    {{\n        {ctype.name} scratch[{p}_N_OPERATORS];\n        s->f = {p}_value(s->x, s->z, scratch);\n    }}",
            ]
        ),
        "step_body": _sub(_CP_STEP, ctype, p, drive=drive).rstrip("\n"),
    }
