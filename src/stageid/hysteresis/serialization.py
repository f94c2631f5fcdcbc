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
               "sample_time": dt, "state": null | [...]}}   # see stageid.hysteresis.creep

The reference actuator of :mod:`stageid.plants.piezo_actuator` (not a PI model) is stored as
``{"format": "stageid.hysteresis/1", "kind": "piezo-actuator", "inputs", "outputs",
"parameters": {...}}``.

Written by :func:`stageid.models.serialization.dumps`, which is byte-stable:
``dumps(model_from_dict(json.loads(text)).to_dict()) == text``.
"""

from __future__ import annotations

from typing import Any

from .._errors import ModelError, ModelFormatError

__all__ = ["model_from_dict"]

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


def _numbers(d: dict, key: str) -> list[float]:
    v = d[key]
    if not isinstance(v, list) or not all(isinstance(e, (int, float)) and not isinstance(e, bool) for e in v):
        raise ModelFormatError(f"`{key}` must be a list of numbers; got {v!r:.80}.")
    return [float(e) for e in v]


def _number(d: dict, key: str, default: float) -> float:
    v = d.get(key, default)
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        raise ModelFormatError(f"`{key}` must be a number; got {v!r}.")
    return float(v)


def model_from_dict(d: dict[str, Any]) -> Any:
    """Build a :class:`PIModel` or :class:`ModifiedPIModel` from its ``stageid.hysteresis/1`` dict.

    Parameters
    ----------
    d : dict
        The parsed JSON object.

    Returns
    -------
    PIModel or ModifiedPIModel

    Raises
    ------
    ModelFormatError
        Missing or malformed fields (the message names the field).

    Examples
    --------
    >>> from stageid.hysteresis import PIModel
    >>> from stageid.hysteresis.serialization import model_from_dict
    >>> m = PIModel(r=[0.0, 1.0], weights=[1.0, 0.5])
    >>> model_from_dict(m.to_dict()).weights.tolist()
    [1.0, 0.5]
    """
    from .operators import OperatorState
    from .pi import HYSTERESIS_FORMAT, ModifiedPIModel, PIModel

    if not isinstance(d, dict):
        raise ModelFormatError(f"a hysteresis model file must hold a JSON object; got {type(d).__name__}.")
    if d.get("format") != HYSTERESIS_FORMAT:
        raise ModelFormatError(f"`format` must be {HYSTERESIS_FORMAT!r}; got {d.get('format')!r}.")
    kind = d.get("kind")
    if kind == "piezo-actuator":  # the reference actuator of stageid.plants (not a PI model)
        from ..plants.piezo_actuator import PiezoActuator

        return PiezoActuator.from_dict(d)
    if kind not in _KEYS:
        raise ModelFormatError(f'`kind` must be "pi" or "modified-pi"; got {kind!r}.')
    for key in _KEYS[kind]:
        if key not in d:
            raise ModelFormatError(f"`{key}` is missing from the {kind} model.")
    unknown = set(d) - {"format", "kind", *_KEYS[kind], *_OPTIONAL}
    if unknown:
        raise ModelFormatError(f"unknown field(s) {', '.join(sorted(unknown))} in a {kind} model.")
    arrays = {k: _numbers(d, k) for k in _KEYS[kind]}
    n = len(arrays["r"])
    for k, v in arrays.items():
        if len(v) != n:
            raise ModelFormatError(f"`{k}` must have {n} entries (one per threshold in `r`); got {len(v)}.")
    names = {}
    for key, default in (("inputs", ["V"]), ("outputs", ["y"])):
        v = d.get(key, default)
        if not isinstance(v, list) or len(v) != 1 or not isinstance(v[0], str):
            raise ModelFormatError(f"`{key}` must be a list of one name; got {v!r}.")
        names[key] = tuple(v)
    state = None
    if d.get("state") is not None:
        s = d["state"]
        if not isinstance(s, dict) or set(s) != {"x", "z"}:
            raise ModelFormatError(f"`state` must be an object with `x` and `z`; got {s!r:.80}.")
        z = _numbers(s, "z")
        if len(z) != n:
            raise ModelFormatError(f"`state.z` must have {n} entries; got {len(z)}.")
        state = OperatorState(_number(s, "x", 0.0), z)
    limits = d.get("input_limits")
    if limits is not None:
        if (
            not isinstance(limits, list)
            or len(limits) != 2
            or not all(isinstance(e, (int, float)) and not isinstance(e, bool) for e in limits)
        ):
            raise ModelFormatError(f"`input_limits` must be [low, high] or null; got {limits!r}.")
        limits = (float(limits[0]), float(limits[1]))
    common = dict(
        weights=arrays["weights"],
        input_offset=_number(d, "input_offset", 0.0),
        output_offset=_number(d, "output_offset", 0.0),
        state=state,
        inputs=names["inputs"],
        outputs=names["outputs"],
        input_limits=limits,
    )
    if d.get("creep") is not None:  # optional: files written before the creep option have none
        from .creep import CreepTerm

        common["creep"] = CreepTerm.from_dict(d["creep"])
    try:
        if kind == "pi":
            return PIModel(r=arrays["r"], **common)
        return ModifiedPIModel(
            r=arrays["r"],
            rc=arrays["rc"],
            ra=arrays["ra"],
            rb=arrays["rb"],
            input_warp=_number(d, "input_warp", 0.0),
            warp_scale=_number(d, "warp_scale", 1.0),
            **common,
        )
    except ModelFormatError:
        raise
    except ModelError as exc:
        raise ModelFormatError(str(exc)) from None
