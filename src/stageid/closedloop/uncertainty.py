"""Uncertainty of the identified plant: the PEM covariance carried through eq. 18 and the reduction.

Delta method, step by step (all first order, evaluated at the estimate):

1. each pair ``T_ij`` moves by ``dT_ij = g_ij dtheta_ij``, ``g_ij = dT_ij / dtheta_ij`` on the unit
   circle, ``dtheta_ij`` with the covariance of :mod:`~stageid.closedloop.covariance`; the pairs
   are independent (own output channel or own experiment);
2. eq. 18, ``G = T U^-1`` with ``U = M_r - M T``, gives ``dG = dT U^-1 + G M dT U^-1
   = (I + G M) dT U^-1``, so ``dG_ab = sum_ij (I + G M)_ai dT_ij (U^-1)_jb``;
3. the reduction (sec. 3.3) is a least-squares fit of the reduced entry ``P_r(phi)`` to the
   deduced response over the band, with relative residual ``r = (ZOH{P_r} - P) / P``.  By the
   implicit-function theorem its parameters move by ``dphi = (W J_r)^+ W (dP / P)`` (real and
   imaginary parts stacked, ``J_r = d r / d phi``, ``W`` the fit's line weights), and the returned model at any frequency by
   ``dP_r(f) = dP_r/dphi(f) dphi``.  Cancellation (sec. 3.2.3) removes pairs that cancel to the
   tolerance: it does not move the response, so it adds nothing to first order;
4. the unstable poles the reduction keeps fixed are the zeros of ``det U(z)`` outside the unit
   circle, and move with ``T``: at a simple zero ``z0`` with left/right null vectors ``w, v`` of
   ``U(z0)``, ``dz = w^H M dT v / (w^H U'(z0) v)`` and ``dp = dz / (z0 dt)``.  The reduced fit
   then re-balances its free parameters, ``dphi = J_r^+ (dP / P - J_p dp)``, and the model moves
   by ``dP_r/dphi dphi + dP_r/dp dp`` (``dP_r / dp = P_r / (s - p)``).  Real kept poles only;
   a kept complex pair is held fixed.

**The reduction's bias.**  A fixed structure that cannot follow the deduced response leaves a
systematic error the noise does not explain.  It is estimated per entry from the relative
misfit ``r = (ZOH{P_r} - P) / P`` beyond its noise expectation (``r_noise = (I - J_r J_r^+) dP / P``)
and added as ``b^2(f) |P_r(f)|^2``, so ``std`` is the root mean squared error of the returned
model and not only its scatter.  At 70-80 dB this term, not the noise, dominates: the deduced
response's error comes mostly from the closed-loop models' own bias, which the reduction's
misfit measures.  That error grows toward the low end of the band (there ``T`` is close to
``I``: a small error of ``T`` is a large relative error of ``(M - M T)^-1``), so the default
``bias="local"`` follows the misfit along the band, ``|r|^2 - E|r_noise|^2`` averaged over
``LOCAL_WINDOW`` of the band's points on either side (outside the band, the larger of the
edge's value and the band's mean);
``bias="flat"`` spreads its band average ``b^2 = max(0, ||r||^2 - E||r_noise||^2) / n_band``
evenly (too narrow at the low end: 84 % coverage at 20-39 Hz on the maglev), and
``bias="inflate"`` scales the propagated variance by the misfit's ratio to its noise expectation
(keeping its frequency shape).  All three count only the misfit beyond what the noise
explains at :data:`SIGNIFICANCE` (:func:`significant_share`): the misfit's noise has few degrees
of freedom, and its chance excess is no bias.  Coverage of each, and where they fail, in
studies/uncertainty_closedloop/RESULTS.md.

With the ``"full"`` structure the returned plant is the cancelled deduction: its ``std`` is
that of step 2.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from .._errors import DataError, IdentificationError
from ..models.frequency_response import FrequencyResponse
from ..runtime.threads import single_blas_thread
from .covariance import transfer_gradient, transfer_gradient_at
from .reduction import ReducedEntry
from .zoh import zoh_response

__all__ = [
    "BIAS_RULES",
    "LOCAL_WINDOW",
    "local_bias",
    "SIGNIFICANCE",
    "significant_share",
    "check_frequencies",
    "deduction_sensitivity",
    "deduced_variance",
    "unstable_pole_sensitivity",
    "plant_uncertainty",
]


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


#: how the reduction's misfit beyond the noise enters ``std`` (module notes)
BIAS_RULES = ("flat", "inflate", "local", "none")


@single_blas_thread
def plant_uncertainty(result, freqs_hz: object, bias: str = "local") -> FrequencyResponse:
    """The returned plant's response and ``std = sqrt(E|G_est - G|^2)`` at ``freqs_hz`` (see the module notes).

    ``bias``: "local" (the default) adds the misfit beyond its noise as a relative error that
    follows the misfit along the band (:func:`local_bias`), "flat" its band average at every
    frequency, "inflate" scales the propagated variance by the misfit's ratio to its noise
    expectation, "none" leaves the propagated variance alone (the studies compare them).

    Raises
    ------
    DataError
        A grid that is not finite, positive and increasing.
    IdentificationError
        When the result carries no covariance (fitted with ``covariance="none"``), or an
        unknown ``bias`` rule.
    """
    if bias not in BIAS_RULES:
        raise IdentificationError(f"`bias` must be one of {', '.join(BIAS_RULES)}; got {bias!r}.")
    f = check_frequencies(freqs_hz)
    if result.covariance is None:
        raise IdentificationError(
            "this closed-loop result has no parameter covariance: fit with covariance='sandwich' or 'white'."
        )
    with np.errstate(all="ignore"):
        G = result.model.frequency_response(f)
    if not np.all(np.isfinite(G)):
        raise DataError("`freqs_hz` hits a pole of the identified plant; choose other frequencies.")
    if not result.reduced:  # "full": the cancelled deduction, step 2 only
        var = deduced_variance(result, f)
    else:
        var, misfit, noise, noise_sq = _reduced_variance(result, f)
        fb = result.covariance.band_freqs
        # only the misfit the noise cannot explain counts as bias (:func:`significant_share`)
        share = significant_share(misfit.sum(0), noise.sum(0), noise_sq)
        excess = np.maximum(misfit.sum(0) - noise.sum(0), 0.0) * share
        if bias == "flat":
            var += excess[None] / fb.size * np.abs(G) ** 2
        elif bias == "inflate":
            var *= (1.0 + excess / np.maximum(noise.sum(0), 1e-300))[None]
        elif bias == "local":
            var += local_bias(fb, misfit, noise, f) * share[None] * np.abs(G) ** 2
    return FrequencyResponse(f, G, np.sqrt(var), None, result.model.inputs, result.model.outputs)


#: ``bias="local"``: the misfit is averaged over this fraction of the band's (log-spaced) points
#: on either side of each frequency
LOCAL_WINDOW = 0.1


def local_bias(fb: np.ndarray, misfit: np.ndarray, noise: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``b^2(f)`` of ``bias="local"``: the reduction's squared relative misfit beyond its noise
    expectation, per band frequency ``fb`` (``misfit``, ``noise`` of shape (n_band, p, p)),
    averaged over ``LOCAL_WINDOW`` of the band on either side, then interpolated in log frequency
    to ``f``; outside the band, the larger of the nearest edge's value and the band's mean (the
    ``"flat"`` value).  Shape (n_freqs, p, p)."""
    h = max(1, int(round(LOCAL_WINDOW * fb.size)))
    kernel = np.ones(2 * h + 1)
    count = np.convolve(np.ones(fb.size), kernel, mode="same")
    excess = misfit - noise
    smooth = np.apply_along_axis(lambda x: np.convolve(x, kernel, mode="same"), 0, excess) / count[:, None, None]
    smooth = np.maximum(smooth, 0.0)
    lf, lb = np.log(f), np.log(fb)
    out = np.empty((f.size,) + misfit.shape[1:])
    for a in range(misfit.shape[1]):
        for b in range(misfit.shape[2]):
            out[:, a, b] = np.interp(lf, lb, smooth[:, a, b])
    # outside the band nothing measures the misfit: the larger of the edge's and the band's mean
    outside = (f < fb[0]) | (f > fb[-1])
    out[outside] = np.maximum(out[outside], np.maximum(excess.mean(axis=0), 0.0)[None])
    return out


