"""Prediction-error identification of discrete polynomial models (Shakir & Kim, eq. 12-14).

The general structure (eq. 12 of Shakir & Kim; Ljung 1999, sec. 4.2) is

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

The parameters minimise eq. 13, ``V_N = sum e(t)^2``, with the prediction error of eq. 14,
``e = H^-1 (y - G u)`` — here ``e = D/C (A y - B/F u)`` — by
:func:`scipy.optimize.least_squares` (trust-region reflective) with the analytic Jacobian,
started from an ARX estimate refined by Steiglitz-McBride / instrumental-variable passes.
The predictor is kept stable: roots of ``C`` and ``F`` that leave the unit circle are
reflected into it (Ljung 1999, sec. 10.5) before the loss is evaluated.
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.signal as ss
from scipy.optimize import least_squares

from .._errors import DataError, IdentificationError

__all__ = ["PolynomialModel", "pem", "arx", "select_order", "STRUCTURES"]

STRUCTURES = ("arx", "armax", "oe", "bj")
_FREE = {"arx": ("na", "nb"), "armax": ("na", "nb", "nc"), "oe": ("nb", "nf"), "bj": ("nb", "nc", "nd", "nf")}


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

    def transfer(self, input_name: str = "u1", output_name: str = "y1"):
        """The deterministic part ``G = q^-nk B / (A F)`` as a discrete :class:`~stageid.models.TransferMatrix`."""
        from ..models import TransferMatrix

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
        return yy - _residual(self.A, self.B, self.C, self.D, self.F, self.nk, uu, yy)


# ----------------------------------------------------------------- helpers
def _segments(u: object, y: object) -> list[tuple[np.ndarray, np.ndarray]]:
    """Accept one record (1-D arrays) or a list of records; return [(u, y), ...] copies."""
    if isinstance(u, (list, tuple)) and len(u) and np.ndim(u[0]) >= 1 and not np.isscalar(u[0]):
        us, ys = list(u), list(y)  # type: ignore[arg-type]
    else:
        us, ys = [u], [y]
    if len(us) != len(ys):
        raise DataError(f"inputs and outputs must come in the same number of records; got {len(us)} and {len(ys)}.")
    out = []
    for k, (uk, yk) in enumerate(zip(us, ys)):
        ua = np.array(uk, dtype=float).reshape(-1)
        ya = np.array(yk, dtype=float).reshape(-1)
        if ua.size != ya.size:
            raise DataError(f"record {k}: input and output must have the same length; got {ua.size} and {ya.size}.")
        if not (np.all(np.isfinite(ua)) and np.all(np.isfinite(ya))):
            raise DataError(f"record {k}: input and output must be finite (no NaN/inf).")
        out.append((ua, ya))
    return out


def _check_dt(dt: object) -> float:
    """``dt`` as a float, or DataError unless it is a finite number of seconds > 0."""
    if isinstance(dt, bool) or not isinstance(dt, numbers.Real) or not (np.isfinite(float(dt)) and float(dt) > 0):
        raise DataError(f"`dt` must be a positive, finite number of seconds; got {dt!r}.")
    return float(dt)


def _check_moving(segs: list[tuple[np.ndarray, np.ndarray]], structure: str) -> None:
    """IdentificationError when the input is constant (zero range) in every record.

    Like :meth:`stageid.subspace.HankelMAP.fit` with no input moving, this is refused rather
    than warned about: a constant input (zero, or a level held since before the record) is not
    a step the model can learn from, and the regression would otherwise return a model fitted
    to the record's start-up transient alone.
    """
    if all(uu.size == 0 or np.ptp(uu) == 0 for uu, _ in segs):
        levels = sorted({float(uu[0]) for uu, _ in segs if uu.size})
        level = f"constant at {levels[0]:g}" if len(levels) == 1 else "constant"
        raise IdentificationError(
            f"the input must move in at least one record to identify the {structure} model; got an input of "
            f"zero range ({level}) in all {len(segs)} record(s)."
        )


def _stabilize(poly: np.ndarray) -> np.ndarray:
    """Reflect roots of a monic polynomial in ``q^-1`` that lie outside the unit circle."""
    if poly.size <= 1:
        return poly
    roots = np.roots(poly)  # roots in z of z^n + p1 z^(n-1) + ...
    bad = np.abs(roots) >= 1.0
    if not bad.any():
        return poly
    roots[bad] = 1.0 / np.conj(roots[bad])
    roots[np.abs(roots) > 0.9999] *= 0.9999 / np.abs(roots[np.abs(roots) > 0.9999])
    return np.real(np.poly(roots))


def _residual(A, B, C, D, F, nk, u, y) -> np.ndarray:
    return _residual_parts(A, B, C, D, F, nk, u, y)[2]


def _residual_parts(A, B, C, D, F, nk, u, y) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(B/F u, A y - B/F u, e)``: the prediction error and the signals its Jacobian reuses."""
    bu = np.concatenate([np.zeros(nk), B])
    yu = ss.lfilter(bu, F, u)  # B/F u
    w = ss.lfilter(A, [1.0], y) - yu  # A y - B/F u
    return yu, w, ss.lfilter(D, C, w)


