"""FRF of periodic excitation (multisines): averaging over periods, noise from their scatter.

Pintelon & Schoukens, *System Identification*, 2nd ed., sec. 2.4: after the transient
periods are dropped, the DFT of every period ``p`` gives ``U^[p](k)``, ``Y^[p](k)``; their
means over the ``P`` periods are ``U(k)``, ``Y(k)`` (eq. 2-41) and the FRF is
``G(k) = Y(k) U(k)^-1`` with one record per column of ``U`` (one experiment per excited
input, or orthogonal multisines).  The noise of ``G`` follows from the scatter of the
per-period residuals ``Y^[p] - G U^[p]`` (eq. 2-43, ``P - 1`` degrees of freedom); the
coherence is ``1 - sigma^2 P / |Y|^2``.  Only the excited lines (input power above 1e-10 of
the largest line) are returned.  On noise-free steady-state data the estimate is exact.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._errors import DataError
from ..base import Estimator, Interval
from ..data import Experiment, as_experiments
from ..models.frequency_response import FrequencyResponse
from .estimate import FRFResult

__all__ = ["PeriodicFRF", "periodic_frf", "excited_lines", "period_average"]

#: Lines whose input power is below this fraction of the strongest line count as not excited.
EXCITED_FRACTION = 1e-10


class PeriodicFRF(Estimator):
    """Average over periods and estimate the FRF at the excited lines (see the module docstring).

    Parameters
    ----------
    periods : int
        Periods in each record (the record length must be a multiple of it).
    transient_periods : int
        Leading periods dropped (the transient); at least 2 must remain for the noise.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Experiment
    >>> u = np.tile(np.random.default_rng(0).standard_normal(100), 5)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:500]
    >>> res = PeriodicFRF(periods=5, transient_periods=1).fit(Experiment(u, y, 1.0))
    >>> z = np.exp(2j * np.pi * res.model.freqs); H = 1 / z + 0.5 / z**2
    >>> bool(np.max(np.abs(res.model.response[:, 0, 0] - H)) < 1e-12), res.diagnostics["period"]
    (True, 100)
    >>> frd = periodic_frf(Experiment(u, y, 1.0), periods=5, transient_periods=1)
    >>> bool(np.array_equal(frd.response, res.model.response))
    True
    """

    parameter_constraints = {
        "periods": [Interval(int, 1, None)],
        "transient_periods": [Interval(int, 0, None)],
    }

    def __init__(self, periods: int, transient_periods: int = 1) -> None:
        self.periods = periods
        self.transient_periods = transient_periods

    def fit(self, data: Experiment | Sequence[Experiment]) -> FRFResult:
        """The estimate from records of one length holding ``periods`` whole periods each; as
        many records as inputs (each exciting the inputs differently) unless there is one input.

        Returns
        -------
        FRFResult
            ``model`` with ``std`` (from the period-to-period scatter) and ``coherence``;
            ``diagnostics`` the period in samples and the periods averaged.

        Raises
        ------
        ParameterError
            A bad setting.
        DataError
            A length that is not a multiple of ``periods``, fewer than 2 periods left, fewer
            records than inputs, or no line where the input matrix is invertible.
        """
        self.validate_params()
        exps = as_experiments(data)
        periods, transient = int(self.periods), int(self.transient_periods)
        L, kept = _period_layout(exps, periods, transient)
        start = transient * L

        def per_period(x: np.ndarray) -> np.ndarray:  # (kept, lines, channels)
            return np.fft.rfft(x[start:].reshape(kept, L, -1), axis=1)

        Up = np.stack([per_period(e.u) for e in exps], axis=-1)  # (P, lines, m, ne)
        Yp = np.stack([per_period(e.y) for e in exps], axis=-1)  # (P, lines, q, ne)
        lines, G, std, coh = _average(Up, Yp)
        freqs = lines / (L * exps[0].dt)
        frd = FrequencyResponse(freqs, G, std, coh, exps[0].input_names, exps[0].output_names)
        return FRFResult(frd, self.clone(), {"period": L, "periods_averaged": kept})


def periodic_frf(
    data: Experiment | Sequence[Experiment], periods: int, transient_periods: int = 1
) -> FrequencyResponse:
    """The response of :class:`PeriodicFRF` ``(periods, transient_periods).fit(data)`` (its examples show both)."""
    return PeriodicFRF(periods, transient_periods).fit(data).model


def _period_layout(exps: list[Experiment], periods: int, transient: int) -> tuple[int, int]:
    """The period in samples and the periods kept after the transient; DataError when the
    records do not hold whole periods of one length, keep fewer than 2, or are fewer than the inputs."""
    N = exps[0].n_samples
    m, ne = exps[0].n_inputs, len(exps)
    if any(e.n_samples != N for e in exps):
        raise DataError(f"periodic averaging needs records of one length; got {sorted({e.n_samples for e in exps})}.")
    if N % periods:
        raise DataError(
            f"a record of {N} samples does not hold {periods} whole periods ({N} / {periods} is not whole)."
        )
    kept = periods - transient
    if kept < 2:
        raise DataError(f"{periods} periods minus {transient} transient periods leaves {kept}; at least 2 are needed.")
    if ne < m:
        raise DataError(f"{m} inputs need at least {m} records with different excitation; got {ne}.")
    return N // periods, kept


def _average(Up: np.ndarray, Yp: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Excited lines, ``G``, its std and the coherence from per-period spectra (eq. 2-41 to 2-43).

    ``Up`` (P, lines, m, ne), ``Yp`` (P, lines, q, ne): the DFT of every period of every record.
    """
    lines = excited_lines(Up.mean(axis=0))
    Up, Yp = Up[:, lines], Yp[:, lines]
    G, var, sigma2, _ = period_average(Up, Yp)
    ypow = np.mean(np.abs(Yp.mean(axis=0)) ** 2, axis=2)
    with np.errstate(invalid="ignore", divide="ignore"):
        coh = np.where(ypow > 0, 1.0 - sigma2.mean(axis=2) / np.where(ypow > 0, ypow, 1.0), 0.0)
    return lines, G, np.sqrt(var), np.clip(coh, 0.0, 1.0)


