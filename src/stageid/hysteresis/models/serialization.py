"""The ``stageid.hysteresis/1`` JSON format of PI and modified-PI models (and the reference actuator).

::

    {"format": "stageid.hysteresis/1", "kind": "pi" | "modified-pi",
     "inputs": ["V"], "outputs": ["y"],
     "input_offset": 0.0, "output_offset": 0.0,
     "r": [...],                      # thresholds, one per operator
     "rc": [...], "ra": [...], "rb": [...],   # modified-pi only (eq. 3)
     "input_warp": 0.0, "warp_scale": 1.0,    # modified-pi only: optional input warp
     "weights": [...],
     "state": {"x": 0.0, "z": [...]},         # operator state to start from
     "input_limits": [lo, hi] | null,         # drive range (compensator default, clipped to);
                                              # identified models: the identified input range
     "creep": {"time_constants": [...], "weights": [...],   # optional (absent: no creep),
               "sample_time": dt, "state": null | [...]}}   # see stageid.hysteresis.models.creep

Other kinds in the same format (the reference actuator of :mod:`stageid.plants.piezo_actuator`,
``{"format": "stageid.hysteresis/1", "kind": "piezo-actuator", "inputs", "outputs",
"parameters": {...}}``) are read by loaders their packages register with :func:`register_kind`;
this module imports none of them.

Every numeric entry must be a JSON number: ``true``, ``"0.5"``, a nested or ragged list are
refused with one line naming the field (the rule of :func:`stageid.checks.is_real`).

Written by :func:`stageid.models.serialization.dumps`, which is byte-stable:
``dumps(model_from_dict(json.loads(text)).to_dict()) == text``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ..._errors import ModelError, ModelFormatError
from ...checks import is_real, shown
from ...plugins import HYSTERESIS_KINDS, declared, load_object
from .creep import CreepTerm
from .operators import OperatorState
from .pi import HYSTERESIS_FORMAT, ModifiedPIModel, PIModel

__all__ = ["model_from_dict", "register_kind", "numbers", "number"]

_KEYS = {
    "pi": ("r", "weights"),
    "modified-pi": ("r", "rc", "ra", "rb", "weights"),
}
_OPTIONAL = (
    "inputs",
    "outputs",
    "input_offset",
    "output_offset",
    "state",
    "input_limits",
    "name",
    "description",
    "input_warp",
    "warp_scale",
    "creep",
)

# kind -> loader of a parsed dict: a callable, or "module:attribute" imported when a file of
# that kind is read.  Packages above hysteresis declare their kinds as entry points
# (stageid.plugins.HYSTERESIS_KINDS, read in _kinds) or call register_kind at import.
_KINDS: dict[str, Callable[[dict], Any] | str] = {}


def _kinds() -> dict[str, Callable[[dict], Any] | str]:
    return {**declared(HYSTERESIS_KINDS), **_KINDS}


def register_kind(kind: str, loader: Callable[[dict], Any] | str) -> None:
    """Register ``loader`` (a callable or ``"module:attribute"``) for files of ``kind``.

    The loader gets the parsed JSON object and returns the model, raising
    :class:`~stageid.ModelFormatError` for malformed fields.  PI kinds cannot be replaced.
    """
    if kind in _KEYS:
        raise ModelError(f"`kind` {kind!r} is a PI model kind and cannot be registered again.")
    _KINDS[kind] = loader


def _loader(kind: str) -> Callable[[dict], Any]:
    loader = _kinds()[kind]
    return loader if callable(loader) else load_object(loader)


def numbers(value: Any, key: str) -> list[float]:
    """A JSON list of numbers as floats; ModelFormatError for anything else (nested lists,
    booleans, quoted numbers, non-finite or out-of-range values)."""
    if not isinstance(value, list) or not all(is_real(e) for e in value):
        raise ModelFormatError(f"`{key}` must be a list of numbers; got {shown(value)}.")
    return [float(e) for e in value]


def number(value: Any, key: str) -> float:
    """A JSON number as a float; ModelFormatError for a boolean, a string or anything else."""
    if not is_real(value):
        raise ModelFormatError(f"`{key}` must be a number; got {shown(value)}.")
    return float(value)


def _header(d: Any) -> str:
    """The ``kind`` of a hysteresis model dict after checking the format and the fields."""
    if not isinstance(d, dict):
        raise ModelFormatError(f"a hysteresis model file must hold a JSON object; got {type(d).__name__}.")
    if d.get("format") != HYSTERESIS_FORMAT:
        raise ModelFormatError(f"`format` must be {HYSTERESIS_FORMAT!r}; got {shown(d.get('format'))}.")
    kind = d.get("kind")
    if kind in _kinds():
        return kind
    if kind not in _KEYS:
        expected = ", ".join(repr(k) for k in (*_KEYS, *_kinds()))
        raise ModelFormatError(f"`kind` must be one of {expected}; got {shown(kind)}.")
    for key in _KEYS[kind]:
        if key not in d:
            raise ModelFormatError(f"`{key}` is missing from the {kind} model.")
    unknown = set(d) - {"format", "kind", *_KEYS[kind], *_OPTIONAL}
    if unknown:
        raise ModelFormatError(f"unknown field(s) {', '.join(sorted(map(str, unknown)))} in a {kind} model.")
    return kind


def _name(d: dict, key: str, default: str) -> tuple[str]:
    v = d.get(key, [default])
    if not isinstance(v, list) or len(v) != 1 or not isinstance(v[0], str):
        raise ModelFormatError(f"`{key}` must be a list of one name; got {shown(v)}.")
    return (v[0],)


def _state(s: Any, n: int) -> OperatorState | None:
    if s is None:
        return None
    if not isinstance(s, dict) or set(s) != {"x", "z"}:
        raise ModelFormatError(f"`state` must be an object with `x` and `z`; got {shown(s)}.")
    z = numbers(s["z"], "state.z")
    if len(z) != n:
        raise ModelFormatError(f"`state.z` must have {n} entries; got {len(z)}.")
    return OperatorState(number(s["x"], "state.x"), z)


def _limits(limits: Any) -> tuple[float, float] | None:
    if limits is None:
        return None
    if not isinstance(limits, list) or len(limits) != 2 or not all(is_real(e) for e in limits):
        raise ModelFormatError(f"`input_limits` must be [low, high] or null; got {shown(limits)}.")
    return float(limits[0]), float(limits[1])


def model_from_dict(d: dict[str, Any]) -> Any:
    """Build a :class:`PIModel` or :class:`ModifiedPIModel` from its ``stageid.hysteresis/1`` dict.

    Other kinds go to the loader registered for them (:func:`register_kind`).

    Parameters
    ----------
    d : dict
        The parsed JSON object.

    Returns
    -------
    PIModel or ModifiedPIModel (or the model of a registered kind)

    Raises
    ------
    ModelFormatError
        Missing or malformed fields (the message names the field).

    Examples
    --------
    >>> from stageid.hysteresis import PIModel
    >>> from stageid.hysteresis.models.serialization import model_from_dict
    >>> m = PIModel(r=[0.0, 1.0], weights=[1.0, 0.5])
    >>> model_from_dict(m.to_dict()).weights.tolist()
    [1.0, 0.5]
    """
    kind = _header(d)
    if kind in _kinds():
        return _loader(kind)(d)
    arrays = {k: numbers(d[k], k) for k in _KEYS[kind]}
    n = len(arrays["r"])
    for k, v in arrays.items():
        if len(v) != n:
            raise ModelFormatError(f"`{k}` must have {n} entries (one per threshold in `r`); got {len(v)}.")
    common = dict(
        weights=arrays.pop("weights"),
        input_offset=number(d.get("input_offset", 0.0), "input_offset"),
        output_offset=number(d.get("output_offset", 0.0), "output_offset"),
        state=_state(d.get("state"), n),
        inputs=_name(d, "inputs", "V"),
        outputs=_name(d, "outputs", "y"),
        input_limits=_limits(d.get("input_limits")),
    )
    if d.get("creep") is not None:  # optional: files written before the creep option have none
        common["creep"] = CreepTerm.from_dict(d["creep"])
    if kind == "modified-pi":
        common["input_warp"] = number(d.get("input_warp", 0.0), "input_warp")
        common["warp_scale"] = number(d.get("warp_scale", 1.0), "warp_scale")
    try:
        return (PIModel if kind == "pi" else ModifiedPIModel)(**arrays, **common)
    except ModelFormatError:
        raise
    except ModelError as exc:
        raise ModelFormatError(str(exc)) from None
