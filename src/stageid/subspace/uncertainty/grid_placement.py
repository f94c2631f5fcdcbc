"""Where the realised model's covariance is formed: a few of the realisation's frequencies.

The realisation (:mod:`stageid.subspace.uncertainty`) is a weighted least-squares fit on ``n_fit`` frequencies
evenly over the band; its tangent projection, and so the realised model's covariance, is a sum
over those frequencies.  The exact eq. 9 covariance (:mod:`~stageid.subspace.statistics.window_covariance`) costs the square
of the frequencies it is formed on, so it is formed on at most ``budget`` of them and the sum is
approximated by a quadrature: every kept frequency stands for the fit's frequencies nearest to
it (its weight is their number).  An even subset (``"even"``, every ``s``-th frequency, equal
weights) resolves a smooth response; it misses a lightly damped mode whose peak falls between
its points, and the projection then rests on the mode's flanks, where the fit is least
informative about it: the realised parameters look less constrained than they are.

``"modes"`` (the rule, fixed from the resolution each mode's peak needs, before any coverage
study was run with it):

1. The modes are the realised model's complex pole pairs (``s = ln z / dt``) with a damped
   frequency ``f_d = Im s / 2 pi`` inside the band and a half-power half-width
   ``h = -Re s / 2 pi = zeta f_n`` narrower than the even subset's spacing ``delta``
   (fewer than about two of its points in the half-power band ``f_d +- h``).  Those wider are
   resolved by the even subset, and a model without such modes keeps the even subset (its
   frequencies and equal weights: the former grid).
2. Near a mode the response is ``r / (j 2 pi (f - f_d) + 2 pi h)`` plus a smooth rest: a circle
   in the complex plane, traced at the angle ``theta = atan((f - f_d) / h)`` (twice it on the
   circle).  Points at equal steps of ``theta`` are equally spaced along the circle, half of
   them inside the half-power band (``|theta| < 45 deg``): the density of the points of mode
   ``i`` in frequency is ``h / (pi (h^2 + (f - f_d)^2))`` (a Cauchy density, cut to the band).
3. Half the points follow the modes (their densities averaged), half the even background:
   the frequencies are the ``budget`` quantiles (at ``k / (budget - 1)``, so both ends of the
   band are kept, as by the even subset) of ``1/2 uniform(band) + 1/2 mean_i Cauchy(f_d_i, h_i)``.
   The half that stays even keeps the background at twice the even subset's spacing, where the
   response is a sum of mode tails and smooth.  Each of ``M`` modes gets ``(budget - 1) / 2M``
   quantile steps, half of them across its half-power band: at least one point there while
   ``M <= (budget - 1) / 4``, and at least three within ``f_d +- 3 h`` (80 % of its circle)
   while ``M <= 0.4 (budget - 1) / 3`` (before step 4, which moves a point by up to half the
   fit's spacing).
4. Every point is moved to the nearest frequency of the fit's grid (the quadrature then
   approximates the fit's own sum, and the full grid reproduces it); duplicates are dropped,
   so at most ``budget`` points remain, all inside the band and so below Nyquist.  The
   weight of a kept frequency is the number of the fit's frequencies nearer to it than to
   any other kept one (halves at ties).

No constant of the rule was set from a coverage figure; the measured effect, and why the band's
ends are kept (the bias term of :mod:`.realisation_bias` would extrapolate there), are in
``studies/uncertainty/RESULTS.md``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["GRID_PLACEMENTS", "resonances", "even_indices", "mode_indices", "quadrature_weights", "placed_grid"]

#: ``placement`` of :func:`placed_grid`: ``"modes"`` (the rule above) or ``"even"`` (a stride).
GRID_PLACEMENTS = ("modes", "even")


def resonances(A: np.ndarray, dt: float | None, band: tuple[float, float]) -> np.ndarray:
    """``(f_d, h)`` in Hz of the complex pole pairs of ``A`` with ``f_d`` inside ``band`` and
    ``h = -Re s / 2 pi > 0`` (``s = ln z / dt``, or the eigenvalue itself when ``dt`` is None),
    shape (n_modes, 2), sorted by ``f_d``.

    Examples
    --------
    >>> w = 2 * np.pi * 10.0
    >>> A = np.array([[0.0, 1.0], [-w * w, -2 * 0.01 * w]])   # 10 Hz, 1 % damping
    >>> np.round(resonances(A, None, (1.0, 100.0)), 3).tolist()
    [[9.999, 0.1]]
    """
    ev = np.linalg.eigvals(A) if A.size else np.zeros(0, complex)
    if dt is not None:
        ev = ev[np.abs(ev) > 0]
        s = np.log(ev.astype(complex)) / dt
    else:
        s = ev.astype(complex)
    s = s[s.imag > 0]  # one of each pair; real poles are no resonance
    fd, h = s.imag / (2 * np.pi), -s.real / (2 * np.pi)
    keep = (fd >= band[0]) & (fd <= band[1]) & (h > 0)
    order = np.argsort(fd[keep])
    return np.column_stack([fd[keep][order], h[keep][order]])


def even_indices(n_fit: int, budget: int) -> np.ndarray:
    """Every ``ceil(n_fit / budget)``-th index of the fit's grid (at most ``budget``)."""
    stride = max(1, int(np.ceil(n_fit / max(int(budget), 1))))
    return np.arange(0, n_fit, stride)


