"""Polynomial model structures of the closed-loop fits (Shakir & Kim, eq. 11-12; Ljung 1999, sec. 4.2).

The general structure (eq. 12) is

    A(q) y(t) = B(q) / F(q) u(t - nk) + C(q) / D(q) e(t),

with ``q`` the backward shift (the paper writes ``q = z^-1``), monic ``A, C, D, F`` and
``B = b0 + b1 q^-1 + ...``.  The paper prints the left-hand polynomial of eq. 12 as ``F``
and the plant-model denominator as ``A``; we use Ljung's letters (``A`` on the output,
``F`` under ``B``), which is the reading consistent with its special case eq. 11 (an
output-error plant ``B/A`` plus a ``C/D`` noise model).  Special cases:

=========  ===============================  ==========================
structure  model                             free polynomials
=========  ===============================  ==========================
``arx``    A y = B u + e                     A, B
``armax``  A y = B u + C e                   A, B, C
``oe``     y = B/F u + e                     B, F
``bj``     y = B/F u + C/D e                 B, F, C, D
=========  ===============================  ==========================

The prediction error of eq. 14, ``e = H^-1 (y - G u)``, is here ``e = D/C (A y - B/F u)``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.signal as ss

from .._errors import IdentificationError
from ..models import TransferMatrix

__all__ = [
    "PolynomialModel",
    "STRUCTURES",
    "FREE_ORDERS",
    "structure_orders",
    "check_orders",
    "stabilize",
    "residual",
    "residual_parts",
    "pack",
    "unpack",
]

STRUCTURES = ("arx", "armax", "oe", "bj")
#: the orders each structure lets vary
FREE_ORDERS = {"arx": ("na", "nb"), "armax": ("na", "nb", "nc"), "oe": ("nb", "nf"), "bj": ("nb", "nc", "nd", "nf")}


@dataclass(frozen=True, eq=False)
class PolynomialModel:
    """A discrete SISO model ``A y = B/F u(t - nk) + C/D e`` (polynomials in ``q^-1``).

    Attributes
    ----------
    A, B, C, D, F : ndarray
        Coefficients in ascending powers of ``q^-1``; ``A, C, D, F`` are monic.
    nk : int
        Input delay in samples.
    dt : float
        Sample time in seconds.
    structure : str
        One of ``"arx", "armax", "oe", "bj"``.
    loss : float
        Mean squared prediction error ``V_N / N`` at the optimum (eq. 13).
    n_samples : int
        Number of samples the loss was computed on.
    n_iterations : int
        Function evaluations used by the optimiser (0 for ARX).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    F: np.ndarray
    nk: int
    dt: float
    structure: str
    loss: float = float("nan")
    n_samples: int = 0
    n_iterations: int = 0
    converged: bool = True
    extra: dict = field(default_factory=dict)

    @property
    def n_parameters(self) -> int:
        """Number of free parameters."""
        return (self.A.size - 1) + self.B.size + (self.C.size - 1) + (self.D.size - 1) + (self.F.size - 1)

    def plant_polynomials(self) -> tuple[np.ndarray, np.ndarray]:
        """``(num, den)`` of ``G(z) = z^-nk B / (A F)`` in descending powers of ``z``."""
        den_q = np.convolve(self.A, self.F)
        num_q = np.concatenate([np.zeros(self.nk), self.B])
        n = max(num_q.size, den_q.size)
        num_z = np.concatenate([num_q, np.zeros(n - num_q.size)])
        den_z = np.concatenate([den_q, np.zeros(n - den_q.size)])
        # common trailing zeros are pole-zero pairs at z = 0: drop them
        while num_z.size > 1 and num_z[-1] == 0.0 and den_z[-1] == 0.0:
            num_z, den_z = num_z[:-1], den_z[:-1]
        return num_z, den_z

    def transfer(self, input_name: str = "u1", output_name: str = "y1") -> TransferMatrix:
        """The deterministic part ``G = q^-nk B / (A F)`` as a discrete :class:`~stageid.models.TransferMatrix`."""
        num, den = self.plant_polynomials()
        return TransferMatrix([[num]], [[den]], self.dt, (input_name,), (output_name,))

    def frequency_response(self, freqs_hz: Sequence[float] | np.ndarray) -> np.ndarray:
        """``G(exp(j 2 pi f dt))``, ndarray of shape (n_freqs,)."""
        w = np.exp(-2j * np.pi * np.asarray(freqs_hz, dtype=float) * self.dt)  # q^-1 on the unit circle
        num = np.polynomial.polynomial.polyval(w, np.concatenate([np.zeros(self.nk), self.B]))
        den = np.polynomial.polynomial.polyval(w, np.convolve(self.A, self.F))
        return num / den

    def simulate(self, u: np.ndarray) -> np.ndarray:
        """Noise-free response ``B/(A F) u(t - nk)`` from rest, shape (n_samples,)."""
        uu = np.asarray(u, dtype=float).reshape(-1)
        return ss.lfilter(np.concatenate([np.zeros(self.nk), self.B]), np.convolve(self.A, self.F), uu)

    def predict(self, u: np.ndarray, y: np.ndarray) -> np.ndarray:
        """One-step-ahead prediction ``y - e`` (eq. 14), shape (n_samples,)."""
        uu = np.asarray(u, dtype=float).reshape(-1)
        yy = np.asarray(y, dtype=float).reshape(-1)
        return yy - residual(self.A, self.B, self.C, self.D, self.F, self.nk, uu, yy)


