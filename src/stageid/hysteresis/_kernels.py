"""Compiled inner loops of the hysteresis operators (numba, ``cache=True``, ``nogil=True``).

Every kernel has a plain-Python twin in :mod:`stageid.hysteresis.operators`
(``play_reference``, ``coupled_play_reference``) or below (``cp_invert_reference``) that the
tests compare it with.  The loops over operators are written so LLVM vectorises them (no
branches, ``min``/``max`` only); the only fast-math flags used are ``nnan``/``ninf``/``nsz``
(the inputs are checked finite before they get here) and ``reassoc`` for the weighted sum,
which changes its rounding by ~1e-16 relative, far inside the 1e-12 the tests ask for.

Weighted sums of coupled-play operators (the modified PI model, eq. 4) have three kernels:

* :func:`cp_sum` updates every operator at every sample (~0.33-0.43 ns per sample and
  operator on the 2-core EPYC benchmark machine);
* :func:`cp_sum_events` follows the piecewise-linear output between reversals (0.04-0.12 ns
  on smooth records, but it sorts all slope changes at every reversal: 14-17 ns on a random
  walk that turns at every other sample);
* :func:`cp_sum_banded` skips the operators that cannot move: each block of 4 operators
  (sorted by band width) knows the open interval of inputs in which none of its operators
  moves, and only the blocks the input leaves are updated; the narrowest blocks, which move
  at almost every sample, are simply updated every sample, with their outputs kept in
  registers from one sample to the next (~0.17 ns at 20 operators and ~0.09 at 100 on a
  random walk that turns at every other sample, 0.03-0.07 on a walk that mostly stands
  still).  :func:`play_sum_banded` is the same for plays (4 operations per operator instead
  of 8: ~0.14 / ~0.08 ns).  Their block updates are LLVM vector code written through
  ``numba.extending.intrinsic`` (numba runs no SLP vectoriser, and its loop vectoriser
  leaves 4-operator loops and min/max reductions scalar); each lane does the plain formula.

:func:`cp_sum_auto` picks the event kernel for smooth records and the banded one otherwise;
:func:`play_sum_auto` does the same for the classical PI model.  Every kernel produces the
reference's operator outputs bit for bit (the event kernels to 1e-12 of the input range);
see ``benchmarks/RESULTS-hysteresis.md``.

This module imports numba; it is imported lazily by the operators and models.
"""

from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

_FM = {"nnan", "ninf", "nsz", "reassoc", "contract"}
_jit = numba.njit(cache=True, nogil=True, fastmath=_FM)
_jit_exact = numba.njit(cache=True, nogil=True)


@_jit
def play_bank(x, r, z0):  # pragma: no cover - compiled
    """Play outputs, shape (n_samples, n_operators), and the final outputs."""
    n = x.shape[0]
    m = r.shape[0]
    out = np.empty((n, m))
    z = z0.copy()
    for k in range(n):
        xk = x[k]
        for i in range(m):
            lo = xk - r[i]
            hi = xk + r[i]
            v = min(hi, z[i])
            v = max(lo, v)
            z[i] = v
            out[k, i] = v
    return out, z


@_jit
def cp_bank(x, r, rc, ra, rb, z0):  # pragma: no cover - compiled
    """Coupled-play outputs, shape (n_samples, n_operators), and the final outputs."""
    n = x.shape[0]
    m = r.shape[0]
    out = np.empty((n, m))
    z = z0.copy()
    for k in range(n):
        xk = x[k]
        for i in range(m):
            up = max(xk - r[i], min(xk - rc[i], 0.0))
            down = min(xk + ra[i], max(xk + rb[i], 0.0))
            v = max(up, min(down, z[i]))
            z[i] = v
            out[k, i] = v
    return out, z


@_jit
def play_sum(x, r, w, z0):  # pragma: no cover - compiled
    """Weighted sum of plays ``y(k) = sum_i w_i z_i(k)`` and the final outputs."""
    n = x.shape[0]
    m = r.shape[0]
    y = np.empty(n)
    z = z0.copy()
    for k in range(n):
        xk = x[k]
        acc = 0.0
        for i in range(m):
            v = max(xk - r[i], min(xk + r[i], z[i]))
            z[i] = v
            acc += w[i] * v
        y[k] = acc
    return y, z


@_jit
def cp_sum(x, r, rc, ra, rb, w, z0):  # pragma: no cover - compiled
    """Weighted sum of CP operators (eq. 4) and the final outputs; every operator, every sample.

    Needs ``0 <= rc <= r`` and ``0 <= rb <= ra`` (what :func:`operators.check_cp_thresholds`
    guarantees).  Written in the clamp form ``gamma_up(x) = x + clamp(-x, -r, -rc)``,
    ``gamma_down(x) = x + clamp(-x, rb, ra)``: the same floating-point values as
    ``max(x - r, min(x - rc, 0))`` / ``min(x + ra, max(x + rb, 0))`` (each branch is one
    rounded addition of the same two numbers, the flat part is ``x + (-x) = 0``) with 9
    instead of 11 operations per operator; the operators are padded to a multiple of 8 with
    inert ones (zero weight) so the vectorised loop has no scalar remainder.
    """
    n = x.shape[0]
    m = r.shape[0]
    mp = (m + 7) // 8 * 8
    nr = np.zeros(mp)
    nrc = np.zeros(mp)
    RA = np.zeros(mp)
    RB = np.zeros(mp)
    W = np.zeros(mp)
    z = np.zeros(mp)
    for i in range(m):
        nr[i] = -r[i]
        nrc[i] = -rc[i]
        RA[i] = ra[i]
        RB[i] = rb[i]
        W[i] = w[i]
        z[i] = z0[i]
    y = np.empty(n)
    for k in range(n):
        xk = x[k]
        t = -xk
        acc = 0.0
        for i in range(mp):
            up = xk + max(nr[i], min(nrc[i], t))
            down = xk + max(RB[i], min(RA[i], t))
            v = max(up, min(down, z[i]))
            z[i] = v
            acc += W[i] * v
        y[k] = acc
    return y, z[:m].copy()


# ------------------------------------------------------------------ monotone inversion
@_jit_exact
def _eval(x, P, z):  # pragma: no cover - compiled
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