def mode_indices(fit_grid: np.ndarray, budget: int, modes: np.ndarray) -> np.ndarray:
    """Indices of the fit's grid chosen by the rule of the module docstring (sorted, unique)."""
    n_fit = fit_grid.size
    even = even_indices(n_fit, budget)
    if even.size >= n_fit or n_fit < 2:
        return even
    lo, hi = float(fit_grid[0]), float(fit_grid[-1])
    delta = (hi - lo) * (even[1] - even[0]) / (n_fit - 1) if even.size > 1 else hi - lo
    narrow = modes[(modes[:, 1] < delta)] if modes.size else modes
    if narrow.size == 0:
        return even
    budget = even.size  # no more points than the even subset
    # the mixture's cumulative distribution on a fine grid, inverted at the budget's quantiles
    f = np.linspace(lo, hi, 64 * n_fit)
    fd, h = narrow[:, 0][:, None], narrow[:, 1][:, None]
    arc = (np.arctan((f[None] - fd) / h) - np.arctan((lo - fd) / h)) / (
        np.arctan((hi - fd) / h) - np.arctan((lo - fd) / h)
    )
    cdf = 0.5 * (f - lo) / (hi - lo) + 0.5 * arc.mean(axis=0)
    targets = np.interp(np.linspace(0.0, 1.0, budget), cdf, f)
    idx = np.rint((targets - lo) / (hi - lo) * (n_fit - 1)).astype(int)
    return np.unique(np.clip(idx, 0, n_fit - 1))


def quadrature_weights(indices: np.ndarray, n_fit: int) -> np.ndarray:
    """How many of the fit's ``n_fit`` frequencies each kept index stands for (the nearest kept
    one; halves at ties): sums to ``n_fit``."""
    k = np.asarray(indices, dtype=float)
    edges = np.concatenate([[-0.5], 0.5 * (k[1:] + k[:-1]), [n_fit - 0.5]])
    return np.diff(edges)


def placed_grid(
    band: tuple[float, float], n_fit: int, budget: int, A: np.ndarray, dt: float | None, placement: str = "modes"
) -> tuple[np.ndarray, np.ndarray]:
    """The covariance grid (Hz) and its quadrature weights: ``"modes"`` by the module's rule for
    the realised model's state matrix ``A``, ``"even"`` every ``s``-th frequency of the fit's grid
    with equal weights (the former grid).  At most ``budget`` points of the fit's grid."""
    fit_grid = np.linspace(band[0], band[1], n_fit)
    if placement == "even":
        idx = even_indices(n_fit, budget)
        return fit_grid[idx], np.ones(idx.size)
    idx = mode_indices(fit_grid, int(budget), resonances(A, dt, band))
    even = even_indices(n_fit, budget)
    if idx.size == even.size and np.array_equal(idx, even):
        return fit_grid[idx], np.ones(idx.size)  # no mode needs more points: the former grid
    return fit_grid[idx], quadrature_weights(idx, n_fit)
