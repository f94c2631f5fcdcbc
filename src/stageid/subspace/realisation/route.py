"""What every route from the eq. 9 estimate to ``(A, B, C, D)`` is given (Cao & Chen 2013, eq. 10-15).

:func:`~.era.realize` builds one :class:`RouteTask` and hands it to the route picked by name
(``REALIZATIONS``: :func:`~.era.markov_realization`, :func:`~.frequency_domain.response_realization`),
so that a new route needs only a function of the task.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["RouteTask"]


@dataclass(frozen=True, eq=False)
class RouteTask:
    """The inputs of a realisation route.

    Attributes
    ----------
    theta : ndarray of shape (p q, 2 p m + p q)
        ``[Gamma Phi D_p]`` (eq. 16), outputs noise-whitened (:mod:`.weighting`).
    horizon, n_inputs, n_outputs, order : int
        ``p``, ``m``, ``q`` and the number of states asked for.
    freqs : ndarray of shape (n_freqs,)
        The band of the frequency route, in Hz (not used by the Markov route).
    dt : float
        Sample time in s.
    feedthrough, refine : bool
        Estimate ``D``; refine the frequency route by output error.
    max_iter : int
        Refinement steps at most.
    """

    theta: np.ndarray
    horizon: int
    n_inputs: int
    n_outputs: int
    order: int
    freqs: np.ndarray
    dt: float
    feedthrough: bool = False
    refine: bool = True
    max_iter: int = 30

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(p, m, q)``."""
        return self.horizon, self.n_inputs, self.n_outputs
