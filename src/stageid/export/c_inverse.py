"""C99 streaming compensator of a modified PI model: per-sample inversion.

What the C computes is what :class:`stageid.hysteresis.Compensator` computes (see
:mod:`stageid.export.c_hysteresis`; the classical PI model's closed-form inverse is
:mod:`.c_pi_inverse`, re-exported here): ``F(x) = sum_i w_i CP_i(x; z_i)`` is piecewise linear and nondecreasing with
slope at least ``smin``; each sample solves ``F(x) = y_ref - y0`` for its exact root, as the
  package does (:mod:`stageid.hysteresis.inverse`), by its own iteration: Newton steps from the
  last input with the slope on the side of travel (kept from the last sample; at a reversal
  the slope of the zero-width operators), except that a move whose first Newton step would
  cross operator corners starts from the root of the reversal curve of the last turn
  (:mod:`stageid.export.c_reversal_curve`: the root itself when the move before the turn wiped
  out every operator the move reaches); regula falsi / bisection inside the bracket as
  safeguards, until ``|F(x) - target|`` is within the rounding error of F.  One pass over the
  operators per iterate gives F, the slope and the new operator outputs, using only the branch
  of travel (the outputs of the last sample lie between the branches); the solve works in the
  move's coordinate ``sg x`` (a fall as the rise of ``-x``: exact negations), so it has one code
  path for both directions.  Both sides land on the exact root, so they agree to rounding; the
  number of passes per sample depends on how many operator corners the reference crosses and
  how far the first iterate lands from the root (``benchmarks/RESULTS-export.md``).

In single precision the passes return ``F(x) - target`` by compensated sums
(:mod:`stageid.export.c_float_sums`), and the stopping bound and the bracket width are those a
``float`` resolves of the drive; a drive at a limit is that limit rounded to float.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from . import c_float_sums as fs
from .c_pi_inverse import operator_limits, pi_inverse_fields
from .c_reversal_curve import reversal_curve
from .c_writer import CType, const_tables, define, fill, init_lines, limit_define, literal

__all__ = ["pi_inverse_fields", "modified_pi_inverse"]

_CP_PASS = """\
/* F(x) = sum_i w_i CP_i(x; z_i) for x ${side} the state's input, the operator outputs there (zn)
   and the slope of F ${beyond} x.  ${why} */
static ${T} ${p}_${name}(${T} x, const ${T} *restrict z, ${T} *restrict zn, ${T} *slope)
{
    ${T} f = 0.0${f}, s = 0.0${f};
    int i;
    for (i = 0; i < ${p}_N_OPERATORS; ++i) {
${branch}
        const ${T} v = ${new_output};
        const int moves = (${on_branch}) & (${moves});  /* on the branch, where it has slope 1 */
        zn[i] = v;
        f += ${p}_w[i] * v;
        s += moves ? ${p}_w[i] : 0.0${f};  /* in this form gcc vectorises the loop (-O2 and -O3) */
    }
    *slope = s;
    return f;
}
"""

# x moving up: the ascending branch up(x) = max(x - r, min(x - rc, 0)) (slope 1 right of x except
# on its flat stretch rc <= x < r) takes an operator along once it reaches the output z.  Moving
# down: the descending branch down(x) = min(x + ra, max(x + rb, 0)) (slope 1 left of x except on
# -ra < x <= -rb).  The outputs of the last sample lie between the branches, so only the branch
# of travel can move them; a state stored inconsistent with its x (CONSISTENT 0) also takes the
# other branch into the output, as the package's first sample does.
_DIRECTIONS = {
    "rise": {
        "side": "at or right of",
        "beyond": "right of",
        "branch": """\
        const ${T} a = x - ${p}_r[i], b = x - ${p}_rc[i];
        const ${T} up = ${p}_max(a, ${p}_min(b, 0.0${f}));""",
        "moves": "(a >= 0.0${f}) | (b < 0.0${f})",
        "on_branch": "up >= v",
        "lean": "${p}_max(up, z[i])",
        "general": "${p}_max(up, ${p}_min(${p}_min(x + ${p}_ra[i], ${p}_max(x + ${p}_rb[i], 0.0${f})), z[i]))",
    },
    "fall": {
        "side": "at or left of",
        "beyond": "left of",
        "branch": """\
        const ${T} c = x + ${p}_ra[i], d = x + ${p}_rb[i];
        const ${T} down = ${p}_min(c, ${p}_max(d, 0.0${f}));""",
        "moves": "(c <= 0.0${f}) | (d > 0.0${f})",
        "on_branch": "down <= v",
        "lean": "${p}_min(down, z[i])",
        "general": "${p}_min(down, ${p}_max(${p}_max(x - ${p}_r[i], ${p}_min(x - ${p}_rc[i], 0.0${f})), z[i]))",
    },
}

_MOVE = """\
${move_doc}
static ${T} ${p}_move(${T} sg, ${T} m, const ${T} *restrict z, ${T} *restrict zn, ${T} *slope${shift_params}${err_param})
{
    return sg > 0.0${f} ? ${p}_rise(m, z, zn, slope${shift_args}${err_arg}) : -${p}_fall(-m, z, zn, slope${shift_args}${err_arg});
}
"""

_CP_SOLVE = """\
static ${T} ${p}_abs(${T} v) { return v < 0.0${f} ? -v : v; }

