"""The modified-PI compensator's sums in single precision: error-free transformations.

In ``float`` the drive is the root of ``F(x) = target`` where the slope of F can be small
against the weights (``smin`` against ``sum |w|``), so an error in F moves the drive by
``1 / smin`` times as much.  The double code sums ``w_i v_i`` as the package does; a float sum
of that kind carries ``m`` roundings of the largest partial sum, and the tolerances a float solve
can then afford (``8 u sum|w| (|x| + max r)``) let the drive stop short of the root by up to
``1e-4`` of its range.  The single-precision code therefore computes ``F(x) - target`` itself,
without forming F:

* the target less the output offset as a pair (``TwoSum``; the offset as two floats);
* every product ``w_i v_i`` with its rounding error (``TwoProduct``: one fused multiply-add where
  the target has a fast one, ``FP_FAST_FMAF``, else Dekker's product with ``w`` split into
  halves of 12 bits at export time) plus ``w_lo v`` for the part of the double weight a float
  misses;
* the sum from ``-target`` with the rounding error of every addition kept (``TwoSum``,
  Ogita-Rump-Oishi's Sum2), so ``F(x) - target`` comes out to about one rounding of itself, not
  of F;
* the state keeps F at its input as a pair (``f``, ``f_lo``).

The solve then stops at a float's resolution of the drive, not at a rounding bound of F.  Left:
the float rounding of the operator outputs ``x - r_i`` and of the thresholds (a float model of F
differs from the double one by about ``u sum |w_i v_i|``) and of the reference itself.  The
transformations need IEEE single arithmetic evaluated as written (``FLT_EVAL_METHOD`` 0, no
``-ffast-math``); fused multiply-adds the compiler forms are harmless (the split is used only
where the target has none, and ``pr`` comes from ``fmaf`` where it has).
"""

from __future__ import annotations

from string import Template

import numpy as np

from .c_writer import CType, array

__all__ = ["LANES", "double_fragments", "float_fragments", "float_helpers", "float_pass", "split"]

#: Independent sums of the float pass: one 16-byte vector of floats (SSE, NEON).
LANES = 4

_PASS_FLOAT = """\
/* F(x) - target with F(x) = sum_i w_i CP_i(x; z_i), for x ${side} the state's input (target + target_lo
   the target), the operator outputs there (zn) and the slope of F ${beyond} x.  ${why}
   LANES independent sums, each with its rounding errors kept (TwoSum, TwoProduct), so that the
   loop vectorises; the lanes are summed the same way at the end. */
static ${T} ${p}_${name}(${T} x, const ${T} *restrict z, ${T} *restrict zn, ${T} *slope, ${T} target, ${T} target_lo)
{
    ${T} f[${p}_LANES] = {0.0f}, e[${p}_LANES] = {0.0f}, sl[${p}_LANES] = {0.0f};
    int i, k;
    for (i = 0; i < ${p}_N_OPERATORS; i += ${p}_LANES) {
        for (k = 0; k < ${p}_LANES; ++k) {
            const int j = i + k;
${branch}
            const ${T} v = ${new_output};
            const int moves = (${on_branch}) & (${moves});  /* on the branch, where it has slope 1 */
            const ${T} pr = ${p}_product(${p}_w[j], v), t = f[k] + pr;
            zn[j] = v;
            e[k] += ${p}_sum_error(f[k], pr, t) + ${p}_product_error(j, v, pr) + ${p}_w_lo[j] * v;
            f[k] = t;
            sl[k] += moves ? ${p}_w[j] : 0.0f;
        }
    }
    return ${p}_lanes(f, e, sl, slope, target, target_lo);
}
"""

_MOVE_DOC = """\
/* The pass on a move in the move's coordinate m = sg x (a fall taken as a rise of -x, so that the
   solve has one code path): returns sg ${value} at x; the outputs and the slope as the pass gives them.
   Two loops, not one on mirrored tables: the extra negations cost 10-20 % at -O3. */"""

