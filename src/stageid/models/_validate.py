"""Shared checks for model fields: matrices, polynomials, names, sample time, simulated responses.

Every number of a model, from the Python API or a model file, follows the one rule of
:func:`stageid.checks.is_real`: a finite real number, never a ``bool`` and never a string
(``"0.5"`` is refused as ``"dt": "0.002"`` is).
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence
from typing import Any

import numpy as np

from .._errors import ModelError
from ..checks import is_real, shown

__all__ = [
    "as_transfer_entries",
    "input_samples",
    "check_same_dt",
    "as_matrix",
    "as_polynomial",
    "as_names",
    "as_dt",
    "as_sample_time",
    "count_channels",
    "frequency_variable",
    "check_response",
]

_NESTED = (list, tuple, np.ndarray)


def _entry(value: object) -> float | None:
    """``value`` as a float by the one rule (complex with a zero imaginary part allowed); None if not."""
    if is_real(value):
        return float(value)
    if _is_complex(value) and value.imag == 0:  # type: ignore[attr-defined]
        return _entry(value.real)  # type: ignore[attr-defined]
    return None


def _is_complex(value: object) -> bool:
    """A complex number that is not real (so never a bool, an int or a float)."""
    return isinstance(value, numbers.Complex) and not isinstance(value, (numbers.Real, np.bool_))


def _numbers(
    name: str, value: object, error: type[ModelError], where: str = "", words: str = "a 2-D array of numbers"
) -> np.ndarray:
    """A nested list (or numpy array) of numbers as a float array, every entry by the one rule."""
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "fiu":
            return np.array(value, dtype=float)
        if value.dtype.kind == "c":
            if np.any(value.imag != 0):
                raise error(
                    f"`{name}` must be a real matrix; got complex entries (a state-space model has real matrices)."
                )
            return np.array(value.real, dtype=float)
        if value.dtype.kind != "O":
            raise error(f"`{name}` must be {words}; got an array of {value.dtype}.")
        value = value.tolist()
    if not isinstance(value, (list, tuple)):
        x = _entry(value)
        if x is None:
            raise error(f"`{name}` must be {words}; got {shown(value)}.")
        return np.array(x)
    if any(isinstance(v, _NESTED) for v in value):
        if not all(isinstance(v, _NESTED) for v in value):
            raise error(f"`{name}` must be {words}; got a ragged or nested list.")
        rows = [_numbers(name, v, error, f"{where}[{i}]", words) for i, v in enumerate(value)]
        shapes = {r.shape for r in rows}
        if len(shapes) > 1:
            raise error(f"`{name}` must be {words}; got rows of different lengths {sorted(shapes)}.")
        return np.array(rows) if rows else np.zeros(0)
    out = np.empty(len(value))
    for k, v in enumerate(value):
        x = _entry(v)
        if x is None:
            if _is_complex(v):
                raise error(
                    f"`{name}` must be a real matrix; got complex entries (a state-space model has real matrices)."
                )
            raise error(f"`{name}` must be {words}; entry {where}[{k}] is {shown(v)}, not a finite real number.")
        out[k] = x
    return out


def as_matrix(
    name: str, value: object, shape: tuple[int | None, int | None], error: type[ModelError] = ModelError
) -> np.ndarray:
    """Return ``value`` as a read-only float matrix of ``shape`` (None = any size).

    Raises ``error`` with a message such as "`B` must have shape (15, 3); got (5, 3)." or
    "`A` must hold finite real numbers only; entry [0][1] is '0.5'."
    """
    if isinstance(value, str) or value is None:
        raise error(f"`{name}` must be a 2-D array of numbers; got {type(value).__name__}.")
    if not isinstance(value, (*_NESTED, numbers.Number)):
        raise error(f"`{name}` must be a 2-D array of numbers; got {type(value).__name__}.")
    arr = _numbers(name, value, error)
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


def as_polynomial(field: str, i: int, j: int, value: object, error: type[ModelError] = ModelError) -> np.ndarray:
    """Coefficients of entry ``[i][j]`` as a read-only, non-empty, finite 1-D float array."""
    name = f"{field}[{i}][{j}]"
    if isinstance(value, str):
        raise error(f"`{name}` must be a list of numbers; got a string.")
    if not isinstance(value, (*_NESTED, numbers.Number)):
        raise error(f"`{name}` must be a list of numbers; got {type(value).__name__}.")
    arr = _numbers(name, value, error, words="a list of numbers")
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1 or arr.size == 0:
        raise error(f"`{name}` must be a non-empty 1-D list of coefficients; got shape {arr.shape}.")
    if not np.all(np.isfinite(arr)):
        raise error(f"`{name}` must contain only finite numbers.")
    arr.setflags(write=False)
    return arr


def _shape2(value: object) -> tuple[int, int] | None:
    """The (rows, columns) of a rectangular 2-D array or nested list, else None (nothing converted)."""
    if isinstance(value, np.ndarray):
        return value.shape if value.ndim == 2 else None  # type: ignore[return-value]
    if isinstance(value, (list, tuple)) and value and all(isinstance(r, _NESTED) for r in value):
        lengths = {len(r) for r in value}
        return (len(value), lengths.pop()) if len(lengths) == 1 else None
    return None


def count_channels(names: Sequence[str] | None, D: object, other: object, axis: int) -> int:
    """Number of inputs (``axis=1``) or outputs (``axis=0``): from the names, else ``D``, else ``B``/``C``."""
    if names is not None and not isinstance(names, str) and len(names) > 0:
        return len(names)
    for matrix in (D, other):
        shape = _shape2(matrix)
        if shape is not None:
            return int(shape[axis])
    return 0


def as_names(
    field: str, names: Sequence[str] | None, count: int, prefix: str, error: type[ModelError] = ModelError
) -> tuple[str, ...]:
    """Validate channel names (default ``prefix1, prefix2, ...``)."""
    if names is None or (not isinstance(names, str) and len(names) == 0):
        return tuple(f"{prefix}{i + 1}" for i in range(count))
    if isinstance(names, str) or not all(isinstance(n, str) for n in names):
        raise error(f"`{field}` must be a list of {count} strings; got {shown(names)}.")
    names = tuple(names)
    if len(names) != count:
        raise error(f"`{field}` must have {count} names; got {len(names)}.")
    if len(set(names)) != len(names):
        raise error(f"`{field}` must not repeat a name; got {shown(list(names))}.")
    return names


#: the smallest time step whose sampling rate 1/dt is a finite float
MIN_DT = 1.0 / np.finfo(float).max


def as_sample_time(value: object, error: type[ModelError] = ModelError, what: str = "`dt` must be") -> float:
    """A time step in seconds: a positive number (one rule) whose sampling rate ``1/dt`` is finite."""
    if not is_real(value) or float(value) <= 0:
        raise error(f"{what} a positive number of seconds; got {shown(value)}.")
    dt = float(value)
    if dt < MIN_DT:
        raise error(
            f"{what} a positive number of seconds with a finite sampling rate 1/dt (dt >= {MIN_DT:.3g} s); "
            f"got {dt!r}, whose sampling rate overflows."
        )
    return dt


def as_dt(value: object, error: type[ModelError] = ModelError) -> float | None:
    """``None`` for continuous time, else a positive float sample time (:func:`as_sample_time`)."""
    if value is None:
        return None
    return as_sample_time(value, error, "`dt` must be null (continuous) or")


def frequency_variable(freqs_hz: object, dt: float | None) -> np.ndarray:
    """Return s = j 2 pi f (continuous) or z = exp(j 2 pi f dt) (discrete)."""
    f = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
    if f.ndim != 1 or not np.all(np.isfinite(f)) or np.any(f < 0):
        raise ModelError("frequencies must be a 1-D array of finite, non-negative values in Hz.")
    w = 2.0 * np.pi * f
    return 1j * w if dt is None else np.exp(1j * w * dt)


def check_response(y: np.ndarray, poles: np.ndarray, dt: float | None) -> np.ndarray:
    """``y`` when finite; else ModelError naming the sample where the simulation diverged and why.

    An unstable model's response grows until it leaves the floating-point range; the message
    says so (and names the unstable pole) instead of leaving inf/NaN for a later check to find.
    """
    finite = np.isfinite(y).all(axis=1) if y.ndim == 2 else np.isfinite(y)
    if finite.all():
        return y
    where = f"the simulation diverged at sample {int(np.argmin(finite))} of {y.shape[0]}"
    size = poles.real if dt is None else np.abs(poles)
    if poles.size and size.max() >= (0.0 if dt is None else 1.0):
        p = poles[np.argmax(size)]
        pole = f"s = {p:.4g} rad/s" if dt is None else f"z = {p:.4g}, |z| = {abs(p):.4g}"
        raise ModelError(f"{where}: the model is unstable (pole at {pole}) and its response overflowed.")
    raise ModelError(
        f"{where}: the response overflowed the floating-point range (input too large for the model's gain)."
    )


def input_samples(u: object, n_inputs: int) -> np.ndarray:
    """``u`` as a float array of shape (n_samples, n_inputs) (1-D is one input)."""
    uu = np.array(u, dtype=float)
    if uu.ndim == 1:
        uu = uu[:, None]
    if uu.ndim != 2 or uu.shape[1] != n_inputs:
        raise ModelError(f"input must have shape (n_samples, {n_inputs}); got {tuple(np.shape(u))}.")
    return uu


def check_same_dt(dt: object, model_dt: float) -> None:
    """ModelError unless ``dt`` is None or equals the model's sample time (the sample-time rule)."""
    from ..data.sampling import PERIOD_RTOL, same_period, seconds  # models do not need data loaded otherwise

    if dt is not None and not same_period(as_sample_time(dt, ModelError), model_dt):
        raise ModelError(
            f"the input's sample time {seconds(dt)} s differs from the model's {seconds(model_dt)} s "
            f"(tolerance {PERIOD_RTOL:g} relative)."
        )