/* The rounding error of a computed F at x: the package's bound (residual_bound). */
static ${T} ${p}_error(${T} x) { return ${p}_ROUNDING * (${p}_abs(x) + ${p}_R_MAX); }

/* F, its slope on the side of travel (rising: right of x) and the operator outputs at an iterate. */
typedef struct {
    ${T} f, slope${err_member}, z[${p}_N_OPERATORS];
    int rising;
} ${p}_point;

/* The pass at m = sg x into *at (${value} there, not sg ${value}); returns sg ${value}. */
static ${T} ${p}_pass(${T} sg, ${T} m, const ${T} *z, ${p}_point *at${shift_params})
{
    const ${T} fm = ${p}_move(sg, m, z, at->z, &at->slope${shift_args}${err_at});
    at->f = sg * fm;
    at->rising = sg > 0.0${f};
    return fm;
}

/* x with F(x) = target, from the state's x where F = s->f and `slope` is the slope of F on the
   side of travel; worked in the move's coordinate m = sg x (negation is exact, so a fall gives
   the same numbers as its mirror).  F is piecewise linear and rises at least SMIN per unit of m,
   so the root lies in [m0, m0 + (goal - f0) / SMIN], cut at the drive limit.  Newton steps land
   on the root once they start on its piece; an iterate outside the bracket is replaced by regula
   falsi against the far end (computed then, and the answer if F there does not reach the
   target: a drive limit) or by bisection.  The solve stops when |F - target| is within the
   rounding error of F, as the package does: both return the exact root to rounding.  Returns
   where the answer's F, slope and operator outputs are: 0 nowhere (x unchanged), 1 in *at (the
   last iterate), 2 in *far_at (the far end). */
