"""Reduction of the deduced plant to fixed-structure continuous transfer functions (sec. 3.2.3-3.3).

Each entry ``P_i`` of the deduced (discrete) plant is replaced by a continuous transfer
function ``P_r`` with ``n_zeros`` zeros and ``n_poles`` poles, fitted over a band
``[f_min, f_max]`` and keeping the entry's unstable poles fixed at their deduced values
(they are the plant's instability and cannot be traded for in-band fit).  The paper's
structure is ``[0, 2]`` on the diagonal (eq. 22a, 23a, 24a) and third order for the
couplings (eq. 22b-24c; up to one zero, as eq. 22c and 24b have).

Because the data are sampled, ``P_r`` is compared with the deduced response through its
zero-order-hold equivalent, ``ZOH{P_r}(exp(j w dt))`` — comparing ``P_r(j w)`` directly
would misread the hold's half-sample delay (11 degrees at 300 Hz and 5 kHz) as plant
dynamics.  The fit minimises the complex relative error ``(P_i - P_r) / P_i``; the
reported band error is the paper's ``eps = | |P_i| - |P_r| | / |P_i|`` (magnitudes, as
section 3.3 defines it) together with the complex relative error.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from .._errors import IdentificationError
from .order_selection import criterion_value
from .zoh import zoh_at, zoh_derivatives

#: Sanathanan-Koerner passes after Levy's estimate in the reduction's linear start
SK_ITERATIONS = 6

__all__ = [
    "ReducedEntry",
    "reduce_entry",
    "reduce_best",
    "information_criterion",
    "free_fit",
    "finish_entry",
    "minimise",
    "paper_orders",
]


@dataclass(frozen=True, eq=False)
class ReducedEntry:
    """A fixed-structure continuous fit of one plant entry.

    Attributes
    ----------
    num, den : ndarray
        Continuous coefficients, descending powers of ``s``.
    unstable_poles : ndarray
        The kept right-half-plane poles (rad/s).
    eps_magnitude : float
        ``max | |P_i| - |P_r| | / |P_i|`` over the band (the paper's eps).
    eps_complex : float
        ``max |P_i - P_r| / |P_i|`` over the band.
    eps_median : float
        The median over the band of ``|P_i - P_r| / |P_i|``: how well the structure follows the
        band as a whole, apart from narrow stretches where the deduced response itself is off.
    eps_weighted : float
        The RMS over the band of ``w |P_i - P_r| / |P_i|`` with the fit's weights ``w``: the cost
        the fit minimises, by which the candidates of one entry are compared.
    weights : ndarray of shape (n_freqs,), optional
        The fit's line weights ``w`` over its band (None: all 1).
    """

    num: np.ndarray
    den: np.ndarray
    unstable_poles: np.ndarray
    eps_magnitude: float
    eps_complex: float
    eps_median: float = float("nan")
    eps_weighted: float = float("nan")
    weights: np.ndarray | None = None

    @property
    def poles(self) -> np.ndarray:
        return np.roots(self.den)

    @property
    def zeros(self) -> np.ndarray:
        return np.roots(self.num) if np.count_nonzero(self.num) > 1 else np.zeros(0, complex)


def paper_orders(n: int) -> dict[tuple[int, int], tuple[int, int]]:
    """The paper's structure for an ``n x n`` plant: ``(n_zeros, n_poles)`` = (0, 2) on the
    diagonal, (1, 3) off it (third order; one zero allowed as in eq. 22c and 24b)."""
    return {(i, j): ((0, 2) if i == j else (1, 3)) for i in range(n) for j in range(n)}


def _poly_from_params(a: np.ndarray) -> np.ndarray:
    return np.concatenate([[1.0], a])


def reduce_entry(
    response: np.ndarray,
    freqs_hz: np.ndarray,
    dt: float,
    n_zeros: int,
    n_poles: int,
    unstable_poles: np.ndarray | None = None,
    max_nfev: int = 400,
    stable_free: bool = True,
    weights: np.ndarray | None = None,
) -> ReducedEntry:
    """Fit ``P_r = b(s) / (d_u(s) d_s(s))`` to the deduced discrete response over a band.

    Parameters
    ----------
    response : ndarray of complex, shape (n_freqs,)
        Deduced (discrete) plant response ``P_i`` at ``freqs_hz``.
    freqs_hz : ndarray of shape (n_freqs,)
        Frequencies of the band in Hz (at least ``n_zeros + n_free + 2`` of them, ``n_free``
        the poles not kept fixed).
    dt : float
        Sample time of the data (for the ZOH comparison).
    n_zeros, n_poles : int
        Structure ``[n_zeros, n_poles]``, ``n_zeros <= n_poles``.
    unstable_poles : ndarray of complex, optional
        Right-half-plane poles (rad/s) kept fixed; conjugate pairs must be complete (default none).
    max_nfev : int
        Evaluation limit of the nonlinear refinement.
    stable_free : bool
        Keep the free poles in the left half plane (reflect and refit); with False the
        free poles may land anywhere, so unstable poles are fitted rather than kept.
    weights : ndarray of shape (n_freqs,), optional
        Weights of the relative error per line (default 1; the estimator passes
        :func:`~stageid.closedloop.reliability.reliability_weights`).

    Returns
    -------
    ReducedEntry

    Raises
    ------
    IdentificationError
        When the structure cannot hold the unstable poles or the band has too few points.

    Examples
    --------
    >>> import numpy as np
    >>> f = np.linspace(20, 300, 60)
    >>> from stageid.closedloop.zoh import zoh_response
    >>> P = zoh_response([3.0], np.poly([50.0, -80.0]), 2e-4, f)
    >>> r = reduce_entry(P, f, 2e-4, 0, 2, np.array([50.0]))
    >>> bool(r.eps_complex < 1e-6), np.round(np.sort(r.poles.real), 3).tolist()
    (True, [-80.0, 50.0])
    """
    fit, theta, up = free_fit(response, freqs_hz, dt, n_zeros, n_poles, unstable_poles, max_nfev, weights)
    return finish_entry(fit, theta, up, max_nfev, stable_free)


def free_fit(
    response: np.ndarray,
    freqs_hz: np.ndarray,
    dt: float,
    n_zeros: int,
    n_poles: int,
    unstable_poles: np.ndarray | None = None,
    max_nfev: int = 400,
    weights: np.ndarray | None = None,
) -> tuple[_RationalFit, np.ndarray, np.ndarray]:
    """The first step of :func:`reduce_entry`: Levy start and nonlinear fit with the free poles anywhere.

    Returns ``(fit, theta, kept unstable poles)`` for :func:`finish_entry`; the "free" and the
    "stable" candidates of :func:`reduce_best` share it (the stable one continues from it).
    """
    P = np.asarray(response, dtype=complex).reshape(-1)
    f = np.asarray(freqs_hz, dtype=float).reshape(-1)
    up = np.zeros(0, complex) if unstable_poles is None else np.asarray(unstable_poles, dtype=complex).reshape(-1)
    n_free = n_poles - up.size
    _check_entry_fit(P, f, up.size, n_zeros, n_poles)
    w = np.ones(f.size) if weights is None else np.asarray(weights, dtype=float).reshape(-1)
    w0 = 2 * np.pi * np.sqrt(f.min() * f.max())  # frequency normalisation
    du_n = np.real(np.poly(up / w0)) if up.size else np.array([1.0])
    theta = _levy_start(P, f, dt, w0, du_n, n_zeros, n_free, w)
    fit = _RationalFit(P, f, dt, w0, du_n, n_zeros, n_poles, w)
    return fit, minimise(fit, theta, max_nfev), up


def minimise(fit: _RationalFit, theta: np.ndarray, max_nfev: int = 400) -> np.ndarray:
    """The weighted relative error of ``fit`` minimised from ``theta`` (nonlinear least squares)."""
    try:
        return least_squares(
            fit.residual,
            theta,
            jac=fit.jacobian,
            method="lm" if theta.size <= fit.f.size else "trf",
            max_nfev=max_nfev,
            xtol=1e-12,
            ftol=1e-12,
        ).x
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise IdentificationError(f"the reduced-order fit [{fit.n_zeros}, {fit.n_poles}] failed: {exc}") from None


def finish_entry(
    fit: _RationalFit, theta: np.ndarray, up: np.ndarray, max_nfev: int = 400, stable_free: bool = True
) -> ReducedEntry:
    """The entry of :func:`free_fit`'s result: free poles reflected and refitted if ``stable_free``, band errors."""
    if fit.n_poles - up.size and stable_free:
        theta = _reflect_and_refit(fit, theta, max_nfev)
    num, den = fit.polynomials(theta)
    Pr = zoh_at(num, den, fit.dt, fit.z)
    eps_mag = float(np.max(np.abs(np.abs(fit.P) - np.abs(Pr)) / np.abs(fit.P)))
    rel = np.abs(fit.P - Pr) / np.abs(fit.P)
    return ReducedEntry(
        num,
        den,
        up,
        eps_mag,
        float(np.max(rel)),
        float(np.median(rel)),
        float(np.sqrt(np.mean((fit.w * rel) ** 2))),
        fit.w,
    )


def _check_entry_fit(P: np.ndarray, f: np.ndarray, n_fixed: int, n_zeros: int, n_poles: int) -> None:
    """IdentificationError unless the structure holds the fixed poles and the band has enough finite points."""
    n_free = n_poles - n_fixed
    if n_zeros < 0 or n_poles < 1 or n_zeros > n_poles:
        raise IdentificationError(
            f"a reduced structure needs 0 <= n_zeros <= n_poles and n_poles >= 1; got [{n_zeros}, {n_poles}]."
        )
    if n_free < 0:
        raise IdentificationError(
            f"structure [{n_zeros}, {n_poles}] cannot keep the entry's {n_fixed} unstable poles; give more poles."
        )
    if f.size < n_zeros + n_free + 2 or f.size != P.size:
        raise IdentificationError(
            f"the band needs at least {n_zeros + n_free + 2} frequencies matching the response; got {f.size} and {P.size}."
        )
    if not np.all(np.isfinite(P)) or np.any(P == 0):
        raise IdentificationError("the deduced response must be finite and non-zero over the band.")


def _reflect_and_refit(fit: _RationalFit, theta: np.ndarray, max_nfev: int) -> np.ndarray:
    """The free poles must stay stable: reflect right-half-plane roots of ``d_s`` and refit once."""
    nb = fit.n_zeros + 1
    roots = np.roots(_poly_from_params(theta[nb:]))
    if not np.any(roots.real > 0):
        return theta
    roots = np.where(roots.real > 0, -np.conj(roots), roots)
    theta = np.concatenate([theta[:nb], np.real(np.poly(roots))[1:]])
    refit = least_squares(fit.residual, theta, jac=fit.jacobian, method="trf", max_nfev=max_nfev).x
    # the refit is unconstrained: on a truly unstable entry it walks back to the unstable
    # optimum, and the promise is stable free poles, so the reflected fit stands then
    if np.any(np.roots(_poly_from_params(refit[nb:])).real > 0):
        return theta
    return refit


def _levy_start(
    P: np.ndarray, f: np.ndarray, dt: float, w0: float, du_n: np.ndarray, n_zeros: int, n_free: int, w: np.ndarray
) -> np.ndarray:
    """Linear estimate of ``[b; a_1..a_nfree]`` on the continuous approximation ``P_c ~ P_d exp(+j w dt / 2)``:
    Levy's equation error, then :data:`SK_ITERATIONS` Sanathanan-Koerner passes.

    Levy's error ``P_c d(s) - b(s)`` is the relative error times ``P_c d(s)``, which swells far from
    the poles and shrinks at a lightly damped mode: the mode is fitted last, and a coupling's
    resonance can come out far off (measured: a [1, 3] coupling reduced to a pole at -2e9 rad/s from
    a deduced response within 2.5 % of the truth). Each pass divides by ``|P_c d_prev(s)|``, the
    previous pass's denominator, so the equation error tends to the relative error itself (times
    the weights ``w``, as the nonlinear fit counts it).
    """
    s_n = 2j * np.pi * f / w0
    Pc = P * np.exp(1j * np.pi * f * dt)
    cols = [s_n**k for k in range(n_zeros, -1, -1)]  # numerator b
    du = np.polyval(du_n, s_n)
    cols += [-Pc * du * s_n**k for k in range(n_free - 1, -1, -1)]  # a_1..a_nfree
    rhs = Pc * du * s_n**n_free
    Phi = np.column_stack(cols) if cols else np.zeros((f.size, 0))
    scale = np.abs(rhs) / w
    theta = None
    for _ in range(1 + SK_ITERATIONS):
        Phi_w, rhs_w = Phi / scale[:, None], rhs / scale
        step, *_ = np.linalg.lstsq(
            np.vstack([Phi_w.real, Phi_w.imag]), np.concatenate([rhs_w.real, rhs_w.imag]), rcond=None
        )
        if not np.all(np.isfinite(step)):
            break
        theta = step
        den = np.abs(Pc * du * np.polyval(np.concatenate([[1.0], theta[n_zeros + 1 :]]), s_n))
        if not np.all(np.isfinite(den) & (den > 0)):
            break
        scale = den / w
    return theta


class _RationalFit:
    """``b(s) / (d_u(s) d_s(s))`` in the normalised variable ``s / w0``, and its relative ZOH error.

    The grid ``z``, ``1 / P`` and the powers of ``w0`` are computed once: the least-squares
    search evaluates :meth:`residual` thousands of times (the same numbers as
    :func:`zoh_response` on ``f``).
    """

    def __init__(self, P, f, dt, w0, du_n, n_zeros, n_poles, w=None):
        self.P, self.f, self.dt, self.w0, self.du_n = P, f, dt, w0, du_n
        self.w = np.ones(np.size(f)) if w is None else w
        self.Pw = P / self.w  # residuals divide by P and multiply by w: once
        self.n_zeros, self.n_poles = n_zeros, n_poles
        self.z = np.exp(2j * np.pi * np.asarray(f, dtype=float) * dt)
        self.num_scale = w0 ** (-np.arange(n_zeros, -1, -1, dtype=float))
        self.den_scale = w0 ** (-np.arange(n_poles, -1, -1, dtype=float))
        # d den / d a_k (du_n times s^(n_free - 1 - k), scaled like den): fixed, so built once
        n_free = n_poles + 1 - du_n.size
        unit = np.eye(n_free + 1)[1:]
        self.den_jac = np.array([np.convolve(du_n, e) for e in unit]).reshape(n_free, n_poles + 1)
        self.den_jac = (self.den_jac * (self.den_scale / self.den_scale[0]))[:, 1:].T

    def parameters(self, num: np.ndarray, den: np.ndarray) -> np.ndarray:
        """The parameters of a fit without fixed poles (``du_n = [1]``) whose :meth:`polynomials`
        are ``(num, den)`` (monic ``den`` of degree ``n_poles``, ``num`` of ``n_zeros + 1`` terms)."""
        den_n = den / self.den_scale * self.den_scale[0]
        return np.concatenate([num * self.den_scale[0] / self.num_scale, den_n[1:]])

    def polynomials(self, th: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(num, den)`` in ``s`` (descending, monic ``den``) of the parameters ``th``."""
        nb = self.n_zeros + 1
        # np.polymul of these (leading coefficients 1, nothing to trim) is this convolution
        den_n = np.convolve(self.du_n, _poly_from_params(th[nb:]))
        # undo the normalisation s_n = s / w0: multiply coefficient k (power p) by w0^-p
        num = th[:nb] * self.num_scale
        den = den_n * self.den_scale
        return num / den[0], den / den[0]

    def residual(self, th: np.ndarray) -> np.ndarray:
        """``w (ZOH{P_r} - P) / P``, real and imaginary parts stacked."""
        num, den = self.polynomials(th)
        r = (zoh_at(num, den, self.dt, self.z) - self.P) / self.Pw
        return np.concatenate([r.real, r.imag])

    def jacobian(self, th: np.ndarray) -> np.ndarray:
        """``d residual / d th``: the chain rule through :func:`zoh_derivatives` (exact, no differences)."""
        num, den = self.polynomials(th)
        _, d_num, d_den = zoh_derivatives(num, den, self.dt, self.z)
        nb = self.n_zeros + 1
        dH = np.hstack([d_num[:, -nb:] * (self.num_scale / self.den_scale[0]), d_den @ self.den_jac])
        dH /= self.Pw[:, None]
        return np.vstack([dH.real, dH.imag])


def information_criterion(entry: ReducedEntry, n_zeros: int, n_poles: int) -> float:
    """BIC of a candidate fit over its band: ``n ln(eps_weighted^2) + ln(n) k`` with ``n`` the real and
    imaginary parts of its lines and ``k`` its free coefficients (its kept poles are not free), the
    criterion the pairs' orders are selected by (:mod:`~stageid.closedloop.order_selection`)."""
    n = 2 * entry.weights.size if entry.weights is not None else 2
    k = n_zeros + 1 + n_poles - np.size(entry.unstable_poles)
    return float(criterion_value("bic", n, entry.eps_weighted**2, k))


def reduce_best(
    P: np.ndarray,
    f: np.ndarray,
    dt: float,
    nz: int,
    n_p: int,
    keep: np.ndarray | Sequence[np.ndarray],
    diagonal: bool,
    weights: np.ndarray | None = None,
) -> ReducedEntry:
    """Fit one entry three ways and keep the best by the cost the fits minimise (``eps_weighted``),
    counted against the coefficients each fit frees (:func:`information_criterion`).

    * unstable poles fixed at the values the deduction gives (when they fit the structure),
      one candidate per set of ``keep`` (an array is one set);
    * all poles free over the band (the zeros of ``M (I - T)`` that place the unstable poles
      are fixed by data below the band, where a chirp spends little time, so in MIMO they are
      often less accurate than the in-band response itself);
    * all poles stable: preferred for a coupling when within 1.5 x of the best band error,
      because an unstable pole that only one coupling carries is no feedback loop's to
      stabilise (see the +9.74 rad/s pole of eq. 22c) and usually a displaced spurious doublet.

    The free fit's space holds the kept one, so its cost is never higher; a pole below the band
    moves the band's response little, and where freeing it buys less than its coefficient is worth
    the deduction's value stands: it comes from the records down to their resolution, the band fit
    only from the band.
    """
    cands = []
    # the all-free and the all-stable candidates start with the same fit: done once
    fit, theta, up = free_fit(P, f, dt, nz, n_p, np.zeros(0), weights=weights)
    sets = [keep] if isinstance(keep, np.ndarray) else list(keep)
    for kept in (k for k in sets if 0 < k.size <= n_p):
        cands.append(reduce_entry(P, f, dt, nz, n_p, kept, weights=weights))
        # the free fit started from the kept one too: the kept poles are one point of its space,
        # so the free candidate is never worse than the kept one by the cost both minimise
        other = minimise(fit, fit.parameters(cands[-1].num, cands[-1].den))
        if np.sum(fit.residual(other) ** 2) < np.sum(fit.residual(theta) ** 2):
            theta = other
    free = (fit, theta, up)
    cands.append(finish_entry(*free, stable_free=False))
    stable = finish_entry(*free, stable_free=True)
    stable_ok = not np.any(stable.poles.real > 0)
    if stable_ok:
        cands.append(stable)
    best = min(cands, key=lambda r: information_criterion(r, nz, n_p))
    if not diagonal and stable_ok and stable.eps_weighted <= 1.5 * best.eps_weighted:
        return stable
    return best
