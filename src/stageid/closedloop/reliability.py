"""How far the deduced plant can be trusted, frequency by frequency (eq. 18 to first order).

``G = T U^-1`` with ``U = M_r - M T`` gives, for an error ``dT`` of the identified loop,

    dG = dT U^-1 + T U^-1 M dT U^-1 = (I + G M) dT U^-1,

so an error of ``T`` of one size at every frequency (the pairs' bias near the noise floor)
becomes an error of entry ``(i, j)`` of ``G`` of at most ``|dT| ||row i of (I + G M)||
||column j of U^-1||``.  Below the crossover ``U`` is small (``I - T`` is the sensitivity) and
this gain large: a coupling deduced from a loop whose ``T`` is within 1e-3 of the truth can be
off by several times its own size at the lower band edge while it is within 1 % in the middle
of the band.  The reduction weighs each line by this gain so that such edges do not decide it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["deduction_gain", "reliability_weights"]


def deduction_gain(T: np.ndarray, M: np.ndarray, G: np.ndarray, Mr: np.ndarray | None = None) -> np.ndarray:
    """``||row i of (I + G M)|| ||column j of (M_r - M T)^-1||`` per line and entry.

    Parameters
    ----------
    T, M, G : ndarray of complex, shape (n_freqs, p, p)
        Identified closed loop, controller and deduced plant at the same lines.
    Mr : ndarray of complex, shape (n_freqs, p, p), optional
        Reference filter of a two-degree-of-freedom law (default ``M``).

    Returns
    -------
    ndarray of shape (n_freqs, p, p)
        The first-order gain from a unit error of ``T`` to entry ``(i, j)`` of ``G``.

    Examples
    --------
    >>> import numpy as np
    >>> G, M = np.array([[[2.0]]]), np.array([[[0.5]]])
    >>> T = G * M / (1 + G * M)
    >>> float(deduction_gain(T, M, G)[0, 0, 0])  # (1 + G M) / (M (1 - T)) = 2 / 0.25
    8.0
    """
    eye = np.eye(T.shape[1])
    U = (M if Mr is None else Mr) - M @ T
    rows = np.linalg.norm(eye + G @ M, axis=2)  # (n_freqs, p): row i of I + G M
    cols = np.linalg.norm(np.linalg.inv(U), axis=1)  # (n_freqs, p): column j of U^-1
    return rows[:, :, None] * cols[:, None, :]


def reliability_weights(response: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """Weights of an entry's relative error over the band: 1 where the deduction's gain relative
    to the entry is at most its median over the band, falling as ``median / (gain / |P|)`` above.

    The relative error ``(P_r - P) / P`` is right where the deduced response holds (the entry's
    size sets the scale of its misfit); where an error of ``T`` reaches the entry amplified more
    than it does in the middle of the band, the misfit is counted in units of that amplified error
    instead.  ``response`` and ``gain`` have shape (n_freqs,) or (n_freqs, p, p), lines first; the
    weights, of the same shape, are in (0, 1].

    Examples
    --------
    >>> reliability_weights(np.array([1.0, 1.0, 1.0]), np.array([1.0, 2.0, 8.0])).tolist()
    [1.0, 1.0, 0.25]
    """
    rel = np.asarray(gain, dtype=float) / np.maximum(np.abs(response), 1e-300)
    ref = np.median(rel, axis=0, keepdims=True)
    ok = np.isfinite(ref) & (ref > 0)
    return np.where(ok, 1.0 / np.maximum(1.0, rel / np.where(ok, ref, 1.0)), 1.0)