def as_transfer_entries(num: Any, den: Any) -> tuple[tuple, tuple]:
    """``num``/``den`` as [output][input] tuples of checked coefficient arrays (proper, non-zero ``den``)."""
    from .conversions import strip_leading_zeros as _strip

    if isinstance(num, np.ndarray) and num.ndim == 1:
        num = [[num]]
    if isinstance(den, np.ndarray) and den.ndim == 1:
        den = [[den]]
    for field, val in (("num", num), ("den", den)):
        if (
            not isinstance(val, (list, tuple, np.ndarray))
            or len(val) == 0
            or any(not isinstance(row, (list, tuple, np.ndarray)) or len(row) == 0 for row in val)
        ):
            raise ModelError(f"`{field}` must be nested as [output][input][coefficient]; got {type(val).__name__}.")
    p = len(num)
    m = len(num[0])
    for field, val in (("num", num), ("den", den)):
        shape = (len(val), *{len(row) for row in val})
        if len(val) != p or any(len(row) != m for row in val):
            raise ModelError(f"`{field}` must have shape ({p}, {m}) entries ([output][input]); got {shape}.")
    nums = tuple(tuple(as_polynomial("num", i, j, num[i][j]) for j in range(m)) for i in range(p))
    dens = tuple(tuple(as_polynomial("den", i, j, den[i][j]) for j in range(m)) for i in range(p))
    for i in range(p):
        for j in range(m):
            d = _strip(dens[i][j])
            if not np.any(d):
                raise ModelError(f"`den[{i}][{j}]` is zero.")
            n = _strip(nums[i][j])
            if n.size > d.size and np.any(nums[i][j]):
                raise ModelError(
                    f"entry [{i}][{j}] is improper: numerator degree {n.size - 1} exceeds denominator degree {d.size - 1}."
                )
    return nums, dens