@_jit_exact
def cp_invert_step(P, z, x_prev, target, lo, hi, smin, tol):  # pragma: no cover - compiled
    """One sample of the monotone inversion: the input x with F(x) = target, state updated in place.

    ``P`` rows are r, rc, ra, rb, w; ``z`` the operator outputs (updated); ``lo``/``hi`` drive
    limits; ``smin`` a guaranteed lower bound of the slope of F (> 0); ``tol`` the accepted
    |F(x) - target|.  Returns x.  F is piecewise linear and nondecreasing: safeguarded Newton
    steps inside a bracket land on the exact piece in a few iterations.
    """
    f, sp, sm = _eval(x_prev, P, z)
    x = x_prev
    if abs(f - target) <= tol:
        x = x_prev
    else:
        if target > f:
            a = x_prev
            fa = f
            b = x_prev + (target - f) / smin
            if b > hi:
                b = hi
            fb, _s1, _s2 = _eval(b, P, z)
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
            fa, _s1, _s2 = _eval(a, P, z)
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
                if not (xn > a and xn < b):
                    # regula falsi fallback inside the bracket
                    if fb > fa:
                        xn = a + (target - fa) * (b - a) / (fb - fa)
                    if not (xn > a and xn < b):
                        xn = 0.5 * (a + b)
                fn, snp, snm = _eval(xn, P, z)
                x = xn
                if abs(fn - target) <= tol:
                    break
                if fn < target:
                    a, fa = xn, fn
                    xc, fc, sc = xn, fn, snp
                else:
                    b, fb = xn, fn
                    xc, fc, sc = xn, fn, snm
                if b - a <= 1e-15 * (1.0 + abs(a) + abs(b)):
                    break
    # update the state with the chosen input
    m = P.shape[1]
    for i in range(m):
        r, rc, ra, rb = P[0, i], P[1, i], P[2, i], P[3, i]
        up = max(x - r, min(x - rc, 0.0))
        down = min(x + ra, max(x + rb, 0.0))
        z[i] = max(up, min(down, z[i]))
    return x


@_jit_exact
def cp_invert(target, P, z0, x0, lo, hi, smin, tol):  # pragma: no cover - compiled
    """Batch monotone inversion: inputs for every target sample, final state (x, z)."""
    n = target.shape[0]
    out = np.empty(n)
    z = z0.copy()
    x = x0
    for k in range(n):
        x = cp_invert_step(P, z, x, target[k], lo, hi, smin, tol)
        out[k] = x
    return out, z, x


