"""One-way conversions on matrices and coefficient arrays, used by the LTI model classes.

Like scipy's ``signal/_lti_conversion.py`` serving ``_ltisys.py``: every function here takes and
returns plain arrays, so :mod:`stageid.models.lti` builds its model objects on top of it and
nothing here imports a model class.

======================  ===============================================================
``tf2ss(_siso)``        controllable-canonical realisation, block diagonal per entry
``ss2tf(_siso)``        ``num/den`` of each entry's minimal SISO realisation
``filter_entries``      discrete transfer-matrix response by difference equations
``c2d_matrices``        ZOH / Tustin discretisation of ``(A, B, C, D)``
``d2c_matrices``        their inverses (ZOH by the matrix logarithm)
``invariant_zeros``     finite zeros of the Rosenbrock pencil
``ss_response``         ``C (vI - A)^-1 B + D`` on a grid of ``v``
``rational_response``   ``num(v) / den(v)`` without overflow for high orders
``transfer_response``   that for every entry of a transfer matrix
``ss_dc_gain``          ``D + C (I - A)^-1 B`` (discrete) or ``D - C A^-1 B`` (continuous)
``transfer_dc_gain``    ``num(v) / den(v)`` at ``v = 1`` or ``0``, every entry
``markov_parameters``   ``D, CB, CAB, ...``
``balanced``            a diagonal similarity that balances ``A`` (before a reduction)
``poles_stable``        all poles inside the unit circle / left half plane, with a margin
======================  ===============================================================
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .._errors import ModelError
from .minimal import minimal_matrices

__all__ = [
    "METHODS",
    "check_method",
    "strip_leading_zeros",
    "tf2ss_siso",
    "tf2ss",
    "ss2tf_siso",
    "ss2tf",
    "filter_entries",
    "c2d_matrices",
    "d2c_matrices",
    "invariant_zeros",
    "ss_response",
    "rational_response",
    "transfer_response",
    "ss_dc_gain",
    "transfer_dc_gain",
    "markov_parameters",
    "balanced",
    "poles_stable",
    "dt_from_control",
]

METHODS = ("zoh", "tustin")


def _signal():
    """scipy.signal, imported on first use (it costs about a second at start-up)."""
    import scipy.signal

    return scipy.signal


def check_method(method: str) -> str:
    """``method`` if it is a discretisation method ("zoh" or "tustin"), else ModelError."""
    if method not in METHODS:
        raise ModelError(f"`method` must be one of {', '.join(METHODS)}; got {method!r}.")
    return method


def strip_leading_zeros(poly: np.ndarray) -> np.ndarray:
    """The polynomial without leading zero coefficients (a zero polynomial keeps its last one).

    A cheap ``np.trim_zeros(poly, "f")`` for 1-D arrays: the reduced closed-loop fits call it for
    every residual.
    """
    nz = np.flatnonzero(poly)
    return poly[nz[0] :] if nz.size else poly[-1:]


def tf2ss_siso(
    num: np.ndarray, den: np.ndarray, keep_states: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, C, D)`` of ``num/den`` (descending powers), controllable canonical form.

    The same matrices as ``scipy.signal.tf2ss`` (``A``'s first row ``-den[1:] / den[0]``, ``B = e_1``),
    built directly because fits call it for every residual; a static gain has no state, and the
    cases scipy trims with a warning (a tiny leading numerator coefficient) or refuses (an
    improper ``num/den``) go to scipy itself.  A zero numerator has no state either, unless
    ``keep_states``: then it keeps ``den``'s states with ``C = 0``, as scipy does (a derivative
    with respect to the numerator's coefficients needs them).

    Examples
    --------
    >>> tf2ss_siso([0.0], [1.0, 0.5])[0].shape, tf2ss_siso([0.0], [1.0, 0.5], keep_states=True)[0].tolist()
    ((0, 0), [[-0.5]])
    """
    d = strip_leading_zeros(np.asarray(den, dtype=float))
    n = strip_leading_zeros(np.asarray(num, dtype=float))
    if d.size == 1:
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.array([[n[-1] / d[0] if n.size == 1 else 0.0]])
    if not np.any(n) and not keep_states:
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.zeros((1, 1))
    n, d = n / d[0], d / d[0]
    if n.size > d.size or 0.0 < abs(n[0]) <= 1e-14:
        a, b, c, dd = _signal().tf2ss(n, d)
        return a, b, c, dd
    k = d.size - 1
    n = np.concatenate([np.zeros(d.size - n.size), n])
    A = np.zeros((k, k))
    A[0] = -d[1:]
    A[1:, :-1] = np.eye(k - 1)
    B = np.zeros((k, 1))
    B[0, 0] = 1.0
    return A, B, (n[1:] - n[0] * d[1:])[None, :], np.array([[n[0]]])


