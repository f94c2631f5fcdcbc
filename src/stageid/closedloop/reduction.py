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

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.signal as ss
from scipy.optimize import least_squares

from .._errors import IdentificationError

__all__ = ["ReducedEntry", "reduce_entry", "zoh_response", "paper_orders"]


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
    """

    num: np.ndarray
    den: np.ndarray
    unstable_poles: np.ndarray
    eps_magnitude: float
    eps_complex: float

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


def zoh_response(num: np.ndarray, den: np.ndarray, dt: float, freqs_hz: np.ndarray) -> np.ndarray:
    """Frequency response of the ZOH equivalent of the continuous ``num/den`` at ``freqs_hz``.

    Computed exactly from ``expm`` of the controllable-canonical realisation (no
    ``(z - e^{p dt})`` partial fractions, so repeated poles are fine).
    """
    num = np.atleast_1d(np.asarray(num, dtype=float))
    den = np.atleast_1d(np.asarray(den, dtype=float))
    A, B, C, D = ss.tf2ss(num, den)
    n = A.shape[0]
    z = np.exp(2j * np.pi * np.asarray(freqs_hz, dtype=float) * dt)
    if n == 0:
        return np.full(z.shape, complex(D[0, 0]))
    blk = np.zeros((n + 1, n + 1))
    blk[:n, :n] = A * dt
    blk[:n, n:] = B * dt
    E = sla.expm(blk)
    Ad, Bd = E[:n, :n], E[:n, n:]
    M = z[:, None, None] * np.eye(n)[None] - Ad[None]
    X = np.linalg.solve(M, np.broadcast_to(Bd, (z.size, n, 1)))
    return (C[None] @ X)[:, 0, 0] + D[0, 0]


def _poly_from_params(a: np.ndarray) -> np.ndarray:
    return np.concatenate([[1.0], a])


def reduce_entry(
    response: np.ndarray,
    freqs_hz: np.ndarray,
    dt: float,
    n_zeros: int,
    n_poles: int,
    unstable_poles: np.ndarray = np.zeros(0),
    max_nfev: int = 400,
    stable_free: bool = True,
) -> ReducedEntry:
    """Fit ``P_r = b(s) / (d_u(s) d_s(s))`` to the deduced discrete response over a band.

    Parameters
    ----------
    response : ndarray of complex, shape (n_freqs,)
        Deduced (discrete) plant response ``P_i`` at ``freqs_hz``.
    freqs_hz : ndarray of shape (n_freqs,)
        Frequencies of the band in Hz (at least ``n_zeros + n_poles + 1`` of them).
    dt : float
        Sample time of the data (for the ZOH comparison).
    n_zeros, n_poles : int
        Structure ``[n_zeros, n_poles]``, ``n_zeros <= n_poles``.
    unstable_poles : ndarray of complex
        Right-half-plane poles (rad/s) kept fixed; conjugate pairs must be complete.
    max_nfev : int
        Evaluation limit of the nonlinear refinement.
    stable_free : bool
        Keep the free poles in the left half plane (reflect and refit); with False the
        free poles may land anywhere, so unstable poles are fitted rather than kept.

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
    >>> P = zoh_response([3.0], np.poly([50.0, -80.0]), 2e-4, f)
    >>> r = reduce_entry(P, f, 2e-4, 0, 2, np.array([50.0]))
    >>> bool(r.eps_complex < 1e-6), np.round(np.sort(r.poles.real), 3).tolist()
    (True, [-80.0, 50.0])
    """
    P = np.asarray(response, dtype=complex).reshape(-1)
    f = np.asarray(freqs_hz, dtype=float).reshape(-1)
    up = np.asarray(unstable_poles, dtype=complex).reshape(-1)
    n_free = n_poles - up.size
    if n_zeros < 0 or n_poles < 1 or n_zeros > n_poles:
        raise IdentificationError(
            f"a reduced structure needs 0 <= n_zeros <= n_poles and n_poles >= 1; got [{n_zeros}, {n_poles}]."
        )
    if n_free < 0:
        raise IdentificationError(
            f"structure [{n_zeros}, {n_poles}] cannot keep the entry's {up.size} unstable poles; give more poles."
        )
    if f.size < n_zeros + n_free + 2 or f.size != P.size:
        raise IdentificationError(
            f"the band needs at least {n_zeros + n_free + 2} frequencies matching the response; got {f.size} and {P.size}."
        )
    if not np.all(np.isfinite(P)) or np.any(P == 0):
        raise IdentificationError("the deduced response must be finite and non-zero over the band.")
    w0 = 2 * np.pi * np.sqrt(f.min() * f.max())  # frequency normalisation
    du_n = np.real(np.poly(up / w0)) if up.size else np.array([1.0])
    # --- linear (Levy) start on the continuous approximation P_c ~ P_d exp(+j w dt / 2)
    s_n = 2j * np.pi * f / w0
    Pc = P * np.exp(1j * np.pi * f * dt)
    cols = [s_n**k for k in range(n_zeros, -1, -1)]  # numerator b
    du = np.polyval(du_n, s_n)
    cols += [-Pc * du * s_n**k for k in range(n_free - 1, -1, -1)]  # a_1..a_nfree
    rhs = Pc * du * s_n**n_free
    Phi = np.column_stack(cols) if cols else np.zeros((f.size, 0))
    wgt = 1.0 / np.abs(rhs)
    Phi_w = Phi * wgt[:, None]
    theta, *_ = np.linalg.lstsq(
        np.vstack([Phi_w.real, Phi_w.imag]), np.concatenate([(rhs * wgt).real, (rhs * wgt).imag]), rcond=None
    )
    nb = n_zeros + 1

    def build(th: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        b_n = th[:nb]
        ds_n = _poly_from_params(th[nb:])
        den_n = np.polymul(du_n, ds_n)
        # undo the normalisation s_n = s / w0: multiply coefficient k (power p) by w0^-p
        num = b_n * w0 ** (-np.arange(n_zeros, -1, -1, dtype=float))
        den = den_n * w0 ** (-np.arange(n_poles, -1, -1, dtype=float))
        return num / den[0], den / den[0]

    def resid(th: np.ndarray) -> np.ndarray:
        num, den = build(th)
        r = (zoh_response(num, den, dt, f) - P) / P
        return np.concatenate([r.real, r.imag])

    try:
        sol = least_squares(
            resid,
            theta,
            method="lm" if theta.size * 2 <= 2 * f.size else "trf",
            max_nfev=max_nfev,
            xtol=1e-12,
            ftol=1e-12,
        )
        theta = sol.x
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise IdentificationError(f"the reduced-order fit [{n_zeros}, {n_poles}] failed: {exc}") from None
    num, den = build(theta)
    # the free part must stay stable: reflect any right-half-plane root and refit once
    if n_free and stable_free:
        roots = np.roots(_poly_from_params(theta[nb:]))
        if np.any(roots.real > 0):
            roots = np.where(roots.real > 0, -np.conj(roots), roots)
            theta = np.concatenate([theta[:nb], np.real(np.poly(roots))[1:]])
            sol = least_squares(resid, theta, method="trf", max_nfev=max_nfev)
            theta = sol.x
            num, den = build(theta)
    Pr = zoh_response(num, den, dt, f)
    eps_mag = float(np.max(np.abs(np.abs(P) - np.abs(Pr)) / np.abs(P)))
    eps_cplx = float(np.max(np.abs(P - Pr) / np.abs(P)))
    return ReducedEntry(num, den, up, eps_mag, eps_cplx)