static int ${p}_solve(const ${p}_state *s, ${T} target, ${T} slope, ${T} *x_out, ${p}_point *at, ${p}_point *far_at${solve_params})
{
    const ${T} sg = ${rising} ? 1.0${f} : -1.0${f};
    const ${T} goal = ${goal}, m0 = sg * s->x, edge = sg > 0.0${f} ? ${p}_HIGH : -${p}_LOW;
    ${T} near = m0, fnear = ${fnear}, far = m0 + (goal - fnear) / ${p}_SMIN, ffar = 0.0${f};
    ${T} mc = m0, fc = fnear, sc = slope, last = 0.0${f};
    int known = 0, it;
    if (far > edge) far = edge;
    *x_out = s->x;
    if (!(far > m0)) {  /* x at or beyond the limit: the answer is the limit */
${at_edge}        const ${T} back = far < m0 ? -sg : sg;  /* (reached backwards if x lies beyond it) */
        ${p}_pass(back, back * sg * far, s->z, far_at${shift_args});
        *x_out = sg * far;
        return 2;
    }
    for (it = 0; it < 200; ++it) {
        ${T} xn = sc > 0.0${f} ? mc + (goal - fc) / sc : 0.5${f} * (near + far);
${guess}        if (xn == mc) return it > 0;  /* the step is below the resolution of x: mc is the root */
        if (it > 0 && ${p}_abs(fc - goal) > 0.5${f} * last) {
            /* Newton did not halve the residual (a slope off the root's piece: the first sample
               from a stored state that is not consistent, or a corner): bisect the bracket */
            xn = 0.5${f} * (near + far);
        } else if (!(xn > near && xn < far)) {
            if (!known) {
                known = 1;
                ffar = ${p}_pass(sg, far, s->z, far_at${shift_args});
                if (ffar <= goal) {  /* the root is at or past the far end */
                    *x_out = sg * far;
                    return 2;
                }
            }
            if (ffar != fnear) xn = near + (goal - fnear) * (far - near) / (ffar - fnear);
            if (!(xn > near && xn < far)) xn = 0.5${f} * (near + far);
        }
        last = ${p}_abs(fc - goal);
        fc = ${p}_pass(sg, xn, s->z, at${shift_args});
        *x_out = sg * xn;
        mc = xn;
        sc = at->slope;
        if (${p}_abs(fc - goal) <= ${stop}) return 1;
        if (fc < goal) {
            near = xn;
            fnear = fc;
        } else {
            far = xn;
            ffar = fc;
            known = 1;
        }
        if (${p}_abs(far - near) <= ${p}_BRACKET * (1.0${f} + ${p}_abs(near) + ${p}_abs(far))) return 1;
    }
    return 1;
}
"""

_CP_STEP = """\
${target}    ${p}_point at, far;
    ${T} x = s->x;
    int found = 0;  /* 0: x unchanged, 1: x is the last iterate (at), 2: the far end (far) */
    if (${moved}) {
        const int rising = ${rising};
        if (rising != s->rising) {  /* reversal: right after a move only the operators of zero */
            s->slope = ${p}_TURN_SLOPE;  /* loop width move the other way (a first guess) */
            s->rising = rising;
            if (s->turns == ${p}_TURNS) {  /* full: forget the two oldest turns (a ring) */
                s->oldest = (s->oldest + 2) & (${p}_TURNS - 1);
                s->turns -= 2;
            }
            s->x_turn[(s->oldest + s->turns) & (${p}_TURNS - 1)] = x;
            s->f_turn[(s->oldest + s->turns) & (${p}_TURNS - 1)] = s->f;
            ++s->turns;
        }
        found = ${p}_solve(s, target, s->slope, &x, &at, &far${solve_args});
    }
    if (!found && s->fresh) {  /* a stored state need not be the operators' outputs at x */
        ${p}_pass(1.0${f}, x, s->z, &at${shift_args});
        s->rising = 1;
        found = 1;
    }
    if (found) {
        const ${p}_point *p = found == 1 ? &at : &far;
        int i;
        for (i = 0; i < ${p}_N_OPERATORS; ++i) s->z[i] = p->z[i];
${store_f}
        s->slope = p->slope;
        s->rising = p->rising;
        s->x = x;
        while (s->turns >= 3) {  /* past the turn before the last: both wiped out (return-point memory) */
            const ${T} before = s->f_turn[(s->oldest + s->turns - 2) & (${p}_TURNS - 1)];
            if (s->rising ? s->f <= before : s->f >= before) break;
            s->turns -= 2;
        }
    }
    s->fresh = 0;
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


FLOAT_ROUNDING = 0.5  # float: solve and stop to this many u (|x| + R_MAX) in x (a few ulps)
TURNS = 16  # turns the modified-PI compensator keeps for its first iterates (return-point memory)
PAD = 2  # operators per 16-byte vector of doubles (SSE2 / NEON, the baseline targets)


_LONG_MOVE = """\
        if (it == 0 && xn - m0 > ${p}_LONG_MOVE) {  /* a long move: from the reversal curve */
            const ${T} g = ${p}_turn_guess(s, target, sg);
            if (g > near && g < far) xn = g;
        }
"""


def _cp_functions(ctype: CType, prefix: str, consistent: bool, turn_guess: str) -> str:
    """The two passes (rise, fall: one template), the reversal curve's first iterate (C text, or ""
    for none) and the solve; in float with the sums of :mod:`.c_float_sums`."""
    frag = (fs.float_fragments if ctype.is_float else fs.double_fragments)(ctype, prefix)
    passes = []
    for name, d in _DIRECTIONS.items():
        why = (
            "The state is the operators' outputs at its x (CONSISTENT 1): F takes only the branch of travel."
            if consistent
            else "The stored state need not be the outputs at x: both branches enter, as in eq. 3."
        )
        fields = {**d, "new_output": d["lean" if consistent else "general"], "name": name, "why": why}
        filled = {k: fill(v, ctype, prefix) for k, v in fields.items() if k not in ("lean", "general")}
        if ctype.is_float:
            passes.append(fs.float_pass(filled, ctype, prefix))
        else:
            passes.append(fill(_CP_PASS, ctype, prefix, **filled))
    move = "\n".join(passes) + "\n" + fill(_MOVE, ctype, prefix, **frag)
    guess = fill(_LONG_MOVE, ctype, prefix) if turn_guess else ""
    return move + "\n" + turn_guess + "\n" + fill(_CP_SOLVE, ctype, prefix, guess=guess, **frag)


