"""``HankelMAP``: configure, fit, get a frozen result (Cao & Chen 2013, the whole method).

:meth:`HankelMAP.fit` follows the paper, one named step per equation:

1. ``hankel_toeplitz_statistics``: the normal-equation statistics of the Hankel-Toeplitz
   regression (eq. 9), from lag correlations; several records (e.g. one per excited input)
   pool their windows (:mod:`.hankel_toeplitz`);
2. ``map_posterior``: ``theta = [Gamma Phi D_p]`` by MAP (eq. 16-18, prior ``theta_0 = 0`` and
   a weak ``P_0``) or by batch least squares (flat prior, Lim, Phan & Longman), the prior picked
   by ``method`` from ``METHODS`` (:mod:`.map_estimator`);
3. ``realize``: the system matrices, with every output weighted by the inverse of its noise
   standard deviation (:mod:`.weighting`), by the route picked by ``realization`` from
   ``REALIZATIONS`` (:mod:`.realization`):

   * ``"frequency"`` (default): the response of the identified model over the excited band,
     realised by the frequency-domain counterpart of Lemma 1 and refined by an output-error
     fit on that band (:mod:`.frequency_domain`, :mod:`.refinement`).  Band-limited records
     (the paper's 1-100 Hz chirps at Ts = 2 ms) determine ``theta`` only up to directions
     without input energy, and those directions enter the Markov parameters: Lemma 1 on
     them is then off in band, while the in-band response of eq. 9 stays accurate;
   * ``"markov"``: the paper's route, ``H0 = Gamma + Phi D_p`` (eq. 10), ``H_i = Phi^i H0``
     (eq. 12), ``H(0)``, ``H(1)`` (eq. 14) and Lemma 1 (eq. 15, ``era``).  Exact for broadband
     (white) inputs;
4. ``stack_channel_models``: per-input-channel models stacked into the MIMO model
   (eq. 19-22) when ``per_channel=True`` (:mod:`.channels`).

The horizon and the order are chosen by held-out prediction error when ``"auto"``
(:mod:`.selection`), with the outputs weighted by their noise as in the realisation.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from .._errors import DataError, ExcitationWarning, StabilityWarning
from ..base import Band, Boolean, Estimator, InstanceOf, Interval, Options, Satisfies
from ..checks import check_band, is_integer
from ..data.experiment import Experiment
from ..models.statespace import StateSpaceModel
from ..runtime.resources import require_memory
from ..runtime.threads import single_blas_thread
from ..validation.order_choice import poor_order_message
from .channels import channel_groups, stack_channel_models
from .map.posterior import (
    LS_RIDGE_STRENGTH,
    LS_SINGULAR_PIVOT,
    METHODS,
    Prior,
    map_posterior,
    singular_pivot,
)
from .realisation.era import REALIZATIONS, realize
from .realisation.refinement import refinement_bytes
from .records import (
    as_records,
    check_continuation,
    excited_band,
    excited_lines,
    prepared_records,
    still_inputs,
    to_unit_rms,
)
from .result import ChannelFit, HankelMAPResult
from .selection import (
    SelectionTable,
    horizon_candidates,
    pooled_split,
    select_horizon,
    select_order,
    split_statistics,
)
from .statistics.hankel_toeplitz import hankel_toeplitz_statistics, statistics_bytes
from .statistics.theta_response import response_bytes
from .statistics.window_covariance import WindowLags, window_lags

__all__ = ["HankelMAP", "HankelMAPResult", "ChannelFit"]


def _is_order_list(value: object) -> bool:
    return isinstance(value, (list, tuple)) and len(value) > 0 and all(is_integer(v) and v >= 1 for v in value)


class HankelMAP(Estimator):
    """Open-loop MIMO state-space identification by the Hankel-Toeplitz model and MAP (Cao & Chen 2013).

    Parameters
    ----------
    horizon : int or "auto", default "auto"
        ``p`` of eq. 2-9. "auto" picks it from 8..80 by held-out prediction error of the first
        block rows of eq. 9 (the next 8 samples), every candidate predicting the same samples
        from the same point (``selection.select_horizon``).
    order : int, sequence of int, or "auto", default "auto"
        Model order (per input channel when ``per_channel``; a sequence gives one per input).
        "auto" picks it by held-out simulation error.
    method : {"map", "ls"}, default "map"
        MAP with ``prior`` (eq. 17) or batch least squares (flat prior; singular normal
        equations, e.g. noise-free or strictly band-limited records, get a 1e-10 ridge and an
        :class:`ExcitationWarning`, see ``map_estimator.LS_RIDGE_STRENGTH``).
    per_channel : bool, default False
        Identify one single-input model per input from the records in which only that
        input moves and stack them (eq. 19-22).  Otherwise all records are pooled into one
        direct MIMO fit (all inputs may move at once).
    forgetting : float, default 1.0
        Exponential forgetting factor in (0, 1] (eq. 17 with discounting) for drifting stages.
    prior : None, float or Prior, default None
        None: ``theta_0 = 0`` and ``P_0^-1 = 1e-5 diag(sum x x^T)`` (a large covariance, as
        in the paper); a float (> 0, finite) sets that relative strength; a :class:`Prior`
        is taken in the data's units.  Not used by ``method="ls"``.  (How 1e-5 was chosen:
        ``studies/hankel_map/RESULTS.md``.)
    realization : {"frequency", "markov"}, default "frequency"
        The route from ``theta`` to the system matrices (see the module notes).
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
    poles and frequency response do not depend on the units of the data.  The realisation and
    the held-out scores weigh noise-whitened outputs (:mod:`stageid.subspace.realisation.weighting`): each
    output multiplied by the inverse of its noise standard deviation, estimated from the
    eq. 9 residual, the weight undone on ``C`` and ``D``; for the horizon, the noise of the
    largest candidate's training residual on the scored block rows.  A small coupling output that is mostly sensor
    noise then does not steer the realisation of the driven output.  A coupling output is
    fitted only as well as its noise allows: with an order too low for the channel the noisy
    coupling outputs may be left unfitted in favour of the driven one.  What the weighting
    changed on the P-558 study is in ``studies/hankel_map/RESULTS.md``.

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

    parameter_constraints = {
        "horizon": [Interval(int, 1, None), Options("auto")],
        "order": [Interval(int, 1, None), Satisfies(_is_order_list, "a list of integers >= 1"), Options("auto")],
        "method": [Options(*METHODS)],
        "per_channel": [Boolean()],
        "forgetting": [Interval(float, 0.0, 1.0, closed="right")],
        "prior": [None, Interval(float, 0.0, None, closed="neither"), InstanceOf(Prior)],
        "realization": [Options(*REALIZATIONS)],
        "band": [None, Band()],
        "n_frequencies": [Interval(int, 8, None)],
        "refine": [Boolean()],
        "feedthrough": [Boolean()],
        "detrend": [Boolean()],
        "validation_fraction": [Interval(float, 0.0, 0.9, closed="neither")],
        "max_order": [Interval(int, 1, None)],
    }

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

    def check_together(self) -> None:
        """A list of orders gives one per input, so it needs ``per_channel`` unless it has one entry."""
        if isinstance(self.order, (list, tuple)) and len(self.order) > 1 and not self.per_channel:
            raise self.invalid("order", "one order (a list of several needs per_channel=True)")

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
        ParameterError
            Bad hyper-parameters.
        DataError
            A ``band`` above the Nyquist frequency, a list of orders whose length is not the
            number of inputs, records too short for the horizon, no input moving in any
            record, or (``per_channel``) no record in which only a given input moves.
        ResourceError
            When the horizon, order and frequency count would need more memory than is available.
        IdentificationError
            When no model can be realised.
        """
        self.validate_params()
        return self.fit_records(as_records(data, "HankelMAP.fit"), previous=None)

    def fit_records(self, exps: tuple[Experiment, ...], previous: HankelMAPResult | None) -> HankelMAPResult:
        """The method on checked records: a first fit, or an update continuing ``previous``
        (what :meth:`HankelMAPResult.update` calls)."""
        first, notes = exps[0], []
        dt = first.dt
        if previous is not None:
            check_continuation(previous.model, first)
        if self.band is not None:  # the one band rule, now with the records' Nyquist frequency
            check_band(self.band, "band", "HankelMAP", nyquist=0.5 / dt)
        records = prepared_records(exps, self.detrend)
        still_inputs(records, first.input_names, notes)
        # every channel to unit RMS (an update keeps the first fit's scales), see `records`
        su, sy = to_unit_rms(records, None if previous is None else (previous.input_scale, previous.output_scale))
        groups = channel_groups(records, first.input_names, self.per_channel)  # eq. 19
        orders = self._orders(len(groups))
        fits = []
        for gi, (cols, recs) in enumerate(groups):
            prev = previous.channels[gi] if previous is not None else None
            fits.append(self._fit_channel(recs, cols, orders[gi], first, prev, notes, su[cols], sy))
        model = stack_channel_models([f.model for f in fits], dt, first.input_names, first.output_names)  # eq. 20-22
        stable = model.is_stable()
        if not stable:
            notes.append("the identified model is unstable (a pole on or outside the unit circle).")
            warnings.warn(
                f"HankelMAP: the identified model is unstable (max |pole| = {np.max(np.abs(model.poles())):.4f}).",
                StabilityWarning,
                stacklevel=4,  # the caller of fit / update (past the BLAS-thread wrapper)
            )
        return HankelMAPResult(
            model, tuple(fits), self.clone(), _diagnostics(fits, stable, notes), su.copy(), sy.copy()
        )

    def _fit_channel(
        self,
        recs: list[tuple[np.ndarray, np.ndarray]],
        cols: list[int],
        order: int | str,
        first: Experiment,
        prev: ChannelFit | None,
        notes: list[str],
        su: np.ndarray,
        sy: np.ndarray,
    ) -> ChannelFit:
        """One (sub-)model from records scaled to unit RMS (``su``, ``sy`` undo it): eq. 9 -> 16-18 -> 10-15."""
        m, q, dt, lam = len(cols), first.n_outputs, first.dt, float(self.forgetting)
        in_names = tuple(first.input_names[c] for c in cols)
        prior_of = METHODS[self.method]
        horizon, order = (prev.horizon, prev.order) if prev is not None else (self.horizon, order)
        self._require_memory(recs, m, q, horizon, order)
        # section 3.2: the horizon, given or chosen by held-out prediction error
        train, val = {}, {}
        horizon_table = order_table = None
        cands = horizon_candidates(m, q, [u.shape[0] for u, _ in recs]) if horizon == "auto" else [horizon]
        # one lag pass over the whole records serves their statistics, the kept WindowLags and
        # (less the held-out segments') the training segments' statistics
        pooled = prev is None and lam == 1.0  # a first fit without forgetting: whole-record statistics
        whole = window_lags(recs, max(cands)) if pooled else None
        if horizon == "auto" or order == "auto":
            train, val = split_statistics(recs, cands, lam, self.validation_fraction, whole)
        if horizon == "auto":
            horizon, horizon_table = select_horizon(train, val, cands, lambda s: prior_of(s, self.prior, su, sy))
        short = [u.shape[0] for u, _ in recs if u.shape[0] <= 2 * horizon]
        if short:
            raise DataError(f"horizon {horizon} needs records of more than {2 * horizon} samples; got {min(short)}.")
        # eq. 9 (without forgetting, from the whole records' lag correlations taken above)
        stats = pooled_split(train, val, horizon, recs, self.validation_fraction, whole) if pooled else None
        if stats is None:
            stats = hankel_toeplitz_statistics(recs, horizon, lam)
        # eq. 16-18 (an update continues the previous posterior, which holds the prior)
        if prev is None:
            post = map_posterior(stats, prior_of(stats, self.prior, su, sy))
            if self.method == "ls":
                self._warn_singular(stats, horizon, notes)
        else:
            post = map_posterior(stats, None, prev.scaled_posterior, lam)
        band = prev.band if prev is not None else excited_band(stats, dt, self.band, notes)
        freqs = np.linspace(band[0], band[1], self.n_frequencies)
        if order == "auto":  # section 3.2: the order by held-out simulation error
            if horizon not in train:
                raise DataError(
                    "the records are too short to hold out data for choosing the order; give `order` explicitly."
                )
            post_train = map_posterior(train[horizon], prior_of(train[horizon], self.prior, su, sy))
            order, order_table = select_order(
                post_train, self.max_order, freqs, dt, recs, self.validation_fraction, **self._realize_settings()
            )
        _warn_held_out(horizon_table, order_table, in_names, notes)
        # eq. 10-15 or the frequency route; back to the data's units (u_s = u / su, y_s = y / sy)
        model, cost = realize(post, int(order), freqs, dt, **self._realize_settings())
        model = StateSpaceModel(
            model.A, model.B / su[None, :], model.C * sy[:, None], model.D * sy[:, None] / su[None, :], dt
        )
        if model.n_states and excited_lines(stats) * m < int(order) / 2:
            msg = (
                f"the records excite too few frequencies for order {order} (inputs {list(in_names)}); "
                f"the data are not persistently exciting."
            )
            _excitation_warning(msg, notes, stacklevel=6)
        return ChannelFit(
            in_names,
            first.output_names,
            post,
            horizon,
            int(order),
            band,
            model.with_names(in_names, first.output_names),
            horizon_table,
            order_table,
            cost,
            scales=(su.copy(), sy.copy()),
            window_lags=_kept_lags(whole, recs, horizon) if pooled else None,
        )

    # ----------------------------------------------------------------- helpers
    def _realize_settings(self) -> dict:
        return {"realization": self.realization, "feedthrough": self.feedthrough, "refine": self.refine}

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

    def _require_memory(self, recs, m: int, q: int, horizon: int | str, order: int | str) -> None:
        """Refuse (ResourceError) a horizon, order and frequency count that would not fit in memory."""
        lengths = [u.shape[0] for u, _ in recs]
        p = max(horizon_candidates(m, q, lengths)) if horizon == "auto" else int(horizon)
        n = self.max_order if order == "auto" else int(order)
        nz = int(self.n_frequencies)
        need = statistics_bytes(p, m, q) + response_bytes(p, m, q, nz)
        if self.realization == "frequency" and self.refine:
            need += refinement_bytes(n, m, q, nz)
        require_memory(
            need, f"HankelMAP with horizon {p}, order {n} and {nz} frequencies on {m} inputs and {q} outputs"
        )

    def _warn_singular(self, stats, horizon: int, notes: list[str]) -> None:
        pivot = singular_pivot(stats)
        if pivot is not None:
            msg = (
                f"the least-squares normal equations of horizon {horizon} are singular (smallest relative pivot "
                f"{pivot:.1e}, expected >= {LS_SINGULAR_PIVOT:g}; noise-free or not persistently exciting data): "
                f"solved with a {LS_RIDGE_STRENGTH:g} ridge; method='map' is the regularised estimate."
            )
            _excitation_warning(msg, notes, stacklevel=7)


def _kept_lags(whole: WindowLags | None, recs, horizon: int) -> WindowLags | None:
    """The fit's :class:`WindowLags` at ``horizon``, from those of the largest candidate when
    the records held them."""
    return whole.at(horizon) if whole is not None and whole.horizon >= horizon else window_lags(recs, horizon)


def _excitation_warning(msg: str, notes: list[str], stacklevel: int) -> None:
    """Keep ``msg`` in the result's notes and warn with it (``stacklevel`` counted from here)."""
    notes.append(msg)
    warnings.warn(msg, ExcitationWarning, stacklevel=stacklevel)


