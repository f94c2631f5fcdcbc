"""The modified-PI compensator's sums in single precision: compensated, in float.

In ``float`` the drive is the root of ``F(x) = target``, and the slope of F can be small against
the weights (``smin`` against ``sum |w|``): an error in F moves the drive ``1 / slope`` times as
far.  A plain float sum of ``w_i v_i`` carries the roundings of its partial sums (up to ``m u
sum |w_i v_i|``), so the float solve could only stop at ``8 u sum|w| (|x| + max r)`` in F, and
the drive stopped short of the root (or did not move at all at the turn of a slow reference) by
up to a few 1e-5 of its range.  The single-precision code therefore computes ``F(x) - target``
itself, never forming F (Ogita, Rump and Oishi's Sum2, SIAM J. Sci. Comput. 26, 2005):

* the target less the output offset as a pair (Knuth's ``TwoSum``; the offset as two floats);
* the terms ``w_i v_i`` summed in ``LANES`` independent sums that keep the rounding error of
  every addition (``TwoSum``), the lanes and ``-target`` last in the same way; ``w_lo v`` adds
  the part of the double weight its float misses.  Each lane is a recurrence of distance
  ``LANES`` over arrays in the operator loop (entry ``j + LANES`` the lane's sum up to operator
  ``j``): gcc vectorises it at -O2 and -O3 without reordering a sum, where lane arrays reduced
  in a nested loop were outer-loop vectorised or unrolled to scalar code at -O3;
* the state keeps F at its input as a pair (``f``, ``f_lo``).

``F(x) - target`` then carries about one rounding of itself plus the roundings of the terms
``u / 2 |w_i v_i|``, which are the size of the roundings of the operator outputs ``v_i = x - r_i``
themselves (so exact products, ``TwoProduct``, were tried and left out: the same errors within
noise; figures in ``benchmarks/RESULTS-export.md``).  The solve stops where ``|F - target|`` is
within ``RESOLUTION SMIN (|x| + max r)`` (half an ulp of ``|x| + max r`` in the drive) or within
the products' roundings ``u / 2 sum |w_i v_i|`` (the pass sums them too): a Newton step from
there only chases those roundings, at the cost of a second pass.  The skip test uses the slope
on the side of travel.  The
transformations need IEEE single arithmetic evaluated as written (``FLT_EVAL_METHOD`` 0, no
``-ffast-math``); a fused multiply-add the compiler forms from a product and the sum after it
leaves the result within the tolerance (tested with ``-ffp-contract=fast -march=native``).
"""

from __future__ import annotations

from string import Template

import numpy as np

from .c_writer import CType, const_tables, define, limit_define

__all__ = [
    "LANES",
    "double_fragments",
    "float_fragments",
    "float_helpers",
    "float_pass",
    "float_constants",
    "init_f",
    "pinned",
]

#: Independent sums of the float pass: one 16-byte vector of floats (SSE, NEON).
LANES = 4

_PASS_FLOAT = """\
/* F(x) - target with F(x) = sum_i w_i CP_i(x; z_i), for x ${side} the state's input (target + target_lo
   the target), the operator outputs there (zn), the slope of F ${beyond} x and the size of the
   terms' roundings (err).  ${why}
   Every sum in LANES lanes, operator j in lane j % LANES: entry j + LANES of each array is the lane's
   sum up to operator j, a recurrence of distance LANES that vectorises (gcc -O2 and -O3) without
   reordering a sum; the terms' sum keeps the rounding error of every addition (TwoSum) in E. */
static ${T} ${p}_${name}(${T} x, const ${T} *restrict z, ${T} *restrict zn, ${T} *slope, ${T} target, ${T} target_lo, ${T} *err)
{
    ${T} F[${p}_N_OPERATORS + ${p}_LANES], E[${p}_N_OPERATORS + ${p}_LANES];
    ${T} S[${p}_N_OPERATORS + ${p}_LANES], A[${p}_N_OPERATORS + ${p}_LANES];
    const int n = ${p}_N_OPERATORS;
    int j;
    for (j = 0; j < ${p}_LANES; ++j) F[j] = E[j] = S[j] = A[j] = 0.0f;  /* the lanes start at 0 (an initialiser would clear all: rep stos at -O2) */
    for (j = 0; j < ${p}_N_OPERATORS; ++j) {
${branch}
        const ${T} v = ${new_output};
        const int moves = (${on_branch}) & (${moves});  /* on the branch, where it has slope 1 */
        const ${T} pr = ${p}_w[j] * v, t = F[j] + pr;
        zn[j] = v;
        /* the addition's error, and the part of the double weight its float misses */
        E[j + ${p}_LANES] = E[j] + ${p}_sum_error(F[j], pr, t) + ${p}_w_lo[j] * v;
        F[j + ${p}_LANES] = t;
        S[j + ${p}_LANES] = S[j] + (moves ? ${p}_w[j] : 0.0f);
        A[j + ${p}_LANES] = A[j] + (pr < 0.0f ? -pr : pr);  /* sum |w_i v_i| */
    }
    *slope = (S[n] + S[n + 1]) + (S[n + 2] + S[n + 3]);  /* the LANES (4) lanes */
    *err = ${p}_TERMS_ROUNDING * ((A[n] + A[n + 1]) + (A[n + 2] + A[n + 3]));
    return ${p}_lanes(F + n, E + n, target, target_lo);
}
"""

