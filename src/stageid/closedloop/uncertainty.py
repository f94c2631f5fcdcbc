"""Uncertainty of the identified plant: the PEM covariance carried through eq. 18 and the reduction.

Delta method, step by step (all first order, evaluated at the estimate):

1. each pair ``T_ij`` moves by ``dT_ij = g_ij dtheta_ij``, ``g_ij = dT_ij / dtheta_ij`` on the unit
   circle, ``dtheta_ij`` with the covariance of :mod:`~stageid.closedloop.covariance`; the pairs
   are independent (own output channel or own experiment);
2. eq. 18, ``G = T U^-1`` with ``U = M_r - M T``, gives ``dG = dT U^-1 + G M dT U^-1
   = (I + G M) dT U^-1``, so ``dG_ab = sum_ij (I + G M)_ai dT_ij (U^-1)_jb``;
3. the reduction (sec. 3.3) is a least-squares fit of the reduced entry ``P_r(phi)`` to the
   deduced response over the band, with relative residual ``r = (ZOH{P_r} - P) / P``.  By the
   implicit-function theorem its parameters move by ``dphi = J_r^+ (dP / P)`` (real and
   imaginary parts stacked, ``J_r = d r / d phi``), and the returned model at any frequency by
   ``dP_r(f) = dP_r/dphi(f) dphi``.  Cancellation (sec. 3.2.3) removes pairs that cancel to the
   tolerance: it does not move the response, so it adds nothing to first order.

**The reduction's bias.**  A fixed structure that cannot follow the deduced response leaves a
systematic error the noise does not explain.  It is estimated per entry as the band's mean
squared relative misfit beyond its noise expectation,
``b^2 = max(0, ||r||^2 - E||r_noise||^2) / n_band`` with ``r_noise = (I - J_r J_r^+) dP / P``,
and added as ``b^2 |P_r(f)|^2`` at every frequency (a relative error flat in frequency,
extrapolated outside the band), so ``std`` is the root mean squared error of the returned
model and not only its scatter.

With the ``"full"`` structure the returned plant is the cancelled deduction: its ``std`` is
that of step 2.
"""

from __future__ import annotations

import numpy as np

from .._errors import DataError, IdentificationError
from ..frf.frd import FrequencyResponse
from .covariance import transfer_gradient
from .reduction import ReducedEntry, zoh_response

__all__ = ["check_frequencies", "deduction_sensitivity", "deduced_variance", "plant_uncertainty"]


def check_frequencies(freqs_hz: object) -> np.ndarray:
    """A 1-D grid of finite, positive, strictly increasing frequencies; DataError otherwise."""
    f = np.asarray(freqs_hz, dtype=float).reshape(-1)
    if f.size == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0) or np.any(np.diff(f) <= 0):
        raise DataError("`freqs_hz` must be finite, > 0 Hz and strictly increasing, with at least one frequency.")
    return f


def deduction_sensitivity(result, freqs_hz: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict, np.ndarray]:
    """``(L, R, g, P)`` at ``freqs_hz``: ``dG_ab = sum_ij L_ai dT_ij R_jb`` (eq. 18 linearised).

    ``L = I + G M`` and ``R = (M_r - M T)^-1``, shape (n_freqs, p, p); ``g`` = ``{(i, j): dT_ij /
    dtheta}``, complex (n_freqs, n_par); ``P`` the deduced response.
    """
    cov = result.covariance
    with np.errstate(all="ignore"):
        T = result.closed_loop.frequency_response(freqs_hz)
        M = result.controller.frequency_response(freqs_hz)
        Mr = M if cov.reference_filter is None else cov.reference_filter.frequency_response(freqs_hz)
    R = np.linalg.inv(Mr - M @ T)
    P = T @ R
    L = np.eye(T.shape[1])[None] + P @ M
    g = {ij: transfer_gradient(m, freqs_hz) for ij, m in result.pem_models.items()}
    return L, R, g, P


def _quadratic(H: np.ndarray, C: np.ndarray) -> np.ndarray:
    """``E|H dtheta|^2`` per row for ``dtheta`` of covariance ``C``: ``diag(H C H^H)``."""
    return ((H @ C) * H.conj()).real.sum(axis=1)


def deduced_variance(result, freqs_hz: np.ndarray) -> np.ndarray:
    """``E|dG_ab|^2`` of the full-order deduction (steps 1-2), shape (n_freqs, p, p)."""
    L, R, g, _ = deduction_sensitivity(result, freqs_hz)
    p = L.shape[1]
    var = np.zeros(L.shape)
    for (i, j), gij in g.items():
        C = result.covariance.covariances[(i, j)]
        for a in range(p):
            for b in range(p):
                var[:, a, b] += _quadratic((L[:, a, i] * R[:, j, b])[:, None] * gij, C)
    return var


