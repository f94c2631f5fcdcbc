"""Preprocessing of measured records: offset/trend removal, train/validation split, merging,
decimation.  Every function returns new :class:`Experiment` objects; inputs are never modified.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._errors import DataError
from .experiment import Experiment, as_experiments, check_same_channels

__all__ = ["Offsets", "remove_offset", "split", "merge", "decimate"]

_KINDS = ("constant", "linear")
_CHANNELS = ("both", "inputs", "outputs")


@dataclass(frozen=True, eq=False)
class Offsets:
    """The trend removed by :func:`remove_offset`: ``offset + slope * (time - t_ref)`` per channel.

    Attributes
    ----------
    kind : {"constant", "linear"}
        What was removed.
    t_ref : float
        Time origin of the trend in seconds (the ``t0`` of the experiment it was fitted on).
    input_offset, input_slope : ndarray of shape (n_inputs,)
        Trend of each input at ``t_ref`` and its slope per second (zeros where not removed).
    output_offset, output_slope : ndarray of shape (n_outputs,)
        The same for the outputs.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Experiment, remove_offset
    >>> exp = Experiment(u=np.ones(4), y=np.full(4, 3.0), dt=1.0)
    >>> centred, offsets = remove_offset(exp)
    >>> offsets.output_offset
    array([3.])
    >>> np.allclose(offsets.restore(centred).y, exp.y)
    True
    """

    kind: str
    t_ref: float
    input_offset: np.ndarray
    output_offset: np.ndarray
    input_slope: np.ndarray
    output_slope: np.ndarray

    def __post_init__(self) -> None:
        for field in ("input_offset", "output_offset", "input_slope", "output_slope"):
            arr = np.array(getattr(self, field), dtype=float, copy=True).reshape(-1)
            arr.setflags(write=False)
            object.__setattr__(self, field, arr)

    def trend(self, exp: Experiment) -> tuple[np.ndarray, np.ndarray]:
        """Evaluate the trend on the sample times of ``exp``.

        Returns
        -------
        u_trend : ndarray of shape (n_samples, n_inputs)
        y_trend : ndarray of shape (n_samples, n_outputs)

        Raises
        ------
        DataError
            When ``exp`` has other channel counts than the experiment the trend was fitted on.
        """
        if exp.n_inputs != self.input_offset.size or exp.n_outputs != self.output_offset.size:
            raise DataError(
                f"offsets were fitted on {self.input_offset.size} inputs / {self.output_offset.size} outputs; "
                f"got an experiment with {exp.n_inputs} / {exp.n_outputs}."
            )
        tau = (exp.time - self.t_ref)[:, None]
        return self.input_offset + tau * self.input_slope, self.output_offset + tau * self.output_slope

    def remove(self, exp: Experiment) -> Experiment:
        """Subtract this trend from another record (e.g. validation data with the training offsets)."""
        u_trend, y_trend = self.trend(exp)
        return exp.with_(u=exp.u - u_trend, y=exp.y - y_trend)

    def restore(self, exp: Experiment) -> Experiment:
        """Add this trend back (e.g. to a simulated response of a model fitted on centred data)."""
        u_trend, y_trend = self.trend(exp)
        return exp.with_(u=exp.u + u_trend, y=exp.y + y_trend)


def remove_offset(exp: Experiment, kind: str = "constant", channels: str = "both") -> tuple[Experiment, Offsets]:
    """Remove the mean (``"constant"``) or a least-squares straight line (``"linear"``).

    Parameters
    ----------
    exp : Experiment
        The record; not modified.
    kind : {"constant", "linear"}
        ``"constant"`` subtracts each channel's mean; ``"linear"`` subtracts the
        least-squares line ``a + b * (time - t0)`` of each channel.
    channels : {"both", "inputs", "outputs"}
        Which channels to treat; the others are returned unchanged (zero offset).

    Returns
    -------
    centred : Experiment
        The record with the trend removed (same names, units, dt, t0).
    offsets : Offsets
        What was removed; ``offsets.restore(...)`` adds it back, ``offsets.remove(other)``
        applies it to another record.

    Raises
    ------
    DataError
        For an unknown ``kind``/``channels`` or a linear trend on fewer than 2 samples.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Experiment, remove_offset
    >>> t = np.arange(5.0)
    >>> exp = Experiment(u=np.zeros(5), y=2.0 + 0.5 * t, dt=1.0)
    >>> flat, offsets = remove_offset(exp, kind="linear", channels="outputs")
    >>> np.allclose(flat.y, 0.0), float(offsets.output_slope[0])
    (True, 0.5)
    """
    if not isinstance(exp, Experiment):
        raise DataError(f"`exp` must be an Experiment; got {type(exp).__name__}.")
    if kind not in _KINDS:
        raise DataError(f"`kind` must be one of {', '.join(repr(k) for k in _KINDS)}; got {kind!r}.")
    if channels not in _CHANNELS:
        raise DataError(f"`channels` must be one of {', '.join(repr(c) for c in _CHANNELS)}; got {channels!r}.")
    if kind == "linear":
        exp.require_samples(2, "removing a linear trend")

    def fit(x: np.ndarray, active: bool) -> tuple[np.ndarray, np.ndarray]:
        zeros = np.zeros(x.shape[1])
        if not active:
            return zeros, zeros
        mean = x.mean(axis=0)
        if kind == "constant":
            return mean, zeros
        tau = exp.time - exp.t0
        tau_c = tau - tau.mean()
        slope = tau_c @ (x - mean) / (tau_c @ tau_c)
        return mean - slope * tau.mean(), slope

    u_off, u_slope = fit(exp.u, channels in ("both", "inputs"))
    y_off, y_slope = fit(exp.y, channels in ("both", "outputs"))
    offsets = Offsets(kind, exp.t0, u_off, y_off, u_slope, y_slope)
    return offsets.remove(exp), offsets


def split(exp: Experiment, fraction: float = 0.75, *, min_samples: int = 2) -> tuple[Experiment, Experiment]:
    """Split a record in time into an identification part and a validation part.

    Parameters
    ----------
    exp : Experiment
        The record; not modified.
    fraction : float
        Share of samples in the first part, 0 < fraction < 1; the first part has
        ``round(fraction * n_samples)`` samples.
    min_samples : int
        Minimum length of each part.

    Returns
    -------
    train, validation : Experiment
        Consecutive pieces; ``validation.t0`` continues where ``train`` ends.

    Raises
    ------
    DataError
        When ``fraction`` is outside (0, 1) or a part would have fewer than ``min_samples``.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Experiment, split
    >>> train, val = split(Experiment(u=np.zeros(100), y=np.zeros(100), dt=0.01), 0.7)
    >>> train.n_samples, val.n_samples, round(val.t0, 12)
    (70, 30, 0.7)
    """
    if not isinstance(exp, Experiment):
        raise DataError(f"`exp` must be an Experiment; got {type(exp).__name__}.")
    try:
        frac = float(fraction)
    except (TypeError, ValueError):
        raise DataError(f"`fraction` must be a number between 0 and 1 (exclusive); got {fraction!r}.") from None
    if not 0.0 < frac < 1.0:
        raise DataError(f"`fraction` must be a number between 0 and 1 (exclusive); got {fraction!r}.")
    if int(min_samples) != min_samples or min_samples < 1:
        raise DataError(f"`min_samples` must be a positive integer; got {min_samples!r}.")
    n = exp.n_samples
    n_train = int(round(frac * n))
    if n_train < min_samples or n - n_train < min_samples:
        raise DataError(
            f"splitting {n} samples at fraction {frac:g} gives parts of {n_train} and {n - n_train} samples; "
            f"each part needs at least {min_samples}."
        )
    return exp.slice(0, n_train), exp.slice(n_train, n)


def merge(experiments: Experiment | Sequence[Experiment]) -> tuple[Experiment, ...]:
    """Collect several records of one system into a checked tuple (for multi-experiment fits).

    Unlike :func:`~stageid.data.as_experiments` this also requires equal channel units.

    Parameters
    ----------
    experiments : Experiment or sequence of Experiment

    Returns
    -------
    tuple of Experiment

    Raises
    ------
    DataError
        No experiments, differing sample times, channel names or units.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Experiment, merge
    >>> a = Experiment(u=np.zeros(10), y=np.zeros(10), dt=0.1)
    >>> len(merge([a, a.with_(name="second")]))
    2
    """
    exps = as_experiments(experiments)
    check_same_channels(exps, "units", "use the same units")
    return exps


def decimate(exp: Experiment, factor: int, *, antialias: bool = True) -> Experiment:
    """Keep every ``factor``-th sample, after a zero-phase anti-aliasing low-pass by default.

    Parameters
    ----------
    exp : Experiment
    factor : int
        Decimation factor >= 1; the new sample time is ``factor * dt``.
    antialias : bool
        Filter with the FIR low-pass of :func:`scipy.signal.decimate` (order ``20 factor``,
        Hamming window, cut-off at the new Nyquist frequency) applied with zero phase, the
        record's ends extended by odd reflection so constants and slow signals pass
        unchanged up to the edges, before down-sampling;
        ``False`` just picks samples (only safe when the signals have no content above
        the new Nyquist frequency).

    Returns
    -------
    Experiment
        ``ceil(n_samples / factor)`` samples, same ``t0``.

    Raises
    ------
    DataError
        When ``factor`` is not a positive integer or the record is too short to filter.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.data import Experiment, decimate
    >>> exp = Experiment(u=np.zeros(1000), y=np.zeros(1000), dt=1e-4)
    >>> slow = decimate(exp, 10)
    >>> slow.n_samples, round(slow.dt, 12)
    (100, 0.001)
    """
    if isinstance(factor, bool) or int(factor) != factor or factor < 1:
        raise DataError(f"`factor` must be a positive integer; got {factor!r}.")
    factor = int(factor)
    if factor == 1:
        return exp.with_()
    if not antialias:
        return exp.with_(u=exp.u[::factor], y=exp.y[::factor], dt=exp.dt * factor)
    from scipy import signal

    n_taps = 20 * factor + 1  # scipy's FIR design for decimate: order 20 * factor
    if exp.n_samples < n_taps:
        raise DataError(
            f"decimating by {factor} with anti-aliasing needs at least {n_taps} samples; got {exp.n_samples}."
        )
    taps = signal.firwin(n_taps, 1.0 / factor, window="hamming")  # unit gain at DC
    u = _zero_phase_fir(exp.u, taps)[::factor]
    y = _zero_phase_fir(exp.y, taps)[::factor]
    return exp.with_(u=u, y=y, dt=exp.dt * factor)


def _zero_phase_fir(x: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """Apply a symmetric odd-length FIR along axis 0 without delay, padding each end by odd reflection.

    The padding ``2 x[0] - x[k]`` continues the record's value and slope through its ends,
    so constants and straight lines pass exactly and slow signals have no edge transient
    (zero padding, as in :func:`scipy.signal.decimate`, pulls the ends towards 0).
    """
    from scipy import signal

    half = taps.size // 2
    head = 2.0 * x[:1] - x[half:0:-1]
    tail = 2.0 * x[-1:] - x[-2 : -half - 2 : -1]
    padded = np.concatenate([head, x, tail], axis=0)
    return signal.oaconvolve(padded, taps[:, None], mode="valid", axes=0)