def structure_orders(structure: str, n: int) -> dict[str, int]:
    """The orders of one model order ``n``: all free polynomials of order ``n`` (BJ noise 2/2)."""
    return {
        "arx": {"na": n, "nb": n},
        "armax": {"na": n, "nb": n, "nc": n},
        "oe": {"nb": n, "nf": n},
        "bj": {"nb": n, "nf": n, "nc": 2, "nd": 2},
    }[structure]


def check_orders(structure: str, orders: Mapping[str, int], nk: int) -> dict[str, int]:
    """All five orders (0 for the fixed polynomials); IdentificationError names a bad one."""
    if structure not in STRUCTURES:
        raise IdentificationError(f"`structure` must be one of {', '.join(STRUCTURES)}; got {structure!r}.")
    full = {"na": 0, "nb": 0, "nc": 0, "nd": 0, "nf": 0}
    for key, val in orders.items():
        if key not in full:
            raise IdentificationError(f"unknown order {key!r}; expected some of na, nb, nc, nd, nf.")
        if key not in FREE_ORDERS[structure] and val:
            raise IdentificationError(
                f"order {key} is not free in a {structure} model (free: {', '.join(FREE_ORDERS[structure])}); got {key}={val}."
            )
        if int(val) != val or val < 0:
            raise IdentificationError(f"order {key} must be a non-negative integer; got {val!r}.")
        full[key] = int(val)
    if full["nb"] < 1:
        raise IdentificationError(f"a {structure} model needs nb >= 1; got nb={full['nb']}.")
    if int(nk) != nk or nk < 0:
        raise IdentificationError(f"`nk` must be a non-negative integer number of samples; got {nk!r}.")
    return full


def stabilize(poly: np.ndarray, max_radius: float | None = None) -> np.ndarray:
    """Reflect roots of a monic polynomial in ``q^-1`` that lie outside the unit circle (Ljung, sec. 10.5).

    Without ``max_radius`` a polynomial with no root outside comes back as it is, and reflected
    roots are held within 0.9999; with it, every root is held within ``max_radius`` and the
    result is monic (a noise model's zeros, which the records resolve only so close to the circle).
    """
    if poly.size <= 1:
        return poly
    roots = np.roots(poly)  # roots in z of z^n + p1 z^(n-1) + ...
    bad = np.abs(roots) >= 1.0
    if not bad.any() and max_radius is None:
        return poly
    roots[bad] = 1.0 / np.conj(roots[bad])
    cap = 0.9999 if max_radius is None else max_radius
    big = np.abs(roots) > cap
    roots[big] *= cap / np.abs(roots[big])
    return np.real(np.poly(roots))


def residual(A, B, C, D, F, nk, u, y) -> np.ndarray:
    """The prediction error ``e = D/C (A y - B/F u)`` of eq. 14."""
    return residual_parts(A, B, C, D, F, nk, u, y)[2]


def residual_parts(A, B, C, D, F, nk, u, y) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(B/F u, A y - B/F u, e)``: the prediction error and the signals its Jacobian reuses."""
    bu = np.concatenate([np.zeros(nk), B])
    yu = ss.lfilter(bu, F, u)  # B/F u
    # A = 1 (OE, BJ) and C = D = 1 (OE, ARX): lfilter would return y and w unchanged (up to the sign of zeros)
    w = (y if A.size == 1 and A[0] == 1.0 else ss.lfilter(A, [1.0], y)) - yu  # A y - B/F u
    e = w.copy() if C.size == 1 and D.size == 1 and C[0] == 1.0 and D[0] == 1.0 else ss.lfilter(D, C, w)
    return yu, w, e


def unpack(theta: np.ndarray, orders: Mapping[str, int]):
    """``(A, B, C, D, F)`` from the parameter vector (order na, nb, nc, nd, nf)."""
    k = 0
    parts = {}
    for name in ("na", "nb", "nc", "nd", "nf"):
        n = orders[name]
        parts[name] = theta[k : k + n]
        k += n
    A = np.concatenate([[1.0], parts["na"]])
    B = parts["nb"].copy()
    C = np.concatenate([[1.0], parts["nc"]])
    D = np.concatenate([[1.0], parts["nd"]])
    F = np.concatenate([[1.0], parts["nf"]])
    return A, B, C, D, F


def pack(A, B, C, D, F) -> np.ndarray:
    """The parameter vector of :func:`unpack` (monic leading ones dropped)."""
    return np.concatenate([A[1:], B, C[1:], D[1:], F[1:]])


def fit_length(p: np.ndarray, n: int) -> np.ndarray:
    """``p`` cut or zero-padded to ``n`` coefficients."""
    if p.size >= n:
        return p[:n].copy()
    return np.concatenate([p, np.zeros(n - p.size)])