def _warn_held_out(horizon_table: SelectionTable | None, order_table: SelectionTable | None, in_names, notes) -> None:
    """Warn when a chosen horizon or order predicts the held-out data worse than zero."""
    for table in (horizon_table, order_table):
        if table is not None:
            err = table.errors[table.values.index(table.chosen)]
            if err < 1.0:
                continue
            advice = (
                f"it predicts the held-out data worse than zero (inputs {list(in_names)}): the records are too short "
                f"or too little excited for this model."
            )
            if table.kind == "order":  # one shape with every estimator's order warning
                measure = f"has held-out error {err:.3g}"
                msg = poor_order_message("HankelMAP", table.chosen, table.values, measure, "< 1", advice)
            else:
                msg = f"the chosen {table.kind} {table.chosen} has held-out error {err:.3g} (expected < 1); {advice}"
            _excitation_warning(msg, notes, stacklevel=7)


def _diagnostics(fits: list[ChannelFit], stable: bool, notes: list[str]) -> dict:
    one = len(fits) == 1
    return {
        "horizon": fits[0].horizon if one else [f.horizon for f in fits],
        "order": fits[0].order if one else [f.order for f in fits],
        "band_hz": fits[0].band if one else [f.band for f in fits],
        "n_windows": float(sum(f.scaled_posterior.n_windows for f in fits)),
        "stable": bool(stable),
        "warnings": notes,
    }
