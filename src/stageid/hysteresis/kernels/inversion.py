"""Per-sample inversion of PI and modified-PI models (eq. 5) and the inverse-PI play stream.

:func:`cp_invert_step` solves ``F(x) = target`` for the piecewise-linear, nondecreasing
``F(x) = sum_i w_i CP_i(x; z_i)`` of the current sample; the tests check it by the round trip
``model(inverse(y)) = y`` (``tests/test_hysteresis_inverse.py``) against the plain-Python
models.  Exact arithmetic (no fast-math): the bracket logic compares values.
"""

from __future__ import annotations

import numba
import numpy as np

from .loops import jit_exact

#: Steps of :func:`cp_invert_step`, inlined into it in numba's IR: the per-sample code stays one piece
_step_part = numba.njit(cache=True, nogil=True, inline="always")


@jit_exact
def cp_eval(x, P, z):  # pragma: no cover - compiled
    """F(x) = sum w_i CP_i(x; z_i) and its slope on the piece to the right (+) and left (-)."""
    m = P.shape[1]
    f = 0.0
    sp = 0.0
    sm = 0.0
    for i in range(m):
        r, rc, ra, rb, w = P[0, i], P[1, i], P[2, i], P[3, i], P[4, i]
        a = x - r
        b = x - rc
        up = a if a > min(b, 0.0) else min(b, 0.0)
        # right/left slopes of gamma_up: 1 where x-r dominates or x-rc < 0 dominates
        up_sp = 1.0 if (a >= 0.0 or b < 0.0) else 0.0
        up_sm = 1.0 if (a > 0.0 or b <= 0.0) else 0.0
        c = x + ra
        d = x + rb
        down = c if c < max(d, 0.0) else max(d, 0.0)
        dn_sp = 1.0 if (c < 0.0 or d >= 0.0) else 0.0
        dn_sm = 1.0 if (c <= 0.0 or d > 0.0) else 0.0
        zi = z[i]
        if down < zi:
            inner = down
            in_sp = dn_sp
            in_sm = dn_sm
        elif down > zi:
            inner = zi
            in_sp = 0.0
            in_sm = 0.0
        else:
            inner = zi
            in_sp = 0.0
            in_sm = dn_sm
        if up > inner:
            v = up
            v_sp = up_sp
            v_sm = up_sm
        elif up < inner:
            v = inner
            v_sp = in_sp
            v_sm = in_sm
        else:
            v = up
            v_sp = max(up_sp, in_sp)
            v_sm = min(up_sm, in_sm)
        f += w * v
        sp += w * v_sp
        sm += w * v_sm
    return f, sp, sm


@jit_exact
def cp_invert_step(P, z, x_prev, target, lo, hi, smin, err_w, err_r):  # pragma: no cover - compiled
    """One sample of the monotone inversion: the input x with F(x) = target, state updated in place.

    ``P`` rows are r, rc, ra, rb, w; ``z`` the operator outputs (updated); ``lo``/``hi`` drive
    limits; ``smin`` a guaranteed lower bound of the slope of F (> 0).  Returns x.  F is
    piecewise linear and nondecreasing: safeguarded Newton steps inside a bracket land on the
    piece that holds the root in a few iterations, and the Newton step from that piece lands on
    the root itself.  The iteration stops there: when ``|F(x) - target|`` is within the rounding
    error of the computed F, ``err_w (|x| + err_r)`` (see ``models.common.residual_bound``), or a
    step no longer moves x.
    """
    f, sp, sm = cp_eval(x_prev, P, z)
    x = x_prev
    if abs(f - target) <= err_w * (abs(x_prev) + err_r):
        x = x_prev
    else:
        if target > f:
            a = x_prev
            fa = f
            b = x_prev + (target - f) / smin
            if b > hi:
                b = hi
            fb, _s1, _s2 = cp_eval(b, P, z)
            if fb <= target:
                x = b
                fa = fb
                a = b
        else:
            b = x_prev
            fb = f
            a = x_prev - (f - target) / smin
            if a < lo:
                a = lo
            fa, _s1, _s2 = cp_eval(a, P, z)
            if fa >= target:
                x = a
                fb = fa
                b = a
        if a < b:
            # Newton from the side we came from, inside [a, b]
            if target > f:
                xc, fc, sc = a, fa, sp
            else:
                xc, fc, sc = b, fb, sm
            x = xc
            for _it in range(200):
                if sc > 0.0:
                    xn = xc + (target - fc) / sc
                else:
                    xn = 0.5 * (a + b)
                if xn == xc:  # the step is below the resolution of x: xc is the root
                    break
                if not (xn > a and xn < b):
                    # regula falsi fallback inside the bracket
                    if fb > fa:
                        xn = a + (target - fa) * (b - a) / (fb - fa)
                    if not (xn > a and xn < b):
                        xn = 0.5 * (a + b)
                fn, snp, snm = cp_eval(xn, P, z)
                x = xn
                if abs(fn - target) <= err_w * (abs(xn) + err_r):
                    break
                if fn < target:
                    a, fa = xn, fn
                    xc, fc, sc = xn, fn, snp
                else:
                    b, fb = xn, fn
                    xc, fc, sc = xn, fn, snm
                if b - a <= 1e-15 * (1.0 + abs(a) + abs(b)):
                    break
    cp_settle(P, z, x)
    return x


