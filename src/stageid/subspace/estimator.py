"""``HankelMAP``: configure, fit, get a frozen result (Cao & Chen 2013, the whole method).

Pipeline of :meth:`HankelMAP.fit`:

1. normal-equation statistics of the Hankel-Toeplitz regression (eq. 9) per record, from lag
   correlations (``hankel_toeplitz``); several records (e.g. one per excited input) pool
   their windows;
2. ``theta = [Gamma Phi D_p]`` by MAP (eq. 16-18, prior ``theta_0 = 0`` and a weak
   ``P_0``) or by batch least squares (flat prior, Lim, Phan & Longman) (``map_estimator``);
3. the system matrices (``realization``), with every output weighted by the inverse of its
   estimated noise standard deviation (see the Notes of :class:`HankelMAP`):

   * ``realization="frequency"`` (default): the response of the identified model over the
     excited band, realised by the frequency-domain counterpart of Lemma 1 and refined by an
     output-error fit on that band.  The fit starts from the better (lower in-band cost) of
     that realisation and a balanced truncation of one of twice the order: on white-input
     records the latter starts 3-30 % above the optimum, so the fit takes 3-4 steps instead
     of 8-14; on band-limited records the former usually wins.  When the refined model still
     misses the response by more than 1e-3 of its energy (an order too low for the
     structure, as on real records), the fit is also run from the other start and the better
     end is kept.  Band-limited records (the paper's 1-100 Hz chirps at
     Ts = 2 ms) determine ``theta`` only up to directions without input energy, and those
     directions enter the Markov parameters: Lemma 1 on them is then several percent off in
     band, while the in-band response of eq. 9 stays accurate (to ~0.1 % with ``p = 40`` on
     the P-558 reference) whatever the prior does out of band;
   * ``realization="markov"``: the paper's route, ``H0 = Gamma + Phi D_p`` (eq. 10),
     ``H_i = Phi^i H0`` (eq. 12), ``H(0)``, ``H(1)`` (eq. 14) and Lemma 1 (eq. 15).  Exact for
     broadband (white) inputs;
4. per-input-channel identification stacked into the MIMO model (eq. 19-22) when
   ``per_channel=True``.

The horizon and the order are chosen by held-out prediction error when ``"auto"``
(``selection``), with the outputs weighted by their noise as in the realisation.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from .._errors import DataError, ExcitationWarning, IdentificationError, StabilityWarning
from .._threads import single_blas_thread
from ..data.experiment import Experiment, as_experiments
from ..models.statespace import StateSpaceModel
from .hankel_toeplitz import (
    WindowStatistics,
    _input_periodogram,
    record_statistics,
    segments_statistics,
    theta_frequency_response,
    theta_response_std,
)
from .map_estimator import Posterior, Prior, batch_posterior, default_prior, map_estimate
from .realization import (
    _fit_cost,
    balanced_start,
    era,
    fit_input_matrices,
    frequency_realization,
    markov_from_theta,
    refine_frequency_fit,
)
from .selection import SelectionTable, default_horizons, prediction_error, row_residuals, simulation_error

__all__ = ["HankelMAP", "HankelMAPResult", "ChannelFit"]

_METHODS = ("map", "ls")
DEFAULT_PRIOR_STRENGTH = 1e-5
# method="ls" on singular normal equations (relative Cholesky pivot below LS_SINGULAR_PIVOT, e.g.
# noise-free records, where the past outputs are a function of the state and the past inputs, or
# strictly band-limited inputs).  The minimum-norm (pseudo-inverse) solution of the OKID /
# identified-Hankel family is no cure: after the mean removal the noise-free windows satisfy
# y = O x0 + T u + c 1 with a constant offset c (the record mean of y is not exactly G(1) times
# that of u), which an exact fit can only explain by a mode at z = 1 (on the 3-state MIMO check
# of the tests the minimum-norm fit gave |poles| 0.73, 0.83, 0.99998 instead of 0.7, 0.8, 0.9).
# A ridge of 1e-10 of each regressor's energy (1e-12 .. 1e-8 all give the poles to 1e-5) removes
# that mode and leaves a full-rank LS problem untouched; the fit warns when it is used.
LS_SINGULAR_PIVOT = 1e-12
LS_RIDGE_STRENGTH = 1e-10
# the noise std of an output (output weights of the realisation and selection, see the Notes
# of HankelMAP) is taken as at least this fraction of the output's RMS: noise-free records
# then weigh the outputs as unit RMS does
NOISE_STD_FLOOR = 1e-3
#: Relative cost decrease below which the output-error refinement of the realisation stops:
#: from its starts the later steps move the response far less than its own uncertainty (P-558
#: benchmark, N = 50 000, p = 40: error 1.328e-3 after 1 step, 1.356e-3 after 3 or 4; the
#: acceptance sweep moved by <= 0.02 % against 1e-3).
REFINE_TOL = 3e-3
#: Relative misfit of the refined realisation (cost over the response's energy) above which
#: the refinement also runs from the second start.  Fits of the synthetic stages end at
#: 3e-7 - 3e-6; the DaISy CD player arm (order 3) at 1e-2, the flexible structure (order 12)
#: at 0.2.
MULTI_START_MISFIT = 1e-3
_REALIZATIONS = ("frequency", "markov")


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

    @cached_property
    def posterior(self) -> Posterior:
        """The posterior in the data's units (``scaled_posterior`` is the one the fit worked
        with, every channel divided by ``scales = (input scales, output scales)``).  Built on
        first use: a fit that nobody asks for uncertainty does not pay for rescaling the
        ``d x d`` information matrix."""
        if self.scales is None:
            return self.scaled_posterior
        return _unscaled_posterior(self.scaled_posterior, *self.scales)


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
        The configuration that produced this result (used by :meth:`update`).
    diagnostics : dict
        ``horizon``, ``order``, ``band_hz``, ``n_windows``, ``stable``, ``warnings`` (texts).
    input_scale, output_scale : ndarray of shape (n_inputs,) and (n_outputs,)
        RMS of each (mean-removed) channel of the first fit's records: the fit works on
        channels scaled to unit RMS so that its result does not depend on the units.
    """

    model: StateSpaceModel
    channels: tuple[ChannelFit, ...]
    estimator: HankelMAP
    diagnostics: dict = field(default_factory=dict)
    input_scale: np.ndarray | None = None
    output_scale: np.ndarray | None = None

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
        return self.estimator._fit(_as_records(data, "HankelMAPResult.update"), previous=self)

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
            if n_parameters is not None and not _is_pos_int(n_parameters):
                raise DataError(f"`n_parameters` must be a positive integer or None; got {n_parameters!r}.")
            k = p if n_parameters is None else min(int(n_parameters), p)
            cols = 2 * p * m + p * q - p * m + np.arange(m)  # u(k) columns of D_p
            rows = np.arange(k * q)
            mean = post.theta[np.ix_(rows, cols)].reshape(k, q, m)
            P = post.covariance * p  # overlap inflation, see response_bands
            var = np.outer(np.diag(post.noise_cov)[rows], np.diag(P)[cols]).reshape(k, q, m)
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
        by about the overlap, and the bands (like those of :meth:`markov_parameters`) use
        ``p P`` (an effective sample size of ``n_windows / p``).  They do not include the
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
        f = _check_freqs(freqs_hz, self.model.dt)
        Gs, Ss = [], []
        for ch in self.channels:
            post = ch.scaled_posterior
            p, m, q = post.horizon, post.n_inputs, post.n_outputs
            # in the noise-whitened outputs the realisation fits (theta_w = W theta diag(c))
            w = _output_weights(post)
            wp, c = _weight_scales(w, p, m)
            G, S = theta_response_std(
                _weighted_theta(post.theta, w, p, m, q),
                post.covariance * p * np.outer(c, c),
                post.noise_cov * np.outer(wp, wp),
                p,
                m,
                q,
                f,
                self.model.dt,
            )
            G, S = G / w[None, :, None], S / w[None, :, None]
            if self.input_scale is not None and self.output_scale is not None:
                su = self.input_scale[[self.model.inputs.index(n) for n in ch.inputs]]
                unit = self.output_scale[:, None] / su[None, :]
                G, S = G * unit[None], S * unit[None]
            Gs.append(G)
            Ss.append(S)
        return np.concatenate(Gs, axis=2), np.concatenate(Ss, axis=2)

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


