"""Banded play and CP sums: only the blocks of operators the input can move are updated.

Operators are sorted by band width into blocks of 4 (:mod:`.band_codegen`).  A block knows
the open interval of inputs in which none of its operators moves; the narrowest ("hot")
blocks are updated at every sample, the others ("cold") only when the input leaves their
band, with the plain formula, so every operator output is the reference's exactly and only
the weighted sum is associated differently (~1e-16 relative).  The number of hot blocks is
chosen from a cost model of the measured band exits (:func:`banded_drive`).
"""

from __future__ import annotations

import numba
import numpy as np

from .band_codegen import (
    INERT,
    LANES,
    make_block,
    make_hot,
    make_run,
    outside4,
    reduce4,
)
from .loops import FASTMATH, jit, jit_exact
from .ordering import stable_argsort

__all__ = ["cp_sum_banded", "play_sum_banded", "banded_drive", "BAND_BLOCK"]

BAND_BLOCK = 2048  #: samples between two choices of the number of hot blocks
_inline = numba.njit(cache=True, nogil=True, fastmath=FASTMATH, inline="always")  # helpers of run_band

_cp_hot, _play_hot = make_hot("cp"), make_hot("play")
_cp_block, _play_block = make_block("cp"), make_block("play")
_cp_run, _play_run = make_run("cp"), make_run("play")


@_inline
def block_update(P, b, xk, play):  # pragma: no cover - compiled
    """Plain update of block b at xk: (weighted sum, band low, band high)."""
    if play:
        return _play_block(P, b, xk)
    return _cp_block(P, b, xk)


@jit
def refresh(xk, n_hot, P, Cb, lob, hib, state, play):  # pragma: no cover - compiled
    """Exact update of every cold block (``n_hot ..``) at xk: sums, bands, state[0:3]."""
    C = 0.0
    hi = 1e308
    lo = -1e308
    for b in range(n_hot, P.shape[0]):
        cb, lb, hb = block_update(P, b, xk, play)
        Cb[b] = cb
        lob[b] = lb
        hib[b] = hb
        C += cb
        hi = hb if hb < hi else hi
        lo = lb if lb > lo else lo
    state[0] = C
    state[1] = lo
    state[2] = hi


@_inline
def leave_band(xk, n_hot, P, Cb, lob, hib, counts, play):  # pragma: no cover - compiled
    """The input left the cold band at xk: update the cold blocks it left (found 4 at a time).

    Returns the new cold sum and band (C, lo, hi); ``counts[1:4]`` get the block updates,
    whether a block other than the first cold one moved, and the first cold one's updates.
    """
    nb = P.shape[0]
    C = 0.0
    hi = 1e308
    lo = -1e308
    beyond = False
    for g in range(n_hot, nb, LANES):
        left = outside4(lob, hib, g, xk)
        if nb - g < LANES:
            left &= (1 << (nb - g)) - 1  # (the padding is never left; belt and braces)
        if left != 0:
            for j in range(LANES):
                if (left >> j) & 1:
                    b = g + j
                    counts[1] += 1
                    if b == n_hot:
                        counts[3] += 1
                    else:
                        beyond = True
                    Cb[b], lob[b], hib[b] = block_update(P, b, xk, play)
        cg, lg, hg = reduce4(Cb, lob, hib, g)
        C += cg
        hi = hg if hg < hi else hi
        lo = lg if lg > lo else lo
    counts[2] += beyond
    return C, lo, hi


@jit
def run_band(x, y, k0, k1, n_hot, P, Cb, lob, hib, W0, state, counts, play):  # pragma: no cover - compiled
    """Samples ``k0 .. k1-1`` of the banded sums; ``state = [C, lo, hi, x_last, y_last]``.

    The first ``n_hot`` blocks are updated at every sample that moves.  A cold block ``b``
    holds its weighted sum ``Cb[b]`` and the open band ``(lob[b], hib[b])`` of inputs at which
    none of its operators moves; ``C``/``lo``/``hi`` are the sum over the cold blocks and the
    intersection of their bands.  Only when the input leaves that band are the cold blocks it
    left updated.  ``counts`` gets the number of band exits, of block updates, of exits that
    update a block other than the first cold one and of updates of the first cold one (what
    one more hot block would save).
    """
    C, lo, hi, xl, yl = state[0], state[1], state[2], state[3], state[4]
    counts[:] = 0
    k = k0
    while k < k1:
        if play:
            k, xl, yl = _play_run(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)
        else:
            k, xl, yl = _cp_run(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)
        if k >= k1:
            break
        xk = x[k]
        counts[0] += 1
        C, lo, hi = leave_band(xk, n_hot, P, Cb, lob, hib, counts, play)
        yl = C + W0 * xk
        if n_hot > 0:
            yl += _play_hot(P, n_hot, xk) if play else _cp_hot(P, n_hot, xk)
        y[k] = yl
        xl = xk
        k += 1
    state[0], state[1], state[2], state[3], state[4] = C, lo, hi, xl, yl