def _unpack(theta: np.ndarray, orders: dict[str, int]):
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


def _pack(A, B, C, D, F) -> np.ndarray:
    return np.concatenate([A[1:], B, C[1:], D[1:], F[1:]])


def _shifted(x: np.ndarray, lags: int, start: int) -> np.ndarray:
    """Columns x(t - start - k), k = 0..lags-1 (zeros before the record), shape (n, lags)."""
    out = np.empty((x.size, lags))
    _fill_shifted(out, x, start)
    return out


def _fill_shifted(out: np.ndarray, x: np.ndarray, start: int, negate: bool = False) -> None:
    """Write the columns of ``_shifted(x, out.shape[1], start)`` (negated if asked) into ``out``.

    ``out`` may be a column block of a larger row-major matrix, so the regressors are written
    in place instead of building, negating and stacking separate column blocks.
    """
    n, lags = out.shape
    zero = -0.0 if negate else 0.0  # the sign -_shifted(...) gives the leading zeros
    for k in range(lags):
        s = min(start + k, n)
        out[:s, k] = zero
        if negate:
            np.negative(x[: n - s], out=out[s:, k])
        else:
            out[s:, k] = x[: n - s]


def _regressor(
    blocks: list[list[tuple[np.ndarray, int, int, bool]]], rows: int, out: np.ndarray | None = None
) -> np.ndarray:
    """Stack shifted-signal blocks into one (rows, n_columns) matrix, record by record.

    ``blocks[r]`` lists ``(signal, lags, start, negate)`` for record ``r``; the columns of a
    record are ``[+/-_shifted(signal, lags, start), ...]`` side by side and the records are
    stacked below each other (what ``np.vstack`` of ``np.hstack``-ed blocks gives).
    """
    ncol = sum(b[1] for b in blocks[0]) if blocks else 0
    if out is None:
        out = np.empty((rows, ncol))
    r0 = 0
    for rec in blocks:
        n = rec[0][0].size if rec else 0
        c0 = 0
        for sig, lags, start, negate in rec:
            _fill_shifted(out[r0 : r0 + n, c0 : c0 + lags], sig, start, negate)
            c0 += lags
        r0 += n
    return out


