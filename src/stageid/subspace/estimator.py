"""``HankelMAP``: configure, fit, get a frozen result (Cao & Chen 2013, the whole method).

:meth:`HankelMAP.fit` follows the paper, one named step per equation:

1. ``hankel_toeplitz_statistics``: the normal-equation statistics of the Hankel-Toeplitz
   regression (eq. 9), from lag correlations; several records (e.g. one per excited input)
   pool their windows (:mod:`.statistics.hankel_toeplitz`);
2. ``map_posterior``: ``theta = [Gamma Phi D_p]`` by MAP (eq. 16-18, prior ``theta_0 = 0`` and
   a weak ``P_0``) or by batch least squares (flat prior, Lim, Phan & Longman), the prior picked
   by ``method`` from ``METHODS`` (:mod:`.map.posterior`);
3. ``realize``: the system matrices, with every output weighted by the inverse of its noise
   standard deviation (:mod:`.realisation.weighting`), by the route picked by ``realization`` from
   ``REALIZATIONS`` (:mod:`.realisation.era`):

   * ``"frequency"`` (default): the response of the identified model over the excited band,
     realised by the frequency-domain counterpart of Lemma 1 and refined by an output-error
     fit on that band (:mod:`.realisation.frequency_domain`, :mod:`.realisation.refinement`).  Band-limited records
     (the paper's 1-100 Hz chirps at Ts = 2 ms) determine ``theta`` only up to directions
     without input energy, and those directions enter the Markov parameters: Lemma 1 on
     them is then off in band, while the in-band response of eq. 9 stays accurate;
   * ``"markov"``: the paper's route, ``H0 = Gamma + Phi D_p`` (eq. 10), ``H_i = Phi^i H0``
     (eq. 12), ``H(0)``, ``H(1)`` (eq. 14) and Lemma 1 (eq. 15, ``era``).  Exact for broadband
     (white) inputs;
4. ``stack_channel_models``: per-input-channel models stacked into the MIMO model
   (eq. 19-22) when ``per_channel=True`` (:mod:`.channels`).

The horizon and the order are chosen by held-out prediction error when ``"auto"``
(:mod:`.selection`), with the outputs weighted by their noise as in the realisation.  Steps
1-3 for one input group are :func:`~.channel_fit.fit_channel`.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from .._errors import DataError, StabilityWarning
from ..base import Band, Boolean, Estimator, InstanceOf, Interval, Options, Satisfies
from ..checks import check_band, is_integer
from ..data.chunked import ChunkedRecord
from ..data.experiment import Experiment
from ..runtime.threads import single_blas_thread
from .channel_fit import fit_channel
from .channels import stack_channel_models
from .chunked_source import chunked_source
from .map.posterior import (
    METHODS,
    Prior,
)
from .realisation.era import REALIZATIONS
from .records import as_records, check_continuation
from .result import ChannelFit, HankelMAPResult
from .sources import RecordArrays

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
        Output-error refinement of the frequency realisation (on the eq. 9 response).
    output_error : bool, default True
        Refine the realised model on the records themselves: Levenberg-Marquardt on the
        simulated output error from rest, the outputs weighted by their noise, from the
        realisation (:mod:`stageid.subspace.realisation.output_error`).  The eq. 9 model's
        horizon truncates the past, and a lightly damped mode that rings longer than the
        horizon is placed where the truncated model puts it; the records place it better.
        Not applied by :meth:`HankelMAPResult.update` or with ``forgetting < 1``, whose model is
        the posterior's, nor on a chunked record (read chunk by chunk, never whole in memory),
        nor where one step would exceed ``OE_MAX_WORK`` operations (records with tens of
        outputs), which the diagnostics' warnings then say.
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
        "output_error": [Boolean()],
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
        output_error: bool = True,
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
        self.output_error = output_error
        self.feedthrough = feedthrough
        self.detrend = detrend
        self.validation_fraction = validation_fraction
        self.max_order = max_order

    def check_together(self) -> None:
        """A list of orders gives one per input, so it needs ``per_channel`` unless it has one entry."""
        if isinstance(self.order, (list, tuple)) and len(self.order) > 1 and not self.per_channel:
            raise self.invalid("order", "one order (a list of several needs per_channel=True)")

    @single_blas_thread
    def fit(self, data: Experiment | Sequence[Experiment] | ChunkedRecord) -> HankelMAPResult:
        """Identify a model from one or several records, or from one record larger than memory.

        Parameters
        ----------
        data : Experiment, sequence of Experiment, or ChunkedRecord
            Records sharing channels and sample time; a :class:`~stageid.data.chunked.ChunkedRecord`
            is read chunk by chunk (:mod:`.chunked_source`; ``fit_chunked`` computes its
            statistics on a Dask cluster).

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
            record, (``per_channel``) no record in which only a given input moves, or a
            chunked record with ``per_channel``, ``forgetting`` or several orders.
        ResourceError
            When the horizon, order and frequency count would need more memory than is available.
        IdentificationError
            When no model can be realised.
        """
        self.validate_params()
        notes: list[str] = []
        if isinstance(data, ChunkedRecord):
            return self.fit_source(*chunked_source(self, data, notes), None, notes)
        return self.fit_source(*self.memory_source(as_records(data, "HankelMAP.fit"), None, notes), None, notes)

    def memory_source(
        self, exps: tuple[Experiment, ...], previous: HankelMAPResult | None, notes: list[str]
    ) -> tuple[RecordArrays, np.ndarray, np.ndarray]:
        """Checked records in memory as a record source, with their unit-RMS scales (an update
        keeps those of ``previous``, whose channels and sample time the records must have)."""
        first = exps[0]
        if previous is not None:
            check_continuation(previous.model, first)
        if self.band is not None:  # the one band rule, now with the records' Nyquist frequency
            check_band(self.band, "band", "HankelMAP", nyquist=0.5 / first.dt)
        scales = None if previous is None else (previous.input_scale, previous.output_scale)
        return RecordArrays.prepare(exps, self.detrend, scales, notes)

    def fit_source(
        self, source: Any, su: np.ndarray, sy: np.ndarray, previous: HankelMAPResult | None, notes: list[str]
    ) -> HankelMAPResult:
        """The method on a record source (:mod:`.sources`) of channels scaled by ``su``, ``sy``: a
        first fit, or an update continuing ``previous`` (what :meth:`HankelMAPResult.update` calls)."""
        groups = source.groups(self.per_channel)  # eq. 19
        orders = self._orders(len(groups))
        fits = []
        for gi, (cols, group) in enumerate(groups):
            prev = previous.channels[gi] if previous is not None else None
            fits.append(fit_channel(self, group, cols, orders[gi], prev, notes, su[cols], sy))
        names = (source.input_names, source.output_names)
        model = stack_channel_models([f.model for f in fits], source.dt, *names)  # eq. 20-22
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

    # ----------------------------------------------------------------- helpers
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