@jit
def banded_drive(x, P, W0, n_hot_blocks, play):  # pragma: no cover - compiled
    """Model output of the packed blocks P for the input x (n >= 1); P's outputs updated.

    The first sample is the plain update of every block.  ``n_hot_blocks < 0`` re-chooses the
    number of hot blocks every ``BAND_BLOCK`` samples from a cost model of the measured band
    exits and block updates: a hot block costs ``c_hot`` at every sample, a band exit
    ``c_exit`` plus 0.9 per cold block scanned, a block update ``c_update`` (ns, fitted to
    timings; ``benchmarks/RESULTS-hysteresis.md``).  The cost with one more hot block is
    predicted exactly from the counts; one block less is measured again every 32 choices.
    """
    n = x.shape[0]
    nb = P.shape[0]
    y = np.empty(n)
    Cb = np.zeros(nb + LANES - 1)  # padded: the exit scan reads 4 blocks at a time
    lob = np.full(nb + LANES - 1, -1e308)
    hib = np.full(nb + LANES - 1, 1e308)
    state = np.empty(5)
    counts = np.zeros(4, np.int64)
    xs = x[0]
    # int64 counters, not literals: numba compiles a callee once more for every literal type it sees
    refresh(xs, np.int64(0), P, Cb, lob, hib, state, play)
    y[0] = state[0] + W0 * xs
    state[3] = xs
    state[4] = y[0]
    adapt = n_hot_blocks < 0
    n_hot = 1 if adapt else min(n_hot_blocks, nb)
    if n_hot > 0:
        refresh(xs, n_hot, P, Cb, lob, hib, state, play)
    c_hot = 0.8 if play else 1.35
    c_exit = 20.0
    c_update = 4.2 if play else 5.2
    est = np.zeros(nb + 1)  # estimated ns per sample for each number of hot blocks (0: not tried)
    n_blocks = 0
    k = np.int64(1)
    while k < n:
        k1 = min(n, k + BAND_BLOCK)
        run_band(x, y, k, k1, n_hot, P, Cb, lob, hib, W0, state, counts, play)
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
                refresh(state[3], n_hot, P, Cb, lob, hib, state, play)
                state[4] = y[k1 - 1]
        k = k1
    return y


@jit_exact
def by_band_width(ident, width, w):  # pragma: no cover - compiled
    """``(W0, order)``: the summed weight of the identity operators (``ident``), and the other
    operators' indices sorted by band ``width`` (stable: equal widths keep their order)."""
    W0 = 0.0
    mm = 0
    for i in range(ident.shape[0]):
        if ident[i]:
            W0 += w[i]
        else:
            mm += 1
    live = np.empty(mm, np.int64)
    widths = np.empty(mm)
    j = 0
    for i in range(ident.shape[0]):
        if not ident[i]:
            live[j] = i
            widths[j] = width[i]
            j += 1
    return W0, live[stable_argsort(widths)]


@jit_exact
def in_blocks(order, rows, padding):  # pragma: no cover - compiled
    """The operators ``order`` in blocks of ``LANES``: ``P[b, k, l]`` is ``rows[k]`` of operator
    ``order[b * LANES + l]``; the lanes past the last operator hold ``padding[k]`` (an inert
    operator: zero weight, thresholds it never reaches)."""
    nb = max((order.shape[0] + LANES - 1) // LANES, 1)
    P = np.empty((nb, rows.shape[0], LANES))
    for b in range(nb):
        for k in range(rows.shape[0]):
            P[b, k, :] = padding[k]
    for j in range(order.shape[0]):
        for k in range(rows.shape[0]):
            P[j // LANES, k, j % LANES] = rows[k, order[j]]
    return P


@jit_exact
def banded_sum(x, P, W0, order, ident, z0, row, n_hot_blocks, play):  # pragma: no cover - compiled
    """The weighted sums over ``x`` of the packed blocks ``P`` (operators ``order`` by band width,
    their outputs in row ``row``) and ``W0`` times the input, and the final operator outputs
    (the identity operators' is the last input)."""
    x = np.ascontiguousarray(x)  # the vector code indexes the raw data
    zfinal = z0.copy()
    if x.shape[0] == 0:
        return np.empty(0), zfinal
    y = banded_drive(x, P, W0, 0 if order.shape[0] == 0 else n_hot_blocks, play)
    for j in range(order.shape[0]):
        zfinal[order[j]] = P[j // LANES, row, j % LANES]
    for i in range(ident.shape[0]):
        if ident[i]:
            zfinal[i] = x[-1]
    return y, zfinal


@jit_exact
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
    m = r.shape[0]
    ident = np.zeros(m, np.bool_)
    width = np.empty(m)
    for i in range(m):
        ident[i] = r[i] == 0.0 and rc[i] == 0.0 and ra[i] == 0.0 and rb[i] == 0.0
        width[i] = min(r[i] + rb[i], rc[i] + ra[i])
    W0, srt = by_band_width(ident, width, w)
    rows = np.vstack((-r, -rc, ra, rb, w, z0, 1e-15 * (r + rc + ra + rb)))
    P = in_blocks(srt, rows, np.array([-INERT, -INERT, INERT, INERT, 0.0, 0.0, 0.0]))
    return banded_sum(x, P, W0, srt, ident, z0, 5, n_hot_blocks, False)


@jit_exact
def play_sum_banded(x, r, w, z0, x0=0.0, n_hot_blocks=-1):  # pragma: no cover - compiled
    """Weighted play sum ``sum_i w_i z_i`` by the banded scheme of :func:`cp_sum_banded`.

    The play's own update ``max(x - r, min(x + r, z))`` (4 operations per operator instead of
    the CP's 8) and band ``(z - r, z + r)``; operators with ``r = 0`` are the identity.  The
    operator outputs equal :func:`operators.play_reference` bit for bit, for any starting
    state; ``x0`` is ignored as in :func:`cp_sum_banded`.
    """
    ident = r == 0.0
    W0, srt = by_band_width(ident, r, w)
    P = in_blocks(srt, np.vstack((r, w, z0, 4e-15 * r)), np.array([INERT, 0.0, 0.0, 0.0]))
    return banded_sum(x, P, W0, srt, ident, z0, 2, n_hot_blocks, True)
