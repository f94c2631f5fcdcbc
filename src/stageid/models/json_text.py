"""The text of stageid model files: byte-stable JSON writing and guarded parsing.

Writing is byte-stable: numbers are written with Python's shortest round-trip ``repr``, keys
in the given order, one matrix row per line, so ``dumps(loads(text)) == text`` for any text
this module wrote.  Parsing refuses, with one :class:`~stageid.ModelFormatError` line, what
``json.loads`` would turn into an internal error: nesting deeper than any model file needs
(100 000 brackets exhaust the recursion limit), integers longer than Python converts
(4300 digits), and text larger than the memory available to hold it.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from typing import Any

import numpy as np

from .._errors import ModelFormatError
from ..runtime.resources import require_memory

__all__ = ["LTI_FORMAT", "MAX_DEPTH", "lti_dict", "dumps", "parse", "nesting_depth"]

LTI_FORMAT = "stageid.lti/1"

#: deepest nesting of arrays and objects a model file may have (a transfer matrix needs 4)
MAX_DEPTH = 32
#: parsed JSON holds each number as a Python object in a list: about this many bytes per character
_BYTES_PER_CHAR = 4

_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')


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


def lti_dict(
    kind: str, dt: float | None, fields: dict[str, Any], inputs: Sequence[str], outputs: Sequence[str]
) -> dict[str, Any]:
    """The ``stageid.lti/1`` dictionary of a model, keys in file order: format, kind, dt, the
    model's ``fields`` (``A``..``D`` or ``num``, ``den`` as nested lists), inputs, outputs."""
    return {"format": LTI_FORMAT, "kind": kind, "dt": dt, **fields, "inputs": list(inputs), "outputs": list(outputs)}


def dumps(d: dict[str, Any]) -> str:
    """Serialise a model dictionary as stable, human-readable JSON text (ends with a newline)."""
    return _encode(d, 0) + "\n"


def nesting_depth(text: str) -> int:
    """Deepest nesting of ``[`` and ``{`` in JSON ``text`` (brackets inside strings not counted)."""
    bare = _STRING.sub('""', text).encode("utf-8", "surrogatepass")
    b = np.frombuffer(bare, dtype=np.uint8)
    step = np.isin(b, (ord("["), ord("{"))).astype(np.int64) - np.isin(b, (ord("]"), ord("}")))
    return int(np.cumsum(step).max(initial=0))


def parse(text: str) -> Any:
    """``json.loads(text)`` after the guards of the module docstring.

    Raises
    ------
    ModelFormatError
        Not JSON, nested deeper than :data:`MAX_DEPTH`, or an integer of more than 4300 digits.
    ResourceError
        When holding the parsed text would need more memory than is available.
    """
    require_memory(_BYTES_PER_CHAR * len(text), f"parsing a model file of {len(text)} characters")
    depth = nesting_depth(text)
    if depth > MAX_DEPTH:
        raise ModelFormatError(
            f"the model file nests arrays or objects {depth} deep; a model file needs at most {MAX_DEPTH}."
        )
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ModelFormatError(f"the model file is not valid JSON ({exc.msg} at line {exc.lineno}).") from None
    except ValueError:  # Python refuses integer strings over 4300 digits (CVE-2020-10735)
        raise ModelFormatError(
            "the model file holds an integer with more than 4300 digits; model files hold finite numbers only."
        ) from None
    except RecursionError:  # guarded above; kept so no nesting can end as an internal error
        raise ModelFormatError("the model file nests arrays or objects too deep.") from None
