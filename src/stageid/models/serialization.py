"""The ``stageid.lti/1`` JSON format, and loading of any stageid model file by its ``format``.

State space::

    {"format": "stageid.lti/1", "kind": "statespace", "dt": 0.002,     (null = continuous)
     "A": [[...]], "B": [[...]], "C": [[...]], "D": [[...]],
     "inputs": ["Z", "Rx", "Ry"], "outputs": ["z", "rx", "ry"]}

Transfer matrix (``num``/``den`` nested [output][input], descending powers of s or z)::

    {"format": "stageid.lti/1", "kind": "transfer", "dt": null,
     "num": [[[b0, b1, ...], ...], ...], "den": [[[a0, a1, ...], ...], ...],
     "inputs": [...], "outputs": [...]}

Writing is byte-stable: numbers are written with Python's shortest round-trip ``repr``,
keys in a fixed order, one matrix row per line, so ``dumps(loads(text)) == text`` for any
text this module wrote.  Other model formats (hysteresis models) register a loader in
``_FORMATS`` so ``load_model`` and the CLI handle every stageid model file.
"""

from __future__ import annotations

import importlib
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .._errors import ModelFormatError
from ..atomic import atomic_write_text

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

LTI_FORMAT = "stageid.lti/1"

# format name -> "module:function" turning the parsed dict into a model (imported lazily)
_FORMATS: dict[str, str] = {
    LTI_FORMAT: "stageid.models.serialization:lti_from_dict",
    "stageid.hysteresis/1": "stageid.hysteresis.serialization:model_from_dict",
}


def register_format(name: str, loader: str) -> None:
    """Register ``"module:function"`` as the loader of model files whose ``format`` is ``name``."""
    _FORMATS[name] = loader


def _num(x: float) -> str:
    x = float(x)
    if not np.isfinite(x):
        raise ModelFormatError(f"model files hold finite numbers only; got {x}.")
    return repr(x)


def _encode(value: Any, indent: int) -> str:
    pad = " " * indent
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        if not value:
            return "[]"
        if all(isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool) for v in value):
            return "[" + ", ".join(_num(v) for v in value) + "]"
        if all(isinstance(v, str) for v in value):
            return "[" + ", ".join(json.dumps(v) for v in value) + "]"
        inner = (",\n" + pad + "  ").join(_encode(v, indent + 2) for v in value)
        return "[\n" + pad + "  " + inner + "\n" + pad + "]"
    if isinstance(value, dict):
        items = (",\n" + pad + "  ").join(json.dumps(k) + ": " + _encode(v, indent + 2) for k, v in value.items())
        return "{\n" + pad + "  " + items + "\n" + pad + "}"
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return _num(value)
    if isinstance(value, str):
        return json.dumps(value)
    raise ModelFormatError(f"cannot write a value of type {type(value).__name__} to a model file.")


def dumps(d: dict[str, Any]) -> str:
    """Serialise a model dictionary as stable, human-readable JSON text (ends with a newline)."""
    return _encode(d, 0) + "\n"


def loads(text: str) -> Any:
    """Parse a model file's text into a model object (any registered format)."""
    try:
        d = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ModelFormatError(f"the model file is not valid JSON ({exc.msg} at line {exc.lineno}).") from None
    return model_from_dict(d)


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
            shown = ", ".join(keys[:8]) + (", ..." if len(keys) > 8 else "")
            came = f"an object without it (keys: {shown})" if keys else "an empty object"
        raise ModelFormatError(f"`format` is missing; expected one of {', '.join(sorted(_FORMATS))}; got {came}.")
    if fmt not in _FORMATS:
        raise ModelFormatError(f"unknown model format {fmt!r}; expected one of {', '.join(sorted(_FORMATS))}.")
    module, func = _FORMATS[fmt].split(":")
    try:
        loader: Callable[[dict], Any] = getattr(importlib.import_module(module), func)
    except (ImportError, AttributeError):
        raise ModelFormatError(f"model format {fmt!r} is not supported by this installation.") from None
    return loader(d)


def lti_to_dict(model: Any) -> dict[str, Any]:
    """The ``stageid.lti/1`` dictionary of a StateSpaceModel or TransferMatrix (keys in file order)."""
    from .statespace import StateSpaceModel
    from .transfer import TransferMatrix

    if isinstance(model, StateSpaceModel):
        return {
            "format": LTI_FORMAT,
            "kind": "statespace",
            "dt": model.dt,
            "A": model.A.tolist(),
            "B": model.B.tolist(),
            "C": model.C.tolist(),
            "D": model.D.tolist(),
            "inputs": list(model.inputs),
            "outputs": list(model.outputs),
        }
    if isinstance(model, TransferMatrix):
        return {
            "format": LTI_FORMAT,
            "kind": "transfer",
            "dt": model.dt,
            "num": [[e.tolist() for e in row] for row in model.num],
            "den": [[e.tolist() for e in row] for row in model.den],
            "inputs": list(model.inputs),
            "outputs": list(model.outputs),
        }
    raise ModelFormatError(f"expected a StateSpaceModel or TransferMatrix; got {type(model).__name__}.")


_REQUIRED = {"statespace": ("dt", "A", "B", "C", "D"), "transfer": ("dt", "num", "den")}


def lti_from_dict(d: dict[str, Any]) -> Any:
    """Build a model from a ``stageid.lti/1`` dictionary; :class:`ModelFormatError` names the bad field."""
    from .statespace import StateSpaceModel
    from .transfer import TransferMatrix

    if d.get("format") != LTI_FORMAT:
        raise ModelFormatError(f"`format` must be {LTI_FORMAT!r}; got {d.get('format')!r}.")
    kind = d.get("kind")
    if kind not in _REQUIRED:
        raise ModelFormatError(f'`kind` must be "statespace" or "transfer"; got {kind!r}.')
    for key in _REQUIRED[kind]:
        if key not in d:
            raise ModelFormatError(f"`{key}` is missing from the {kind} model.")
    unknown = set(d) - {"format", "kind", "inputs", "outputs", "name", "description", *_REQUIRED[kind]}
    if unknown:
        raise ModelFormatError(f"unknown field(s) {', '.join(sorted(unknown))} in a {kind} model.")
    names = {k: d.get(k) for k in ("inputs", "outputs")}
    for k, v in names.items():
        if v is not None and (not isinstance(v, list) or not all(isinstance(s, str) for s in v)):
            raise ModelFormatError(f"`{k}` must be a list of strings; got {v!r}.")
    cls = StateSpaceModel if kind == "statespace" else TransferMatrix
    obj = object.__new__(cls)
    fields = {k: d[k] for k in _REQUIRED[kind]}
    fields.update(inputs=tuple(names["inputs"] or ()), outputs=tuple(names["outputs"] or ()))
    for k, v in fields.items():
        object.__setattr__(obj, k, v)
    obj._init_fields(ModelFormatError)  # same checks as the constructor, reported as format errors
    return obj


def load_model(path: str | os.PathLike[str]) -> Any:
    """Read any stageid model file (``stageid.lti/1`` or a registered format).

    Raises
    ------
    ModelFormatError
        When the file is missing, not JSON, or a field is malformed (the message names it).
    """
    p = Path(path)
    try:
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