def excited_lines(Um: np.ndarray) -> np.ndarray:
    """Lines (not DC) whose input power exceeds :data:`EXCITED_FRACTION` of the strongest and whose
    input matrix ``Um`` (lines, m, ne) is invertible.

    Raises
    ------
    DataError
        When there is none (a constant input or proportional inputs).
    """
    power = np.sum(np.abs(Um) ** 2, axis=(1, 2))
    lines = np.flatnonzero(power > EXCITED_FRACTION * power.max(initial=0.0))
    lines = lines[lines > 0]  # the mean (DC) line carries offsets, not the response
    if lines.size:
        sv = np.linalg.svd(Um[lines], compute_uv=False)
        lines = lines[sv[:, -1] > 1e-8 * sv[:, 0]]
    if not lines.size:
        raise DataError("no excited line where the inputs are independent: a constant input or proportional inputs.")
    return lines


def period_average(Up: np.ndarray, Yp: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``G = Ym Um^-1`` from per-period spectra and the noise variance of its entries (eq. 2-41 to 2-43).

    Parameters
    ----------
    Up : ndarray of shape (n_periods, n_lines, n_inputs, n_records), complex
    Yp : ndarray of shape (n_periods, n_lines, n_outputs, n_records), complex

    Returns
    -------
    G : ndarray of shape (n_lines, n_outputs, n_inputs)
    var : ndarray of shape (n_lines, n_outputs, n_inputs)
        ``E|G_est - G|^2`` from the period-to-period scatter of the residuals ``Yp - G Up``.
    sigma2 : ndarray of shape (n_lines, n_outputs, n_records)
        Variance of the period-mean residual of each output and record.
    Uinv : ndarray of shape (n_lines, n_records, n_inputs)
        The (pseudo-)inverse of the period-mean input matrix.
    """
    kept = Up.shape[0]
    Um, Ym = Up.mean(axis=0), Yp.mean(axis=0)
    Uinv = _inverse(Um)  # (lines, ne, m)
    G = Ym @ Uinv  # (lines, q, m)
    resid = Yp - G[None] @ Up  # (P, lines, q, ne)
    sigma2 = np.sum(np.abs(resid - resid.mean(axis=0)) ** 2, axis=0) / (kept - 1) / kept  # var of the mean
    var = np.einsum("kqe,kem->kqm", sigma2, np.abs(Uinv) ** 2)
    return G, var, sigma2, Uinv


def _inverse(Um: np.ndarray) -> np.ndarray:
    """``Um^-1`` line by line: the plain inverse when square (a tenth of the SVD's cost), else the pseudo-inverse."""
    if Um.shape[-1] == Um.shape[-2]:
        try:
            return np.linalg.inv(Um)
        except np.linalg.LinAlgError:
            pass  # a singular line: the pseudo-inverse for all
    return np.linalg.pinv(Um)