_TARGET_FLOAT = """\
    const ${T} target = in[0] - ${p}_OUTPUT_OFFSET;
    const ${T} target_lo = ${p}_sum_error(in[0], -${p}_OUTPUT_OFFSET, target) - ${p}_OUTPUT_OFFSET_LO;
    const ${T} d0 = (target - s->f) + (target_lo - s->f_lo);  /* the target less F at x, to rounding */
"""

# a move whose drive change |d0| / slope is within RESOLUTION (|x| + R_MAX) is none (the slope on the
# side of travel: of the last move, or right after a turn TURN_SLOPE)
_MOVED_FLOAT = "${p}_abs(d0) > ${p}_RESOLUTION * (${p}_abs(x) + ${p}_R_MAX) * ((d0 > 0.0f) == s->rising ? s->slope : ${p}_TURN_SLOPE)"

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

/* sum_k f[k] + e[k] - target - target_lo with the additions' errors kept; the slope from its lanes. */
static ${T} ${p}_lanes(const ${T} *f, const ${T} *e, const ${T} *sl, ${T} *slope, ${T} target, ${T} target_lo)
{
    ${T} hi = -target, lo = -target_lo;
    int k;
    for (k = 0; k < ${p}_LANES; ++k) {
        const ${T} t = hi + f[k];
        lo += ${p}_sum_error(hi, f[k], t) + e[k];
        hi = t;
        *slope = k == 0 ? sl[0] : *slope + sl[k];
    }
    return hi + lo;
}

#ifdef FP_FAST_FMAF
/* A fused multiply-add gives the product's rounding error exactly; the product from one too, so
   that the compiler cannot fuse it into the sum that follows (that would change the sum). */
static ${T} ${p}_product(${T} w, ${T} v) { return fmaf(w, v, 0.0f); }
static ${T} ${p}_product_error(int i, ${T} v, ${T} pr) { return fmaf(${p}_w[i], v, -pr); }
#else
${halves}
static ${T} ${p}_product(${T} w, ${T} v) { return w * v; }

/* The rounding error of pr = w_i v, exactly (Dekker's TwoProduct: v split in 12-bit halves, so
   every partial product is exact). */
static ${T} ${p}_product_error(int i, ${T} v, ${T} pr)
{
    const ${T} c = 4097.0f * v, vh = c - (c - v), vl = v - vh;
    return ((${p}_wh[i] * vh - pr) + ${p}_wh[i] * vl + ${p}_wl[i] * vh) + ${p}_wl[i] * vl;
}
#endif
"""


def _fill(text: str, ctype: CType, prefix: str, **extra: str) -> str:
    return Template(text).safe_substitute(T=ctype.name, f="f" if ctype.is_float else "", p=prefix, **extra)


def float_pass(direction: dict[str, str], ctype: CType, prefix: str) -> str:
    """The float pass of one direction (``direction``: the filled fields of ``_DIRECTIONS``, whose
    operator index ``i`` becomes the lane's ``j``)."""
    fields = {k: v.replace("[i]", "[j]") for k, v in direction.items()}
    fields["branch"] = "\n".join("    " + line for line in fields["branch"].splitlines())
    return _fill(_PASS_FLOAT, ctype, prefix, **fields)


def split(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Veltkamp's split of float32 ``values`` into halves of 12 significant bits (``hi + lo`` is
    exact), computed in float32 as the C would."""
    v = np.asarray(values, dtype=np.float32)
    with np.errstate(over="ignore"):
        c = np.float32(4097.0) * v
        hi = c - (c - v)
    return hi.astype(float), (v - hi).astype(float)


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
    }


def float_helpers(weights: np.ndarray, ctype: CType, prefix: str) -> str:
    """TwoSum and TwoProduct for the float passes (``weights``: the padded float weights)."""
    hi, lo = split(weights)
    n = f"{prefix}_N_OPERATORS"
    halves = (
        f"/* w in halves of 12 significant bits (Veltkamp), for Dekker's product */\n"
        f"static const {ctype.name} {prefix}_wh[{n}] = {array(hi, ctype)};\n"
        f"static const {ctype.name} {prefix}_wl[{n}] = {array(lo, ctype)};"
    )
    return _fill(_HELPERS_FLOAT, ctype, prefix, halves=halves)