def tf2ss(num: Sequence, den: Sequence) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, C, D)`` of a transfer matrix ``num[i][j] / den[i][j]``: one canonical block per entry."""
    p, m = len(num), len(num[0])
    blocks = [(i, j, tf2ss_siso(num[i][j], den[i][j])) for i in range(p) for j in range(m)]
    n = sum(b[2][0].shape[0] for b in blocks)
    A, B, C, D = np.zeros((n, n)), np.zeros((n, m)), np.zeros((p, n)), np.zeros((p, m))
    k = 0
    for i, j, (a, b, c, d) in blocks:
        r = a.shape[0]
        A[k : k + r, k : k + r] = a
        B[k : k + r, j] = b[:, 0]
        C[i, k : k + r] = c[0]
        D[i, j] = d[0, 0]
        k += r
    return A, B, C, D


def ss2tf(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> tuple[list, list]:
    """``(num, den)`` nested [output][input] of a state-space model, each entry from its minimal realisation."""
    num, den = [], []
    for i in range(C.shape[0]):
        pairs = [ss2tf_siso(A, B[:, [j]], C[[i]], D[[i]][:, [j]]) for j in range(B.shape[1])]
        num.append([b for b, _ in pairs])
        den.append([a for _, a in pairs])
    return num, den


def filter_entries(num: Sequence, den: Sequence, u: np.ndarray) -> np.ndarray:
    """Response of a discrete transfer matrix to ``u`` (n_samples, m) from rest, entry by entry."""
    lfilter = _signal().lfilter
    y = np.zeros((u.shape[0], len(num)))
    for i in range(len(num)):
        for j in range(len(num[0])):
            d = strip_leading_zeros(np.asarray(den[i][j]))
            n = strip_leading_zeros(np.asarray(num[i][j]))
            y[:, i] += lfilter(np.concatenate([np.zeros(d.size - n.size), n]), d, u[:, j])
    return y


def ss2tf_siso(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(num, den)`` of a SISO state-space model, from its minimal realisation."""
    A, B, C = minimal_matrices(A, B, C)
    if A.shape[0] == 0:
        return np.array([D[0, 0]]), np.array([1.0])
    b, a = _signal().ss2tf(A, B, C, D)
    return np.real_if_close(b[0]).astype(float), np.real_if_close(a).astype(float)


def c2d_matrices(A, B, C, D, dt: float, method: str = "zoh") -> tuple[np.ndarray, ...]:
    """Discrete ``(Ad, Bd, Cd, Dd)`` of a continuous model at ``dt``.

    "zoh": ``Ad = expm(A dt)``, ``Bd = int_0^dt expm(A s) ds B`` from the exponential of the
    block matrix ``[[A, B], [0, 0]] dt``; "tustin": the bilinear map ``s = 2/dt (z-1)/(z+1)``.
    """
    n, m = B.shape
    if method == "zoh":
        import scipy.linalg as sla

        block = np.zeros((n + m, n + m))
        block[:n, :n] = A * dt
        block[:n, n:] = B * dt
        E = sla.expm(block)
        return E[:n, :n], E[:n, n:], C, D
    I = np.eye(n)
    Minv = I - A * dt / 2.0
    try:
        Ad = np.linalg.solve(Minv, I + A * dt / 2.0)
        MB = np.linalg.solve(Minv, B)
    except np.linalg.LinAlgError:
        raise ModelError(
            f"Tustin discretisation is undefined: A has an eigenvalue at 2/dt = {2 / dt:g} rad/s."
        ) from None
    return Ad, MB * dt, np.linalg.solve(Minv.T, C.T).T, D + C @ MB * dt / 2.0