def plant_uncertainty(result, freqs_hz: object) -> FrequencyResponse:
    """The returned plant's response and ``std = sqrt(E|G_est - G|^2)`` at ``freqs_hz`` (see the module notes).

    Raises
    ------
    DataError
        A grid that is not finite, positive and increasing.
    IdentificationError
        When the result carries no covariance (fitted with ``covariance="none"``).
    """
    f = check_frequencies(freqs_hz)
    if result.covariance is None:
        raise IdentificationError(
            "this closed-loop result has no parameter covariance: fit with covariance='sandwich' or 'white'."
        )
    with np.errstate(all="ignore"):
        G = result.plant.frequency_response(f)
    if not np.all(np.isfinite(G)):
        raise DataError("`freqs_hz` hits a pole of the identified plant; choose other frequencies.")
    if not result.reduced:  # "full": the cancelled deduction, step 2 only
        var = deduced_variance(result, f)
    else:
        var = _reduced_variance(result, f, G)
    return FrequencyResponse(f, G, np.sqrt(var), None, result.plant.inputs, result.plant.outputs)


def _reduced_variance(result, f: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Steps 1-3 for every entry of a reduced plant, plus its bias term."""
    fb = result.covariance.band_freqs
    L, R, g, P = deduction_sensitivity(result, fb)
    w0 = 2 * np.pi * np.sqrt(fb[0] * fb[-1])
    discrete = result.plant.dt is not None
    var = np.zeros(G.shape)
    for (a, b), red in result.reduced.items():
        Pab = P[:, a, b]
        Jr = _stack(_tangent(red, fb, result.dt, w0, zoh=True) / Pab[:, None])
        Q = np.linalg.pinv(Jr, rcond=1e-10)
        E = _tangent(red, f, result.dt, w0, zoh=discrete)
        noise_resid = 0.0
        for (i, j), gij in g.items():
            C = result.covariance.covariances[(i, j)]
            S = _stack((L[:, a, i] * R[:, j, b] / Pab)[:, None] * gij)  # d(dP/P)/dtheta, stacked
            QS = Q @ S
            var[:, a, b] += _quadratic(E @ QS, C)
            Rn = S - Jr @ QS  # what the fit leaves of the noise
            noise_resid += float(np.sum((Rn @ C) * Rn))
        fit = _stack((zoh_response(red.num, red.den, result.dt, fb) - Pab) / Pab)
        bias2 = max(0.0, float(fit @ fit) - noise_resid) / fb.size
        var[:, a, b] += bias2 * np.abs(G[:, a, b]) ** 2
    return var


def _stack(Z: np.ndarray) -> np.ndarray:
    return np.concatenate([Z.real, Z.imag], axis=0)


def _tangent(red: ReducedEntry, f: np.ndarray, dt: float, w0: float, zoh: bool) -> np.ndarray:
    """``d P_r / d phi`` at ``f``, complex (n_freqs, n_phi), of ``P_r = b(s) / (d_u(s) d_s(s))``.

    ``phi`` are the numerator coefficients and the free (monic) denominator factor ``d_s``'s,
    in the normalised variable ``s / w0``; the kept unstable poles ``d_u`` are fixed, as in
    the fit.  Any parametrisation of the same model family spans the same tangent, so the
    projection does not depend on this choice.  ``zoh``: of the ZOH equivalent at ``dt``
    (time-scaled by ``w0``, exact), else of ``P_r(j w)``.
    """
    num_n = red.num * w0 ** np.arange(red.num.size - 1, -1, -1.0)
    den_n = red.den * w0 ** np.arange(red.den.size - 1, -1, -1.0)
    num_n, den_n = num_n / den_n[0], den_n / den_n[0]
    up = np.asarray(red.unstable_poles, dtype=complex)
    du_n = np.real(np.poly(up / w0)) if up.size else np.array([1.0])
    ds_n = np.polydiv(den_n, du_n)[0]
    tfs = [(np.concatenate([[1.0], np.zeros(k)]), den_n) for k in range(num_n.size)]
    den_a = np.polymul(den_n, ds_n)
    num_du = np.polymul(num_n, du_n)
    tfs += [(-np.concatenate([num_du, np.zeros(k)]), den_a) for k in range(ds_n.size - 1)]
    if zoh:
        return np.column_stack([zoh_response(nm, dn, dt * w0, f / w0) for nm, dn in tfs])
    s = 2j * np.pi * f / w0
    return np.column_stack([np.polyval(nm, s) / np.polyval(dn, s) for nm, dn in tfs])
