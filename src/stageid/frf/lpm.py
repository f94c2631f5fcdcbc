"""The local polynomial method (LPM) for non-periodic excitation.

Pintelon, Schoukens, Vandersteen & Barbe, "Estimation of nonparametric noise and FRF models
for multivariable systems", Mech. Syst. Signal Process. 24 (2010), sec. 3.  Around every DFT
line ``k`` of the whole record the FRF and the leakage (transient) term are approximated by
polynomials of degree ``R`` in the line offset ``r``:

    Y_e(k + r) = (G_k + sum_s g_s r^s) U_e(k + r) + T_e,k + sum_s t_e,s r^s + V_e(k + r)   (eq. 11)

for ``r = -n .. n`` and every record ``e``.  Linear least squares over the ``n_e (2n + 1)``
equations gives ``G_k`` at the record's full resolution, free of the leakage that limits
Welch's estimate at lightly damped resonances; the residuals give the noise variance
``sigma^2 = |E|^2 / dof`` (eq. 16) and ``cov(G_k) = sigma^2 [(K^H K)^-1]_G`` (eq. 18).
The multiple coherence reported is ``1 - sigma^2 / mean_r |Y(k + r)|^2`` over the window.

The lines are solved by a numba kernel (:mod:`.lpm_kernels`, :mod:`.lpm_lanes`: Gram matrices
from moments of the line products, complex Cholesky, 16 lines side by side); its plain-numpy
twin :func:`solve_lines_python` (``lpm_frf(..., compiled=False)``) is the reference the tests
compare it with and decides the lines the kernel flags as ill-conditioned.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from .._errors import DataError
from ..base import Boolean, Estimator, Interval
from ..data import Experiment, as_experiments
from ..models.frequency_response import FrequencyResponse
from ..runtime.resources import require_memory
from .estimate import FRFResult
from .lpm_kernels import lpm_lines_kernel

__all__ = ["LocalPolynomialFRF", "lpm_frf", "lpm_half_width", "solve_lines_python", "solve_lines_compiled"]

#: Lines solved at once (bounds the temporaries to a few tens of MB).
LINES_PER_BATCH = 8192
#: Mean input power in a window, relative to the input's mean over the record, below which
#: the line counts as not excited (band-limited noise leaves ~1e-10 outside its band).
EXCITED_POWER = 1e-6


def lpm_half_width(n_inputs: int, n_records: int, degree: int) -> int:
    """The smallest half width ``n`` leaving at least 6 residual degrees of freedom per window
    in each record's own regression, whatever the number of records.

    Pooling ``n_records`` records would allow a narrower window for the same total degrees of
    freedom, but when each record excites one input (the usual way of measuring a MIMO FRF)
    the pooled regression falls apart into one per record, each with ``(R + 1)`` G and
    ``(R + 1)`` transient coefficients per output: the pooled rule left those 9 lines for 6
    unknowns on the P-558 3x3 stage and tripled the error (benchmarks/RESULTS-frf.md).
    """
    del n_records  # see above: the per-record rule holds for any number of records
    n_params = (n_inputs + 1) * (degree + 1)
    return max(1, int(np.ceil((n_params + 6 - 1) / 2)))


class LocalPolynomialFRF(Estimator):
    """LPM estimate of the FRF with its standard deviation and coherence (see the module docstring).

    Parameters
    ----------
    degree : int
        Polynomial degree ``R`` of the FRF and transient terms (2 in the paper), 0 to 6.
    half_width : int, optional
        Lines on each side of ``k``; default :func:`lpm_half_width`.
    compiled : bool
        Solve the lines with the numba kernel (:func:`solve_lines_compiled`, default) or with
        its plain-numpy twin :func:`solve_lines_python` (the reference the tests compare with).

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Experiment
    >>> rng = np.random.default_rng(0); u = rng.standard_normal(4000)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:4000]
    >>> res = LocalPolynomialFRF(degree=2).fit(Experiment(u, y, 1.0))
    >>> z = np.exp(2j * np.pi * res.model.freqs); H = 1 / z + 0.5 / z**2
    >>> bool(np.max(np.abs(res.model.response[:, 0, 0] - H)) < 1e-6), res.diagnostics["half_width"]
    (True, 6)
    >>> bool(np.array_equal(lpm_frf(Experiment(u, y, 1.0)).response, res.model.response))
    True
    """

    parameter_constraints = {
        "degree": [Interval(int, 0, 6)],
        "half_width": [Interval(int, 1, None), None],
        "compiled": [Boolean()],
    }

    def __init__(self, degree: int = 2, half_width: int | None = None, compiled: bool = True) -> None:
        self.degree = degree
        self.half_width = half_width
        self.compiled = compiled

    def fit(self, data: Experiment | Sequence[Experiment]) -> FRFResult:
        """The LPM estimate of records of one length (one per excited input, or several inputs excited at once).

        Returns
        -------
        FRFResult
            ``model`` at ``k / (N dt)`` for ``k = 1 .. N//2 - 1``, leaving out the lines that
            are not excited (an input's power in the window below ``EXCITED_POWER`` of its
            record mean, as outside the band of band-limited noise) or whose local regression
            is not invertible (``diag(M) diag(M^-1) > 1e12``); ``diagnostics`` the half width
            and the number of lines left out.

        Raises
        ------
        ParameterError
            A bad setting.
        DataError
            Records of different lengths, too few lines for the window, or an input with no
            excitation (a singular local regression).
        """
        self.validate_params()
        exps = as_experiments(data)
        degree = int(self.degree)
        N = exps[0].n_samples
        if any(e.n_samples != N for e in exps):
            raise DataError(f"the LPM needs records of one length; got {sorted({e.n_samples for e in exps})} samples.")
        m, ne = exps[0].n_inputs, len(exps)
        n = lpm_half_width(m, ne, degree) if self.half_width is None else int(self.half_width)
        K_last = N // 2
        if K_last + 1 < 2 * n + 1 or K_last < 2:
            raise DataError(
                f"the LPM window of {2 * n + 1} lines needs at least {4 * n + 2} samples per record; got {N}."
            )
        ks = np.arange(1, K_last)
        n_th = (m + ne) * (degree + 1)
        require_memory(
            16.0 * min(ks.size, LINES_PER_BATCH) * ne * (2 * n + 1) * (n_th + exps[0].n_outputs) * 4,
            "local polynomial method",
        )
        G, var, coh, ok = _solve(exps, ks, n, degree, K_last, bool(self.compiled))
        std = np.sqrt(var, out=var)  # in place: at full resolution these arrays are large
        freqs = ks[ok] / (N * exps[0].dt)
        frd = FrequencyResponse(freqs, G, std, coh, exps[0].input_names, exps[0].output_names, copy=False)
        return FRFResult(frd, self.clone(), {"half_width": n, "lines_left_out": int(ks.size - ok.sum())})


def lpm_frf(
    data: Experiment | Sequence[Experiment],
    degree: int = 2,
    half_width: int | None = None,
    *,
    compiled: bool = True,
) -> FrequencyResponse:
    """The response of :class:`LocalPolynomialFRF` ``(degree, half_width, compiled).fit(data)``
    (its examples show both)."""
    return LocalPolynomialFRF(degree, half_width, compiled).fit(data).model


def _solve(
    exps: list[Experiment], ks: np.ndarray, n: int, degree: int, k_last: int, compiled: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``G``, ``var``, coherence of the usable lines among ``ks`` (in input units), and which are usable."""
    U, Y, u_scale = _spectra(exps)
    if compiled:  # one call: the kernel's work arrays are per line; it writes in input units
        G, var, coh, ok = solve_lines_compiled(U, Y, ks, n, degree, k_last, u_scale)
    else:
        G, var, coh, ok = _batched(solve_lines_python, U, Y, ks, n, degree, k_last)
        G /= u_scale
        var /= u_scale**2
    if not ok.any():
        raise DataError(
            "no DFT line has an invertible local regression: an input without excitation or inputs always proportional."
        )
    if not ok.all():
        G, var, coh = G[ok], var[ok], coh[ok]
    return G, var, coh, ok