_MOVE_DOC = """\
/* The pass on a move in the move's coordinate m = sg x (a fall taken as a rise of -x, so that the
   solve has one code path): returns sg ${value} at x; the outputs and the slope as the pass gives them.
   Two loops, not one on mirrored tables: the extra negations slow -O3 (RESULTS-export.md). */"""

_TARGET_FLOAT = """\
    const ${T} target = in[0] - ${p}_OUTPUT_OFFSET;
    const ${T} target_lo = ${p}_sum_error(in[0], -${p}_OUTPUT_OFFSET, target) - ${p}_OUTPUT_OFFSET_LO;
    const ${T} d0 = (target - s->f) + (target_lo - s->f_lo);  /* the target less F at x, to rounding */
"""

# a move whose drive change |d0| / slope is within RESOLUTION (|x| + R_MAX) is none (the slope on the
# side of travel: of the last move, or right after a turn TURN_SLOPE)
_MOVED_FLOAT = "${p}_abs(d0) > ${p}_RESOLUTION * (${p}_abs(x) + ${p}_R_MAX) * ((d0 > 0.0f) == s->rising ? s->slope : ${p}_TURN_SLOPE)"

# the solve also stops where F - target is within the products' roundings (u / 2 sum |w_i v_i|, the
# pass's err): a Newton step from there only chases them (u / 2, not u: with u the ill-conditioned
# walks lost accuracy, benchmarks/RESULTS-export.md)
_STOP_FLOAT = "${p}_max(${p}_error(xn), at->err)"

_STORE_FLOAT = """\
        s->f = target + p->f;  /* F at x as a pair: the target plus the answer's F - target */
        s->f_lo = ${p}_sum_error(target, p->f, s->f) + target_lo;"""

_HELPERS_FLOAT = """\
/* The rounding error of t = a + b, exactly (Knuth's TwoSum). */
static ${T} ${p}_sum_error(${T} a, ${T} b, ${T} t)
{
    const ${T} bb = t - a;
    return (a - (t - bb)) + (b - bb);
}

/* sum_k f[k] + e[k] - target - target_lo with the additions' errors kept. */
static ${T} ${p}_lanes(const ${T} *f, const ${T} *e, ${T} target, ${T} target_lo)
{
    ${T} hi = -target, lo = -target_lo;
    int k;
    for (k = 0; k < ${p}_LANES; ++k) {
        const ${T} t = hi + f[k];
        lo += ${p}_sum_error(hi, f[k], t) + e[k];
        hi = t;
    }
    return hi + lo;
}"""


def _fill(text: str, ctype: CType, prefix: str, **extra: str) -> str:
    return Template(text).safe_substitute(T=ctype.name, f="f" if ctype.is_float else "", p=prefix, **extra)


def float_pass(direction: dict[str, str], ctype: CType, prefix: str) -> str:
    """The float pass of one direction (``direction``: the filled fields of ``_DIRECTIONS``)."""
    fields = {k: v.replace("[i]", "[j]") for k, v in direction.items()}  # (j: i names no operator here)
    return _fill(_PASS_FLOAT, ctype, prefix, **fields)