def d2c_matrices(A, B, C, D, dt: float, method: str = "zoh") -> tuple[np.ndarray, ...]:
    """Continuous ``(Ac, Bc, Cc, Dc)`` of a discrete model with sample time ``dt``.

    "zoh" inverts the hold by the principal matrix logarithm of ``[[Ad, Bd], [0, I]]`` and
    raises :class:`ModelError` when no real logarithm exists (an eigenvalue of ``Ad`` on the
    closed negative real axis); "tustin" inverts the bilinear map (undefined for ``z = -1``).
    """
    n, m = B.shape
    eig = np.linalg.eigvals(A)
    if method == "zoh":
        bad = eig[(np.abs(eig.imag) <= 1e-12 * np.maximum(1.0, np.abs(eig))) & (eig.real <= 0)]
        if bad.size:
            raise ModelError(
                f"no real matrix logarithm exists: the discrete model has a pole at z = {bad[0].real:.6g} "
                "on the closed negative real axis, so it has no continuous ZOH equivalent."
            )
        import scipy.linalg as sla

        block = np.zeros((n + m, n + m))
        block[:n, :n] = A
        block[:n, n:] = B
        block[n:, n:] = np.eye(m)
        L = sla.logm(block) / dt
        if np.iscomplexobj(L):
            if np.max(np.abs(L.imag)) > 1e-8 * max(1.0, np.max(np.abs(L.real))):
                raise ModelError("no real matrix logarithm exists for this discrete model (complex logm).")
            L = L.real
        return L[:n, :n], L[:n, n:], C, D
    I = np.eye(n)
    P = A + I
    if np.min(np.abs(eig + 1.0)) < 1e-12:
        raise ModelError("the inverse Tustin map is undefined: the model has a pole at z = -1.")
    Pinv_B = np.linalg.solve(P, B)
    Ac = (2.0 / dt) * np.linalg.solve(P.T, (A - I).T).T
    return Ac, 2.0 * Pinv_B / dt, 2.0 * np.linalg.solve(P.T, C.T).T, D - C @ Pinv_B