#: the misfit counts as bias only beyond this quantile of its distribution under the noise alone
SIGNIFICANCE = 0.95


def significant_share(misfit: np.ndarray, noise: np.ndarray, noise_sq: np.ndarray) -> np.ndarray:
    """The share of the band's misfit excess ``misfit - noise`` that the noise cannot explain.

    Under the noise alone the band total of ``|r|^2`` is a quadratic form in the PEM parameters,
    ``sum_k lambda_k chi2_1``, with mean ``noise = sum lambda`` and ``noise_sq = sum lambda^2``.
    The deduced response's error lives in the few directions ``T``'s parameters determine well,
    so the form has few effective degrees of freedom (``noise^2 / noise_sq``, about 2 on a SISO
    loop): its excess over the mean swings by about its own mean from the noise alone, and counted
    as bias it widens the band on every record whose noise happened to fall outside the reduced
    structure.  Only the misfit beyond the noise's :data:`SIGNIFICANCE` quantile (Satterthwaite's
    scaled chi-square, ``noise_sq / noise * chi2(noise^2 / noise_sq)``) counts; when the bias
    dominates, the share tends to 1.  Arrays of one shape, the share in [0, 1].
    """
    m, mu, sq = (np.asarray(x, dtype=float) for x in (misfit, noise, noise_sq))
    ok = (mu > 0) & (sq > 0)
    scale = np.where(ok, sq / np.where(ok, mu, 1.0), 0.0)
    dof = np.where(ok, mu**2 / np.where(ok, sq, 1.0), 1.0)
    q = scale * chi2.ppf(SIGNIFICANCE, dof)
    excess = m - mu
    return np.where(excess > 0, np.maximum(m - q, 0.0) / np.where(excess > 0, excess, 1.0), 0.0)


