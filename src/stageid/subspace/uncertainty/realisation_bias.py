"""The realisation's misfit beyond its noise: a bias term for the realised Hankel-MAP model's bands.

The ``order``-state realisation is a weighted least-squares fit of ``C (zI - A)^-1 B + D`` to
the eq. 9 response ``G_9`` on the band's grid (:mod:`stageid.subspace.uncertainty`).  Where the order cannot
follow ``G_9`` (or the fit settles on a compromise), the misfit ``r = G_model - G_9`` holds more
than the eq. 9 noise leaves after the projection, ``r_noise = (J dx - I) dG_9`` with
``dx = J^+ dG_9``.  As the closed loop's ``bias="local"`` rule does for its reduction
(:mod:`stageid.closedloop.uncertainty`), the excess ``|r|^2 - E|r_noise|^2``, relative to
``|G_model|^2`` and averaged over ``LOCAL_WINDOW`` of the grid on either side, is added to the
variance as ``b^2(f) |G_model(f)|^2``: ``std`` is then the root mean squared error of the
returned model, not only its scatter.  The eq. 9 estimate's own bias (noisy regressors, a
finite horizon) is not in the misfit and stays uncounted; coverage in
``studies/uncertainty/RESULTS.md``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["LOCAL_WINDOW", "SIGNIFICANCE_Z", "misfit_noise", "local_misfit_bias"]

#: The relative misfit is averaged over this fraction of the grid's points on either side.
LOCAL_WINDOW = 0.1
#: Standard normal quantile of the misfit test (1 % level, one-sided).
SIGNIFICANCE_Z = 2.326


def misfit_noise(K: np.ndarray, phi_cov: np.ndarray, phi_dG: np.ndarray, dG_var: np.ndarray) -> np.ndarray:
    """``E|r_noise|^2`` per response entry of the grid, ``r_noise = K phi - dG``, ``phi = Re(F dG)``.

    ``K`` (N, r) complex: the model's response change per tangent coordinate (``J basis``);
    ``phi_cov`` (r, r) and ``phi_dG`` (r, N): ``Cov(phi)`` and ``E[phi conj(dG)^T]``
    (:meth:`~stageid.subspace.uncertainty.TangentProjection.moments`); ``dG_var`` (N,): ``E|dG|^2``.
    ``E|K phi|^2 - 2 Re E[(K phi) conj dG] + E|dG|^2``, shape (N,), real.
    """
    fitted = np.real(np.sum((K @ phi_cov) * np.conj(K), axis=1))
    cross = np.real(np.sum(K * phi_dG.T, axis=1))
    return np.maximum(fitted - 2.0 * cross + dG_var, 0.0)


def local_misfit_bias(
    grid: np.ndarray,
    misfit: np.ndarray,
    noise: np.ndarray,
    G_grid: np.ndarray,
    freqs: np.ndarray,
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """``b^2(f)``: the squared relative misfit beyond its noise on ``grid`` (``misfit`` =
    ``|r|^2``, ``noise`` = ``E|r_noise|^2``, ``G_grid`` the model's response, each (n_grid, q, m)),
    averaged over ``LOCAL_WINDOW`` of the grid on either side, clipped at zero and interpolated
    to ``freqs``; outside the grid the larger of the nearest edge's value and the grid's mean.
    Shape (n_freqs, q, m).  ``weights`` (the quadrature weights of an uneven grid,
    :mod:`.grid_placement`): the window is then ``LOCAL_WINDOW`` of the band on either side in
    frequency, the average weighted, and the significance test is on the weighted sums with
    Satterthwaite's degrees of freedom ``2 (sum w n)^2 / sum (w n)^2``; None: ``LOCAL_WINDOW`` of
    the points, unweighted, two degrees of freedom per point (the former rule)."""
    # only entries whose misfit over the grid exceeds its noise at the 1 % level (a chi-square
    # with two degrees of freedom per point): below that the local excess is the noise's own scatter
    if weights is None:
        nu = 2.0 * grid.size
        significant = misfit.sum(axis=0) > _chi2_level(nu) * noise.sum(axis=0)
    else:
        # uneven points: the weighted sums of the quadrature; their noise is dominated by the few
        # points at resonances, so the degrees of freedom are Satterthwaite's, not two per point
        wn = np.asarray(weights, dtype=float)[:, None, None] * noise
        nu = 2.0 * wn.sum(axis=0) ** 2 / np.maximum((wn**2).sum(axis=0), 1e-300)
        wm = np.asarray(weights, dtype=float)[:, None, None] * misfit
        significant = wm.sum(axis=0) > _chi2_level(np.maximum(nu, 1.0)) * wn.sum(axis=0)
    scale = np.abs(G_grid) ** 2
    scale = np.maximum(scale, 1e-12 * max(float(scale.max()), 1e-300))
    excess = (misfit - noise) / scale
    if weights is None:
        h = max(1, int(round(LOCAL_WINDOW * grid.size)))
        kernel = np.ones(2 * h + 1)
        count = np.convolve(np.ones(grid.size), kernel, mode="same")
        smooth = np.apply_along_axis(lambda x: np.convolve(x, kernel, mode="same"), 0, excess) / count[:, None, None]
    else:
        # uneven points (dense at resonances): a window in frequency, each point by the share it stands for
        near = np.abs(grid[:, None] - grid[None, :]) <= LOCAL_WINDOW * (grid[-1] - grid[0])
        W = near * np.asarray(weights, dtype=float)[None, :]
        smooth = np.einsum("kl,lij->kij", W / W.sum(axis=1, keepdims=True), excess)
    smooth = np.maximum(smooth, 0.0)
    out = np.empty((freqs.size,) + excess.shape[1:])
    for i in range(excess.shape[1]):
        for j in range(excess.shape[2]):
            out[:, i, j] = np.interp(freqs, grid, smooth[:, i, j])
    outside = (freqs < grid[0]) | (freqs > grid[-1])
    w = np.ones(grid.size) if weights is None else np.asarray(weights, dtype=float)
    mean = np.einsum("k,kij->ij", w / w.sum(), excess)  # the grid's mean, each point by its share
    out[outside] = np.maximum(out[outside], np.maximum(mean, 0.0)[None])
    return out * significant[None]


def _chi2_level(nu):
    """Upper ``SIGNIFICANCE_Z`` quantile of ``chi2(nu) / nu`` (Wilson-Hilferty)."""
    return (1.0 - 2.0 / (9.0 * nu) + SIGNIFICANCE_Z * np.sqrt(2.0 / (9.0 * nu))) ** 3
