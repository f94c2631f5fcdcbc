"""Frequency-response data: a measured FRF as an immutable object, its table format and its figure.

The table format is the one ``stageid freqresp`` writes, extended by ``stageid frf``: a column
``f_hz`` (strictly increasing), ``re_<out>_<in>`` and ``im_<out>_<in>`` for every
(output, input) pair (outputs outer, inputs inner), optionally ``std_<out>_<in>``
(``sqrt(E|H_est - H|^2)``) and ``coh_<out>`` (multiple coherence of each output).  A best
linear approximation of a nonlinear system adds ``stdtot_<out>_<in>``: the std of the estimate
from the noise *and* the stochastic nonlinear distortions (``std_`` is then its noise part
alone).  CSV and NPZ hold the same columns; readers that know only the first ones ignore the rest.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .._errors import DataError
from ..data.mat_responses import mat_responses
from ..display import HtmlRepr

__all__ = ["FrequencyResponse", "read_frd", "frd_columns"]


@dataclasses.dataclass(frozen=True, repr=False)
class FrequencyResponse(HtmlRepr):
    """A measured (or computed) MIMO frequency response.

    Parameters
    ----------
    freqs : ndarray of shape (n_freqs,)
        Frequencies in Hz, finite, non-negative, strictly increasing.
    response : ndarray of shape (n_freqs, n_outputs, n_inputs), complex
    std : ndarray of shape (n_freqs, n_outputs, n_inputs), optional
        ``sqrt(E|H_est - H|^2)`` of each entry.
    coherence : ndarray of shape (n_freqs, n_outputs), optional
        Multiple coherence of each output (ordinary coherence for one input), in [0, 1].
    inputs, outputs : sequence of str
        Channel names; default ``u1, ...`` and ``y1, ...``.
    total_std : ndarray of shape (n_freqs, n_outputs, n_inputs), optional
        Std of each entry from the noise and the stochastic nonlinear distortions together (a
        best linear approximation measured over several random-phase realisations); ``std``
        is then the noise part alone.
    copy : bool
        Copy the arrays (default).  ``False`` takes them over as they are (made read-only, the
        coherence clipped in place): for estimators that built them and keep no reference,
        because at a long record's full resolution a copy costs as much as the estimate.

    Raises
    ------
    DataError
        Shapes that do not fit together, NaN/inf, or frequencies that are not increasing.

    Examples
    --------
    >>> import numpy as np
    >>> frd = FrequencyResponse([1.0, 2.0], np.ones((2, 1, 1), complex))
    >>> frd.n_freqs, frd.inputs, frd.outputs
    (2, ('u1',), ('y1',))
    """

    freqs: np.ndarray
    response: np.ndarray
    std: np.ndarray | None = None
    coherence: np.ndarray | None = None
    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()
    total_std: np.ndarray | None = None
    copy: dataclasses.InitVar[bool] = True

    def __post_init__(self, copy: bool) -> None:
        own = True if copy else None  # None: no copy unless the dtype differs
        f = np.array(self.freqs, dtype=float, copy=own).reshape(-1)
        G = np.array(self.response, dtype=complex, copy=own)
        if G.ndim == 1:
            G = G[:, None, None]
        if G.ndim != 3 or G.shape[0] != f.size:
            raise DataError(f"`response` must have shape ({f.size}, n_outputs, n_inputs); got {G.shape}.")
        if f.size == 0:
            raise DataError("a frequency response needs at least one frequency; got none.")
        if not np.all(np.isfinite(f)) or not np.all(np.isfinite(G)):
            raise DataError("the frequencies and the response must be finite; got NaN or inf.")
        if np.any(f < 0):
            raise DataError(f"frequencies must be >= 0 Hz; got {f.min():g}.")
        bad = np.flatnonzero(np.diff(f) <= 0)
        if bad.size:
            k = int(bad[0]) + 1
            raise DataError(f"frequencies must be strictly increasing; row {k} has {f[k]:g} Hz after {f[k - 1]:g} Hz.")
        _, q, m = G.shape
        set_ = object.__setattr__
        set_(self, "freqs", _frozen(f))
        set_(self, "response", _frozen(G))
        for name in ("std", "total_std"):
            if getattr(self, name) is not None:
                set_(self, name, _frozen(_checked_std(getattr(self, name), name, G.shape, own)))
        if self.coherence is not None:
            c = np.array(self.coherence, dtype=float, copy=own)
            if c.shape != (f.size, q) or not np.all(np.isfinite(c)):
                raise DataError(f"`coherence` must be finite with shape {(f.size, q)}; got shape {c.shape}.")
            set_(self, "coherence", _frozen(np.clip(c, 0.0, 1.0, out=c)))
        set_(self, "inputs", _names(self.inputs, m, "u", "inputs"))
        set_(self, "outputs", _names(self.outputs, q, "y", "outputs"))

    @property
    def n_freqs(self) -> int:
        """Number of frequencies."""
        return int(self.freqs.size)

    @property
    def n_inputs(self) -> int:
        """Number of inputs."""
        return int(self.response.shape[2])

    @property
    def n_outputs(self) -> int:
        """Number of outputs."""
        return int(self.response.shape[1])

    def __repr__(self) -> str:
        named = (("std", self.std), ("total std", self.total_std), ("coherence", self.coherence))
        extras = [w for w, v in named if v is not None]
        return (
            f"FrequencyResponse({self.n_freqs} frequencies {self.freqs[0]:g}-{self.freqs[-1]:g} Hz, "
            f"{self.n_outputs}x{self.n_inputs}{', with ' + ' and '.join(extras) if extras else ''})"
        )

    def band(self, fmin: float | None = None, fmax: float | None = None) -> FrequencyResponse:
        """The frequencies in ``[fmin, fmax]`` (either end open when None).

        Raises
        ------
        DataError
            When no frequency lies in the band.
        """
        lo = -np.inf if fmin is None else fmin
        hi = np.inf if fmax is None else fmax
        keep = (self.freqs >= lo) & (self.freqs <= hi)
        if not np.any(keep):
            raise DataError(
                f"no frequency of the response ({self.freqs[0]:g}-{self.freqs[-1]:g} Hz) lies in {lo:g}-{hi:g} Hz."
            )
        return FrequencyResponse(
            self.freqs[keep],
            self.response[keep],
            None if self.std is None else self.std[keep],
            None if self.coherence is None else self.coherence[keep],
            self.inputs,
            self.outputs,
            None if self.total_std is None else self.total_std[keep],
        )

    def to_columns(self) -> dict[str, np.ndarray]:
        """The table columns (see the module docstring), ready for ``write_csv`` / ``write_npz``."""
        return frd_columns(self)

    def to_control(self) -> Any:
        """A python-control ``FrequencyResponseData`` (frequencies in rad/s; names kept)."""
        import control

        data = np.transpose(self.response, (1, 2, 0))
        return control.FrequencyResponseData(
            data, 2.0 * np.pi * self.freqs, inputs=list(self.inputs), outputs=list(self.outputs)
        )

    @classmethod
    def from_control(cls, sys: Any) -> FrequencyResponse:
        """From a python-control ``FrequencyResponseData`` (its ``omega`` in rad/s)."""
        data = np.asarray(getattr(sys, "frdata", None) if hasattr(sys, "frdata") else sys.fresp)
        if data.ndim == 1:
            data = data[None, None, :]
        return cls(
            np.asarray(sys.omega, dtype=float) / (2.0 * np.pi),
            np.transpose(data, (2, 0, 1)),
            inputs=tuple(sys.input_labels),
            outputs=tuple(sys.output_labels),
        )

    def plot(
        self,
        ax=None,
        model: Any = None,
        fit_band: tuple[float, float] | None = None,
        input_units: Sequence[str] = (),
        output_units: Sequence[str] = (),
    ):
        """Bode figure: magnitude with a +-2 std band, phase, and a coherence panel when known.

        ``model`` (anything with ``frequency_response(freqs)``) is drawn over the data;
        ``fit_band`` greys the frequencies a fit left out; the units label the magnitude axes
        (see :func:`stageid.plots.frf.frf_figure`).  ``ax``: draw in these matplotlib axes
        instead of a new figure: magnitude and phase rows per output (and a coherence row) by
        input columns, as a 2-D array or each input's panels in turn.  Returns the matplotlib
        figure (imported lazily; use the Agg backend off-screen).
        """
        from ..plots.frf import frf_figure

        return frf_figure(self, model, fit_band, input_units, output_units, ax)


def frd_columns(frd: FrequencyResponse) -> dict[str, np.ndarray]:
    """``f_hz``, ``re_``/``im_`` (and ``std_``) per pair, then ``coh_<out>`` per output."""
    cols: dict[str, np.ndarray] = {"f_hz": frd.freqs}
    for i, out in enumerate(frd.outputs):
        for j, inp in enumerate(frd.inputs):
            cols[f"re_{out}_{inp}"] = frd.response[:, i, j].real
            cols[f"im_{out}_{inp}"] = frd.response[:, i, j].imag
            if frd.std is not None:
                cols[f"std_{out}_{inp}"] = frd.std[:, i, j]
            if frd.total_std is not None:
                cols[f"stdtot_{out}_{inp}"] = frd.total_std[:, i, j]
    if frd.coherence is not None:
        for i, out in enumerate(frd.outputs):
            cols[f"coh_{out}"] = frd.coherence[:, i]
    return cols


def read_frd(path: str | os.PathLike[str], response: str | None = None) -> FrequencyResponse:
    """Read a frequency response: CSV or NPZ as ``stageid frf`` writes it, or a MATLAB ``.mat`` file.

    Channel names come from the ``re_<out>_<in>`` columns: the outputs in order of first
    appearance, the inputs likewise; names that contain ``_`` are matched against the
    ``re_`` columns so ``re_z_stage_u`` with outputs ``z_stage`` works when unambiguous.
    A ``.mat`` file gives one SISO response, ``response`` naming it when the file holds several
    (rules: :mod:`stageid.data.mat_responses`).

    Raises
    ------
    DataError
        A missing ``f_hz`` column, an ``re_`` column without its ``im_`` (or the reverse), pairs
        that do not form a full output x input grid, frequencies not strictly increasing,
        NaN/inf (from the reader, with the column and row).
    """
    from ..data.io import read_table

    if os.fspath(path).lower().endswith(".mat"):
        freqs, values, inp, out = mat_responses(path, response)
        try:
            return FrequencyResponse(freqs, values[:, None, None], inputs=(inp,), outputs=(out,))
        except DataError as exc:
            raise DataError(f"file '{os.path.basename(os.fspath(path))}': {exc}") from None
    if response is not None:
        raise DataError(f"`response={response!r}` selects a response of a .mat file; got '{os.fspath(path)}'.")
    # f_hz is the axis; the reader wants a time step, which a frequency table does not have
    table = read_table(path, ts=1.0)
    return frd_from_columns({n: table.column(n) for n in table.names}, os.path.basename(os.fspath(path)))


def frd_from_columns(columns: Mapping[str, np.ndarray], source: str = "") -> FrequencyResponse:
    """Build a :class:`FrequencyResponse` from table columns (see :func:`read_frd`)."""
    where = f"{source}: " if source else ""
    if "f_hz" not in columns:
        raise DataError(f"{where}a frequency response needs an 'f_hz' column; got {', '.join(columns)}.")
    pairs = [n[3:] for n in columns if n.startswith("re_")]
    for n in columns:
        if n.startswith("im_") and n[3:] not in pairs:
            raise DataError(f"{where}column '{n}' has no matching 're_{n[3:]}'; expected re/im pairs.")
    for p in pairs:
        if f"im_{p}" not in columns:
            raise DataError(f"{where}column 're_{p}' has no matching 'im_{p}'; expected re/im pairs.")
    if not pairs:
        raise DataError(f"{where}a frequency response needs re_<out>_<in> / im_<out>_<in> columns; got none.")
    outputs, inputs = _split_pairs(pairs, [n[4:] for n in columns if n.startswith("coh_")], where)
    f = np.asarray(columns["f_hz"], dtype=float)
    G = np.empty((f.size, len(outputs), len(inputs)), complex)
    S, St = (_entry_columns(columns, prefix, outputs, inputs) for prefix in ("std_", "stdtot_"))
    for a, o in enumerate(outputs):
        for b, i in enumerate(inputs):
            G[:, a, b] = np.asarray(columns[f"re_{o}_{i}"]) + 1j * np.asarray(columns[f"im_{o}_{i}"])
    coh = None
    if all(f"coh_{o}" in columns for o in outputs):
        coh = np.column_stack([np.asarray(columns[f"coh_{o}"], dtype=float) for o in outputs])
    try:
        return FrequencyResponse(f, G, S, coh, tuple(inputs), tuple(outputs), St)
    except DataError as exc:
        raise DataError(f"{where}{exc}") from None


def _entry_columns(
    columns: Mapping[str, np.ndarray], prefix: str, outputs: Sequence[str], inputs: Sequence[str]
) -> np.ndarray | None:
    """The ``<prefix><out>_<in>`` columns as (n_freqs, n_outputs, n_inputs), or None unless all are there."""
    if not all(f"{prefix}{o}_{i}" in columns for o in outputs for i in inputs):
        return None
    return np.stack(
        [np.stack([np.asarray(columns[f"{prefix}{o}_{i}"], float) for i in inputs], -1) for o in outputs], 1
    )


def _split_pairs(pairs: Sequence[str], coh_names: Sequence[str], where: str) -> tuple[list[str], list[str]]:
    """Output and input names of the ``<out>_<in>`` pairs: the split that forms a full grid.

    Each ``_`` of the first pair is tried as the separator; the inputs it implies are the
    tails of the pairs sharing its output, the outputs the heads of the pairs ending in an
    input.  The first split whose outputs x inputs are exactly the pairs wins.
    """
    first = pairs[0]
    for k in [k for k, ch in enumerate(first) if ch == "_" and 0 < k < len(first) - 1]:
        out0 = first[:k]
        ins = [p[len(out0) + 1 :] for p in pairs if p.startswith(out0 + "_") and len(p) > len(out0) + 1]
        outs: list[str] = []
        for p in pairs:
            for i in ins:
                if p.endswith("_" + i) and p[: -len(i) - 1] and p[: -len(i) - 1] not in outs:
                    outs.append(p[: -len(i) - 1])
        if len(outs) * len(ins) == len(pairs) and {f"{o}_{i}" for o in outs for i in ins} == set(pairs):
            return outs, ins
    raise DataError(f"{where}the re_/im_ columns ({len(pairs)} pairs) do not form a full output x input grid.")


def _names(names: Sequence[str], n: int, prefix: str, what: str) -> tuple[str, ...]:
    names = tuple(names) if names else tuple(f"{prefix}{k + 1}" for k in range(n))
    if len(names) != n or not all(isinstance(s, str) and s for s in names):
        raise DataError(f"`{what}` must be {n} non-empty names; got {names!r}.")
    return names


def _checked_std(value: Any, name: str, shape: tuple[int, ...], own: bool | None) -> np.ndarray:
    s = np.array(value, dtype=float, copy=own)
    if s.shape != shape:
        raise DataError(f"`{name}` must have shape {shape}; got {s.shape}.")
    if not np.all(np.isfinite(s)) or np.any(s < 0):
        raise DataError(f"`{name}` must be finite and >= 0; got NaN, inf or a negative value.")
    return s


def _frozen(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a