def _pencil_zeros(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> np.ndarray:
    import scipy.linalg as sla

    n = A.shape[0]
    M = np.block([[A, B], [C, D]])
    N = np.zeros_like(M)
    N[:n, :n] = np.eye(n)
    vals = sla.eigvals(M, N)
    finite = vals[np.isfinite(vals)]
    return finite[np.abs(finite) < 1e12]


def invariant_zeros(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> np.ndarray:
    """Finite generalised eigenvalues of the Rosenbrock pencil ``[[A - vI, B], [C, D]]``.

    For a non-square system the zeros are those shared by two random square compressions of
    the pencil (generically exactly the invariant zeros).
    """
    n, m, p = A.shape[0], B.shape[1], C.shape[0]
    if n == 0:
        return np.zeros(0, dtype=complex)
    if m == p:
        return _pencil_zeros(A, B, C, D)
    rng = np.random.default_rng(0)
    k = min(m, p)
    sets = []
    for _ in range(2):
        Wl = rng.standard_normal((k, p)) if p > k else np.eye(p)
        Wr = rng.standard_normal((m, k)) if m > k else np.eye(m)
        sets.append(_pencil_zeros(A, B @ Wr, Wl @ C, Wl @ D @ Wr))
    first, second = sets
    keep = [z for z in first if second.size and np.min(np.abs(second - z)) < 1e-6 * (1.0 + abs(z))]
    return np.array(keep, dtype=complex)


def ss_response(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``C (vI - A)^-1 B + D`` for each ``v``, shape (n_v, p, m); infinite where ``v`` is a pole.

    The Hessenberg form keeps each solve cheap and well conditioned.
    """
    n = A.shape[0]
    if n == 0:
        return np.broadcast_to(D.astype(complex), (v.size, *D.shape)).copy()
    import scipy.linalg as sla

    H, Q = sla.hessenberg(A, calc_q=True)
    Bq = Q.T @ B
    Cq = C @ Q
    out = np.empty((v.size, *D.shape), dtype=complex)
    eye = np.eye(n)
    for k, vk in enumerate(v):
        try:
            out[k] = Cq @ np.linalg.solve(vk * eye - H, Bq) + D
        except np.linalg.LinAlgError:  # exactly on a pole
            out[k] = np.inf
    return out


def rational_response(num: np.ndarray, den: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``num(v) / den(v)`` (descending coefficients); NaN/inf only at a pole, never a warning.

    High orders overflow ``v^n`` for large ``|v|``: there the ratio is evaluated in ``1/v``,
    ``v^(n_num - n_den) num~(1/v) / den~(1/v)`` with the reversed coefficients (the power
    through logarithms).  Where the plain evaluation is finite it is returned unchanged.
    """
    with np.errstate(all="ignore"):
        out = np.polyval(num, v) / np.polyval(den, v)
    bad = ~np.isfinite(out) & (np.abs(v) > 1.0)
    if bad.any():
        n = strip_leading_zeros(np.asarray(num, dtype=float))
        d = strip_leading_zeros(np.asarray(den, dtype=float))
        w = 1.0 / v[bad]
        with np.errstate(all="ignore"):  # the power in logs: it alone may under- or overflow
            ratio = np.polyval(n[::-1], w) / np.polyval(d[::-1], w)
            out[bad] = np.exp(np.log(ratio) + (n.size - d.size) * np.log(v[bad]))
    return out


def transfer_response(num: Sequence, den: Sequence, v: np.ndarray) -> np.ndarray:
    """:func:`rational_response` of every entry ``num[i][j] / den[i][j]``, shape (n_v, p, m)."""
    out = np.empty((v.size, len(num), len(num[0])), dtype=complex)
    for i, (nrow, drow) in enumerate(zip(num, den, strict=True)):
        for j, (n, d) in enumerate(zip(nrow, drow, strict=True)):
            out[:, i, j] = rational_response(n, d, v)
    return out


def ss_dc_gain(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, dt: float | None) -> np.ndarray:
    """Static gain ``D + C M^-1 B`` with ``M = -A`` (continuous) or ``I - A`` (discrete), shape (p, m);
    ModelError when ``M`` is singular (a pole at s = 0 or z = 1)."""
    n = A.shape[0]
    M = -A if dt is None else np.eye(n) - A
    if n and np.linalg.matrix_rank(M) < n:
        raise ModelError("the DC gain is infinite: the model has a pole at s = 0 (z = 1).")
    return D + (C @ np.linalg.solve(M, B) if n else 0.0)


def transfer_dc_gain(num: Sequence, den: Sequence, dt: float | None) -> np.ndarray:
    """Static gain of every entry, shape (p, m): ``num/den`` at ``s = 0`` or ``z = 1``; ModelError for
    a pole there (or a 0/0 a common root would cancel)."""
    v = 0.0 if dt is None else 1.0
    out = np.empty((len(num), len(num[0])))
    for i in range(len(num)):
        for j in range(len(num[0])):
            d = np.polyval(den[i][j], v)
            n = np.polyval(num[i][j], v)
            if abs(d) <= 1e-14 * max(1.0, np.max(np.abs(den[i][j]))):
                if abs(n) > 1e-14:
                    raise ModelError(f"the DC gain of entry [{i}][{j}] is infinite: it has a pole at DC.")
                raise ModelError(f"entry [{i}][{j}] is 0/0 at DC: cancel the common root first.")
            out[i, j] = n / d
    return out


def markov_parameters(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, n_parameters: int) -> np.ndarray:
    """``D, CB, CAB, ..., C A^(k-2) B`` of a discrete model, shape (n_parameters, p, m)."""
    out = np.empty((n_parameters, C.shape[0], B.shape[1]))
    if n_parameters:
        out[0] = D
    AkB = B.copy()
    for k in range(1, n_parameters):
        out[k] = C @ AkB
        AkB = A @ AkB
    return out


def balanced(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(T^-1 A T, T^-1 B, C T)`` with the diagonal ``T`` that balances ``A`` (no permutation).

    Before a minimal realisation: a continuous companion block carries coefficients up to
    ``w^n`` (~1e12 for a third-order coupling at 2000 rad/s), and the reduction's threshold,
    relative to that norm, would call every state of such a plant unobservable.
    """
    if not A.shape[0]:
        return A, B, C
    import scipy.linalg as sla

    A, scaling = sla.matrix_balance(A, permute=False)
    d = np.diag(scaling)
    return A, B / d[:, None], C * d[None, :]


def poles_stable(poles: np.ndarray, dt: float | None, margin: float = 0.0) -> bool:
    """True when every pole is left of ``-margin`` (continuous) or inside ``|z| < 1 - margin`` (discrete)."""
    if poles.size == 0:
        return True
    if dt is None:
        return bool(np.all(poles.real < -margin))
    return bool(np.all(np.abs(poles) < 1.0 - margin))


def dt_from_control(dt: Any) -> float | None:
    """The sample time of a python-control system (``0`` continuous); ModelError if unspecified."""
    if dt is None or dt is True:
        raise ModelError("the python-control system has an unspecified sample time; give it a numeric dt.")
    return None if dt == 0 else float(dt)
