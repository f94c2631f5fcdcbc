"""First iterate of a long move of the exported modified-PI compensator: the reversal curve.

A move that starts at a turn ``x_t`` (where the last move in the other direction ended) follows,
for every operator the move before the turn has wiped out, a curve fixed by the thresholds alone
(Masing's rule): operator ``i`` starts to move once ``|x - x_t|`` exceeds its loop width ``d_i``,

* ``d_i = r_i + rb_i`` when the turn lies on the side of 0 the move leaves (``x_t >= 0`` for a
  rise, from the descending branch at ``x_t + rb_i``; ``x_t > 0`` for a fall), and
* ``d_i = ra_i + rc_i`` otherwise,

so ``|F(x) - F(x_t)| = D(|x - x_t|)`` with ``D(d) = sum_i w_i max(d - d_i, 0)`` -- piecewise
linear and increasing, and its inverse a short table.  The compensator inverts ``D`` at the
target for the first iterate of a sample whose Newton step from the last slope would cross
operator corners; when every operator the move reaches was wiped out by the move before the
turn (and no flat stretch of the coupled plays lies on the way) this is the root itself, else a
point near it.  The Newton iteration that follows is unchanged, so the answer is the exact root
either way; only the number of passes over the operators changes
(``benchmarks/RESULTS-export.md``).

Examples
--------
>>> import numpy as np
>>> from stageid.export.c_reversal_curve import curve_table
>>> knot, value, islope = curve_table(np.array([0.0, 2.0]), np.array([1.0, 1.0]))
>>> knot.tolist(), value.tolist(), islope.tolist()
([0.0, 2.0], [0.0, 2.0], [1.0, 0.5])
"""

from __future__ import annotations

from string import Template
from typing import Any

import numpy as np

from .c_writer import CType, array, literal

__all__ = ["curve_table", "reversal_curve"]

_GUESS = """\
/* First iterate of a long move, in the move's coordinate sg x: the root of the reversal curve
   from the last turn, on which F moves once every operator the move reaches was wiped out by the
   move before the turn (a table of its inverse, d = base + delta islope on the segment of delta;
   module stageid.export.c_reversal_curve).  The knots below delta are counted by a sum, not a
   loop: the compares run in parallel (this lies on every long move's critical path). */
static ${T} ${p}_turn_guess(const ${p}_state *s, ${T} target, ${T} sg)
{
    int j = s->turns - 1, row, k;
    ${T} delta, x_t;
    const ${T} *value;
    while (j >= 2 && sg * (target - s->f_turn[(s->oldest + j - 1) & (${p}_TURNS - 1)]) > 0.0${f})
        j -= 2;  /* past the turn before: the move continues the curve of the turn before that */
    j = (s->oldest + j) & (${p}_TURNS - 1);
    x_t = s->x_turn[j];
    row = x_t < 0.0${f};
    delta = sg * (target - s->f_turn[j]);
    value = ${p}_curve_value[row];
    k = ${count};
    return sg * x_t + (${p}_curve_base[row][k] + delta * ${p}_curve_islope[row][k]);
}
"""


def curve_table(widths: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Knots, values and inverse slopes of ``D(d) = sum_i w_i max(d - d_i, 0)``.

    ``D`` is linear between knots: ``D(d) = value[k] + (d - knot[k]) / islope[k]`` for
    ``knot[k] <= d`` up to the next knot (or beyond the last); the C keeps ``base = knot -
    value islope`` instead of the knots (one multiply-add per guess).  None if ``D`` is not
    increasing after its first knot (a slope <= 0 there: no inverse table).
    """
    order = np.argsort(widths, kind="stable")
    knot, w = np.asarray(widths, dtype=float)[order], np.asarray(weights, dtype=float)[order]
    slope = np.cumsum(w)
    if np.any(slope <= 0.0):
        return None
    value = np.r_[0.0, np.cumsum(slope[:-1] * np.diff(knot))]
    return knot, value, 1.0 / slope


def _spacing(r: np.ndarray) -> float:
    gaps = np.diff(np.unique(r))
    return float(np.min(gaps)) if gaps.size else np.inf


def reversal_curve(model: Any, keep: np.ndarray, ctype: CType, prefix: str) -> tuple[list[str], str] | None:
    """Constants and the C function ``P_turn_guess`` (sg = 1 rising, -1 falling; the answer in
    the move's coordinate sg x) for the operators ``keep`` (None: no table).

    ``P_LONG_MOVE``: a Newton step from the last slope longer than the smallest
    spacing of the thresholds ``r`` is taken as one that crosses corners (the table's iterate
    is used instead).
    """
    r, rc, ra, rb = (v[keep] for v in model.coupled_play_thresholds())
    w = model.weights[keep]
    tables = [curve_table(r + rb, w), curve_table(ra + rc, w)]
    move = _spacing(r)
    if any(t is None for t in tables) or not np.isfinite(move):
        return None
    p, n = prefix, len(w)

    def rows(k: int) -> str:
        return "{\n    " + ",\n    ".join(array(t[k], ctype, indent="    ") for t in tables) + "\n}"

    tables = [(knot - value * islope, value, islope) for knot, value, islope in tables]
    consts = [f"#define {p}_N_KNOTS {n}", f"#define {p}_LONG_MOVE ({literal(move, ctype)})"]
    for k, name in enumerate(("base", "value", "islope")):
        consts.append(f"static const {ctype.name} {p}_curve_{name}[2][{p}_N_KNOTS] = {rows(k)};")
    terms = [f"(value[{j}] < delta)" for j in range(1, n)] or ["0"]
    count = " +\n        ".join(" + ".join(terms[i : i + 4]) for i in range(0, len(terms), 4))
    f = "f" if ctype.is_float else ""
    return consts, Template(_GUESS).substitute(T=ctype.name, p=p, f=f, count=count)
