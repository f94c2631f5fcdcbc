"""Identification of a state-space model from frequency-response data.

:class:`FRDIdentification` follows the frequency-domain subspace route of McKelvey, Akcay &
Ljung (IEEE TAC 41, 1996), reused from :mod:`stageid.subspace`, then a weighted output-error
refinement on the complex response:

1. the band ``(f_low, f_high)`` of the FRF, per-frequency weights (``1/std^2``, or
   ``gamma^2 / (1 - gamma^2)`` from the coherence, or none);
2. an input delay of ``d`` samples removed from the data (``G z^d``), ``d`` given or chosen by
   the held-out error of a realisation (:func:`select_delay`);
3. continuous time: the bilinear map ``z = (1 + s T/2) / (1 - s T/2)`` sends ``j omega`` to
   ``exp(j 2 atan(omega T / 2))`` on the unit circle; the discrete fit there is mapped back
   exactly by the inverse Tustin transform (stability preserved both ways);
4. the order, given or chosen on held-out frequencies (every fourth line left out of the
   fit) by the rule every ``order="auto"`` shares (:func:`select_order`,
   :mod:`stageid.validation.order_choice`);
5. the weighted output-error fit at its optimum (:mod:`stageid.frf.fit_search`): four
   subspace starts and a vector fit, each refined by Levenberg-Marquardt on
   ``sum_k w_k ||G_model(z_k) - G_k||^2`` (steps that leave the unit disc rejected) until a
   step lowers the cost by less than ``REFINE_TOL`` of it, the lowest kept, then mode
   exchanges while they lower it further;
6. the delay put back as ``d`` shift states per input.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from .._errors import DataError
from ..base import Estimator, Interval, Options, Satisfies
from ..checks import is_real
from ..display import html_repr, short_repr
from ..frozen import FrozenMapping
from ..models import StateSpaceModel
from ..models.frequency_response import FrequencyResponse
from .fit_search import fit_at_order
from .fit_selection import largest_order, select_delay, select_order
from .fit_uncertainty import FitCovariance, fit_covariance
from .fit_weights import column_errors, frequency_weights, warn_large_error
from .welch import welch_frf

__all__ = [
    "FRDIdentification",
    "FRDResult",
    "select_order",
    "select_delay",
    "column_errors",
    "add_input_delay",
    "fit_frequencies",
]

#: Lines whose weight is below this fraction of the largest count neither for the column
#: scaling nor for :attr:`FRDResult.column_errors` (their data are noise by their own std).
SIGNIFICANT_WEIGHT = 1e-6


@dataclasses.dataclass(frozen=True)
class FRDResult:
    """The identified model and its diagnostics (no training data kept).

    Attributes
    ----------
    model : StateSpaceModel
    order : int
        States of the dynamic part (the delay adds ``delay * n_inputs`` more).
    delay : int
        Input delay in samples (0 for continuous models).
    column_errors : ndarray of shape (n_inputs,)
        Max over the band of ``|G_model - G_data|`` relative to each input column's peak,
        over the lines whose weight is at least ``SIGNIFICANT_WEIGHT`` of the largest (all
        lines when unweighted).
    singular_values : ndarray
        Of the McKelvey realisation (the order's evidence).
    order_errors : tuple of (order, held-out error) pairs
        Filled when the order was chosen automatically.
    delay_errors : tuple of (delay, held-out error) pairs
        Filled when the delay was chosen automatically.
    weight : str
        The weighting used: ``"total-std"`` (``1 / total_std^2``: a best linear approximation's
        noise and nonlinear distortion), ``"std"`` (``1 / std^2``, the noise), ``"coherence"``
        or ``"none"``.
    band : tuple of float
        The frequencies fitted, Hz.
    covariance : FitCovariance or None
        The refined fit's parameter covariance (from the data's std, else the residual);
        see :meth:`response_uncertainty`.
    estimator : FRDIdentification or None
        A copy of the settings it was fitted with.
    """

    model: StateSpaceModel
    order: int
    delay: int
    column_errors: np.ndarray
    singular_values: np.ndarray
    order_errors: tuple = ()
    delay_errors: tuple = ()
    weight: str = "none"
    band: tuple = ()
    covariance: FitCovariance | None = None
    estimator: Estimator | None = None

    def __repr__(self) -> str:
        return short_repr(self)

    def _repr_html_(self) -> str:
        return html_repr(self)

    @property
    def max_error(self) -> float:
        """The largest of :attr:`column_errors`."""
        return float(np.max(self.column_errors))

    @property
    def diagnostics(self) -> Mapping[str, Any]:
        """What the fit chose and reached: order, delay, weighting, band, largest column error."""
        names = ("order", "delay", "weight", "band", "max_error")
        return FrozenMapping({name: getattr(self, name) for name in names})

    def summary(self) -> str:
        """One line per fact: the model, then :attr:`diagnostics`."""
        m = self.model
        kind = "continuous" if m.dt is None else f"discrete, sample time {m.dt:g} s"
        lines = [f"FRD fit: {m.n_states} states ({kind}), inputs {list(m.inputs)}, outputs {list(m.outputs)}"]
        return "\n".join(lines + [f"  {name}: {value}" for name, value in self.diagnostics.items()])

    def response_uncertainty(self, freqs_hz: Any) -> FrequencyResponse:
        """The model's frequency response with ``std = sqrt(E|G_est - G|^2)`` per entry.

        The data's std (or, without one, the fit's residual) propagated through the weighted
        output-error fit to first order, the order and delay held fixed
        (:mod:`stageid.frf.fit_uncertainty`).

        Parameters
        ----------
        freqs_hz : array_like of shape (n_freqs,)
            Strictly increasing frequencies in Hz, finite, >= 0 and (discrete models) at most
            the Nyquist frequency.

        Raises
        ------
        DataError
            Frequencies outside that range, or a result without a covariance.
        """
        if self.covariance is None:
            raise DataError("this FRDResult has no fit covariance (it was built without one).")
        dt = self.model.dt
        f = np.asarray(freqs_hz, dtype=float)
        nyq = np.inf if dt is None else 0.5 / dt
        if f.ndim != 1 or f.size == 0:
            raise DataError(f"`freqs_hz` must be a non-empty 1-D array of frequencies in Hz; got shape {f.shape}.")
        bad = ~np.isfinite(f) | (f < 0) | (f > nyq * (1 + 1e-12))
        if bad.any():
            raise DataError(f"`freqs_hz` must be finite and within 0-{nyq:g} Hz; got {float(f[bad][0])!r}.")
        zs = np.exp(2j * np.pi * fit_frequencies(f, self.covariance.T, dt) * self.covariance.T)
        std = self.covariance.response_std(zs)
        m = self.model
        return FrequencyResponse(f, m.frequency_response(f), std, None, m.inputs, m.outputs)


def _open_band(value: Any) -> bool:
    """``(f_low, f_high)`` in Hz, either end None; the given ends finite, ``0 <= f_low < f_high``."""
    if not isinstance(value, (tuple, list)) or len(value) != 2:
        return False
    ends = [float(v) for v in value if v is not None and is_real(v)]
    if len(ends) != sum(v is not None for v in value) or not all(np.isfinite(v) and v >= 0 for v in ends):
        return False
    return len(ends) < 2 or ends[0] < ends[1]


class FRDIdentification(Estimator):
    """State-space model from a frequency response (subspace start, weighted output-error fit).

    Parameters
    ----------
    order : int or "auto"
        States of the model (without delay states); ``"auto"`` chooses 1..``max_order`` by
        the error on held-out frequencies, with the rule every ``order="auto"`` shares
        (:mod:`stageid.validation.order_choice`).
    sample_time : float or None
        Sample time of a discrete model, s; None fits a continuous model (``dt: null``).
        Formerly ``dt`` (still accepted, with a DeprecationWarning).
    band : (f_low, f_high) or None
        The band fitted, Hz; an end given as None is the response's own end, and None is the
        whole response.  Formerly ``fmin`` and ``fmax`` (still accepted, with a
        DeprecationWarning; ``fmin=1.0`` alone reads as ``band=(1.0, None)``).
    weight : {"auto", "none", "std", "coherence"}
        ``auto``: ``std`` when the FRF has it, else ``coherence`` when it has that, else none.
    delay : int or "auto"
        Input delay in samples (discrete models only); ``"auto"`` chooses 0..``max_delay``.
    max_order : int
        Largest order tried by ``order="auto"``.
    max_delay : int
        Largest delay tried by ``delay="auto"``.
    max_iter : int
        Most iterations of the output-error refinement of each start (a safeguard: it stops
        when a step lowers the cost by less than
        :data:`stageid.frf.fit_search.REFINE_TOL` of it, or no step lowers it).

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.models import StateSpaceModel
    >>> g = StateSpaceModel([[0.9, 0.3], [-0.3, 0.9]], [[1.0], [0.0]], [[0.2, 0.1]], [[0.0]], dt=0.01)
    >>> f = np.linspace(0.5, 49.5, 100)
    >>> res = FRDIdentification(order=2, sample_time=0.01).fit(FrequencyResponse(f, g.frequency_response(f)))
    >>> bool(res.max_error < 1e-8)
    True
    """

    parameter_constraints = {
        "order": [Interval(int, 1, 400), Options("auto")],
        "sample_time": [Interval(float, 0.0, None, closed="neither"), None],
        "band": [None, Satisfies(_open_band, "(f_low, f_high) in Hz, 0 <= f_low < f_high finite, either end None")],
        "weight": [Options("auto", "none", "std", "coherence")],
        "delay": [Interval(int, 0, 10000), Options("auto")],
        "max_order": [Interval(int, 1, 400)],
        "max_delay": [Interval(int, 0, 10000)],
        "max_iter": [Interval(int, 0, 10000)],
    }

    renamed_parameters = {"dt": "sample_time", "fmin": ("band", 0), "fmax": ("band", 1)}

    def __init__(
        self,
        order: int | str = "auto",
        sample_time: float | None = None,
        band: tuple[float | None, float | None] | None = None,
        weight: str = "auto",
        delay: int | str = 0,
        max_order: int = 20,
        max_delay: int = 20,
        max_iter: int = 1000,
    ) -> None:
        self.order = order
        self.sample_time = sample_time
        self.band = band
        self.weight = weight
        self.delay = delay
        self.max_order = max_order
        self.max_delay = max_delay
        self.max_iter = max_iter

    def check_together(self) -> None:
        f_high = None if self.band is None else self.band[1]
        if self.sample_time is None and self.delay != 0:
            raise self.invalid("delay", "0 for a continuous model (an input delay needs a `sample_time`)")
        if self.sample_time is not None and f_high is not None and f_high > 0.5 / self.sample_time * (1 + 1e-12):
            nyquist = 0.5 / self.sample_time
            raise self.invalid("band", f"a band up to the Nyquist frequency {nyquist:g} Hz of `sample_time`")

    def fit(self, data: FrequencyResponse | Any) -> FRDResult:
        """Identify from a :class:`FrequencyResponse` (or records: their Welch H1 first).

        Raises
        ------
        ParameterError
            A bad setting.
        DataError
            No frequency in the band, frequencies above Nyquist of ``sample_time``, or an order the
            number of frequencies cannot support.
        IdentificationError
            No stable model could be found.
        """
        self.validate_params()
        frd = data if isinstance(data, FrequencyResponse) else welch_frf(data)
        dt = self.sample_time
        frd = frd.band(*(self.band or (None, None)))
        if dt is not None and frd.freqs[-1] > 0.5 / dt * (1 + 1e-9):
            raise DataError(
                f"the response reaches {frd.freqs[-1]:g} Hz, above the Nyquist frequency {0.5 / dt:g} Hz "
                "of the sample time; end the band below it (`band=`) or give a smaller `sample_time=`."
            )
        G = frd.response
        # lines with next to no weight (unexcited, noise only) must not set the scale or the error
        _, w_raw = frequency_weights(frd, self.weight, np.ones(frd.n_inputs))
        counted = w_raw >= SIGNIFICANT_WEIGHT * w_raw.max()
        scale = np.max(np.abs(G[counted]), axis=(0, 1))
        scale = np.where(scale > 0, scale, 1.0)
        Gs = G / scale[None, None, :]
        weight, w = frequency_weights(frd, self.weight, scale)
        T, fz = _fit_grid(frd.freqs, dt)
        # the delay acts on the sample grid of dt: z^d with z = exp(j 2 pi f dt)
        z_dt = np.exp(2j * np.pi * frd.freqs * (dt or 0.0))
        delay, delay_errors = self._delay(Gs, fz, T, z_dt, w, frd.n_freqs)
        Gd = Gs * (z_dt**delay)[:, None, None]
        order, order_errors = self._order(Gd, fz, T, w, frd.n_freqs)
        A, B, C, D, sv = fit_at_order(Gd, fz, T, order, w, self.max_iter, thorough=True)
        # the fit's uncertainty covers what scatters the data: with a BLA also its nonlinear distortion
        data_std = frd.total_std if frd.total_std is not None else frd.std
        std = None if data_std is None else data_std / scale[None, None, :]
        covariance = fit_covariance((A, B, C, D), Gd, np.exp(2j * np.pi * fz * T), w, std, T, scale)
        B, D = B * scale[None, :], D * scale[None, :]
        model = _assemble(A, B, C, D, T, dt, delay, frd)
        response = model.frequency_response(frd.freqs[counted])
        errors = column_errors(response, G[counted])
        warn_large_error(response, G[counted], None if frd.std is None else frd.std[counted], order, order_errors)
        return FRDResult(
            model,
            order,
            delay,
            errors,
            sv,
            order_errors,
            delay_errors,
            weight,
            (float(frd.freqs[0]), float(frd.freqs[-1])),
            covariance,
            self.clone(),
        )

    def _delay(self, Gs, fz, T, zs, w, n_freqs) -> tuple[int, tuple]:
        if self.delay != "auto":
            return int(self.delay), ()
        probe = self.order if self.order != "auto" else min(8, largest_order(n_freqs, Gs.shape[1], Gs.shape[2]))
        return select_delay(Gs, fz, T, zs, probe, self.max_delay, w)

    def _order(self, Gd, fz, T, w, n_freqs) -> tuple[int, tuple]:
        limit = largest_order(n_freqs, Gd.shape[1], Gd.shape[2])
        if self.order != "auto":
            if self.order > limit:
                raise DataError(
                    f"order {self.order} needs more frequencies than the {n_freqs} in the band "
                    f"(at most order {limit} here); lower `order=` or widen the band."
                )
            return int(self.order), ()
        return select_order(Gd, fz, T, min(self.max_order, limit), w)


def _fit_grid(freqs: np.ndarray, dt: float | None) -> tuple[float, np.ndarray]:
    """The sample time ``T`` of the internal discrete fit and the frequencies it sees there.

    The band is spread over the unit circle before the subspace step, which is poorly
    conditioned when all points crowd near ``z = 1`` (a 1 kHz band at 10 kHz sampling):
    continuous frequencies go through the bilinear map with ``T = 1 / (2 f_max)`` (``f_max``
    lands at ``2 atan(pi / 2)``, 0.64 pi); a discrete response at ``dt`` first through the
    inverse Tustin map ``f_c = tan(pi f dt) / (pi dt)``.  Both maps are Moebius maps of the
    unit disc onto itself (or of the left half plane onto it), so the fitted model is
    mapped back exactly, order and stability kept (:func:`_assemble`).
    """
    f = np.asarray(freqs, dtype=float)
    if dt is None:
        T = 1.0 / (2.0 * float(f[-1]))
    else:
        # f_max at (or near) Nyquist maps to infinity: take the scale from at most 0.45 / dt
        f_ref = min(float(f[-1]), 0.45 / dt)
        T = 1.0 / (2.0 * np.tan(np.pi * f_ref * dt) / (np.pi * dt))
    return T, fit_frequencies(f, T, dt)


def fit_frequencies(freqs: np.ndarray, T: float, dt: float | None) -> np.ndarray:
    """Where the frequencies ``freqs`` (Hz) land in the internal fit at sample time ``T``
    (the maps of :func:`_fit_grid`): ``theta / (2 pi T)`` with ``z = exp(j theta)``."""
    f = np.asarray(freqs, dtype=float)
    if dt is None:
        theta = 2.0 * np.arctan(np.pi * f * T)
    else:
        theta = 2.0 * np.arctan(T / dt * np.tan(np.pi * f * dt))  # Nyquist -> pi
        theta = np.where(theta < 0, theta + 2.0 * np.pi, theta)
    return theta / (2.0 * np.pi * T)


def add_input_delay(A, B, C, D, delay: int) -> tuple[np.ndarray, ...]:
    """``(A, B, C, D)`` with ``delay`` shift states in front of every input: ``G(z) z^-delay``."""
    if delay == 0:
        return A, B, C, D
    n, m, q = A.shape[0], B.shape[1], C.shape[0]
    shift = np.kron(np.eye(delay, k=-1), np.eye(m))  # w_(i+1)(k+1) = w_i(k), blocks of m
    last = np.zeros((delay * m, m))
    last[-m:] = np.eye(m)  # the last block is u(k - delay)
    first = np.zeros((delay * m, m))
    first[:m] = np.eye(m)
    Aa = np.block([[A, B @ last.T], [np.zeros((delay * m, n)), shift]])
    Ba = np.vstack([np.zeros((n, m)), first])
    Ca = np.hstack([C, D @ last.T])
    return Aa, Ba, Ca, np.zeros((q, m))


def _assemble(A, B, C, D, T, dt, delay, frd) -> StateSpaceModel:
    """The final model: the fit at ``T`` mapped back (inverse Tustin at ``T``, then Tustin at
    ``dt`` for a discrete model, see :func:`_fit_grid`) and the delay states added."""
    model = StateSpaceModel(A, B, C, D, dt=T, inputs=frd.inputs, outputs=frd.outputs).d2c(method="tustin")
    if dt is None:
        return model
    Ad, Bd, Cd, Dd = add_input_delay(*_matrices(model.c2d(dt, method="tustin")), delay)
    return StateSpaceModel(Ad, Bd, Cd, Dd, dt=dt, inputs=frd.inputs, outputs=frd.outputs)


def _matrices(model: StateSpaceModel) -> tuple[np.ndarray, ...]:
    return model.A, model.B, model.C, model.D
