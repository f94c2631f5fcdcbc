"""Which sum kernel a model runs: event-driven on smooth records, banded otherwise.

The event kernels sort slope changes at every reversal and are nearly free per sample; the
banded kernels cost about the same per sample whatever the input does; they break even at
about 0.3-0.7 % reversals (``benchmarks/RESULTS-hysteresis.md``).
"""

from __future__ import annotations

from .banded import cp_sum_banded, play_sum_banded
from .events import count_reversals, cp_sum_events, lipschitz_state, play_sum_events
from .loops import jit, play_sum


@jit
def turns_and_stills(x):  # pragma: no cover - compiled
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
    still) for choosing a kernel: it has no branches, so it vectorises.
    """
    return turns_and_stills(x)[0] / max(x.shape[0], 1)


def is_smooth(x):
    """True when the input reverses in < 0.5 % of its samples (the event kernels' domain)."""
    n = x.shape[0]
    if n > 1 << 16 and turns_and_stills(x[: 1 << 16])[0] >= 0.005 * n:
        return False  # a rough record is told from its head, without scanning all of it
    turns, stills = turns_and_stills(x)
    if turns >= 0.005 * n:
        return False
    return stills == 0 or count_reversals(x) < 0.005 * n  # turns across plateaus count too


def cp_sum_auto(x, r, rc, ra, rb, w, z0, x0):
    """Weighted CP sum: event-driven when the input turns in < 0.5 % of the samples (smooth
    records; needs a state consistent at ``x0``), else the banded kernel (random walks and
    anything else; it falls back to updating every operator when that is cheaper).

    The event kernel sorts the slope changes of every operator at each reversal and is then
    nearly free per sample; the banded kernel costs about the same per sample whatever the
    input does: they break even at a few reversals per thousand samples
    (``benchmarks/RESULTS-hysteresis.md``).
    """
    n = x.shape[0]
    if n > 64 and is_smooth(x):
        return cp_sum_events(x, r, rc, ra, rb, w, z0, float(x0))
    return cp_sum_banded(x, r, rc, ra, rb, w, z0, float(x0))


def play_sum_auto(x, r, w, z0, x0):
    """Weighted play sum: the event-driven kernel for smooth records (the input turns in
    < 0.5 % of the samples; ascending thresholds and a Lipschitz state required), else the
    banded play kernel; records of up to 64 samples use the loop.  All give the reference's
    operator outputs; the sums agree to rounding (~1e-15 relative).

    The event kernel's cost per reversal grows with the number of operators the last stroke
    moved, so it loses to the banded kernel on inputs that turn often and wins on smooth
    records (``benchmarks/RESULTS-hysteresis.md``).
    """
    n = x.shape[0]
    if n > 64 and is_smooth(x) and lipschitz_state(r, z0):
        return play_sum_events(x, r, w, z0, float(x0))
    if n > 64:
        return play_sum_banded(x, r, w, z0, float(x0))
    return play_sum(x, r, w, z0)