class HankelMAP:
    """Open-loop MIMO state-space identification by the Hankel-Toeplitz model and MAP (Cao & Chen 2013).

    Parameters
    ----------
    horizon : int or "auto", default "auto"
        ``p`` of eq. 2-9. "auto" picks it from 8..80 by held-out multi-step prediction error.
    order : int, sequence of int, or "auto", default "auto"
        Model order (per input channel when ``per_channel``; a sequence gives one per input).
        "auto" picks it by held-out simulation error.
    method : {"map", "ls"}, default "map"
        MAP with ``prior`` (eq. 17) or batch least squares (flat prior; singular normal
        equations, e.g. noise-free or strictly band-limited records, get a 1e-10 ridge and an
        :class:`ExcitationWarning`, see ``LS_RIDGE_STRENGTH``).
    per_channel : bool, default False
        Identify one single-input model per input from the records in which only that
        input moves and stack them (eq. 19-22).  Otherwise all records are pooled into one
        direct MIMO fit (all inputs may move at once).
    forgetting : float, default 1.0
        Exponential forgetting factor in (0, 1] (eq. 17 with discounting) for drifting stages.
    prior : None, float or Prior, default None
        None: ``theta_0 = 0`` and ``P_0^-1 = 1e-5 diag(sum x x^T)`` (a large covariance, as
        in the paper); a float (> 0, finite) sets that relative strength; a :class:`Prior`
        is taken in the data's units.

        The strength 1e-5 was chosen on band-limited records (P-558 and random lightly damped
        stages, N = 1e4-2e4, 1 % noise): 1e-8 leaves band-edge directions of the ill-conditioned
        regression free and let a coupling error reach 1.2 %; 1e-5 keeps it at <= 0.5 % without
        changing the diagonal or broadband results.
    realization : {"frequency", "markov"}, default "frequency"
        See the module notes.
    band : (float, float) or None
        Frequency band in Hz for the frequency realisation, within ``0 .. 1 / (2 dt)`` (a band
        reaching above the Nyquist frequency is a DataError, not clipped); None detects the
        excited band from the input spectra.
    n_frequencies : int, default 200
        Frequency points in the band.
    refine : bool, default True
        Output-error refinement of the frequency realisation.
    feedthrough : bool, default False
        Estimate a direct feedthrough ``D`` (the paper's stage has ``D = 0``).
    detrend : bool, default True
        Remove each record's mean from inputs and outputs.
    validation_fraction : float, default 0.25
        Held-out share (the end of every record) for "auto" selections.
    max_order : int, default 20
        Largest order tried by ``order="auto"``.

    Notes
    -----
    The fit works on channels scaled to unit RMS (each input and output divided by its RMS
    over the records, after the mean removal) and scales the model back: the identified
    poles and frequency response do not depend on the units of the data.  The regression
    (eq. 9-18) does not depend on how the outputs are weighted, but the realisation and the
    selection do: the in-band response of eq. 9 is the least-squares solution of ``p q``
    equations for ``q`` outputs, the SVD of Lemma 1 / its frequency counterpart and the
    output-error refinement trade the outputs against each other, and a held-out score
    averaged over the outputs is dominated by the noisiest.  Unit RMS gives a small coupling
    output that is mostly sensor noise (P-558, chirp on Rx: z 8 nm RMS with 1 nm noise, ry
    0.12 urad with 0.1 urad, against rx 47 urad with 0.1 urad) as much weight as the driven
    output.  The fit therefore weighs noise-whitened outputs, as CVA / maximum-likelihood
    weighting does: each output is multiplied by the inverse of its noise standard
    deviation, estimated from the eq. 9 residual (``noise_cov``, averaged over the ``p`` block
    rows of ``y_p``), in the response of eq. 9, the realisation (the weight is undone on
    ``C`` and ``D``) and the held-out scores (``sum_i w_i^2 err_i / sum_i w_i^2 energy_i``;
    for the horizon, the noise of the largest candidate's training residual).  This stays
    unit-invariant (a change of units scales an output's signal and noise alike) and equals
    the unit-RMS weighting when every output has the same relative noise (the benchmark's
    1 %: weights 0.99-1).  The noise std is floored at ``NOISE_STD_FLOOR`` (1e-3) times the
    output's RMS in the sub-model's records, so noise-free data weigh the outputs as unit
    RMS does.  Measured on the P-558 study (``studies/hankel_map``, 2026-12-01): the
    order-4 Rx sub-model's diagonal error fell from 0.9-1.4 % (unit RMS, automatic horizon
    p = 8) to <= 0.02 % (p = 40), the per-channel sweeps at orders 4-12 from up to 29.8 to
    <= 2.0 um / urad.  A coupling output is fitted only as well as its noise allows: with an
    order too low for the channel (order 3 on Z) the noisy coupling outputs may be left
    unfitted in favour of the driven one.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Experiment
    >>> from stageid.models import StateSpaceModel
    >>> g = StateSpaceModel([[0.9, 0.2], [-0.2, 0.9]], [[1.0], [0.0]], [[0.1, 0.0]], [[0.0]], dt=0.01)
    >>> u = np.random.default_rng(0).standard_normal((3000, 1))
    >>> res = HankelMAP(horizon=10, order=2).fit(Experiment(u, g.simulate(u), 0.01))
    >>> bool(np.allclose(np.sort(np.abs(res.model.poles())), np.abs(g.poles()), atol=1e-3))
    True
    """

    def __init__(
        self,
        horizon: int | str = "auto",
        order: int | Sequence[int] | str = "auto",
        method: str = "map",
        per_channel: bool = False,
        forgetting: float = 1.0,
        prior: None | float | Prior = None,
        realization: str = "frequency",
        band: tuple[float, float] | None = None,
        n_frequencies: int = 200,
        refine: bool = True,
        feedthrough: bool = False,
        detrend: bool = True,
        validation_fraction: float = 0.25,
        max_order: int = 20,
    ) -> None:
        self.horizon = horizon
        self.order = order
        self.method = method
        self.per_channel = per_channel
        self.forgetting = forgetting
        self.prior = prior
        self.realization = realization
        self.band = band
        self.n_frequencies = n_frequencies
        self.refine = refine
        self.feedthrough = feedthrough
        self.detrend = detrend
        self.validation_fraction = validation_fraction
        self.max_order = max_order

    def __repr__(self) -> str:
        keys = ("horizon", "order", "method", "per_channel", "forgetting", "realization")
        return "HankelMAP(" + ", ".join(f"{k}={getattr(self, k)!r}" for k in keys) + ")"

    def get_params(self) -> dict[str, Any]:
        """The hyper-parameters as a dict."""
        keys = (
            "horizon",
            "order",
            "method",
            "per_channel",
            "forgetting",
            "prior",
            "realization",
            "band",
            "n_frequencies",
            "refine",
            "feedthrough",
            "detrend",
            "validation_fraction",
            "max_order",
        )
        return {k: getattr(self, k) for k in keys}

    # ------------------------------------------------------------------ checks
    def _check(self) -> None:
        h = self.horizon
        if not (h == "auto" or (isinstance(h, (int, np.integer)) and not isinstance(h, bool) and h >= 1)):
            raise DataError(f"`horizon` of HankelMAP must be a positive integer or 'auto'; got {h!r}.")
        o = self.order
        if not (
            o == "auto" or _is_pos_int(o) or (isinstance(o, (list, tuple)) and o and all(_is_pos_int(v) for v in o))
        ):
            raise DataError(f"`order` of HankelMAP must be a positive integer, a list of them, or 'auto'; got {o!r}.")
        if self.method not in _METHODS:
            raise DataError(f"`method` of HankelMAP must be one of {', '.join(_METHODS)}; got {self.method!r}.")
        if self.realization not in _REALIZATIONS:
            raise DataError(
                f"`realization` of HankelMAP must be one of {', '.join(_REALIZATIONS)}; got {self.realization!r}."
            )
        try:
            lam = float(self.forgetting)
        except (TypeError, ValueError):
            lam = float("nan")
        if not 0.0 < lam <= 1.0:
            raise DataError(f"`forgetting` of HankelMAP must be in (0, 1]; got {self.forgetting!r}.")
        if not (_is_real(self.validation_fraction) and 0.0 < float(self.validation_fraction) < 0.9):
            raise DataError(f"`validation_fraction` must be a number in (0, 0.9); got {self.validation_fraction!r}.")
        if not _is_pos_int(self.max_order):
            raise DataError(f"`max_order` of HankelMAP must be a positive integer; got {self.max_order!r}.")
        if self.band is not None:
            b = self.band
            if not (
                isinstance(b, (tuple, list, np.ndarray))
                and len(b) == 2
                and all(_is_real(v) for v in b)
                and 0 <= float(b[0]) < float(b[1]) < np.inf
            ):
                raise DataError(f"`band` must be (f_low, f_high) in Hz with 0 <= f_low < f_high finite; got {b!r}.")
        if not (isinstance(self.n_frequencies, (int, np.integer)) and self.n_frequencies >= 8):
            raise DataError(f"`n_frequencies` must be an integer >= 8; got {self.n_frequencies!r}.")
        if self.prior is not None and not isinstance(self.prior, Prior):
            if not _is_real(self.prior):
                raise DataError(f"`prior` must be None, a float strength or a Prior; got {type(self.prior).__name__}.")
            if not (np.isfinite(float(self.prior)) and float(self.prior) > 0):
                raise DataError(f"prior strength must be > 0 and finite; got {self.prior!r}.")

    # --------------------------------------------------------------------- fit
    @single_blas_thread
    def fit(self, data: Experiment | Sequence[Experiment]) -> HankelMAPResult:
        """Identify a model from one or several records.

        Parameters
        ----------
        data : Experiment or sequence of Experiment
            Records sharing channels and sample time.

        Returns
        -------
        HankelMAPResult

        Raises
        ------
        DataError
            Bad hyper-parameters, a ``band`` above the Nyquist frequency, records too short
            for the horizon, no input moving in any record, or (``per_channel``) no record in
            which only a given input moves.
        IdentificationError
            When no model can be realised.
        """
        self._check()
        return self._fit(_as_records(data, "HankelMAP.fit"), previous=None)

    def _fit(self, exps: tuple[Experiment, ...], previous: HankelMAPResult | None) -> HankelMAPResult:
        first = exps[0]
        dt = first.dt
        notes: list[str] = []
        if previous is not None:
            if previous.model.inputs != first.input_names or previous.model.outputs != first.output_names:
                raise DataError(
                    f"new data must have inputs {list(previous.model.inputs)} and outputs "
                    f"{list(previous.model.outputs)}; got {list(first.input_names)} and {list(first.output_names)}."
                )
            if not np.isclose(dt, previous.model.dt, rtol=1e-9, atol=0.0):
                raise DataError(
                    f"new data must have the sample time of the fitted model, {previous.model.dt:g} s; got {dt:g} s."
                )
        nyq = 0.5 / dt
        if self.band is not None and float(self.band[1]) > nyq * (1 + 1e-12):
            raise DataError(
                f"`band` must lie within 0-{nyq:g} Hz (Nyquist at dt = {dt:g} s); "
                f"got {float(self.band[0]):g}-{float(self.band[1]):g} Hz."
            )
        empty = [e.n_samples for e in exps if e.n_samples < 2]
        if empty:
            raise DataError(f"every record needs at least 2 samples; got {min(empty)}.")
        groups: list[tuple[list[int], list[tuple[np.ndarray, np.ndarray]]]] = []
        records = [self._prepare(e) for e in exps]
        m_all = first.n_inputs
        # column by column: numpy reduces a (n, 3) array along axis 0 some 20x slower
        still = [all(np.ptp(r[0][:, j]) == 0 for r in records) for j in range(m_all)]
        if all(still):
            raise DataError(
                f"at least one input must move in some record; got every input ({', '.join(first.input_names)}) "
                f"constant in all {len(records)} record(s)."
            )
        for j in range(m_all):
            if still[j]:
                notes.append(
                    f"input '{first.input_names[j]}' does not move in any record; its response cannot be identified."
                )
        # every channel to unit RMS (the first fit's scales are kept for updates): thresholds,
        # floors, the default prior and the flat prior's minimum-norm solution are then
        # independent of the units of the inputs and of the outputs
        if previous is not None and previous.input_scale is not None and previous.output_scale is not None:
            su, sy = previous.input_scale, previous.output_scale
        else:
            su, sy = _channel_scales(records)
        for u, y in records:  # in place: `_prepare` made the copies
            u /= su
            y /= sy
        if self.per_channel:
            for j in range(m_all):
                sel = []
                for (u, y), e in zip(records, exps):
                    moving = [np.ptp(u[:, i]) > 0 for i in range(m_all)]
                    if moving[j] and sum(moving) == 1:
                        sel.append((u[:, [j]], y))
                if not sel:
                    raise DataError(
                        f"per-channel identification needs, for input '{first.input_names[j]}', a record in "
                        f"which only that input moves; got none."
                    )
                groups.append(([j], sel))
        else:
            groups.append((list(range(m_all)), records))
        orders = self._orders(len(groups))
        fits = []
        for gi, (cols, recs) in enumerate(groups):
            prev_ch = previous.channels[gi] if previous is not None else None
            fits.append(self._fit_group(recs, cols, orders[gi], dt, first, prev_ch, notes, su[cols], sy))
        model = _stack([f.model for f in fits], dt, first.input_names, first.output_names)
        stable = model.is_stable()
        if not stable:
            notes.append("the identified model is unstable (a pole on or outside the unit circle).")
            warnings.warn(
                f"HankelMAP: the identified model is unstable (max |pole| = {np.max(np.abs(model.poles())):.4f}).",
                StabilityWarning,
                stacklevel=3,
            )
        diag = {
            "horizon": [f.horizon for f in fits] if len(fits) > 1 else fits[0].horizon,
            "order": [f.order for f in fits] if len(fits) > 1 else fits[0].order,
            "band_hz": [f.band for f in fits] if len(fits) > 1 else fits[0].band,
            "n_windows": float(sum(f.scaled_posterior.n_windows for f in fits)),
            "stable": bool(stable),
            "warnings": notes,
        }
        return HankelMAPResult(model, tuple(fits), self, diag, su.copy(), sy.copy())

    # ----------------------------------------------------------------- helpers
    def _prepare(self, e: Experiment) -> tuple[np.ndarray, np.ndarray]:
        """Fresh float copies of a record's channels (the fit scales them in place)."""
        u = np.asarray(e.u, dtype=float)
        y = np.asarray(e.y, dtype=float)
        if self.detrend:  # one new array each: the subtraction is the copy
            return u - _column_means(u), y - _column_means(y)
        return u.copy(), y.copy()

    def _orders(self, n_groups: int) -> list[int | str]:
        o = self.order
        if isinstance(o, (list, tuple)):
            if len(o) != n_groups:
                raise DataError(
                    f"`order` must give one order per {'input' if self.per_channel else 'model'} "
                    f"({n_groups}); got {len(o)}."
                )
            return [int(v) for v in o]
        return [o if o == "auto" else int(o)] * n_groups

    def _prior_for(self, stats: WindowStatistics, su: np.ndarray, sy: np.ndarray) -> Prior | None:
        """The prior in the scaled coordinates of the fit (channels divided by ``su``, ``sy``).

        ``method="ls"`` is the flat prior, except on singular normal equations (see
        :data:`LS_SINGULAR_PIVOT`), which get the ridge ``LS_RIDGE_STRENGTH``.
        """
        if self.method == "ls":
            return default_prior(stats, LS_RIDGE_STRENGTH) if _singular_pivot(stats) is not None else None
        if isinstance(self.prior, Prior):
            # a given prior is in the data's units: theta_s = theta diag(xs) / ys, P0s^-1 = P0^-1 / (xs xs^T)
            xs, ys = _regressor_scales(stats.horizon, su, sy)
            prec = np.asarray(self.prior.precision, dtype=float)
            if prec.shape == xs.shape:
                prec = prec / xs**2
            elif prec.shape == (xs.size, xs.size):
                prec = prec / np.outer(xs, xs)  # other shapes: map_estimate reports them
            t0 = None if self.prior.theta0 is None else np.asarray(self.prior.theta0, dtype=float)
            if t0 is not None and t0.shape == (ys.size, xs.size):
                t0 = t0 * xs[None, :] / ys[:, None]
            return Prior(t0, prec)
        strength = DEFAULT_PRIOR_STRENGTH if self.prior is None else float(self.prior)
        return default_prior(stats, strength)

    def _theta(self, stats: WindowStatistics, su: np.ndarray, sy: np.ndarray) -> np.ndarray:
        """The MAP (or least-squares) estimate alone, without the posterior's residual and
        covariance (candidate horizons)."""
        XX, YX, _ = stats.blocks()
        return map_estimate(XX, YX, self._prior_for(stats, su, sy))[0]

    def _fit_group(
        self,
        recs,
        cols,
        order,
        dt,
        first: Experiment,
        prev: ChannelFit | None,
        notes: list[str],
        su: np.ndarray,
        sy: np.ndarray,
    ) -> ChannelFit:
        """One (sub-)model from records already scaled to unit RMS (``su``, ``sy`` undo it)."""
        m = len(cols)
        q = first.n_outputs
        in_names = tuple(first.input_names[c] for c in cols)
        lam = float(self.forgetting)
        horizon_table = None
        order_table = None
        n_total = sum(u.shape[0] for u, _ in recs)
        if prev is not None:
            horizon = prev.horizon
        train = val = {}
        if prev is None:
            auto_h, auto_o = self.horizon == "auto", order == "auto"
            cands = default_horizons(m, q, n_total) if auto_h else [int(self.horizon)]
            if auto_h:
                cands = [p for p in cands if all(u.shape[0] / 32 > 2 * p + 1 for u, _ in recs)] or cands[:1]
            if auto_h or auto_o:
                train, val = self._split_statistics(recs, cands)
            if auto_h:
                horizon, horizon_table = self._select_horizon(train, val, cands, su, sy)
            else:
                horizon = int(self.horizon)
        short = [u.shape[0] for u, _ in recs if u.shape[0] <= 2 * horizon]
        if short:
            raise DataError(f"horizon {horizon} needs records of more than {2 * horizon} samples; got {min(short)}.")
        stats = None
        full_count = sum(u.shape[0] - 2 * horizon + 1 for u, _ in recs)
        if (
            prev is None
            and lam == 1.0
            and horizon in train
            and horizon in val
            and (train[horizon].count + val[horizon].count) >= 0.99 * full_count
        ):
            # the held-out split already holds all but < 1 % of the windows (those straddling
            # segment boundaries): reuse it instead of a second pass over long records
            power = None
            for u, _ in recs:
                pw, fq = _input_periodogram(u)
                power = pw if power is None else power + pw
            s_all = train[horizon] + val[horizon]
            stats = WindowStatistics(s_all.W, s_all.n_windows, horizon, m, q, power, fq, s_all.count)
        else:
            for u, y in recs:
                s = record_statistics(u, y, [horizon], lam)[horizon]
                stats = s if stats is None else stats.scaled(lam**s.count) + s
        assert stats is not None
        if prev is not None:
            post = prev.scaled_posterior.updated(stats, lam)
            band = prev.band
        else:
            post = batch_posterior(stats, self._prior_for(stats, su, sy))
            pivot = _singular_pivot(stats) if self.method == "ls" else None
            if pivot is not None:
                msg = (
                    f"the least-squares normal equations of horizon {horizon} are singular (smallest relative pivot "
                    f"{pivot:.1e}, expected >= {LS_SINGULAR_PIVOT:g}; noise-free or not persistently exciting data): "
                    f"solved with a {LS_RIDGE_STRENGTH:g} ridge; method='map' is the regularised estimate."
                )
                notes.append(msg)
                warnings.warn(msg, ExcitationWarning, stacklevel=4)
            band = self._band(stats, dt, notes, in_names)
        freqs = np.linspace(band[0], band[1], self.n_frequencies)
        if prev is not None:
            order = prev.order
        if order == "auto":
            if horizon not in train:
                raise DataError(
                    "the records are too short to hold out data for choosing the order; give `order` explicitly."
                )
            post_train = batch_posterior(train[horizon], self._prior_for(train[horizon], su, sy))
            order, order_table = self._select_order(post_train, freqs, dt, recs)
        for table in (horizon_table, order_table):
            if table is not None:
                err = table.errors[table.values.index(table.chosen)]
                if err >= 1.0:
                    msg = (
                        f"the chosen {table.kind} {table.chosen} has held-out error {err:.3g} (expected < 1): the model "
                        f"predicts the held-out data worse than zero (inputs {list(in_names)}); the records are too short "
                        f"or too little excited for this model."
                    )
                    notes.append(msg)
                    warnings.warn(msg, ExcitationWarning, stacklevel=4)
        model, cost = self._realize(post, int(order), freqs, dt)
        # back to the data's units: u_s = u / su, y_s = y / sy
        model = StateSpaceModel(
            model.A, model.B / su[None, :], model.C * sy[:, None], model.D * sy[:, None] / su[None, :], dt
        )
        if model.n_states and self._excited_lines(stats, dt, band) * m < int(order) / 2:
            msg = (
                f"the records excite too few frequencies for order {order} (inputs {list(in_names)}); "
                f"the data are not persistently exciting."
            )
            notes.append(msg)
            warnings.warn(msg, ExcitationWarning, stacklevel=4)
        model = model.with_names(in_names, first.output_names)
        return ChannelFit(
            in_names,
            first.output_names,
            post,
            horizon,
            int(order),
            band,
            model,
            horizon_table,
            order_table,
            cost,
            scales=(su.copy(), sy.copy()),
        )

    min_segment = 20

    def _segments(self, n: int) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
        """Training and held-out sample ranges of one record (interleaved, see ``selection``)."""
        k = int(max(4, min(32, n // max(8 * self.min_segment, 1))))
        n_val = max(1, int(round(self.validation_fraction * k)))
        val_idx = sorted({int(np.floor((i + 0.5) * k / n_val)) % k for i in range(n_val)})
        edges = [int(round(i * n / k)) for i in range(k + 1)]
        train, val = [], []
        for i in range(k):
            rng = (edges[i], edges[i + 1])
            target = val if i in val_idx else train
            if target and target[-1][1] == rng[0]:
                target[-1] = (target[-1][0], rng[1])
            else:
                target.append(rng)
        return train, val

    def _split_statistics(self, recs, cands: list[int]):
        lam = float(self.forgetting)
        train: dict[int, WindowStatistics] = {}
        val: dict[int, WindowStatistics] = {}
        # one Gram matrix per segment at its largest usable horizon, summed per horizon; smaller
        # horizons use the leading block (exact statistics over a slightly smaller window set)
        tops: tuple[dict[int, WindowStatistics], dict[int, WindowStatistics]] = ({}, {})
        for u, y in recs:
            tr, va = self._segments(u.shape[0])
            for ranges, acc, weight in ((tr, tops[0], lam), (va, tops[1], 1.0)):
                groups: dict[int, list[tuple[int, int]]] = {}
                for a, b in ranges:
                    usable = [p for p in cands if 2 * p + 1 <= b - a]
                    if usable:
                        groups.setdefault(usable[-1], []).append((a, b))
                for ph, rngs in groups.items():
                    if weight == 1.0:
                        tops_ = [segments_statistics(u, y, rngs, ph)]
                    else:  # forgetting: each range weighted on its own, as a record of its own
                        tops_ = [
                            record_statistics(u[a:b], y[a:b], [ph], weight, with_spectrum=False)[ph] for a, b in rngs
                        ]
                    for top in tops_:
                        acc[ph] = top if ph not in acc else acc[ph] + top
        for acc, target in zip(tops, (train, val)):
            for p in cands:
                for ph, top in acc.items():
                    if ph >= p:
                        sp = _leading(top, p)
                        target[p] = sp if p not in target else target[p] + sp
        return train, val

    def _select_horizon(
        self, train, val, cands: list[int], su: np.ndarray, sy: np.ndarray
    ) -> tuple[int, SelectionTable]:
        usable = [p for p in cands if p in train and p in val]
        thetas = {p: self._theta(train[p], su, sy) for p in usable}
        # one set of output weights for every candidate: the noise of the largest horizon's
        # training residual (see the Notes of HankelMAP)
        weights = _training_weights(thetas[usable[-1]], train[usable[-1]]) if usable else None
        errors = []
        for p in cands:
            if p not in thetas:
                errors.append(float("inf"))
                continue
            errors.append(prediction_error(thetas[p], val[p], weights))
        if not np.isfinite(np.min(errors)):
            raise DataError(
                "the records are too short to hold out data for choosing the horizon; give `horizon` explicitly."
            )
        best = cands[int(np.argmin(errors))]
        return best, SelectionTable("horizon", tuple(cands), tuple(errors), best)

    def _select_order(self, post: Posterior, freqs, dt, recs) -> tuple[int, SelectionTable]:
        cands = list(range(1, self.max_order + 1))
        weights = _output_weights(post)
        errors = []
        for n in cands:
            try:
                mdl, _ = self._realize(post, n, freqs, dt, refine=self.refine, max_iter=8)
            except (IdentificationError, np.linalg.LinAlgError):
                errors.append(float("inf"))
                continue
            errors.append(simulation_error(mdl, recs, [self._segments(u.shape[0])[1] for u, _ in recs], weights))
        if not np.isfinite(np.min(errors)):
            raise IdentificationError("no candidate order gave a stable model; give `order` explicitly.")
        # the smallest order within 0.1 % of the best error (noise makes larger ties unreliable)
        best_err = float(np.min(errors))
        chosen = next(n for n, e in zip(cands, errors) if e <= best_err * 1.001 + 1e-15)
        return chosen, SelectionTable("order", tuple(cands), tuple(errors), chosen)

    def _band(self, stats: WindowStatistics, dt: float, notes: list[str], names) -> tuple[float, float]:
        """The excited band: bins (1/(1024 dt) wide) with >= 1 % of an input's peak bin power."""
        nyq = 0.5 / dt
        if self.band is not None:
            return float(self.band[0]), min(float(self.band[1]), nyq)
        P, f = stats.input_power, stats.freqs
        if P is None:
            return 0.0, nyq
        exc = np.max(P / np.maximum(P.max(axis=0, keepdims=True), 1e-300), axis=1) >= 1e-2
        if not exc.any():
            return 0.0, nyq
        half = 0.5 / (2 * len(f))  # half a bin, in cycles per sample
        lo = max(0.0, float(f[exc].min() - half)) / dt
        hi = min(0.5, float(f[exc].max() + half)) / dt
        if exc.sum() < 3:
            notes.append("the inputs excite a very narrow band; the model is only valid there.")
        return lo, hi

    @staticmethod
    def _excited_lines(stats: WindowStatistics, dt: float, band) -> int:
        P = stats.input_power
        if P is None:
            return 10**6
        Pn = P / np.maximum(P.max(axis=0, keepdims=True), 1e-300)
        return int(np.sum(np.max(Pn, axis=1) >= 1e-2))

    def _realize(
        self, post: Posterior, order: int, freqs: np.ndarray, dt: float, refine: bool | None = None, max_iter: int = 30
    ) -> tuple[StateSpaceModel, float]:
        p, m, q = post.horizon, post.n_inputs, post.n_outputs
        refine = self.refine if refine is None else refine
        # noise-whitened outputs (see the class Notes): y_w = w y, undone on C and D at the end
        w = _output_weights(post)
        theta_w = _weighted_theta(post.theta, w, p, m, q)
        if self.realization == "markov":
            # the Markov parameters of D_p and H0 (eq. 10): Y_0 .. Y_(2p-1); longer sequences
            # only when the order needs them (then H_i = Phi^i H0, eq. 12)
            n2 = int(np.ceil(order / q))
            n1 = max(int(np.ceil(order / m)), 2 * p - 3 - n2)
            Y = markov_from_theta(theta_w, p, m, q, n1 + n2 + 3)
            A, B, C, D, _ = era(Y, order, n1=n1, n2=n2)
            if not self.feedthrough:
                D = np.zeros_like(D)
            return StateSpaceModel(A, B, C / w[:, None], D / w[:, None], dt), float("nan")
        G = theta_frequency_response(theta_w, p, m, q, freqs, dt)
        scale = np.max(np.abs(G), axis=(0, 1))
        scale = np.where(scale > 0, scale, 1.0)
        Gs = G / scale[None, None, :]
        zs = np.exp(2j * np.pi * freqs * dt)
        A, B, C, D, _ = frequency_realization(Gs, freqs, dt, order, feedthrough=self.feedthrough)
        if np.max(np.abs(np.linalg.eigvals(A))) >= 1.0:
            A = _reflect_unstable(A)
            B, D = fit_input_matrices(A, C, Gs, zs, self.feedthrough)
        cost = float("nan")
        if refine:
            # Two starts: the direct realisation, and a balanced truncation of one of twice the
            # order (far closer on white-input records, see realization.balanced_start).  The
            # refinement runs from the one with the lower cost; when the result still misses
            # the response by more than MULTI_START_MISFIT of its energy (the order cannot fit
            # the system: real structures), it also runs from the other start and keeps the
            # better end, since a closer start need not lead to the better local optimum there
            # (flexible structure, order 12: 8.2 from the truncation, 6.5 from the direct start).
            energy = max(float(np.sum(np.abs(Gs) ** 2)), 1e-300)
            starts = [(A, B, C, D)]
            alt = balanced_start(Gs, freqs, dt, order, self.feedthrough)
            if alt is not None:
                starts.append(alt)
                starts.sort(key=lambda abcd: _fit_cost(abcd, Gs, zs))
            best = None
            for k, start in enumerate(starts):
                if k and best[4]["cost"] <= MULTI_START_MISFIT * energy:
                    break
                # a step that lowers the cost by < 0.3 % ends the fit (REFINE_TOL)
                out = refine_frequency_fit(
                    *start, Gs, zs, feedthrough=self.feedthrough, max_iter=max_iter, tol=REFINE_TOL
                )
                if best is None or out[4]["cost"] < best[4]["cost"]:
                    best = out
            assert best is not None
            A, B, C, D, info = best
            cost = info["cost"] / energy
        if not np.all(np.isfinite(A)) or not np.all(np.isfinite(B)):
            raise IdentificationError(f"the realisation of order {order} is not finite.")
        return StateSpaceModel(A, B * scale[None, :], C / w[:, None], D * scale[None, :] / w[:, None], dt), cost


def _output_weights(post: Posterior) -> np.ndarray:
    """Weights of the outputs in the realisation and the order selection: the inverse of each output's noise std.

    The noise variance of output ``i`` is the mean over the ``p`` block rows of ``y_p`` of the
    diagonal of ``post.noise_cov`` (the eq. 9 residual); the std is floored at
    ``NOISE_STD_FLOOR`` times the output's RMS over the posterior's windows (noise-free
    outputs).  The weights are scaled so that the largest is 1.
    """
    p, q = post.horizon, post.n_outputs
    noise_var = np.diag(post.noise_cov).reshape(p, q).mean(axis=0)
    if len(post.data_sums) == 3 and post.n_windows > 0:
        mean_square = np.diag(post.data_sums[2]).reshape(p, q).mean(axis=0) / post.n_windows
    else:  # no data sums: the channels' own scale (unit RMS in the fit's coordinates)
        mean_square = np.ones(q)
    return _noise_weights(noise_var, mean_square)


def _noise_weights(noise_var: np.ndarray, mean_square: np.ndarray) -> np.ndarray:
    """``1 / max(noise std, NOISE_STD_FLOOR * RMS)`` per output, the largest scaled to 1."""
    q = noise_var.size
    noise = np.sqrt(np.clip(noise_var, 0.0, None))
    std = np.maximum(noise, NOISE_STD_FLOOR * np.sqrt(np.clip(mean_square, 0.0, None)))
    ok = np.isfinite(std) & (std > 0)
    if not ok.any():
        return np.ones(q)
    # an output that is zero (and noise-free) in these records: its weight does not matter
    std = np.where(ok, std, np.max(std[ok]))
    w = 1.0 / std
    return w / np.max(w)


def _training_weights(theta: np.ndarray, stats: WindowStatistics) -> np.ndarray:
    """:func:`_noise_weights` from the training residual of ``theta`` on ``stats``."""
    XX, _, YY = stats.blocks()
    p, q = stats.horizon, stats.n_outputs
    dof = max(stats.n_windows - XX.shape[0], 1.0)
    mean_square = np.diag(YY).reshape(p, q).mean(axis=0) / max(stats.n_windows, 1.0)
    return _noise_weights(row_residuals(theta, stats).reshape(p, q).mean(axis=0) / dof, mean_square)


def _weight_scales(w: np.ndarray, p: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Scales of the rows of ``y_p`` (``w`` per block) and of the regressor ``x`` (past outputs over ``w``)."""
    wp = np.tile(w, p)
    return wp, np.concatenate([np.ones(p * m), 1.0 / wp, np.ones(p * m)])


def _weighted_theta(theta: np.ndarray, w: np.ndarray, p: int, m: int, q: int) -> np.ndarray:
    """``theta`` of eq. 9 for the outputs ``w * y``: rows times ``w``, past-output columns over ``w``."""
    rows, cols = _weight_scales(w, p, m)
    return theta * rows[:, None] * cols[None, :]


def _as_records(data: object, where: str) -> tuple[Experiment, ...]:
    """``as_experiments`` with a one-line DataError for anything that is not records."""
    if not isinstance(data, (Experiment, list, tuple)):
        raise DataError(f"{where} needs an Experiment or a sequence of them; got {type(data).__name__}.")
    return as_experiments(data)


def _is_real(v: object) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _check_freqs(freqs_hz: object, dt: float) -> np.ndarray:
    """Frequencies in Hz as a finite 1-D array within ``[0, 1 / (2 dt)]`` (DataError otherwise)."""
    try:
        f = np.asarray(freqs_hz, dtype=float)
    except (TypeError, ValueError):
        raise DataError(
            f"`freqs_hz` must be a 1-D array of frequencies in Hz; got {type(freqs_hz).__name__}."
        ) from None
    if f.ndim != 1 or f.size == 0:
        raise DataError(f"`freqs_hz` must be a non-empty 1-D array of frequencies in Hz; got shape {f.shape}.")
    nyq = 0.5 / dt
    bad = ~np.isfinite(f) | (f < 0) | (f > nyq * (1 + 1e-12))
    if bad.any():
        raise DataError(f"`freqs_hz` must be finite and within 0-{nyq:g} Hz (Nyquist); got {float(f[bad][0])!r}.")
    return f


def _channel_scales(records: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """RMS of every input and output channel over all records (1 for a channel that is zero)."""
    n = sum(u.shape[0] for u, _ in records)
    su = np.sqrt(sum(np.einsum("ij,ij->j", u, u) for u, _ in records) / n)  # no squared copy
    sy = np.sqrt(sum(np.einsum("ij,ij->j", y, y) for _, y in records) / n)
    ok_u = np.isfinite(su) & (su > 0)
    ok_y = np.isfinite(sy) & (sy > 0)
    return np.where(ok_u, su, 1.0), np.where(ok_y, sy, 1.0)


def _column_means(x: np.ndarray) -> np.ndarray:
    """``x.mean(axis=0)`` column by column (a strided pass per column is ~10x faster here than
    numpy's axis-0 reduction of a few-column array)."""
    return np.array([x[:, j].mean() for j in range(x.shape[1])])


def _regressor_scales(p: int, su: np.ndarray, sy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Scales of ``x = [u past; y past; u future]`` and of ``y_p`` (eq. 9 order: time-major)."""
    return np.concatenate([np.tile(su, p), np.tile(sy, p), np.tile(su, p)]), np.tile(sy, p)


def _unscaled_posterior(post: Posterior, su: np.ndarray, sy: np.ndarray) -> Posterior:
    """The posterior of a fit on scaled channels, in the data's units (``theta = ys theta_s / xs``)."""
    xs, ys = _regressor_scales(post.horizon, su, sy)
    XX_ = np.outer(xs, xs)
    YX_ = np.outer(ys, xs)
    YY_ = np.outer(ys, ys)
    sums = tuple(a * f for a, f in zip(post.data_sums, (XX_, YX_, YY_)))
    return Posterior(
        post.information * XX_,
        post.moment * YX_,
        post.theta * (ys[:, None] / xs[None, :]),
        post.noise_cov * YY_,
        post.n_windows,
        post.horizon,
        post.n_inputs,
        post.n_outputs,
        post.residual * YY_,
        sums,
    )


def _singular_pivot(stats: WindowStatistics) -> float | None:
    """The smallest relative Cholesky pivot of ``sum x x^T`` (unit diagonal) when it is below
    ``LS_SINGULAR_PIVOT`` (0.0 when the factorisation fails), else None."""
    XX = stats.blocks()[0]
    dg = np.sqrt(np.clip(np.diag(XX), 0.0, None))
    dg = np.where(dg > 0, dg, 1.0)
    try:
        L = np.linalg.cholesky(XX / np.outer(dg, dg))
    except np.linalg.LinAlgError:
        return 0.0
    pivot = float(np.min(np.diag(L)) ** 2)
    return pivot if pivot < LS_SINGULAR_PIVOT else None


def _leading(stats: WindowStatistics, horizon: int) -> WindowStatistics:
    """Statistics of horizon ``horizon`` from those of a larger one (windows of the larger one)."""
    if horizon == stats.horizon:
        return stats
    k = 2 * horizon * (stats.n_inputs + stats.n_outputs)
    return WindowStatistics(
        stats.W[:k, :k], stats.n_windows, horizon, stats.n_inputs, stats.n_outputs, None, None, stats.count
    )


def _is_pos_int(v: object) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool) and int(v) >= 1


def _reflect_unstable(A: np.ndarray) -> np.ndarray:
    """Mirror eigenvalues outside the unit circle to ``1 / conj(lambda)`` (real similarity kept)."""
    w, V = np.linalg.eig(A)
    bad = np.abs(w) >= 1.0
    w = np.where(bad, 0.999 * w / np.abs(w) ** 2, w)
    A2 = (V @ np.diag(w) @ np.linalg.inv(V)).real
    return A2


def _stack(models: list[StateSpaceModel], dt: float, inputs, outputs) -> StateSpaceModel:
    """Eq. 20-22: ``A = diag(A_i)``, ``B = diag(B_i)``, ``C = [C_1 ... C_m]``, ``D = [D_1 ... D_m]``."""
    if len(models) == 1:
        return models[0].with_names(inputs, outputs)
    import scipy.linalg as sla

    A = sla.block_diag(*[g.A for g in models])
    B = sla.block_diag(*[g.B for g in models])
    C = np.hstack([g.C for g in models])
    D = np.hstack([g.D for g in models])
    return StateSpaceModel(A, B, C, D, dt, tuple(inputs), tuple(outputs))
