"""The ``stageid.lti/1`` JSON format, and loading of any stageid model file by its ``format``.

State space::

    {"format": "stageid.lti/1", "kind": "statespace", "dt": 0.002,     (null = continuous)
     "A": [[...]], "B": [[...]], "C": [[...]], "D": [[...]],
     "inputs": ["Z", "Rx", "Ry"], "outputs": ["z", "rx", "ry"]}

Transfer matrix (``num``/``den`` nested [output][input], descending powers of s or z)::

    {"format": "stageid.lti/1", "kind": "transfer", "dt": null,
     "num": [[[b0, b1, ...], ...], ...], "den": [[[a0, a1, ...], ...], ...],
     "inputs": [...], "outputs": [...]}

Writing is byte-stable and parsing is guarded (:mod:`~stageid.models.json_text`): numbers are
written with Python's shortest round-trip ``repr``, keys in a fixed order, one matrix row per
line, so ``dumps(loads(text)) == text`` for any text this module wrote.  Other model formats (hysteresis models) register a loader in
``_FORMATS`` so ``load_model`` and the CLI handle every stageid model file.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .._errors import ModelError, ModelFormatError
from ..atomic import atomic_write_text
from ..checks import shown
from ..plugins import MODEL_FORMATS, declared, load_object
from ..runtime.resources import require_memory
from .json_text import LTI_FORMAT, dumps, parse
from .lti import StateSpaceModel, TransferMatrix

__all__ = [
    "LTI_FORMAT",
    "dumps",
    "loads",
    "lti_to_dict",
    "lti_from_dict",
    "load_model",
    "save_model",
    "register_format",
]

# format name -> "module:function" turning the parsed dict into a model (imported lazily);
# formats of higher packages (hysteresis) come from their entry points (stageid.plugins)
_FORMATS: dict[str, str] = {LTI_FORMAT: "stageid.models.serialization:lti_from_dict"}


def register_format(name: str, loader: str) -> None:
    """Register ``"module:function"`` as the loader of model files whose ``format`` is ``name``.

    Installed packages declare theirs as entry points of :data:`stageid.plugins.MODEL_FORMATS`.
    """
    _FORMATS[name] = loader


def _formats() -> dict[str, str]:
    return {**declared(MODEL_FORMATS), **_FORMATS}


def loads(text: str) -> Any:
    """Parse a model file's text into a model object (any registered format).

    The text is parsed by :func:`~stageid.models.json_text.parse`, which refuses deep nesting,
    over-long integers and text too large for memory with one line.
    """
    return model_from_dict(parse(text))


def model_from_dict(d: Any) -> Any:
    """Build the model a parsed model file describes, dispatching on its ``format``."""
    if not isinstance(d, dict):
        raise ModelFormatError(f"a model file must hold a JSON object; got {type(d).__name__}.")
    fmt = d.get("format")
    if fmt is None:
        if "format" in d:
            came = "`format`: null"
        else:
            keys = sorted(map(str, d))
            listed = ", ".join(keys[:8]) + (", ..." if len(keys) > 8 else "")
            came = f"an object without it (keys: {listed})" if keys else "an empty object"
        raise ModelFormatError(f"`format` is missing; expected one of {', '.join(sorted(_formats()))}; got {came}.")
    formats = _formats()
    if fmt not in formats:
        raise ModelFormatError(f"unknown model format {shown(fmt)}; expected one of {', '.join(sorted(formats))}.")
    try:
        loader: Callable[[dict], Any] = load_object(formats[fmt])
    except (ImportError, AttributeError):
        raise ModelFormatError(f"model format {fmt!r} is not supported by this installation.") from None
    return loader(d)


def lti_to_dict(model: Any) -> dict[str, Any]:
    """The ``stageid.lti/1`` dictionary of a StateSpaceModel or TransferMatrix (keys in file order)."""
    if isinstance(model, (StateSpaceModel, TransferMatrix)):
        return model.to_dict()
    raise ModelFormatError(f"expected a StateSpaceModel or TransferMatrix; got {type(model).__name__}.")


_REQUIRED = {"statespace": ("dt", "A", "B", "C", "D"), "transfer": ("dt", "num", "den")}


def lti_from_dict(d: dict[str, Any]) -> Any:
    """Build a model from a ``stageid.lti/1`` dictionary; :class:`ModelFormatError` names the bad field.

    Every number follows the one rule of :func:`stageid.checks.is_real` (no ``bool``, no
    quoted numbers), as the constructors check it.
    """
    if d.get("format") != LTI_FORMAT:
        raise ModelFormatError(f"`format` must be {LTI_FORMAT!r}; got {shown(d.get('format'))}.")
    kind = d.get("kind")
    if kind not in _REQUIRED:
        raise ModelFormatError(f'`kind` must be "statespace" or "transfer"; got {shown(kind)}.')
    for key in _REQUIRED[kind]:
        if key not in d:
            raise ModelFormatError(f"`{key}` is missing from the {kind} model.")
    unknown = set(d) - {"format", "kind", "inputs", "outputs", "name", "description", *_REQUIRED[kind]}
    if unknown:
        raise ModelFormatError(f"unknown field(s) {', '.join(sorted(unknown))} in a {kind} model.")
    names = {k: d.get(k) for k in ("inputs", "outputs")}
    for k, v in names.items():
        if v is not None and (not isinstance(v, list) or not all(isinstance(s, str) for s in v)):
            raise ModelFormatError(f"`{k}` must be a list of strings; got {shown(v)}.")
    cls = StateSpaceModel if kind == "statespace" else TransferMatrix
    fields = {k: d[k] for k in _REQUIRED[kind]}
    fields.update(inputs=tuple(names["inputs"] or ()), outputs=tuple(names["outputs"] or ()))
    try:
        return cls(**fields)
    except ModelError as exc:  # the constructor's checks, reported as a format error of the file
        raise ModelFormatError(str(exc)) from None


def load_model(path: str | os.PathLike[str]) -> Any:
    """Read any stageid model file (``stageid.lti/1`` or a registered format).

    Raises
    ------
    ModelFormatError
        When the file is missing, not JSON, or a field is malformed (the message names it).
    """
    p = Path(path)
    try:
        # the parsed text needs a few times its size: refuse before reading a huge file
        require_memory(4 * p.stat().st_size, f"reading model file '{p}'")
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ModelFormatError(f"model file '{p}' does not exist.") from None
    except (UnicodeDecodeError, IsADirectoryError, PermissionError) as exc:
        raise ModelFormatError(f"cannot read model file '{p}': {exc.__class__.__name__}.") from None
    try:
        return loads(text)
    except ModelFormatError as exc:
        raise ModelFormatError(f"{p.name}: {exc}") from None


def save_model(model: Any, path: str | os.PathLike[str]) -> None:
    """Write a model file atomically (a temporary file renamed into place)."""
    text = dumps(model.to_dict())
    atomic_write_text(path, text)