def double_fragments(ctype: CType, prefix: str) -> dict[str, str]:
    """The placeholders of the double code: F summed in operator order, as the package does."""
    return {
        "move_doc": _fill(_MOVE_DOC, ctype, prefix, value="F"),
        "value": "F",
        "shift_params": "",
        "shift_args": "",
        "solve_params": "",
        "solve_args": "",
        "rising": "target > s->f",
        "goal": "sg * target",
        "fnear": "sg * s->f",
        "moved": _fill("${p}_abs(target - s->f) > ${p}_error(x)", ctype, prefix),
        "at_edge": "",
        "target": _fill("    const ${T} target = in[0] - ${p}_OUTPUT_OFFSET;\n", ctype, prefix),
        "store_f": "        s->f = p->f;",
        "err_param": "",
        "err_arg": "",
        "err_member": "",
        "err_at": "",
        "stop": _fill("${p}_error(xn)", ctype, prefix),
    }


def float_fragments(ctype: CType, prefix: str) -> dict[str, str]:
    """The placeholders of the float code: F - target by error-free transformations."""
    t = ctype.name
    return {
        "move_doc": _fill(_MOVE_DOC, ctype, prefix, value="(F - target)"),
        "value": "(F - target)",
        "shift_params": f", {t} target, {t} target_lo",
        "shift_args": ", target, target_lo",
        "solve_params": f", {t} target_lo, {t} d0",
        "solve_args": ", target_lo, d0",
        "rising": "d0 > 0.0f",
        "goal": "0.0f",
        "fnear": "-sg * d0",
        "moved": _fill(_MOVED_FLOAT, ctype, prefix),
        "at_edge": _fill(
            "        if (far == m0 && !s->fresh) return 0;  /* already there: nothing moves */\n", ctype, prefix
        ),
        "target": _fill(_TARGET_FLOAT, ctype, prefix),
        "store_f": _fill(_STORE_FLOAT, ctype, prefix),
        "err_param": f", {t} *err",
        "err_arg": ", err",
        "err_member": ", err",
        "err_at": ", &at->err",
        "stop": _fill(_STOP_FLOAT, ctype, prefix),
    }


def float_helpers(ctype: CType, prefix: str) -> str:
    """TwoSum and the sum of the lanes, for the float passes."""
    return _fill(_HELPERS_FLOAT, ctype, prefix)


def float_constants(weights: np.ndarray, output_offset: float, rounding: float, ctype: CType, p: str) -> list[str]:
    """The part of each (padded) weight and of the output offset a float misses, ``RESOLUTION``
    (``rounding`` units of ``2**-24``), ``TERMS_ROUNDING`` (``u / 2``) and ``LANES``."""
    w32 = np.asarray(weights, dtype=float).astype(np.float32).astype(float)
    off = output_offset - float(np.float32(output_offset))
    return [
        *const_tables(p, ctype, w_lo=np.asarray(weights, dtype=float) - w32),
        define(p, "OUTPUT_OFFSET_LO", off, ctype),
        define(p, "RESOLUTION", rounding * 2.0**-24, ctype),
        define(p, "TERMS_ROUNDING", 2.0**-25, ctype),
        f"#define {p}_LANES {LANES}  /* independent sums of a pass (one vector of floats) */",
    ]


def init_f(ctype: CType, p: str) -> str:
    """C lines that set F at the stored input (in float as a pair: F, then F less its float)."""
    if not ctype.is_float:
        return f"        s->f = {p}_move(1.0, s->x, s->z, scratch, &s->slope);\n"
    return (
        f"        {ctype.name} err;\n"
        f"        s->f = {p}_move(1.0f, s->x, s->z, scratch, &s->slope, 0.0f, 0.0f, &err);\n"
        f"        s->f_lo = {p}_move(1.0f, s->x, s->z, scratch, &s->slope, s->f, 0.0f, &err);\n"
    )


def pinned(limits: tuple[float, float] | None, ctype: CType, p: str, defined: bool = False) -> tuple[list[str], str]:
    """Float only: constants (unless ``defined``) and the C lines that make a drive at a limit that
    limit rounded to float (``x + INPUT_OFFSET`` at the operator input's limit is two roundings
    off it).  A snap, not a clamp: a stored input beyond a limit moves back as the package's does."""
    if limits is None or not ctype.is_float:
        return [], ""
    consts = [limit_define(p, "DRIVE_LOW", limits[0], ctype), limit_define(p, "DRIVE_HIGH", limits[1], ctype)]
    snap = f"    if (x == {p}_LOW) out[0] = {p}_DRIVE_LOW;\n    if (x == {p}_HIGH) out[0] = {p}_DRIVE_HIGH;\n"
    return ([] if defined else consts), snap