def _consistent(model: Any, keep: np.ndarray) -> bool:
    """Whether the stored outputs are the coupled plays' outputs at the stored x (eq. 3 leaves
    them unchanged), as every state a model reaches by running is."""
    r, rc, ra, rb = (v[keep] for v in model.coupled_play_thresholds())
    x, z = float(model.state.x), model.state.z[keep]
    up = np.maximum(x - r, np.minimum(x - rc, 0.0))
    down = np.minimum(x + ra, np.maximum(x + rb, 0.0))
    return bool(np.all(np.maximum(up, np.minimum(down, z)) == z))


def _drive(model: Any, limits: tuple[float, float] | None, ctype: CType, p: str) -> tuple[list[str], str]:
    """Constants and C lines that turn the operator input ``x`` into the drive ``out[0]``."""
    q = model.input_warp
    if q == 0.0:
        snap_consts, snap = fs.pinned(limits, ctype, p)
        return snap_consts, f"    out[0] = x + {p}_INPUT_OFFSET;\n" + snap
    consts = [define(p, "WARP_SCALE", model.warp_scale, ctype), define(p, "WARP_Q", q, ctype)]
    consts += [define(p, "WARP_4Q", 4.0 * q, ctype), define(p, "WARP_UP", 1.0 + q, ctype)]
    consts += [define(p, "WARP_DOWN", -1.0 + q, ctype), define(p, "WARP_UP_SLOPE", 1.0 + 2.0 * q, ctype)]
    consts += [define(p, "WARP_DOWN_SLOPE", 1.0 - 2.0 * q, ctype)]
    drive = fill(_UNWARP, ctype, p)
    if limits is not None:  # the warp's inverse may round a clipped value a hair outside
        consts += [define(p, "DRIVE_LOW", limits[0], ctype), define(p, "DRIVE_HIGH", limits[1], ctype)]
        drive += f"    out[0] = {p}_min({p}_max(out[0], {p}_DRIVE_LOW), {p}_DRIVE_HIGH);\n"
        # as the package's compensator: an input clipped at an operator-side limit drives the limit
        # itself, in double as in float (the unwarp would leave it a rounding error inside)
        drive += f"    if (x >= {p}_HIGH) out[0] = {p}_DRIVE_HIGH;\n    if (x <= {p}_LOW) out[0] = {p}_DRIVE_LOW;\n"
    return consts, drive


def _turn_slope(model: Any) -> float:
    """The slope of F right after a reversal: the operators whose branches coincide (zero loop
    width: all thresholds 0) move at once, the others only once x has crossed their loop.  A
    guess for the first Newton step (exact unless some operator sits where its branches meet);
    at least ``min_slope()``."""
    r, rc, ra, rb = model.coupled_play_thresholds()
    zero_width = (r == 0.0) & (rc == 0.0) & (ra == 0.0) & (rb == 0.0)
    return max(float(np.sum(model.weights[zero_width])), model.min_slope())


def _init_body(model: Any, z: np.ndarray, consistent: bool, ctype: CType, p: str) -> str:
    """The init body: the operator outputs ``z``, the input, F there and the first turn."""
    return "\n".join(
        init_lines("z", z, ctype)
        + [
            f"    s->x = {literal(model.state.x, ctype)};",
            f"    s->fresh = {int(not consistent)};",
            "    s->rising = 1;",
            f"    {{\n        {ctype.name} scratch[{p}_N_OPERATORS];\n" + fs.init_f(ctype, p) + "    }",
            "    s->x_turn[0] = s->x;",
            "    s->f_turn[0] = s->f;",
            "    s->turns = 1;",
            "    s->oldest = 0;",
        ]
    )