def _jacobian(A, B, C, D, F, nk, orders, u, y, parts=None, out=None) -> np.ndarray:
    """d e / d theta for one record, shape (n, n_par); ``parts`` = ``_residual_parts(...)`` if known.

    With ``out`` (a (n, n_par) view) the columns are written there and ``out`` is returned.
    """
    yu, w, e = _residual_parts(A, B, C, D, F, nk, u, y) if parts is None else parts
    blocks = []
    if orders["na"]:
        blocks.append((ss.lfilter(D, C, y), orders["na"], 1, False))
    DCF = np.convolve(C, F)
    if orders["nb"]:
        blocks.append((ss.lfilter(D, DCF, u), orders["nb"], nk, True))
    if orders["nc"]:
        blocks.append((ss.lfilter([1.0], C, e), orders["nc"], 1, True))
    if orders["nd"]:
        blocks.append((ss.lfilter([1.0], C, w), orders["nd"], 1, False))
    if orders["nf"]:
        blocks.append((ss.lfilter(D, DCF, yu), orders["nf"], 1, False))
    return _regressor([blocks], u.size, out=out)


def _check_orders(structure: str, orders: dict[str, int], nk: int) -> dict[str, int]:
    if structure not in STRUCTURES:
        raise IdentificationError(f"`structure` must be one of {', '.join(STRUCTURES)}; got {structure!r}.")
    full = {"na": 0, "nb": 0, "nc": 0, "nd": 0, "nf": 0}
    for key, val in orders.items():
        if key not in full:
            raise IdentificationError(f"unknown order {key!r}; expected some of na, nb, nc, nd, nf.")
        if key not in _FREE[structure] and val:
            raise IdentificationError(
                f"order {key} is not free in a {structure} model (free: {', '.join(_FREE[structure])}); got {key}={val}."
            )
        if int(val) != val or val < 0:
            raise IdentificationError(f"order {key} must be a non-negative integer; got {val!r}.")
        full[key] = int(val)
    if full["nb"] < 1:
        raise IdentificationError(f"a {structure} model needs nb >= 1; got nb={full['nb']}.")
    if int(nk) != nk or nk < 0:
        raise IdentificationError(f"`nk` must be a non-negative integer number of samples; got {nk!r}.")
    return full


# ----------------------------------------------------------------- ARX
def arx(u: object, y: object, na: int, nb: int, nk: int = 1, dt: float = 1.0) -> PolynomialModel:
    """Least-squares ARX estimate ``A y = B u(t - nk) + e``.

    Parameters
    ----------
    u, y : array_like of shape (n_samples,), or lists of such arrays (several records)
    na, nb : int
        Orders of ``A`` (poles) and number of ``B`` coefficients.
    nk : int
        Input delay in samples.
    dt : float
        Sample time in seconds, finite and > 0 (stored in the model).

    Returns
    -------
    PolynomialModel

    Raises
    ------
    DataError
        When ``dt`` is not a positive finite number, or the records are ragged or not finite.
    IdentificationError
        When the input does not move (is constant, zero range) in any record, or the
        regression is rank deficient (input not persistently exciting).  A constant input is
        refused, not warned about, as :meth:`stageid.subspace.HankelMAP.fit` refuses data in
        which no input moves.

    Examples
    --------
    >>> import numpy as np, scipy.signal as ss
    >>> u = np.random.default_rng(0).standard_normal(500)
    >>> y = ss.lfilter([0, 0.5], [1, -0.8], u)
    >>> m = arx(u, y, na=1, nb=1)
    >>> np.round(m.A, 6).tolist(), np.round(m.B, 6).tolist()
    ([1.0, -0.8], [0.5])
    """
    dt = _check_dt(dt)
    segs = _segments(u, y)
    _check_orders("arx", {"na": na, "nb": nb}, nk)
    _check_moving(segs, "arx")
    rows, rhs = [], []
    for uu, yy in segs:
        rows.append(np.hstack([-_shifted(yy, na, 1), _shifted(uu, nb, nk)]))
        rhs.append(yy)
    Phi = np.vstack(rows)
    Y = np.concatenate(rhs)
    theta = _lstsq(Phi, Y, "ARX")
    A = np.concatenate([[1.0], theta[:na]])
    B = theta[na:]
    res = np.concatenate([_residual(A, B, np.ones(1), np.ones(1), np.ones(1), nk, uu, yy) for uu, yy in segs])
    return PolynomialModel(
        A, B, np.ones(1), np.ones(1), np.ones(1), int(nk), dt, "arx", float(np.mean(res**2)), res.size
    )