def statespace_fields(A: Any, B: Any, C: Any, D: Any, dt: Any, inputs: Any, outputs: Any) -> dict[str, Any]:
    """The checked fields of a state-space model: float matrices whose shapes fit together (the
    channel counts from the names, else ``D``, else ``B`` and ``C``), the sample time and the names."""
    A = as_matrix("A", A, (None, None))
    n = A.shape[0]
    if A.shape[1] != n:
        raise ModelError(f"`A` must be square with shape (n, n); got {A.shape}.")
    m = count_channels(inputs, D, B, axis=1)
    p = count_channels(outputs, D, C, axis=0)
    return {
        "A": A,
        "B": as_matrix("B", B, (n, m)),
        "C": as_matrix("C", C, (p, n)),
        "D": as_matrix("D", D, (p, m)),
        "dt": as_dt(dt),
        "inputs": as_names("inputs", inputs, m, "u"),
        "outputs": as_names("outputs", outputs, p, "y"),
    }


def transfer_fields(num: Any, den: Any, dt: Any, inputs: Any, outputs: Any) -> dict[str, Any]:
    """The checked fields of a transfer matrix (:func:`as_transfer_entries`, the sample time, the names)."""
    nums, dens = as_transfer_entries(num, den)
    p, m = len(nums), len(nums[0])
    return {
        "num": nums,
        "den": dens,
        "dt": as_dt(dt),
        "inputs": as_names("inputs", inputs, m, "u"),
        "outputs": as_names("outputs", outputs, p, "y"),
    }
