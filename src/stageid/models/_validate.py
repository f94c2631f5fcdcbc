"""Shared checks for model fields: shapes, finiteness, names, sample time."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._errors import ModelError


def as_matrix(
    name: str, value: object, shape: tuple[int | None, int | None], error: type[ModelError] = ModelError
) -> np.ndarray:
    """Return ``value`` as a read-only float matrix of ``shape`` (None = any size).

    Raises ``error`` with a message such as "`B` must have shape (15, 3); got (5, 3)."
    """
    if isinstance(value, str) or value is None:
        raise error(f"`{name}` must be a 2-D array of numbers; got {type(value).__name__}.")
    if np.iscomplexobj(value):
        cval = np.asarray(value)
        if np.any(cval.imag != 0):
            raise error(f"`{name}` must be a real matrix; got complex entries (a state-space model has real matrices).")
        value = cval.real
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise error(f"`{name}` must be a 2-D array of numbers; got {_describe(value)}.") from None
    if arr.size == 0 and arr.ndim in (1, 2):
        # JSON cannot spell an empty (0, m) or (p, 0) matrix: accept [] or [[], []] for it.
        target = tuple(0 if s is None else s for s in shape)
        if 0 in target:
            arr = np.zeros(target)
    expected = tuple("n" if s is None else s for s in shape)
    if arr.ndim != 2 or any(s is not None and a != s for a, s in zip(arr.shape, shape)):
        exp_txt = "(" + ", ".join(str(s) for s in expected) + ")"
        raise error(f"`{name}` must have shape {exp_txt}; got {tuple(arr.shape)}.")
    if not np.all(np.isfinite(arr)):
        i, j = (int(k) for k in np.argwhere(~np.isfinite(arr))[0])
        raise error(f"`{name}` must contain only finite numbers; entry [{i}][{j}] is {arr[i, j]}.")
    arr = np.ascontiguousarray(arr)
    arr.setflags(write=False)
    return arr


def _describe(value: object) -> str:
    if isinstance(value, (list, tuple)):
        return "a ragged or non-numeric list"
    return type(value).__name__


def as_names(
    field: str, names: Sequence[str] | None, count: int, prefix: str, error: type[ModelError] = ModelError
) -> tuple[str, ...]:
    """Validate channel names (default ``prefix1, prefix2, ...``)."""
    if names is None or (not isinstance(names, str) and len(names) == 0):
        return tuple(f"{prefix}{i + 1}" for i in range(count))
    if isinstance(names, str) or not all(isinstance(n, str) for n in names):
        raise error(f"`{field}` must be a list of {count} strings; got {names!r}.")
    names = tuple(names)
    if len(names) != count:
        raise error(f"`{field}` must have {count} names; got {len(names)}.")
    if len(set(names)) != len(names):
        raise error(f"`{field}` must not repeat a name; got {list(names)}.")
    return names


def as_dt(value: object, error: type[ModelError] = ModelError) -> float | None:
    """``None`` for continuous time, else a positive float sample time."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise error(f"`dt` must be null (continuous) or a positive number of seconds; got {value!r}.")
    dt = float(value)
    if not np.isfinite(dt) or dt <= 0:
        raise error(f"`dt` must be null (continuous) or a positive number of seconds; got {value!r}.")
    return dt


def frequency_variable(freqs_hz: object, dt: float | None) -> np.ndarray:
    """Return s = j 2 pi f (continuous) or z = exp(j 2 pi f dt) (discrete)."""
    f = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
    if f.ndim != 1 or not np.all(np.isfinite(f)) or np.any(f < 0):
        raise ModelError("frequencies must be a 1-D array of finite, non-negative values in Hz.")
    w = 2.0 * np.pi * f
    return 1j * w if dt is None else np.exp(1j * w * dt)