@_jit_exact
def cp_invert_creep(
    yref, P, z0, x0, lo, hi, smin, tol, out_off, in_off, a, ca, s0, u0, g, tol_fp
):  # pragma: no cover - compiled
    """Batch inversion of a modified-PI model with a creep term (no input warp), as
    ``creep.CreepInverse.step`` does it sample by sample: the creep memory ``h = ca . s`` is
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
            x = cp_invert_step(P, z, x, (yref[k] - h - g * e) - out_off, lo, hi, smin, tol)
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


@_jit_exact
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


@_jit_exact
def play_stream(target, P, z0, lo, hi):  # pragma: no cover - compiled
    """Sample-by-sample inverse-PI feedforward (closed-form inverse as a play sum), clipped."""
    n = target.shape[0]
    out = np.empty(n)
    z = z0.copy()
    for k in range(n):
        out[k] = play_step(P, z, target[k])
    return out, z


# ------------------------------------------------------------------ event-driven play sum
@_jit_exact
def lipschitz_state(r, z):  # pragma: no cover - compiled
    """True when |z_{i+1} - z_i| <= r_{i+1} - r_i (thresholds ascending): every state a play
    bank reaches from the zero state (or any consistent state) has this property."""
    m = r.shape[0]
    for i in range(m - 1):
        dr = r[i + 1] - r[i]
        if dr < 0.0:
            return False
        dz = z[i + 1] - z[i]
        if dz > dr * (1.0 + 1e-12) + 1e-300 or -dz > dr * (1.0 + 1e-12) + 1e-300:
            return False
    return True


@_jit_exact
def play_sum_events(x, r, w, z0, x0):  # pragma: no cover - compiled
    """Weighted play sum in O(1) amortised per sample (thresholds ascending, Lipschitz state).

    While the input keeps moving in one direction the operators that follow it form a prefix
    ``i < p`` (their activation points ``z_i +- r_i`` are monotone in ``i`` for a Lipschitz
    state), so ``y = W_p x - d R_p + sum_{i>=p} w_i z_i`` with prefix sums ``W_p``, ``R_p`` of
    ``w`` and ``w r``; the prefix is written back into ``z`` only at a reversal.  The cost is
    one update per sample plus one per operator activation -- independent of the number of
    operators for inputs that do not reverse every sample.
    """
    n = x.shape[0]
    m = r.shape[0]
    cw = np.zeros(m + 1)
    crw = np.zeros(m + 1)
    for i in range(m):
        cw[i + 1] = cw[i] + w[i]
        crw[i + 1] = crw[i] + w[i] * r[i]
    z = z0.copy()
    tail = 0.0
    for i in range(m):
        tail += w[i] * z[i]
    y = np.empty(n)
    p = 0
    d = 0.0
    xl = x0
    n_rev = 0
    for k in range(n):
        xk = x[k]
        if xk != xl:
            dn = 1.0 if xk > xl else -1.0
            if dn != d:
                if p > 0:
                    for i in range(p):
                        z[i] = xl - d * r[i]
                    n_rev += 1
                    if (n_rev & 1023) == 0:
                        tail = 0.0
                        for i in range(m):
                            tail += w[i] * z[i]
                    else:
                        tail += cw[p] * xl - d * crw[p]
                p = 0
                d = dn
            if d > 0.0:
                while p < m and xk - r[p] > z[p]:
                    tail -= w[p] * z[p]
                    p += 1
            else:
                while p < m and xk + r[p] < z[p]:
                    tail -= w[p] * z[p]
                    p += 1
            xl = xk
        y[k] = cw[p] * xk - d * crw[p] + tail
    for i in range(p):
        z[i] = xl - d * r[i]
    return y, z


def play_sum_auto(x, r, w, z0, x0):
    """Weighted play sum: the event-driven kernel for smooth records (the input turns in
    < 0.5 % of the samples; ascending thresholds and a Lipschitz state required), else the
    banded play kernel; records of up to 64 samples use the loop.  All give the reference's
    operator outputs; the sums agree to rounding (~1e-15 relative).

    The event kernel's cost per reversal grows with the number of operators the last stroke
    moved: on a random walk that turns at every other sample it takes 0.2-0.7 ns per sample
    and operator on the benchmark machine, the banded kernel ~0.08-0.14; on smooth records the
    event kernel is 1.5-8x faster than the banded one.
    """
    n = x.shape[0]
    if n > 64 and _is_smooth(x) and lipschitz_state(r, z0):
        return play_sum_events(x, r, w, z0, float(x0))
    if n > 64:
        return play_sum_banded(x, r, w, z0, float(x0))
    return play_sum(x, r, w, z0)


# ------------------------------------------------------------------ event-driven CP sum
@_jit_exact
def _cp_advance(x, r, rc, ra, rb, z, d):  # pragma: no cover - compiled
    """Operator outputs after a monotone move (direction d) from state z to input x (in place)."""
    m = r.shape[0]
    for i in range(m):
        if d > 0.0:
            up = max(x - r[i], min(x - rc[i], 0.0))
            z[i] = max(up, z[i])
        else:
            down = min(x + ra[i], max(x + rb[i], 0.0))
            z[i] = min(down, z[i])


@_jit_exact
def _cp_events(r, rc, ra, rb, w, z, d, pos, dslope):  # pragma: no cover - compiled
    """Slope-change events of sum_i w_i CP_i along a monotone move in direction d; returns count."""
    m = r.shape[0]
    e = 0
    for i in range(m):
        zi = z[i]
        if d > 0.0:
            if zi < 0.0:
                pos[e] = zi + rc[i]
                dslope[e] = w[i]
                e += 1
                pos[e] = rc[i]
                dslope[e] = -w[i]
                e += 1
                pos[e] = r[i]
                dslope[e] = w[i]
                e += 1
            else:
                pos[e] = zi + r[i]
                dslope[e] = w[i]
                e += 1
        else:
            if zi > 0.0:
                pos[e] = zi - rb[i]
                dslope[e] = w[i]
                e += 1
                pos[e] = -rb[i]
                dslope[e] = -w[i]
                e += 1
                pos[e] = -ra[i]
                dslope[e] = w[i]
                e += 1
            else:
                pos[e] = zi - ra[i]
                dslope[e] = w[i]
                e += 1
    return e


@_jit_exact
def cp_sum_events(x, r, rc, ra, rb, w, z0, x0):  # pragma: no cover - compiled
    """Weighted CP sum (eq. 4) driven by slope-change events (exact, piecewise linear).

    On a monotone stretch each operator output is ``max(gamma_up(x), z_start)`` (rising) or
    ``min(gamma_down(x), z_start)`` (falling), so the model output is piecewise linear in x
    with at most three slope changes per operator, at positions known at the reversal.  They
    are sorted once per reversal (O(m log m)); every sample then costs O(1) plus the events
    it passes.  At a reversal the operator outputs are recomputed exactly from the stretch's
    start state, so no rounding accumulates across stretches.
    """
    n = x.shape[0]
    m = r.shape[0]
    z = z0.copy()
    y = np.empty(n)
    pos = np.empty(3 * m)
    dsl = np.empty(3 * m)
    sp = np.empty(3 * m + 1)  # sorted event positions, in the direction coordinate d * x
    sd = np.empty(3 * m + 1)
    d = 0.0
    xl = x0
    n_ev = 0
    j = 0
    F = 0.0
    for i in range(m):
        F += w[i] * z[i]
    fx = x0  # position where F was evaluated
    S = 0.0
    nxt = np.inf  # d * position of the next event
    for k in range(n):
        xk = x[k]
        if xk == xl:
            y[k] = F
            continue
        dn = 1.0 if xk > xl else -1.0
        if dn != d:
            if d != 0.0:
                _cp_advance(xl, r, rc, ra, rb, z, d)
            F = 0.0
            for i in range(m):
                F += w[i] * z[i]
            fx = xl
            d = dn
            n_ev = _cp_events(r, rc, ra, rb, w, z, d, pos, dsl)
            for e in range(n_ev):
                pos[e] *= d
            order = np.argsort(pos[:n_ev])
            for e in range(n_ev):
                sp[e] = pos[order[e]]
                sd[e] = dsl[order[e]]
            sp[n_ev] = np.inf
            sd[n_ev] = 0.0
            j = 0
            S = 0.0
            lim = d * xl
            while sp[j] <= lim:  # events at or behind the start are already in effect
                S += sd[j]
                j += 1
            nxt = sp[j]
        q = d * xk
        while nxt <= q:
            p = d * nxt
            F += S * (p - fx)
            fx = p
            S += sd[j]
            j += 1
            nxt = sp[j]
        F += S * (xk - fx)
        fx = xk
        xl = xk
        y[k] = F
    if d != 0.0:
        _cp_advance(xl, r, rc, ra, rb, z, d)
    return y, z


@_jit_exact
def count_reversals(x):  # pragma: no cover - compiled
    """Number of direction changes of x (standing still is not a change)."""
    n = x.shape[0]
    d = 0.0
    c = 0
    for k in range(1, n):
        dx = x[k] - x[k - 1]
        if dx != 0.0:
            dn = 1.0 if dx > 0.0 else -1.0
            if dn != d and d != 0.0:
                c += 1
            d = dn
    return c


# ------------------------------------------------------------------ banded CP / play sums
# The banded kernels work on blocks of 4 operators (one 256-bit register of doubles).  numba
# does not SLP-vectorise (NUMBA_SLP_VECTORIZE=0) and its loop vectoriser handles neither short
# loops (it interleaves 2 registers, so a 4-operator loop runs scalar) nor min/max reductions,
# so the block updates are written as LLVM vector code through ``numba.extending.intrinsic``:
# every block update is the plain formula lane by lane (the same operations as the reference,
# Python's ``max(a, c) = c if c > a else a``), so the operator outputs are unchanged bit for bit.
_L = 4  # operators per block: one AVX register of doubles
_HUGE = 1e300  # thresholds of the inert padding operators (zero weight, never move)
_BAND_BLOCK = 2048  # samples between two choices of the number of hot blocks
_NREG = 4  # hot blocks whose outputs stay in registers during a run of samples (5 or 6 spill)
_CP_ROWS = 7  # block rows of the CP layout: -r, -rc, ra, rb, w, z, band tolerance
_PLAY_ROWS = 4  # block rows of the play layout: r, w, z, band tolerance

_F64 = ir.DoubleType()
_VEC = ir.VectorType(_F64, _L)
_I64 = ir.IntType(64)
_EXACT = ("nnan", "ninf", "nsz")  # flags of the update's operations: no reassociation
_SUMF = ("nnan", "ninf", "nsz", "reassoc", "contract")  # weighted sums: any association


class _V4:
    """Emits 4-lane double operations (a tiny helper for the intrinsics below)."""

    def __init__(self, builder):
        self.b = builder

    @staticmethod
    def _flag(ins, flags):
        for f in flags:
            ins.flags.append(f)  # flagged instructions are left alone by numba's fastmath pass
        return ins

    def add(self, a, c, flags=_EXACT):
        return self._flag(self.b.fadd(a, c), flags)

    def sub(self, a, c, flags=_EXACT):
        return self._flag(self.b.fsub(a, c), flags)

    def mul(self, a, c, flags=_SUMF):
        return self._flag(self.b.fmul(a, c), flags)

    def max(self, a, c):  # Python's max(a, c)
        return self.b.select(self.b.fcmp_ordered(">", c, a, flags=_EXACT), c, a)

    def min(self, a, c):  # Python's min(a, c)
        return self.b.select(self.b.fcmp_ordered("<", c, a, flags=_EXACT), c, a)

    def splat(self, s):
        v = self.b.insert_element(ir.Constant(_VEC, ir.Undefined), s, ir.Constant(ir.IntType(32), 0))
        mask = ir.Constant(ir.VectorType(ir.IntType(32), _L), [0] * _L)
        return self.b.shuffle_vector(v, ir.Constant(_VEC, ir.Undefined), mask)

    @staticmethod
    def const(c):
        return ir.Constant(_VEC, [c] * _L)

    def lanes(self, v):
        return [self.b.extract_element(v, ir.Constant(ir.IntType(32), i)) for i in range(_L)]

    def hsum(self, v):  # (l0 + l2) + (l1 + l3): one 2-lane add, then one scalar add
        i32 = ir.IntType(32)
        undef = ir.Constant(_VEC, ir.Undefined)
        lo = self.b.shuffle_vector(v, undef, ir.Constant(ir.VectorType(i32, 2), [0, 1]))
        hi = self.b.shuffle_vector(v, undef, ir.Constant(ir.VectorType(i32, 2), [2, 3]))
        s = self.add(lo, hi, _SUMF)
        return self.add(
            self.b.extract_element(s, ir.Constant(i32, 0)), self.b.extract_element(s, ir.Constant(i32, 1)), _SUMF
        )

    def hmin(self, v):
        l0, l1, l2, l3 = self.lanes(v)
        return self.min(self.min(l0, l1), self.min(l2, l3))

    def hmax(self, v):
        l0, l1, l2, l3 = self.lanes(v)
        return self.max(self.max(l0, l1), self.max(l2, l3))


def _c_float64(*tys):
    """True when every type is a C-contiguous float64 array (the intrinsics index raw data)."""
    return all(isinstance(t, types.Array) and t.dtype == types.float64 and t.layout == "C" for t in tys)


def _block_rows(context, builder, aryty, ary, b, n_rows):
    """Pointers to the rows of block b of a C-contiguous (n_blocks, n_rows, 4) array."""
    data = context.make_array(aryty)(context, builder, ary).data
    base = builder.mul(b, ir.Constant(b.type, _L * n_rows))
    return [
        builder.bitcast(builder.gep(data, [builder.add(base, ir.Constant(b.type, _L * j))]), _VEC.as_pointer())
        for j in range(n_rows)
    ]


def _load(builder, p):
    return builder.load(p, align=8)


def _load_at(context, builder, aryty, ary, i):
    """The 4 doubles ary[i .. i+3] of a contiguous 1-d array as a vector."""
    p = builder.gep(context.make_array(aryty)(context, builder, ary).data, [i])
    return _load(builder, builder.bitcast(p, _VEC.as_pointer()))


def _update_lanes(vec, kind, rows, xs, t):
    """Plain update of the 4 operators of a block; the new outputs are stored and returned.

    CP (rows -r, -rc, ra, rb, w, z): ``max(x + max(-r, min(-rc, -x)), min(x + max(rb, min(ra, -x)), z))``
    as in :func:`cp_sum`; play (rows r, w, z): ``max(x - r, min(x + r, z))`` as the reference.
    """
    b = vec.b
    if kind == "cp":
        nr, nrc, ra, rb = (_load(b, rows[j]) for j in range(4))
        up = vec.add(xs, vec.max(nr, vec.min(nrc, t)))
        down = vec.add(xs, vec.max(rb, vec.min(ra, t)))
        v = vec.max(up, vec.min(down, _load(b, rows[5])))
        b.store(v, rows[5], align=8)
    else:
        r = _load(b, rows[0])
        v = vec.max(vec.sub(xs, r), vec.min(vec.add(xs, r), _load(b, rows[2])))
        b.store(v, rows[2], align=8)
    return v


def _layout(kind):
    """(rows per block, weight row, output row, tolerance row)."""
    return (_CP_ROWS, 4, 5, 6) if kind == "cp" else (_PLAY_ROWS, 1, 2, 3)


def _emit_memory_blocks(context, builder, aryty, P, start, stop, xs, t, kind):
    """Update blocks start..stop-1 (outputs in memory); the vector of their weighted sums.

    Two accumulators, so consecutive blocks do not wait for each other's fused multiply-add.
    """
    vec = _V4(builder)
    n_rows, wrow = _layout(kind)[:2]
    zero = vec.const(0.0)
    acc0 = cgutils.alloca_once_value(builder, zero)
    acc1 = cgutils.alloca_once_value(builder, zero)
    n = builder.sub(stop, start)
    with cgutils.for_range(builder, builder.ashr(n, ir.Constant(_I64, 1))) as loop:
        b0 = builder.add(start, builder.shl(loop.index, ir.Constant(_I64, 1)))
        for acc, blk in ((acc0, b0), (acc1, builder.add(b0, ir.Constant(_I64, 1)))):
            rows = _block_rows(context, builder, aryty, P, blk, n_rows)
            v = _update_lanes(vec, kind, rows, xs, t)
            builder.store(vec.add(builder.load(acc), vec.mul(_load(builder, rows[wrow]), v), _SUMF), acc)
    odd = builder.icmp_signed("!=", builder.and_(n, ir.Constant(_I64, 1)), ir.Constant(_I64, 0))
    with builder.if_then(odd):
        rows = _block_rows(context, builder, aryty, P, builder.sub(stop, ir.Constant(_I64, 1)), n_rows)
        v = _update_lanes(vec, kind, rows, xs, t)
        builder.store(vec.add(builder.load(acc0), vec.mul(_load(builder, rows[wrow]), v), _SUMF), acc0)
    return vec.add(builder.load(acc0), builder.load(acc1), _SUMF)


def _make_hot(kind):
    """Intrinsic ``hot(P, n_hot, x) -> float``: update blocks 0..n_hot-1 at x, their weighted sum."""

    @intrinsic
    def hot(typingctx, P, n_hot, x):
        if not _c_float64(P):
            return None
        sig = types.float64(P, n_hot, x)

        def codegen(context, builder, signature, args):
            Pa, nh, xk = args
            vec = _V4(builder)
            t = vec.splat(builder.fneg(xk))
            nh = context.cast(builder, nh, signature.args[1], types.int64)
            zero = ir.Constant(_I64, 0)
            acc = _emit_memory_blocks(context, builder, signature.args[0], Pa, zero, nh, vec.splat(xk), t, kind)
            return vec.hsum(acc)

        return sig, codegen

    return hot


def _make_block(kind):
    """Intrinsic ``block(P, b, x) -> (weighted sum, lo, hi)``: update block b at x and return
    the open band (lo, hi) of inputs at which none of its operators moves.

    Rising, an operator with output v starts to move beyond ``v + rc`` (v < 0) or ``v + r``;
    falling, beyond ``v - rb`` (v > 0) or ``v - ra``; the band is pulled inwards by
    ``1e-15 (r + rc + ra + rb) + 1e-15 |v|`` so rounding never hides a move.
    """
    n_rows, wrow, zrow, tsrow = _layout(kind)

    @intrinsic
    def block(typingctx, P, b, x):
        if not _c_float64(P):
            return None
        sig = types.UniTuple(types.float64, 3)(P, b, x)

        def codegen(context, builder, signature, args):
            Pa, bv, xk = args
            vec = _V4(builder)
            bv = context.cast(builder, bv, signature.args[1], types.int64)
            rows = _block_rows(context, builder, signature.args[0], Pa, bv, n_rows)
            zero = vec.const(0.0)
            v = _update_lanes(vec, kind, rows, vec.splat(xk), vec.splat(builder.fneg(xk)))
            if kind == "cp":
                nr, nrc, ra, rb = (_load(builder, rows[j]) for j in range(4))
                s_up = builder.select(builder.fcmp_ordered("<", v, zero, flags=_EXACT), nrc, nr)
                s_down = builder.select(builder.fcmp_ordered(">", v, zero, flags=_EXACT), rb, ra)
            else:
                r = _load(builder, rows[0])
                s_up = builder.fneg(r)
                s_down = r
            absv = builder.select(builder.fcmp_ordered("<", v, zero, flags=_EXACT), builder.fneg(v), v)
            tol = vec.add(_load(builder, rows[tsrow]), vec.mul(vec.const(1e-15), absv, _EXACT))
            hi = vec.sub(vec.sub(v, s_up), tol)
            lo = vec.add(vec.sub(v, s_down), tol)
            cb = vec.hsum(vec.mul(_load(builder, rows[wrow]), v))
            return context.make_tuple(builder, signature.return_type, [cb, vec.hmax(lo), vec.hmin(hi)])

        return sig, codegen

    return block


def _make_run(kind, n_reg, memory):
    """Intrinsic ``run(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl) -> (k, xl, yl)``.

    Runs samples k.. while the input stays inside the cold blocks' band (lo, hi): the hot
    blocks (the first ``n_hot``) are updated at every sample that moves, the first ``n_reg``
    of them with their outputs kept in registers (no store-to-load latency from one sample
    to the next), the others (``memory`` only; else ``n_hot == n_reg``) in memory, and
    ``y = C + W0 x + hot sum``.  Returns at k1 or at the first sample that leaves the band
    (not processed), with the last input and output.
    """
    n_rows, wrow, zrow = _layout(kind)[:3]

    @intrinsic
    def run(typingctx, x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl):
        if not _c_float64(x, y, P):
            return None
        ret = types.Tuple((types.int64, types.float64, types.float64))
        sig = ret(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)

        def codegen(context, builder, signature, args):
            xa, ya, k0, k1v, Pa, nh, Cv, lov, hiv, W0v, xlv, ylv = args
            k0 = context.cast(builder, k0, signature.args[2], types.int64)
            k1v = context.cast(builder, k1v, signature.args[3], types.int64)
            nh = context.cast(builder, nh, signature.args[5], types.int64)
            aryty = signature.args[4]
            vec = _V4(builder)
            xd = context.make_array(signature.args[0])(context, builder, xa).data
            yd = context.make_array(signature.args[1])(context, builder, ya).data
            rows = [_block_rows(context, builder, aryty, Pa, ir.Constant(_I64, b), n_rows) for b in range(n_reg)]
            k_slot = cgutils.alloca_once_value(builder, k0)
            xl_slot = cgutils.alloca_once_value(builder, xlv)
            yl_slot = cgutils.alloca_once_value(builder, ylv)
            z_slots = [cgutils.alloca_once_value(builder, _load(builder, rows[b][zrow])) for b in range(n_reg)]
            fn = builder.function
            head, body, still, move, update, done = (
                fn.append_basic_block(f"band.{s}") for s in ("head", "body", "still", "move", "update", "done")
            )
            one = ir.Constant(_I64, 1)
            builder.branch(head)
            builder.position_at_end(head)
            kk = builder.load(k_slot)
            builder.cbranch(builder.icmp_signed("<", kk, k1v), body, done)
            builder.position_at_end(body)
            xk = builder.load(builder.gep(xd, [kk]))
            builder.cbranch(builder.fcmp_ordered("==", xk, builder.load(xl_slot), flags=_EXACT), still, move)
            builder.position_at_end(still)  # standing still: nothing moves
            builder.store(builder.load(yl_slot), builder.gep(yd, [kk]))
            builder.store(builder.add(kk, one), k_slot)
            builder.branch(head)
            builder.position_at_end(move)
            inside = builder.and_(
                builder.fcmp_ordered("<", xk, hiv, flags=_EXACT), builder.fcmp_ordered(">", xk, lov, flags=_EXACT)
            )
            builder.cbranch(inside, update, done)
            builder.position_at_end(update)
            xs = vec.splat(xk)
            t = vec.splat(builder.fneg(xk))
            parts = []
            for b in range(n_reg):
                rb_ = list(rows[b])
                rb_[zrow] = z_slots[b]  # the output row lives in a register slot
                v = _update_lanes(vec, kind, rb_, xs, t)
                parts.append(vec.mul(_load(builder, rows[b][wrow]), v))
            if memory:
                parts.append(
                    _emit_memory_blocks(context, builder, aryty, Pa, ir.Constant(_I64, n_reg), nh, xs, t, kind)
                )
            while len(parts) > 1:  # pairwise sum of the block sums
                parts = [vec.add(parts[i], parts[i + 1], _SUMF) for i in range(0, len(parts) - 1, 2)] + (
                    [parts[-1]] if len(parts) % 2 else []
                )
            yk = vec.add(Cv, vec.mul(W0v, xk), _SUMF)
            if parts:
                yk = vec.add(yk, vec.hsum(parts[0]), _SUMF)
            builder.store(yk, builder.gep(yd, [kk]))
            builder.store(yk, yl_slot)
            builder.store(xk, xl_slot)
            builder.store(builder.add(kk, one), k_slot)
            builder.branch(head)
            builder.position_at_end(done)
            for b in range(n_reg):
                builder.store(builder.load(z_slots[b]), rows[b][zrow], align=8)
            return context.make_tuple(
                builder, signature.return_type, [builder.load(k_slot), builder.load(xl_slot), builder.load(yl_slot)]
            )

        return sig, codegen

    return run


@intrinsic
def _left4(typingctx, lob, hib, g, x):
    """Bit j set when x is outside the band (lob[g + j], hib[g + j]), j = 0..3."""
    if not _c_float64(lob, hib):
        return None
    sig = types.int64(lob, hib, g, x)

    def codegen(context, builder, signature, args):
        la, ha, gv, xk = args
        gv = context.cast(builder, gv, signature.args[2], types.int64)
        lo = _load_at(context, builder, signature.args[0], la, gv)
        hi = _load_at(context, builder, signature.args[1], ha, gv)
        xs = _V4(builder).splat(xk)
        out = builder.or_(
            builder.fcmp_ordered(">=", xs, hi, flags=_EXACT), builder.fcmp_ordered("<=", xs, lo, flags=_EXACT)
        )
        return builder.zext(builder.bitcast(out, ir.IntType(_L)), _I64)

    return sig, codegen


@intrinsic
def _reduce4(typingctx, Cb, lob, hib, g):
    """(sum of Cb, max of lob, min of hib) over entries g..g+3."""
    if not _c_float64(Cb, lob, hib):
        return None
    sig = types.UniTuple(types.float64, 3)(Cb, lob, hib, g)

    def codegen(context, builder, signature, args):
        gv = context.cast(builder, args[3], signature.args[3], types.int64)
        vecs = [_load_at(context, builder, signature.args[i], args[i], gv) for i in range(3)]
        vec = _V4(builder)
        return context.make_tuple(
            builder, signature.return_type, [vec.hsum(vecs[0]), vec.hmax(vecs[1]), vec.hmin(vecs[2])]
        )

    return sig, codegen


_cp_hot = _make_hot("cp")
_play_hot = _make_hot("play")
_cp_block = _make_block("cp")
_play_block = _make_block("play")
_cp_run0, _cp_run1, _cp_run2, _cp_run3, _cp_run4 = (_make_run("cp", i, False) for i in range(_NREG + 1))
_pl_run0, _pl_run1, _pl_run2, _pl_run3, _pl_run4 = (_make_run("play", i, False) for i in range(_NREG + 1))
_cp_run_mem = _make_run("cp", _NREG, True)
_pl_run_mem = _make_run("play", _NREG, True)


@_jit
def _banded_refresh(xk, n_hot, P, Cb, lob, hib, state, play):  # pragma: no cover - compiled
    """Exact update of every cold block (``n_hot ..``) at xk: sums, bands, state[0:3]."""
    C = 0.0
    hi = 1e308
    lo = -1e308
    for b in range(n_hot, P.shape[0]):
        if play:
            cb, lb, hb = _play_block(P, b, xk)
        else:
            cb, lb, hb = _cp_block(P, b, xk)
        Cb[b] = cb
        lob[b] = lb
        hib[b] = hb
        C += cb
        hi = hb if hb < hi else hi
        lo = lb if lb > lo else lo
    state[0] = C
    state[1] = lo
    state[2] = hi


@_jit
def _banded_run(x, y, k0, k1, n_hot, P, Cb, lob, hib, W0, state, counts, play):  # pragma: no cover - compiled
    """Samples ``k0 .. k1-1`` of the banded sums; ``state = [C, lo, hi, x_last, y_last]``.

    The first ``n_hot`` blocks are updated at every sample that moves.  A cold block ``b``
    holds its weighted sum ``Cb[b]`` and the open band ``(lob[b], hib[b])`` of inputs at which
    none of its operators moves; ``C``/``lo``/``hi`` are the sum over the cold blocks and the
    intersection of their bands.  Only when the input leaves that band are the cold blocks it
    left updated (exactly, with the plain formula) and their bands recomputed.  ``counts`` gets
    the number of band exits, of block updates, of exits that update a block other than the
    first cold one and of updates of the first cold one (what one more hot block would save).
    """
    C = state[0]
    lo = state[1]
    hi = state[2]
    xl = state[3]
    yl = state[4]
    nb = P.shape[0]
    n_reg = min(n_hot, _NREG)
    exits = 0
    updates = 0
    exits_beyond = 0
    updates_first = 0
    k = k0
    while k < k1:
        if play:
            if n_reg == 0:
                k, xl, yl = _pl_run0(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)
            elif n_reg == 1:
                k, xl, yl = _pl_run1(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)
            elif n_reg == 2:
                k, xl, yl = _pl_run2(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)
            elif n_reg == 3:
                k, xl, yl = _pl_run3(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)
            elif n_hot == _NREG:
                k, xl, yl = _pl_run4(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)
            else:
                k, xl, yl = _pl_run_mem(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)
        else:
            if n_reg == 0:
                k, xl, yl = _cp_run0(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)
            elif n_reg == 1:
                k, xl, yl = _cp_run1(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)
            elif n_reg == 2:
                k, xl, yl = _cp_run2(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)
            elif n_reg == 3:
                k, xl, yl = _cp_run3(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)
            elif n_hot == _NREG:
                k, xl, yl = _cp_run4(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)
            else:
                k, xl, yl = _cp_run_mem(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)
        if k >= k1:
            break
        # sample k leaves the cold band: update the cold blocks it left (found 4 at a time),
        # then the hot ones
        xk = x[k]
        exits += 1
        C = 0.0
        hi = 1e308
        lo = -1e308
        beyond = False
        for g in range(n_hot, nb, _L):
            left = _left4(lob, hib, g, xk)
            if nb - g < _L:
                left &= (1 << (nb - g)) - 1  # (the padding is never left; belt and braces)
            if left != 0:
                for j in range(_L):
                    if (left >> j) & 1:
                        b = g + j
                        updates += 1
                        if b == n_hot:
                            updates_first += 1
                        else:
                            beyond = True
                        if play:
                            cb, lb, hb = _play_block(P, b, xk)
                        else:
                            cb, lb, hb = _cp_block(P, b, xk)
                        Cb[b] = cb
                        lob[b] = lb
                        hib[b] = hb
            cg, lg, hg = _reduce4(Cb, lob, hib, g)
            C += cg
            hi = hg if hg < hi else hi
            lo = lg if lg > lo else lo
        exits_beyond += beyond
        yl = C + W0 * xk
        if n_hot > 0:
            if play:
                yl += _play_hot(P, n_hot, xk)
            else:
                yl += _cp_hot(P, n_hot, xk)
        y[k] = yl
        xl = xk
        k += 1
    state[0] = C
    state[1] = lo
    state[2] = hi
    state[3] = xl
    state[4] = yl
    counts[0] = exits
    counts[1] = updates
    counts[2] = exits_beyond
    counts[3] = updates_first


@_jit
def _banded_drive(x, P, W0, n_hot_blocks, play):  # pragma: no cover - compiled
    """Model output of the packed blocks P for the input x (n >= 1); P's outputs updated.

    The first sample is the plain update of every block.  ``n_hot_blocks < 0`` re-chooses the
    number of hot blocks every ``_BAND_BLOCK`` samples from a cost model of the measured band
    exits and block updates (fitted to timings on the benchmark machine, ns: a hot block costs
    ~1.35 (CP) or ~0.8 (play) at every sample, a band exit ~20 plus ~0.9 per cold block
    scanned, a block update ~5.2 (CP) or ~4.2 (play)).  The cost with one more hot block is
    predicted exactly from the counts; one block less is measured again every 32 choices.
    """
    n = x.shape[0]
    nb = P.shape[0]
    y = np.empty(n)
    Cb = np.zeros(nb + _L - 1)  # padded: the exit scan reads 4 blocks at a time
    lob = np.full(nb + _L - 1, -1e308)
    hib = np.full(nb + _L - 1, 1e308)
    state = np.empty(5)
    counts = np.zeros(4, np.int64)
    xs = x[0]
    _banded_refresh(xs, 0, P, Cb, lob, hib, state, play)
    y[0] = state[0] + W0 * xs
    state[3] = xs
    state[4] = y[0]
    adapt = n_hot_blocks < 0
    n_hot = 1 if adapt else min(n_hot_blocks, nb)
    if n_hot > 0:
        _banded_refresh(xs, n_hot, P, Cb, lob, hib, state, play)
    c_hot = 0.8 if play else 1.35
    c_exit = 20.0
    c_update = 4.2 if play else 5.2
    est = np.zeros(nb + 1)  # estimated ns per sample for each number of hot blocks (0: not tried)
    n_blocks = 0
    k = 1
    while k < n:
        k1 = min(n, k + _BAND_BLOCK)
        _banded_run(x, y, k, k1, n_hot, P, Cb, lob, hib, W0, state, counts, play)
        if adapt:
            per = 1.0 / (k1 - k)
            cost = c_hot * n_hot + (c_exit + 0.9 * (nb - n_hot)) * counts[0] * per + c_update * counts[1] * per
            est[n_hot] = cost if est[n_hot] == 0.0 else 0.5 * (est[n_hot] + cost)
            if n_hot < nb:
                # one more hot block: the exits that left only the first cold block, and its
                # updates, would not happen (the other cold blocks evolve the same either way)
                more = (
                    c_hot * (n_hot + 1)
                    + (c_exit + 0.9 * (nb - n_hot - 1)) * counts[2] * per
                    + c_update * (counts[1] - counts[3]) * per
                )
                est[n_hot + 1] = more if est[n_hot + 1] == 0.0 else 0.5 * (est[n_hot + 1] + more)
            n_blocks += 1
            if (n_blocks & 31) == 0 and n_hot > 0:  # one hot block less: measured again now and then
                est[n_hot - 1] = 0.0
            best = n_hot
            for jb in (n_hot - 1, n_hot + 1):
                if 0 <= jb <= nb and est[jb] < est[best]:  # an untried one (0) gets tried
                    best = jb
            if best != n_hot:
                n_hot = best
                _banded_refresh(state[3], n_hot, P, Cb, lob, hib, state, play)
                state[4] = y[k1 - 1]
        k = k1
    return y


@_jit_exact
def cp_sum_banded(x, r, rc, ra, rb, w, z0, x0=0.0, n_hot_blocks=-1):  # pragma: no cover - compiled
    """Weighted CP sum (eq. 4) that touches only the operators that can move.

    Needs ``0 <= rc <= r`` and ``0 <= rb <= ra``.  ``x0`` is accepted for the signature of the
    other kernels and ignored (like the reference, which starts from ``z0`` alone): the first
    sample is the plain update of every operator, which makes any starting state consistent.

    Operators whose four thresholds are zero are the identity (a linear term).  The others are
    sorted by band width ``min(r + rb, rc + ra)`` into blocks of 4 (padded with inert
    operators).  The narrowest ``n_hot_blocks`` blocks are updated at every sample; every
    other block is skipped while the input stays inside the band where none of its operators
    moves (an operator on a rising input stays put until ``gamma_up(x)`` exceeds its output,
    i.e. below ``z + rc`` or ``z + r``; likewise falling), and updated with the plain formula
    when it leaves.  Every operator output is therefore the reference's value exactly; only the
    weighted sum is associated differently (~1e-16 relative).  ``n_hot_blocks < 0`` chooses
    the number of hot blocks every 2048 samples from the measured band exits (a cost model:
    hot blocks cost every sample, cold ones only on exits), so an input that moves every
    operator at every sample ends up with all blocks hot -- the loop kernel.
    """
    x = np.ascontiguousarray(x)  # the vector code indexes the raw data
    n = x.shape[0]
    m = r.shape[0]
    zfinal = z0.copy()
    if n == 0:
        return np.empty(0), zfinal
    ident = np.zeros(m, np.bool_)
    W0 = 0.0
    mm = 0
    for i in range(m):
        ident[i] = r[i] == 0.0 and rc[i] == 0.0 and ra[i] == 0.0 and rb[i] == 0.0
        if ident[i]:
            W0 += w[i]
        else:
            mm += 1
    nz = np.empty(mm, np.int64)
    width = np.empty(mm)
    j = 0
    for i in range(m):
        if not ident[i]:
            nz[j] = i
            width[j] = min(r[i] + rb[i], rc[i] + ra[i])
            j += 1
    srt = nz[np.argsort(width, kind="mergesort")]
    nb = max((mm + _L - 1) // _L, 1)
    P = np.zeros((nb, _CP_ROWS, _L))
    for b in range(nb):
        for l in range(_L):
            P[b, 0, l] = -_HUGE
            P[b, 1, l] = -_HUGE
            P[b, 2, l] = _HUGE
            P[b, 3, l] = _HUGE
    for j in range(mm):
        i = srt[j]
        b = j // _L
        l = j % _L
        P[b, 0, l] = -r[i]
        P[b, 1, l] = -rc[i]
        P[b, 2, l] = ra[i]
        P[b, 3, l] = rb[i]
        P[b, 4, l] = w[i]
        P[b, 5, l] = z0[i]
        P[b, 6, l] = 1e-15 * (r[i] + rc[i] + ra[i] + rb[i])
    y = _banded_drive(x, P, W0, 0 if mm == 0 else n_hot_blocks, False)
    for j in range(mm):
        zfinal[srt[j]] = P[j // _L, 5, j % _L]
    for i in range(m):
        if ident[i]:
            zfinal[i] = x[n - 1]
    return y, zfinal


@_jit_exact
def play_sum_banded(x, r, w, z0, x0=0.0, n_hot_blocks=-1):  # pragma: no cover - compiled
    """Weighted play sum ``sum_i w_i z_i`` by the banded scheme of :func:`cp_sum_banded`.

    The play's own update ``max(x - r, min(x + r, z))`` (4 operations per operator instead of
    the CP's 8) and band ``(z - r, z + r)``; operators with ``r = 0`` are the identity.  The
    operator outputs equal :func:`operators.play_reference` bit for bit, for any starting
    state; ``x0`` is ignored as in :func:`cp_sum_banded`.
    """
    x = np.ascontiguousarray(x)  # the vector code indexes the raw data
    n = x.shape[0]
    m = r.shape[0]
    zfinal = z0.copy()
    if n == 0:
        return np.empty(0), zfinal
    W0 = 0.0
    mm = 0
    for i in range(m):
        if r[i] == 0.0:
            W0 += w[i]
        else:
            mm += 1
    nz = np.empty(mm, np.int64)
    width = np.empty(mm)
    j = 0
    for i in range(m):
        if r[i] != 0.0:
            nz[j] = i
            width[j] = r[i]
            j += 1
    srt = nz[np.argsort(width, kind="mergesort")]
    nb = max((mm + _L - 1) // _L, 1)
    P = np.zeros((nb, _PLAY_ROWS, _L))
    for b in range(nb):
        for l in range(_L):
            P[b, 0, l] = _HUGE
    for j in range(mm):
        i = srt[j]
        b = j // _L
        l = j % _L
        P[b, 0, l] = r[i]
        P[b, 1, l] = w[i]
        P[b, 2, l] = z0[i]
        P[b, 3, l] = 4e-15 * r[i]
    y = _banded_drive(x, P, W0, 0 if mm == 0 else n_hot_blocks, True)
    for j in range(mm):
        zfinal[srt[j]] = P[j // _L, 2, j % _L]
    for i in range(m):
        if r[i] == 0.0:
            zfinal[i] = x[n - 1]
    return y, zfinal


@_jit
def _turns_and_stills(x):  # pragma: no cover - compiled
    """Samples where the input turns (``dx(k) * dx(k+1) < 0``) and where it stands still."""
    n = x.shape[0]
    c = 0
    s = 0
    for k in range(1, n - 1):
        d0 = x[k] - x[k - 1]
        c += d0 * (x[k + 1] - x[k]) < 0.0
        s += d0 == 0.0
    return c, s


def turn_fraction(x):
    """Fraction of samples where the input turns (``dx(k) * dx(k+1) < 0``), branch-free.

    A cheap stand-in for :func:`count_reversals` (which also counts turns across standing
    still) for choosing a kernel: it vectorises, so it costs ~0.25 ns per sample.
    """
    return _turns_and_stills(x)[0] / max(x.shape[0], 1)


def _is_smooth(x):
    """True when the input reverses in < 0.5 % of its samples (the event kernels' domain)."""
    n = x.shape[0]
    if n > 1 << 16 and _turns_and_stills(x[: 1 << 16])[0] >= 0.005 * n:
        return False  # a rough record is told from its head (the full scan costs ~0.4 ns a sample)
    turns, stills = _turns_and_stills(x)
    if turns >= 0.005 * n:
        return False
    return stills == 0 or count_reversals(x) < 0.005 * n  # turns across plateaus count too


def cp_sum_auto(x, r, rc, ra, rb, w, z0, x0):
    """Weighted CP sum: event-driven when the input turns in < 0.5 % of the samples (smooth
    records; needs a state consistent at ``x0``), else the banded kernel (random walks and
    anything else; it falls back to updating every operator when that is cheaper).

    The event kernel sorts the slope changes of every operator at each reversal (~0.7 us at
    20 operators, ~3 us at 100 on the benchmark machine) and is then nearly free per sample;
    the banded kernel costs 0.03-0.35 ns per sample and operator whatever the input does
    (least on random walks, most when every operator moves at every sample): they break even
    at about 0.3-0.7 % reversals.
    """
    n = x.shape[0]
    if n > 64 and _is_smooth(x):
        return cp_sum_events(x, r, rc, ra, rb, w, z0, float(x0))
    return cp_sum_banded(x, r, rc, ra, rb, w, z0, float(x0))


@_jit_exact
def gram(Z, y):  # pragma: no cover - compiled
    """``Z'Z``, ``Z'y`` and the column sums of Z, single-threaded (no BLAS thread pool: on a
    busy machine the threaded BLAS made the identification 20x slower)."""
    n, m = Z.shape
    G = np.zeros((m, m))
    g = np.zeros(m)
    s = np.zeros(m)
    for k in range(n):
        yk = y[k]
        for i in range(m):
            zi = Z[k, i]
            s[i] += zi
            g[i] += zi * yk
            for j in range(i + 1):
                G[i, j] += zi * Z[k, j]
    for i in range(m):
        for j in range(i):
            G[j, i] = G[i, j]
    return G, g, s