def _spectra(exps: list[Experiment]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """DFTs ``U`` (unit RMS per input) and ``Y`` of the records, (ne, lines, m|q), and the input scales."""
    if len(exps) == 1:  # no stacking copy: the full-resolution spectra are large
        U, Y = np.fft.rfft(exps[0].u, axis=0)[None], np.fft.rfft(exps[0].y, axis=0)[None]
    else:
        U = np.stack([np.fft.rfft(e.u, axis=0) for e in exps])
        Y = np.stack([np.fft.rfft(e.y, axis=0) for e in exps])
    power = np.einsum("eia,eia->a", U.real, U.real) + np.einsum("eia,eia->a", U.imag, U.imag)
    u_scale = np.sqrt(power / (U.shape[0] * U.shape[1]))  # no full-size temporaries
    if np.any(u_scale == 0):
        raise DataError("an input is zero throughout; the LPM needs every input excited.")
    U /= u_scale
    return U, Y, u_scale


def _batched(
    solve: Callable, U: np.ndarray, Y: np.ndarray, ks: np.ndarray, n: int, degree: int, k_last: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``solve`` over ``ks`` in batches of ``LINES_PER_BATCH`` lines (bounded temporaries)."""
    q, m = Y.shape[2], U.shape[2]
    G = np.empty((ks.size, q, m), complex)
    var = np.empty((ks.size, q, m))
    coh = np.empty((ks.size, q))
    ok = np.empty(ks.size, bool)
    for b in range(0, ks.size, LINES_PER_BATCH):
        sl = slice(b, b + LINES_PER_BATCH)
        G[sl], var[sl], coh[sl], ok[sl] = solve(U, Y, ks[sl], n, degree, k_last)
    return G, var, coh, ok


def solve_lines_compiled(
    U: np.ndarray, Y: np.ndarray, ks: np.ndarray, n: int, degree: int, k_last: int, scale: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`solve_lines_python` by the numba kernel :func:`~stageid.frf.lpm_kernels.lpm_lines_kernel`;
    the lines it flags (ill-conditioned or a failed Cholesky pivot) are solved by the twin.  With
    ``scale`` (m,), ``G`` and ``var`` come divided by ``scale[a]`` and ``scale[a]^2``."""
    B, q, m = ks.size, Y.shape[2], U.shape[2]
    G = np.empty((B, q, m), complex)
    var = np.empty((B, q, m))
    coh = np.empty((B, q))
    status = np.empty(B, np.int8)
    Ur, Ui = U.real, U.imag  # strided views: the kernel reads each line once
    ks = np.ascontiguousarray(ks, np.int64)
    lpm_lines_kernel(Ur, Ui, np.ascontiguousarray(Y), ks, n, degree, k_last, EXCITED_POWER, G, var, coh, status, scale)
    hard = np.flatnonzero(status == 2)
    if hard.size:
        G[hard], var[hard], coh[hard], good = _batched(solve_lines_python, U, Y, ks[hard], n, degree, k_last)
        if scale is not None:
            G[hard] /= scale
            var[hard] /= scale**2
        status[hard] = np.where(good, 0, 1)
    return G, var, coh, status == 0


def solve_lines_python(
    U: np.ndarray, Y: np.ndarray, ks: np.ndarray, n: int, degree: int, k_last: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The local regressions (eq. 11) of the lines ``ks``: ``G_k``, ``var(G_k)``, coherence, and
    which lines are usable (a finite, positive variance and ``diag(M) diag(M^-1) <= 1e12``)."""
    ne, _, m = U.shape
    q = Y.shape[2]
    centre = np.clip(ks, n, k_last - n)  # windows stay inside the DFT lines 0 .. N/2
    idx = centre[:, None] + np.arange(-n, n + 1)[None, :]  # (B, rows)
    r = (idx - ks[:, None]) / n  # offsets from k, scaled to about [-1, 1] for conditioning
    powers = r[:, :, None] ** np.arange(degree + 1)  # (B, rows, R+1)
    B = ks.size
    rows = idx.shape[1]
    n_th = (m + ne) * (degree + 1)
    K = np.zeros((B, ne * rows, n_th), complex)
    Yl = np.empty((B, ne * rows, q), complex)
    for e in range(ne):
        Ue = U[e][idx]  # (B, rows, m)
        blk = slice(e * rows, (e + 1) * rows)
        K[:, blk, : m * (degree + 1)] = (Ue[:, :, :, None] * powers[:, :, None, :]).reshape(B, rows, -1)
        t0 = m * (degree + 1) + e * (degree + 1)
        K[:, blk, t0 : t0 + degree + 1] = powers
        Yl[:, blk] = Y[e][idx]
    Kh = np.conj(K).transpose(0, 2, 1)
    gram = Kh @ K
    try:
        inv = np.linalg.inv(gram)
    except np.linalg.LinAlgError:
        raise DataError(
            "the local regression of the LPM is singular: an input without excitation or inputs always proportional."
        ) from None
    inv = np.where(np.isfinite(inv), inv, np.nan)
    theta = inv @ (Kh @ Yl)  # (B, n_th, q)
    resid = Yl - K @ theta
    dof = ne * rows - n_th
    sigma2 = np.sum(np.abs(resid) ** 2, axis=1) / dof  # (B, q)
    g_idx = np.arange(m) * (degree + 1)  # the r^0 coefficient of each input
    G = theta[:, g_idx, :].transpose(0, 2, 1)  # (B, q, m)
    diag = np.real(np.diagonal(inv, axis1=1, axis2=2))[:, g_idx]  # (B, m)
    var = sigma2[:, :, None] * diag[:, None, :]
    power = np.mean(np.abs(Yl) ** 2, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        coh = np.where(power > 0, 1.0 - sigma2 / np.where(power > 0, power, 1.0), 0.0)
    gram_diag = np.real(np.diagonal(gram, axis1=1, axis2=2))[:, g_idx]  # window power of each (unit-RMS) input
    excited = np.all(gram_diag >= EXCITED_POWER * ne * rows, axis=1)
    good = (
        excited
        & np.all(np.isfinite(var), axis=(1, 2))
        & np.all(diag > 0, axis=1)
        & np.all(diag * gram_diag <= 1e12, axis=1)
    )
    return G, var, np.clip(coh, 0.0, 1.0), good