def _reduced_variance(result, f: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Steps 1-4 for every entry of a reduced plant: ``(var, misfit, noise, noise_sq)``.

    ``var`` (n_freqs, p, p) is the propagated variance, ``misfit`` (n_band, p, p) the reduction's
    ``|r|^2`` at each band frequency and ``noise`` (n_band, p, p) its expectation under the noise
    alone; ``noise_sq`` (p, p) is ``sum(lambda^2)`` over the eigenvalues ``lambda`` of the band
    total's noise quadratic form (its variance is ``2 noise_sq``).
    """
    fb = result.covariance.band_freqs
    L, R, g, P = deduction_sensitivity(result, fb)
    w0 = 2 * np.pi * np.sqrt(fb[0] * fb[-1])
    discrete = result.model.dt is not None
    pole_sens = unstable_pole_sensitivity(result)
    p = L.shape[1]
    var, misfit, noise = np.zeros((f.size, p, p)), np.zeros((fb.size, p, p)), np.zeros((fb.size, p, p))
    noise_sq = np.zeros((p, p))
    for (a, b), red in result.reduced.items():
        Pab = P[:, a, b]
        Jr = _stack(_tangent(red, fb, result.dt, w0, zoh=True) / Pab[:, None])
        # the fit weighs its lines (reduction.ReducedEntry.weights): dphi = (W J_r)^+ W dP / P
        ww = np.tile(np.ones(fb.size) if red.weights is None else red.weights, 2)[:, None]
        Q = np.linalg.pinv(ww * Jr, rcond=1e-10)
        E = _tangent(red, f, result.dt, w0, zoh=discrete)
        kept = _kept_poles(red, result.unstable_poles)
        Jp = _stack(_pole_tangent(red, [p for p, _ in kept], fb, result.dt, w0, zoh=True) / Pab[:, None])
        Ep = _pole_tangent(red, [p for p, _ in kept], f, result.dt, w0, zoh=discrete)
        noise_resid = np.zeros(fb.size)
        for (i, j), gij in g.items():
            C = result.covariance.covariances[(i, j)]
            S = _stack((L[:, a, i] * R[:, j, b] / Pab)[:, None] * gij)  # d(dP/P)/dtheta, stacked
            Hp = np.array([pole_sens[k][(i, j)] for _, k in kept]).reshape(len(kept), gij.shape[1])
            S = S - Jp @ Hp  # what the free parameters must absorb
            QS = Q @ (ww * S)
            var[:, a, b] += _quadratic(E @ QS + Ep @ Hp, C)
            Rn = ww * (S - Jr @ QS)  # what the fit leaves of the noise, weighted as the fit counts it
            per_row = np.sum((Rn @ C) * Rn, axis=1)  # [Re; Im] rows of each band frequency
            noise_resid += per_row[: fb.size] + per_row[fb.size :]
            KC = (Rn.T @ Rn) @ C  # the pairs are independent: their eigenvalues add up as a block diagonal
            noise_sq[a, b] += np.sum(KC * KC.T)
        fit = ww[:, 0] * _stack((zoh_response(red.num, red.den, result.dt, fb) - Pab) / Pab)
        misfit[:, a, b], noise[:, a, b] = fit[: fb.size] ** 2 + fit[fb.size :] ** 2, noise_resid
    return var, misfit, noise, noise_sq


def _kept_poles(red: ReducedEntry, s_unstable: np.ndarray) -> list[tuple[float, int]]:
    """``(pole, k)`` for each real kept pole of ``red`` that is the plant's unstable pole ``k``."""
    out = []
    for p in np.asarray(red.unstable_poles, dtype=complex).reshape(-1):
        if abs(p.imag) > 1e-9 * max(1.0, abs(p)) or s_unstable.size == 0:
            continue
        k = int(np.argmin(np.abs(s_unstable - p)))
        if abs(s_unstable[k] - p) <= 1e-9 * max(1.0, abs(p)):
            out.append((float(p.real), k))
    return out


def unstable_pole_sensitivity(result) -> list[dict]:
    """``d p_k / d theta_ij`` of every real unstable pole ``p_k`` (rad/s) of ``result.unstable_poles``.

    Returns one dict per pole, ``{(i, j): ndarray (n_par,)}`` (zeros for a complex pole).
    """
    out = []
    dt = result.dt
    for p in np.asarray(result.unstable_poles, dtype=complex):
        sens = {ij: np.zeros(m.n_parameters) for ij, m in result.pem_models.items()}
        if abs(p.imag) <= 1e-9 * max(1.0, abs(p)):
            z0 = np.exp(p.real * dt)
            Uz, Mz = _loop_at(result, z0)
            h = 1e-6 * z0
            dU = (_loop_at(result, z0 + h)[0] - _loop_at(result, z0 - h)[0]) / (2 * h)
            Wl, _, Vh = np.linalg.svd(Uz)
            w, v = Wl[:, -1], Vh[-1].conj()
            den = w.conj() @ dU @ v
            wM = w.conj() @ Mz
            for (i, j), m in result.pem_models.items():
                dz = wM[i] * v[j] * transfer_gradient_at(m, np.array([z0]))[0] / den
                sens[(i, j)] = (dz / (z0 * dt)).real
        out.append(sens)
    return out


def _loop_at(result, z: complex) -> tuple[np.ndarray, np.ndarray]:
    """``(U(z), M(z))`` with ``U = M_r - M T`` at one complex ``z``."""
    p = result.closed_loop.n_outputs
    T = np.zeros((p, p), complex)
    for (i, j), m in result.pem_models.items():
        num, den = m.plant_polynomials()
        T[i, j] = np.polyval(num, z) / np.polyval(den, z)
    Mz = _ss_at(result.controller, z)
    Mr = Mz if result.covariance.reference_filter is None else _ss_at(result.covariance.reference_filter, z)
    return Mr - Mz @ T, Mz


def _ss_at(model, z: complex) -> np.ndarray:
    if model.n_states == 0:
        return np.asarray(model.D, dtype=complex)
    return model.C @ np.linalg.solve(z * np.eye(model.n_states) - model.A, model.B) + model.D


def _pole_tangent(red: ReducedEntry, poles: list[float], f: np.ndarray, dt: float, w0: float, zoh: bool) -> np.ndarray:
    """``d P_r / d p`` (per rad/s) for each kept pole ``p``: ``P_r / (s - p)``, complex (n_freqs, n_poles)."""
    if not poles:
        return np.zeros((f.size, 0), complex)
    num_n, den_n = _normalised(red, w0)
    cols = []
    for p in poles:
        den_p = np.polymul(den_n, [1.0, -p / w0])
        if zoh:
            cols.append(zoh_response(num_n, den_p, dt * w0, f / w0) / w0)
        else:
            s = 2j * np.pi * f / w0
            cols.append(np.polyval(num_n, s) / np.polyval(den_p, s) / w0)
    return np.column_stack(cols)


def _normalised(red: ReducedEntry, w0: float) -> tuple[np.ndarray, np.ndarray]:
    """``(num, den)`` of ``red`` in ``s / w0``, ``den`` monic."""
    num_n = red.num * w0 ** np.arange(red.num.size - 1, -1, -1.0)
    den_n = red.den * w0 ** np.arange(red.den.size - 1, -1, -1.0)
    return num_n / den_n[0], den_n / den_n[0]


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
    num_n, den_n = _normalised(red, w0)
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