def _lstsq(Phi: np.ndarray, Y: np.ndarray, what: str, strict: bool = True, overwrite: bool = False) -> np.ndarray:
    """Least squares with unit-norm columns; ``overwrite=True`` lets ``Phi`` be scaled in place."""
    scale = np.sqrt(np.add.reduce(Phi * Phi, axis=0))  # = np.linalg.norm(Phi, axis=0), same sums
    if np.any(scale == 0):
        raise IdentificationError(
            f"the {what} regression is singular: a regressor column is identically zero (no excitation)."
        )
    if overwrite:
        Phi /= scale
    else:
        Phi = Phi / scale
    theta, _, rank, _ = np.linalg.lstsq(Phi, Y, rcond=None)
    if strict and rank < Phi.shape[1]:
        raise IdentificationError(
            f"the {what} regression is rank deficient ({rank} of {Phi.shape[1]}): the input does not excite this order."
        )
    return theta / scale


def _steiglitz_mcbride(
    segs, nb: int, nf: int, nk: int, n_iter: int = 8, F0: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Output-error initial estimate: ARX on data pre-filtered by the current 1/F (IV-like).

    ``F0`` (default 1) is the ``F`` to start from: passing the ``F`` that ``k`` iterations
    returned and ``n_iter - k`` continues them exactly.
    """
    F = np.ones(1) if F0 is None else F0
    B = np.zeros(nb)
    rows = sum(uu.size for uu, _ in segs)
    Phi = np.empty((rows, nf + nb))
    for _ in range(n_iter):
        blocks, rhs = [], []
        for uu, yy in segs:
            uf = ss.lfilter([1.0], F, uu)
            yf = ss.lfilter([1.0], F, yy)
            blocks.append([(yf, nf, 1, True), (uf, nb, nk, False)])
            rhs.append(yf)
        _regressor(blocks, rows, out=Phi)
        Y = rhs[0] if len(rhs) == 1 else np.concatenate(rhs)
        theta = _lstsq(Phi, Y, "Steiglitz-McBride", strict=False, overwrite=True)
        F = _stabilize(np.concatenate([[1.0], theta[:nf]]))
        B = theta[nf:]
    return B, F


# ----------------------------------------------------------------- PEM
def pem(
    u: object,
    y: object,
    structure: str = "oe",
    orders: dict[str, int] | None = None,
    nk: int = 1,
    dt: float = 1.0,
    max_nfev: int = 200,
    initial: PolynomialModel | None = None,
) -> PolynomialModel:
    """Prediction-error estimate of a polynomial model (eq. 12-14 of Shakir & Kim).

    Parameters
    ----------
    u, y : array_like of shape (n_samples,), or lists of such arrays
        Input (the reference ``r`` in closed-loop use) and output records.  Several
        records are fitted jointly, each simulated from rest.
    structure : {"arx", "armax", "oe", "bj"}
        Model structure (module docstring).
    orders : dict
        Orders of the free polynomials, e.g. ``{"nb": 4, "nf": 4}`` for OE,
        ``{"na": 2, "nb": 2, "nc": 2}`` for ARMAX, ``{"nb", "nc", "nd", "nf"}`` for BJ.
    nk : int
        Input delay in samples (1 for a sampled strictly proper loop).
    dt : float
        Sample time in seconds, finite and > 0, stored in the result.
    max_nfev : int
        Limit on loss evaluations of the optimiser.
    initial : PolynomialModel, optional
        Start from these polynomials instead of the ARX / Steiglitz-McBride estimate.

    Returns
    -------
    PolynomialModel
        With ``loss`` = mean squared prediction error; ``converged`` False when the
        optimiser stopped on ``max_nfev``.

    Raises
    ------
    DataError
        ``dt`` not a positive finite number; ragged, non-finite or too short records.
    IdentificationError
        Unknown structure, bad orders, or data that do not excite the model (among them an
        input that is constant in every record, refused as in :func:`arx`).

    Examples
    --------
    >>> import numpy as np, scipy.signal as ss
    >>> rng = np.random.default_rng(1)
    >>> u = rng.standard_normal(2000)
    >>> y = ss.lfilter([0, 0.3, 0.1], [1, -1.2, 0.5], u) + 0.01 * rng.standard_normal(2000)
    >>> m = pem(u, y, "oe", {"nb": 2, "nf": 2})
    >>> np.allclose(m.F, [1, -1.2, 0.5], atol=0.01)
    True
    """
    return _pem(u, y, structure, orders, nk, dt, max_nfev, initial)


def _pem(u, y, structure, orders, nk, dt, max_nfev, initial, sm_start=None) -> PolynomialModel:
    """:func:`pem`; ``sm_start = (k, F)``: the Steiglitz-McBride start is already ``k`` iterations in, at ``F``.

    :func:`select_order` passes the state its screen reached for the order it selected, so the
    8 iterations of the start are not run again from ``F = 1`` (the result is the same).
    """
    orders = _check_orders(structure, dict(orders or {}), nk)
    dt = _check_dt(dt)
    segs = _segments(u, y)
    n_total = sum(s[0].size for s in segs)
    n_par = sum(orders.values())
    if n_total < 3 * n_par + 10:
        raise DataError(
            f"a {structure} model with {n_par} parameters needs at least {3 * n_par + 10} samples; got {n_total}."
        )
    _check_moving(segs, structure)
    if initial is not None:
        A, B, C, D, F = (np.asarray(p, float) for p in (initial.A, initial.B, initial.C, initial.D, initial.F))
        A = _fit_len(A, orders["na"] + 1, monic=True)
        B = _fit_len(B, orders["nb"], monic=False)
        C = _fit_len(C, orders["nc"] + 1, monic=True)
        D = _fit_len(D, orders["nd"] + 1, monic=True)
        F = _fit_len(F, orders["nf"] + 1, monic=True)
    elif structure in ("arx", "armax"):
        m0 = arx([s[0] for s in segs], [s[1] for s in segs], orders["na"], orders["nb"], nk, dt)
        A, B, C, D, F = m0.A, m0.B, np.ones(orders["nc"] + 1) * 0, np.ones(1), np.ones(1)
        C = np.concatenate([[1.0], np.zeros(orders["nc"])])
        if structure == "arx":
            return m0
    else:
        if sm_start is not None and 0 < sm_start[0] < 8:
            B, F = _steiglitz_mcbride(segs, orders["nb"], orders["nf"], nk, n_iter=8 - sm_start[0], F0=sm_start[1])
        else:
            B, F = _steiglitz_mcbride(segs, orders["nb"], orders["nf"], nk)
        A = np.ones(1)
        C = np.concatenate([[1.0], np.zeros(orders["nc"])])
        D = np.concatenate([[1.0], np.zeros(orders["nd"])])
        if structure == "bj" and (orders["nc"] or orders["nd"]):
            bu = np.concatenate([np.zeros(nk), B])
            w = [yy - ss.lfilter(bu, F, uu) for uu, yy in segs]
            C, D = _hannan_rissanen(w, orders["nc"], orders["nd"])

    # scale the output so that the loss is O(1): least_squares tolerances are absolute-ish
    yscale = max(np.sqrt(np.mean(np.concatenate([s[1] for s in segs]) ** 2)), 1e-300)
    segs_s = [(uu, yy / yscale) for uu, yy in segs]
    B = B / yscale

    # the optimiser asks for the Jacobian at the point whose residual it has just evaluated:
    # keep that point's polynomials and filtered signals rather than recomputing them
    last: dict = {}

    def evaluate(theta):
        key = np.asarray(theta, dtype=float).tobytes()
        if last.get("key") != key:
            A_, B_, C_, D_, F_ = _unpack(theta, orders)
            polys = (A_, B_, _stabilize(C_), D_, _stabilize(F_))
            last.update(key=key, polys=polys, signals=[_residual_parts(*polys, nk, uu, yy) for uu, yy in segs_s])
        return last["polys"], last["signals"]

    def parts(theta):
        return evaluate(theta)[0]

    def fun(theta):
        _, signals = evaluate(theta)
        return np.concatenate([sig[2] for sig in signals])

    n_rows = sum(uu.size for uu, _ in segs_s)

    def jac(theta):
        polys, signals = evaluate(theta)
        J = np.empty((n_rows, n_par))
        r0 = 0
        for (uu, yy), sig in zip(segs_s, signals):
            _jacobian(*polys, nk, orders, uu, yy, parts=sig, out=J[r0 : r0 + uu.size])
            r0 += uu.size
        return J

    theta0 = _pack(A, B, C, D, F)
    try:
        sol = least_squares(
            fun, theta0, jac=jac, method="trf", x_scale="jac", max_nfev=max_nfev, ftol=1e-12, xtol=1e-12, gtol=1e-12
        )
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise IdentificationError(f"the {structure} prediction-error optimisation failed: {exc}") from None
    A, B, C, D, F = parts(sol.x)
    res = fun(_pack(A, B, C, D, F)) * yscale
    if not np.all(np.isfinite(res)):
        raise IdentificationError(f"the {structure} prediction-error optimisation diverged (non-finite residuals).")
    return PolynomialModel(
        A,
        B * yscale,
        C,
        D,
        F,
        int(nk),
        dt,
        structure,
        float(np.mean(res**2)),
        res.size,
        int(sol.nfev),
        bool(sol.status > 0),
    )


def _hannan_rissanen(w: list[np.ndarray], nc: int, nd: int) -> tuple[np.ndarray, np.ndarray]:
    """ARMA ``D w = C e`` start values: a long AR model gives ``e``, then one linear regression."""
    n_ar = max(20, 3 * (nc + nd))
    rows, rhs = [], []
    for wk in w:
        rows.append(-_shifted(wk, n_ar, 1))
        rhs.append(wk)
    try:
        a = _lstsq(np.vstack(rows), np.concatenate(rhs), "noise AR", strict=False)
    except IdentificationError:
        return np.concatenate([[1.0], np.zeros(nc)]), np.concatenate([[1.0], np.zeros(nd)])
    rows, rhs = [], []
    for wk in w:
        e = ss.lfilter(np.concatenate([[1.0], a]), [1.0], wk)
        rows.append(np.hstack([-_shifted(wk, nd, 1), _shifted(e, nc, 1)]))
        rhs.append(wk - e)
    try:
        th = _lstsq(np.vstack(rows), np.concatenate(rhs), "noise ARMA", strict=False)
    except IdentificationError:
        return np.concatenate([[1.0], np.zeros(nc)]), np.concatenate([[1.0], np.zeros(nd)])
    D = _stabilize(np.concatenate([[1.0], th[:nd]]))
    C = _stabilize(np.concatenate([[1.0], th[nd:]]))
    return C, D


def _fit_len(p: np.ndarray, n: int, monic: bool) -> np.ndarray:
    if p.size >= n:
        return p[:n].copy()
    return np.concatenate([p, np.zeros(n - p.size)])


# ----------------------------------------------------------------- orders
def select_order(
    u: object,
    y: object,
    structure: str = "oe",
    orders: Sequence[int] = tuple(range(1, 11)),
    nk: int = 1,
    dt: float = 1.0,
    criterion: str = "bic",
    max_nfev: int = 200,
    screen: bool = True,
) -> tuple[PolynomialModel, dict[int, float]]:
    """Fit ``structure`` for each order ``n`` (all free polynomials of order ``n``) and keep the best.

    Parameters
    ----------
    u, y : array_like or lists of arrays
        As in :func:`pem`.
    structure : {"arx", "armax", "oe", "bj"}
    orders : sequence of int
        Candidate orders ``n``: ``nb = nf = n`` for OE, ``na = nb = n`` (``nc = n``) for
        ARX/ARMAX, ``nb = nf = n`` and ``nc = nd = 2`` for BJ.
    criterion : {"bic", "aic"}
        ``N log(V) + k log(N)`` (BIC) or ``N log(V) + 2 k`` (AIC), ``k`` the number of parameters.
    screen : bool
        For OE and BJ: rank the orders by the criterion of cheap Steiglitz-McBride estimates and
        run the prediction-error optimisation only for the winner;
        otherwise every order is optimised.

    Returns
    -------
    (PolynomialModel, dict)
        The selected model and the criterion value for each order tried.

    Raises
    ------
    DataError
        ``dt`` not a positive finite number; ragged or non-finite records.
    IdentificationError
        When no order could be fitted, the criterion is unknown, or the input is constant in
        every record (as in :func:`arx`).

    Examples
    --------
    >>> import numpy as np, scipy.signal as ss
    >>> u = np.random.default_rng(2).standard_normal(3000)
    >>> y = ss.lfilter([0, 0.3, 0.1], [1, -1.2, 0.5], u) + 1e-3 * np.random.default_rng(3).standard_normal(3000)
    >>> m, scores = select_order(u, y, "oe", orders=[1, 2, 3, 4])
    >>> m.F.size - 1
    2
    """
    if criterion not in ("bic", "aic"):
        raise IdentificationError(f"`criterion` must be 'bic' or 'aic'; got {criterion!r}.")
    if structure not in STRUCTURES:
        raise IdentificationError(f"`structure` must be one of {', '.join(STRUCTURES)}; got {structure!r}.")
    dt = _check_dt(dt)
    _check_moving(_segments(u, y), structure)
    scores: dict[int, float] = {}
    best: PolynomialModel | None = None
    best_score = np.inf
    last_error: Exception | None = None
    orders = [int(n) for n in orders]
    if screen and structure in ("oe", "bj") and len(orders) > 3:
        segs = _segments(u, y)
        N = sum(s_[0].size for s_ in segs)
        screen_scores = {}
        screen_states = {}
        for n in orders:
            try:
                B, F = _steiglitz_mcbride(segs, n, n, nk, n_iter=6)
                screen_states[n] = (6, F)
            except IdentificationError:
                continue
            bu = np.concatenate([np.zeros(nk), B])
            res = np.concatenate([yy - ss.lfilter(bu, F, uu) for uu, yy in segs])
            V = float(np.mean(res**2))
            k = 2 * n
            penalty = k * np.log(N) if criterion == "bic" else 2.0 * k
            screen_scores[n] = N * np.log(max(V, 1e-300)) + penalty
        if screen_scores:
            n_best = min(screen_scores, key=screen_scores.get)
            orders = [n_best]
    else:
        screen_states = {}
    for n in orders:
        o = {
            "arx": {"na": n, "nb": n},
            "armax": {"na": n, "nb": n, "nc": n},
            "oe": {"nb": n, "nf": n},
            "bj": {"nb": n, "nf": n, "nc": 2, "nd": 2},
        }[structure]
        try:
            m = _pem(u, y, structure, o, nk, dt, max_nfev, None, screen_states.get(n))
        except (IdentificationError, DataError) as exc:
            last_error = exc
            continue
        N, k = m.n_samples, m.n_parameters
        penalty = k * np.log(N) if criterion == "bic" else 2.0 * k
        score = N * np.log(max(m.loss, 1e-300)) + penalty
        scores[int(n)] = float(score)
        if score < best_score:
            best, best_score = m, score
    if best is None:
        raise IdentificationError(f"no {structure} model could be fitted for orders {list(orders)}: {last_error}")
    return best, scores
