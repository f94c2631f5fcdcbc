"""The data board of ``stageid serve``: read a record, pick channels, trim, detrend, and plot.

A record is read with the package's readers (:func:`stageid.data.io.read_table`,
:func:`stageid.models.frequency_response.read_frd`): a MATLAB file whose frequency responses sit
beside a frequency vector (structs included, as instrument exports store them) gives every one
of them (:func:`mat_struct_responses`), by the names the command line's ``--response`` takes.
Preparing a record writes it into the session's workspace as the file the estimate board's
commands read.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .._errors import DataError

__all__ = ["inspect_record", "prepare_time", "prepare_frd", "mat_struct_responses", "svg"]


def svg(fig: Any) -> str:
    """A figure as an inline SVG document (text), rendered on the server."""
    import io

    buffer = io.StringIO()
    fig.savefig(buffer, format="svg", bbox_inches="tight")
    return buffer.getvalue()


def mat_struct_responses(path: Path) -> dict[str, Any]:
    """The frequency responses of a MATLAB file: ``{name: FrequencyResponse}``, one SISO response each.

    Read by the command line's reader (:func:`stageid.data.mat_responses.mat_response_names`,
    :func:`stageid.models.frequency_response.read_frd`): a real frequency vector (``freqs_Hz``,
    ``f_hz``, ``w`` ...) and the complex vectors of its length, structs included; each name is
    the one ``stageid identify frd --response`` takes.
    """
    from ..data.mat_responses import mat_response_names
    from ..models.frequency_response import read_frd

    return {name: read_frd(path, name) for name in mat_response_names(path)}


def _read(path: Path, ts: float | None = None) -> tuple[str, Any]:
    """``("time", Table)`` or ``("frd", {name: FrequencyResponse})`` for a record file.

    ``ts`` is the sample time of a time record without a ``t`` column.  A file that is not a
    time record is tried as a frequency response (an FRF table, or MATLAB structs); when it is
    neither, the table reader's message is the one raised.
    """
    from ..data.io import read_table
    from ..models.frequency_response import frd_from_columns, read_frd

    try:
        table = read_table(path, ts)
    except DataError:
        if path.suffix.lower() == ".mat":
            try:
                responses = mat_struct_responses(path)
            except DataError:
                responses = {}  # no frequency response either: the table reader's message stands
        else:
            try:
                responses = {"response": read_frd(path)}
            except DataError:
                responses = {}
        if not responses:
            raise
        return "frd", responses
    if "f_hz" in table.names:
        return "frd", {"response": frd_from_columns({n: table.column(n) for n in table.names}, path.name)}
    return "time", table


def inspect_record(path: Path, ts: float | None = None) -> dict[str, Any]:
    """What the page shows of a record before preparing it: kind, channels, length, sampling."""
    kind, content = _read(path, ts)
    if kind == "frd":
        return {
            "kind": "frd",
            "responses": {
                name: {
                    "inputs": list(r.inputs),
                    "outputs": list(r.outputs),
                    "n_freqs": r.n_freqs,
                    "fmin": float(r.freqs[0]),
                    "fmax": float(r.freqs[-1]),
                }
                for name, r in content.items()
            },
        }
    return {
        "kind": "time",
        "columns": list(content.names),
        "n_samples": content.n_samples,
        "dt": content.dt,
        "duration": None if content.dt is None else content.dt * content.n_samples,
    }


def _seconds_to_index(value: float | None, exp: Any, default: int) -> int:
    if value is None:
        return default
    return int(np.clip(round((float(value) - exp.t0) / exp.dt), 0, exp.n_samples))


def prepare_time(path: Path, target: Path, settings: dict[str, Any]) -> dict[str, Any]:
    """Channels picked, trimmed to ``[start, stop)`` seconds, detrended; written to ``target`` (NPZ).

    ``settings``: ``inputs``, ``outputs`` (lists of column names), ``start``/``stop`` (s, or
    None for the record's ends), ``detrend`` (``none``, ``constant`` or ``linear``), ``decimate``
    (keep every k-th sample after an anti-aliasing low-pass; 1 or None: keep all), ``ts``.
    """
    from ..data.io import read_table, write_npz
    from ..data.preprocess import decimate, remove_offset
    from ..plots.records import record_figure, spectrum_figure

    detrend = settings.get("detrend") or "none"
    if detrend not in ("none", "constant", "linear"):
        raise DataError(f"detrend must be none, constant or linear; got {detrend!r}.")
    ts = settings.get("ts")
    exp = read_table(path, ts).experiment(settings.get("inputs") or [], settings.get("outputs") or [], name=target.stem)
    i0 = _seconds_to_index(settings.get("start"), exp, 0)
    i1 = _seconds_to_index(settings.get("stop"), exp, exp.n_samples)
    if i1 - i0 < 2:
        raise DataError(f"the trim range keeps {max(i1 - i0, 0)} samples; expected at least 2.")
    exp = exp.slice(i0, i1)
    factor = settings.get("decimate") or 1
    if isinstance(factor, bool) or not isinstance(factor, (int, float)) or factor != int(factor) or factor < 1:
        raise DataError(f"decimate must be a whole number >= 1; got {factor!r}.")
    factor = int(factor)
    if factor > 1:
        exp = decimate(exp, factor)
    if detrend != "none":
        exp, _ = remove_offset(exp, detrend)
    write_npz(target, exp)
    python = [
        "from stageid.data.io import read_table, write_npz",
        f"exp = read_table({str(path)!r}{'' if ts is None else f', ts={ts!r}'}).experiment({list(exp.input_names)!r}, {list(exp.output_names)!r})",
        f"exp = exp.slice({i0}, {i1})",
    ]
    if factor > 1:
        python += ["from stageid.data.preprocess import decimate", f"exp = decimate(exp, {factor})"]
    if detrend != "none":
        python += [
            "from stageid.data.preprocess import remove_offset",
            f"exp, offsets = remove_offset(exp, {detrend!r})",
        ]
    python.append(f"write_npz({target.name!r}, exp)")
    return {
        "kind": "time",
        "file": target.name,
        "inputs": list(exp.input_names),
        "outputs": list(exp.output_names),
        "dt": exp.dt,
        "n_samples": exp.n_samples,
        "figures": {"time": svg(record_figure(exp)), "spectrum": svg(spectrum_figure(exp))},
        "python": "\n".join(python),
    }


def prepare_frd(path: Path, target: Path, settings: dict[str, Any]) -> dict[str, Any]:
    """One frequency response of the record, limited to ``[fmin, fmax]`` Hz, written to ``target`` (CSV)."""
    from ..data.io import write_csv

    _, responses = _read(path)
    if not isinstance(responses, dict):
        raise DataError(f"record {path.name!r} holds time signals, not a frequency response.")
    name = settings.get("response") or next(iter(responses))
    if name not in responses:
        raise DataError(f"record {path.name!r} has no response {name!r}; expected one of {', '.join(responses)}.")
    frd = responses[name].band(settings.get("fmin"), settings.get("fmax"))
    write_csv(target, frd.to_columns())
    return frd_description(frd, target, f"write_csv({target.name!r}, frd.to_columns())  # frd read from {path.name}")


def frd_description(frd: Any, target: Path, python: str) -> dict[str, Any]:
    """The page's view of a frequency-response data set: channels, band and its Bode plot."""
    return {
        "kind": "frd",
        "file": target.name,
        "inputs": list(frd.inputs),
        "outputs": list(frd.outputs),
        "n_freqs": frd.n_freqs,
        "band": [float(frd.freqs[0]), float(frd.freqs[-1])],
        "figures": {"bode": svg(frd.plot())},
        "python": python,
    }
