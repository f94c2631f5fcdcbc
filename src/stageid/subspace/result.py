"""The frozen result of ``HankelMAP.fit``: model, posterior, diagnostics, uncertainty, update.

``HankelMAPResult.update`` folds new records into the posterior (eq. 17-18) and realises the
model again; :meth:`~HankelMAPResult.markov_parameters` and
:meth:`~HankelMAPResult.response_bands` carry the posterior's uncertainty to the Markov
parameters of eq. 4 and to the frequency response of eq. 9.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from .._errors import DataError
from ..base import Estimator
from ..checks import is_integer
from ..data.experiment import Experiment
from ..display import html_repr, short_repr
from ..frozen import FrozenMapping
from ..models.frequency_response import FrequencyResponse
from ..models.statespace import StateSpaceModel
from ..runtime.threads import single_blas_thread
from .map.posterior import Posterior
from .realisation.weighting import weighted_parts
from .records import as_records, check_freqs, unscaled_posterior
from .selection import SelectionTable
from .statistics.theta_response import theta_response_std
from .statistics.window_covariance import WindowLags

__all__ = ["ChannelFit", "HankelMAPResult"]


@dataclass(frozen=True, eq=False)
class ChannelFit:
    """One identified (sub-)model: its posterior, horizon, order, band and selection tables.

    For a direct MIMO fit there is one; for ``per_channel=True`` one per input (eq. 19).
    """

    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    scaled_posterior: Posterior
    horizon: int
    order: int
    band: tuple[float, float]
    model: StateSpaceModel
    horizon_table: SelectionTable | None
    order_table: SelectionTable | None
    fit_cost: float
    offsets: tuple[np.ndarray, np.ndarray] | None = None
    scales: tuple[np.ndarray, np.ndarray] | None = None
    #: Lag statistics of the scaled records (:mod:`.window_covariance`) for the covariance of
    #: ``response_uncertainty`` under overlapping windows; None for updates and forgetting.
    window_lags: WindowLags | None = None

    @cached_property
    def posterior(self) -> Posterior:
        """The posterior in the data's units (``scaled_posterior`` is the one the fit worked
        with, every channel divided by ``scales = (input scales, output scales)``).  Built on
        first use: a fit that nobody asks for uncertainty does not pay for rescaling the
        ``d x d`` information matrix."""
        if self.scales is None:
            return self.scaled_posterior
        return unscaled_posterior(self.scaled_posterior, *self.scales)


@dataclass(frozen=True, eq=False)
class HankelMAPResult:
    """The frozen result of :meth:`HankelMAP.fit` (no training data are kept).

    Attributes
    ----------
    model : StateSpaceModel
        The identified discrete-time model with the records' channel names.
    channels : tuple of ChannelFit
        The sub-fits (one for a direct MIMO fit).  ``posterior`` is in the data's units;
        ``scaled_posterior`` is the one the fit worked with (every channel divided by
        ``input_scale`` / ``output_scale``), which :meth:`update` continues.
    estimator : HankelMAP
        A copy of the configuration that produced this result, taken at the fit (used by
        :meth:`update`): settings changed on the original estimator afterwards do not leak in.
    diagnostics : mapping
        Read-only: ``horizon``, ``order``, ``band_hz``, ``n_windows``, ``stable``, ``warnings``
        (a tuple of texts).
    input_scale, output_scale : ndarray of shape (n_inputs,) and (n_outputs,)
        RMS of each (mean-removed) channel of the first fit's records: the fit works on
        channels scaled to unit RMS so that its result does not depend on the units.
    """

    model: StateSpaceModel
    channels: tuple[ChannelFit, ...]
    estimator: Estimator
    diagnostics: Mapping[str, Any] = field(default_factory=dict)
    input_scale: np.ndarray | None = None
    output_scale: np.ndarray | None = None

    def __post_init__(self) -> None:
        d = dict(self.diagnostics)
        if "warnings" in d:
            d["warnings"] = tuple(d["warnings"])
        object.__setattr__(self, "diagnostics", FrozenMapping(d))

    def __repr__(self) -> str:
        return short_repr(self)

    def _repr_html_(self) -> str:
        return html_repr(self)

    @property
    def posterior(self) -> Posterior:
        """The posterior of the direct fit (the first channel's for per-channel fits)."""
        return self.channels[0].posterior

    @property
    def horizon(self) -> int:
        return self.channels[0].horizon

    # -------------------------------------------------------------- online use
    @single_blas_thread
    def update(self, data: Experiment | Sequence[Experiment]) -> HankelMAPResult:
        """Fold new records into the posterior (eq. 17-18) and return a new result.

        The old information is discounted by ``forgetting^n_new_windows``; the horizon and
        the order stay those of this result; the model is realised again from the updated
        posterior.  New records are treated as separate records (no window straddles the
        boundary between the old and the new data).

        Raises
        ------
        DataError
            When the new records have other channels or another sample time than this result.
        """
        notes: list[str] = []
        est = self.estimator  # the settings of this fit, copied then: later changes to the estimator do not leak in
        return est.fit_source(*est.memory_source(as_records(data, "HankelMAPResult.update"), self, notes), self, notes)

    # --------------------------------------------------------- uncertainty
    def markov_parameters(self, n_parameters: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Markov parameters ``Y_0 .. Y_(p-1)`` identified in ``D_p`` (eq. 4, 9) and their std.

        Returns
        -------
        mean, std : ndarrays of shape (n_parameters, n_outputs, n_inputs)
            Posterior mean and standard deviation (``P (x) Sigma``); ``n_parameters`` is at
            most the horizon.  Per-channel fits are assembled column by column.
        """
        outs = []
        for ch in self.channels:
            post = ch.posterior
            p, m, q = post.horizon, post.n_inputs, post.n_outputs
            if n_parameters is not None and not (is_integer(n_parameters) and n_parameters >= 1):
                raise DataError(f"`n_parameters` must be a positive integer or None; got {n_parameters!r}.")
            k = p if n_parameters is None else min(int(n_parameters), p)
            cols = 2 * p * m + p * q - p * m + np.arange(m)  # u(k) columns of D_p
            rows = np.arange(k * q)
            mean = post.theta[np.ix_(rows, cols)].reshape(k, q, m)
            # no overlap inflation here (unlike response_bands): one row's residuals e(k + i) are
            # independent from window to window, so P (x) Sigma is its marginal as it stands
            var = np.outer(np.diag(post.noise_cov)[rows], np.diag(post.covariance)[cols]).reshape(k, q, m)
            outs.append((mean, np.sqrt(np.clip(var, 0, None))))
        if len(outs) == 1:
            return outs[0]
        k = min(o[0].shape[0] for o in outs)
        return (np.concatenate([o[0][:k] for o in outs], axis=2), np.concatenate([o[1][:k] for o in outs], axis=2))

    def response_bands(self, freqs_hz: Sequence[float] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Frequency response of the identified Hankel-Toeplitz model and its posterior std.

        This is the response the realisation fits (``theta_frequency_response`` with the
        outputs weighted by their inverse noise std, see the Notes of :class:`HankelMAP`); the
        standard deviation propagates ``Cov(vec theta) = P (x) Sigma`` to first order.
        Consecutive windows of eq. 9 share ``2p - 1`` samples, so their errors are not
        independent as the recursion of eq. 17 assumes: the posterior covariance is too small
        by about the overlap, and the bands use ``p P`` (an effective sample size of
        ``n_windows / p``); a single Markov parameter (one row) is not affected.  They do not include the
        bias of the realisation step.

        Parameters
        ----------
        freqs_hz : array_like of shape (n_freqs,)
            Frequencies in Hz, finite and within ``[0, 1 / (2 dt)]``.

        Returns
        -------
        G, std : ndarrays of shape (n_freqs, n_outputs, n_inputs) (complex and real)

        Raises
        ------
        DataError
            When ``freqs_hz`` is not a 1-D array of finite frequencies up to Nyquist.
        """
        f = check_freqs(freqs_hz, self.model.dt)
        Gs, Ss = [], []
        for ch in self.channels:
            post = ch.scaled_posterior
            # in the noise-whitened outputs the realisation fits (theta_w = W theta diag(c))
            spread, w = weighted_parts(post)
            G, S = theta_response_std(spread, f, self.model.dt)
            G, S = G / w[None, :, None], S / w[None, :, None]
            if self.input_scale is not None and self.output_scale is not None:
                su = self.input_scale[[self.model.inputs.index(n) for n in ch.inputs]]
                unit = self.output_scale[:, None] / su[None, :]
                G, S = G * unit[None], S * unit[None]
            Gs.append(G)
            Ss.append(S)
        return np.concatenate(Gs, axis=2), np.concatenate(Ss, axis=2)

    def response_uncertainty(
        self, freqs_hz: Sequence[float] | np.ndarray, method: str = "auto", n_samples: int = 40, seed: int = 0
    ) -> FrequencyResponse:
        """The realised model's frequency response with ``std = sqrt(E|G_est - G|^2)`` per entry.

        Unlike :meth:`response_bands` (the eq. 9 response), this is the posterior carried
        through the realisation to the model itself: first order (``method="delta"``, the
        default for the refined frequency route) or by realising draws of the posterior
        (``"sampling"``, the default otherwise); see :mod:`stageid.subspace.uncertainty`.

        Parameters
        ----------
        freqs_hz : array_like of shape (n_freqs,)
            Strictly increasing frequencies in Hz within ``[0, 1 / (2 dt)]``.
        method : {"auto", "delta", "sampling"}
        n_samples, seed : int
            Draws and seed of ``"sampling"``.

        Returns
        -------
        FrequencyResponse
            ``response`` the model's, ``std`` its standard deviation, the model's channel names.

        Raises
        ------
        DataError
            Frequencies that are not finite, not increasing, or outside ``[0, Nyquist]``.

        Examples
        --------
        >>> import numpy as np
        >>> from stageid.data import Experiment
        >>> from stageid.models import StateSpaceModel
        >>> from stageid.subspace import HankelMAP
        >>> g = StateSpaceModel([[0.9]], [[1.0]], [[0.1]], [[0.0]], dt=0.01)
        >>> rng = np.random.default_rng(0)
        >>> u = rng.standard_normal((2000, 1))
        >>> y = g.simulate(u) + 0.01 * rng.standard_normal((2000, 1))
        >>> fr = HankelMAP(horizon=5, order=1).fit(Experiment(u, y, 0.01)).response_uncertainty([1.0, 10.0])
        >>> fr.std.shape, bool(np.all(np.abs(fr.response - g.frequency_response([1.0, 10.0])) < 5 * fr.std))
        ((2, 1, 1), True)
        """
        from .uncertainty import realised_response_uncertainty

        return realised_response_uncertainty(self, freqs_hz, method, n_samples, seed)

    def summary(self) -> str:
        """A short text summary (horizon, order, band, stability, selection tables)."""
        d = self.diagnostics
        lines = [
            f"HankelMAP result: {self.model.n_states} states, inputs {list(self.model.inputs)}, "
            f"outputs {list(self.model.outputs)}, dt = {self.model.dt:g} s",
            f"method {self.estimator.method}, realization {self.estimator.realization}, "
            f"per_channel {self.estimator.per_channel}, forgetting {self.estimator.forgetting}",
        ]
        for ch in self.channels:
            lines.append(
                f"  inputs {list(ch.inputs)}: horizon {ch.horizon}, order {ch.order}, "
                f"band {ch.band[0]:.3g}-{ch.band[1]:.3g} Hz, windows {ch.scaled_posterior.n_windows:.0f}"
            )
            if ch.horizon_table is not None:
                lines.append("    " + ch.horizon_table.to_text().replace("\n", "\n    "))
            if ch.order_table is not None:
                lines.append("    " + ch.order_table.to_text().replace("\n", "\n    "))
        lines.append(f"stable: {d.get('stable')}")
        for w in d.get("warnings", []):
            lines.append(f"warning: {w}")
        return "\n".join(lines)