def modified_pi_inverse(model: Any, limits: tuple[float, float] | None, ctype: CType, prefix: str) -> dict[str, str]:
    """Fields of the per-sample inversion of a modified PI model (drive ``limits`` or None).

    Operators of weight 0 are left out: they add exactly 0 to F and its slopes, and their state
    is never seen; weight-0 operators with zero thresholds pad the rest to a multiple of
    :data:`PAD`, so that gcc vectorises the passes also at -O2 (its cheap cost model there takes
    only loops without a remainder).  ``ROUNDING`` and ``R_MAX`` are the package's rounding bound of F
    (:func:`stageid.hysteresis.models.common.residual_bound`).  In single precision the passes
    return ``F - target`` to about its own rounding (:mod:`.c_float_sums`), so the bound is
    ``FLOAT_ROUNDING u SMIN (|x| + R_MAX)`` or the products' roundings of the pass: the drive is
    solved to a float's resolution, not to a rounding bound of F (which would be ``1 / SMIN``
    times wider in the drive).
    """
    from ..hysteresis.models.common import residual_bound

    p = prefix
    lo, hi = operator_limits(model, limits)
    keep = model.weights != 0.0
    m = int(np.count_nonzero(keep))
    block = fs.LANES if ctype.is_float else PAD  # operators per vector of the passes
    padded = -(-m // block) * block
    err_w, err_r = residual_bound(model)
    if ctype.is_float:  # F - target is exact to rounding: stop at what a float resolves of the drive
        err_w = FLOAT_ROUNDING * 2.0**-24 * model.min_slope()
    consistent = _consistent(model, keep)
    frag = (fs.float_fragments if ctype.is_float else fs.double_fragments)(ctype, p)

    def pad(v: np.ndarray) -> np.ndarray:  # weight-0 operators with zero thresholds: add exact zeros
        return np.r_[v[keep], np.zeros(padded - m)]

    consts = [f"#define {p}_N_OPERATORS {padded}"]
    consts += [define(p, "INPUT_OFFSET", model.input_offset, ctype)]
    consts += [define(p, "OUTPUT_OFFSET", model.output_offset, ctype)]
    consts += [define(p, "SMIN", model.min_slope(), ctype)]
    consts += [define(p, "TURN_SLOPE", _turn_slope(model), ctype)]
    consts += [define(p, "BRACKET", 2.0**-22 if ctype.is_float else 1e-15, ctype)]
    consts += [define(p, "ROUNDING", err_w, ctype), define(p, "R_MAX", err_r, ctype)]
    consts += [limit_define(p, "LOW", lo, ctype), limit_define(p, "HIGH", hi, ctype)]
    consts += [f"#define {p}_CONSISTENT {int(consistent)}  /* the stored outputs are those at the stored x */"]
    consts += [f"#define {p}_TURNS {TURNS}  /* turns kept for the reversal curves (return-point memory) */"]
    T = ctype.name
    r, rc, ra, rb = (pad(v) for v in model.coupled_play_thresholds())
    consts += const_tables(p, ctype, r=r, rc=rc, ra=ra, rb=rb, w=pad(model.weights))
    helpers = ""
    if ctype.is_float:
        consts += fs.float_constants(pad(model.weights), model.output_offset, FLOAT_ROUNDING, ctype, p)
        helpers = "\n" + fs.float_helpers(ctype, p)
    curve = reversal_curve(model, keep, ctype, p)
    consts += curve[0] if curve else []
    warp_consts, drive = _drive(model, limits, ctype, p)
    uses_math = model.input_warp != 0.0 or not (np.isfinite(lo) and np.isfinite(hi))
    return {
        "title": "compensator of a modified Prandtl-Ishlinskii model (per-sample inversion)",
        "members": f"    {T} z[{padded}];  /* outputs of the operators of nonzero weight (then padding) */\n"
        f"    {T} x, f, slope;  /* last operator input, F there, its slope on the side of the last move */\n"
        + (f"    {T} f_lo;  /* the rest of F (F = f + f_lo) */\n" if ctype.is_float else "")
        + f"    {T} x_turn[{TURNS}], f_turn[{TURNS}];  /* the turns still in memory (x and F), the last on top */\n"
        "    int turns, oldest;  /* how many, and where the oldest is (a ring of TURNS) */\n"
        "    int rising, fresh;  /* side of the last move; 1 until the first sample if not CONSISTENT */",
        "constants": "\n".join(consts + warp_consts) + "\n",
        "helpers": helpers + "\n" + _cp_functions(ctype, p, consistent, curve[1] if curve else ""),
        "includes": "#include <math.h>\n" if uses_math else "",
        "init_body": _init_body(model, pad(model.state.z), consistent, ctype, p),
        "step_body": fill(_CP_STEP, ctype, p, drive=drive, **frag).rstrip("\n"),
    }