@_step_part
def cp_settle(P, z, x):  # pragma: no cover - compiled
    """Every operator output ``z`` (updated in place) moved to the input ``x``."""
    for i in range(P.shape[1]):
        r, rc, ra, rb = P[0, i], P[1, i], P[2, i], P[3, i]
        up = max(x - r, min(x - rc, 0.0))
        down = min(x + ra, max(x + rb, 0.0))
        z[i] = max(up, min(down, z[i]))


@jit_exact
def cp_invert(target, P, z0, x0, lo, hi, smin, err_w, err_r):  # pragma: no cover - compiled
    """Batch monotone inversion: inputs for every target sample, final state (x, z)."""
    n = target.shape[0]
    out = np.empty(n)
    z = z0.copy()
    x = x0
    for k in range(n):
        x = cp_invert_step(P, z, x, target[k], lo, hi, smin, err_w, err_r)
        out[k] = x
    return out, z, x


@jit_exact
def cp_invert_creep(
    yref, P, z0, x0, lo, hi, smin, err_w, err_r, out_off, in_off, a, ca, s0, u0, g, tol_fp
):  # pragma: no cover - compiled
    """Batch inversion of a modified-PI model with a creep term (no input warp), as
    ``compensator.CreepInverse.step`` does it sample by sample: the creep memory ``h = ca . s`` is
    subtracted from the target, ``P`` carries the instantaneous creep gain ``g`` folded into
    the linear operator's weight, and the excess ``g (u - x(u))`` (the input offset, up to
    rounding) is resolved by the same fixed-point loop.  Returns (drives, z, x, s)."""
    n = yref.shape[0]
    out = np.empty(n)
    z = z0.copy()
    zs = z0.copy()
    s = s0.copy()
    x = x0
    up = u0
    nl = a.shape[0]
    for k in range(n):
        h = 0.0
        for j in range(nl):
            h += ca[j] * s[j]
        e = up - (up - in_off)
        for i in range(z.shape[0]):
            zs[i] = z[i]
        xs = x
        u = np.nan
        for _ in range(100):
            x = cp_invert_step(P, z, x, (yref[k] - h - g * e) - out_off, lo, hi, smin, err_w, err_r)
            u = x + in_off
            e_new = u - (u - in_off)
            if abs(g * (e_new - e)) <= tol_fp:
                break
            for i in range(z.shape[0]):
                z[i] = zs[i]
            x = xs
            e = e_new
        for j in range(nl):
            s[j] = a[j] * s[j] + (1.0 - a[j]) * u
        up = u
        out[k] = u
    return out, z, x, s


@jit_exact
def play_step(P, z, x):  # pragma: no cover - compiled
    """One sample of a weighted play sum (rows of P: r, w); state z updated in place."""
    m = P.shape[1]
    acc = 0.0
    for i in range(m):
        r = P[0, i]
        v = max(x - r, min(x + r, z[i]))
        z[i] = v
        acc += P[1, i] * v
    return acc


@jit_exact
def play_stream(target, P, z0, lo, hi):  # pragma: no cover - compiled
    """Sample-by-sample inverse-PI feedforward (closed-form inverse as a play sum), clipped."""
    n = target.shape[0]
    out = np.empty(n)
    z = z0.copy()
    for k in range(n):
        out[k] = play_step(P, z, target[k])
    return out, z
