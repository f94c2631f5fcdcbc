"""One rule for each kind of setting: numbers, integers, choices, frequency bands, seeds.

Every public function and estimator of stageid checks its settings with these helpers, so the
rules and the messages are the same everywhere.  A message names the setting and its owner,
says what was expected and what came::

    `horizon` of HankelMAP must be an integer >= 1; got -3.

Each helper takes the exception class to raise (``error``), so a signal generator raises
:class:`~stageid.SignalError` and an estimator :class:`~stageid.ParameterError` with the same
text.  Numbers are Python or numpy reals, never ``bool`` and never strings: ``"0.002"`` is
refused everywhere, as ``True`` is.

Frequencies to evaluate a response at (``check_freqs``) are finite, ``>= 0`` and at most the
Nyquist frequency.  A frequency band is one rule: ``(f_low, f_high)`` in Hz with ``0 <= f_low < f_high`` finite,
and ``f_high`` at most the Nyquist frequency when the sample time is known.  A method that
needs a positive lower edge (a logarithmic grid) starts its grid at its first positive point.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from typing import Any

import numpy as np

from ._errors import DataError, ParameterError

__all__ = [
    "is_real",
    "is_integer",
    "is_positive_sequence",
    "in_interval",
    "check_real",
    "check_integer",
    "check_choice",
    "check_band",
    "check_freqs",
    "check_seed",
    "describe_interval",
    "shown",
]


def is_real(value: Any) -> bool:
    """True for a finite real number (Python or numpy), never for ``bool`` or a string."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        return False
    try:
        return math.isfinite(float(value))
    except OverflowError:  # an int beyond the float range
        return False


def is_integer(value: Any) -> bool:
    """True for a Python or numpy integer, never for ``bool``."""
    return isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))


def is_positive_sequence(value: Any) -> bool:
    """True for a non-empty 1-D list, tuple or array of finite numbers > 0 (time constants, ...)."""
    if not isinstance(value, (tuple, list, np.ndarray)) or np.ndim(value) != 1 or len(value) == 0:
        return False
    return all(is_real(v) and v > 0 for v in value)


def describe_interval(low: float | None, high: float | None, closed: str = "both", integer: bool = False) -> str:
    """The words of an interval in the messages: "a number in (0, 1]", "an integer >= 2"."""
    kind = "an integer" if integer else "a number"
    left = closed in ("both", "left")
    right = closed in ("both", "right")
    if low is not None and high is not None:
        return f"{kind} in {'[' if left else '('}{low:g}, {high:g}{']' if right else ')'}"
    if low is not None:
        return f"{kind} {'>=' if left else '>'} {low:g}"
    if high is not None:
        return f"{kind} {'<=' if right else '<'} {high:g}"
    return "an integer" if integer else "a finite number"


def in_interval(v: float, low: float | None, high: float | None, closed: str = "both") -> bool:
    """True when ``v`` lies between ``low`` and ``high`` (``None``: open; ends per ``closed``)."""
    left = closed in ("both", "left")
    right = closed in ("both", "right")
    if low is not None and (v < low or (v == low and not left)):
        return False
    return not (high is not None and (v > high or (v == high and not right)))


def shown(value: Any, limit: int = 80) -> str:
    """``repr(value)`` for a one-line message, cut short when long.

    A 5000-digit integer has no ``repr`` at all in Python >= 3.11 (``ValueError``), and a
    huge list would flood the line.
    """
    try:
        text = repr(value)
    except ValueError:
        return f"an integer of about {int(value.bit_length() * 0.30103) + 1} digits"
    if len(text) > limit:
        text = text[: limit - 20] + f"... ({type(value).__name__} of {len(text)} characters)"
    return " ".join(text.split())


def _fail(error: type[Exception], param: str, owner: str, expected: str, value: Any) -> Exception:
    where = f" of {owner}" if owner else ""
    return error(f"`{param}`{where} must be {expected}; got {shown(value)}.")


def check_real(
    value: Any,
    param: str,
    owner: str = "",
    *,
    low: float | None = None,
    high: float | None = None,
    closed: str = "both",
    error: type[Exception] = ParameterError,
) -> float:
    """``value`` as a finite float inside ``[low, high]`` (ends per ``closed``), else ``error``."""
    if not is_real(value) or not in_interval(float(value), low, high, closed):
        raise _fail(error, param, owner, describe_interval(low, high, closed), value)
    return float(value)


def check_integer(
    value: Any,
    param: str,
    owner: str = "",
    *,
    low: int | None = None,
    high: int | None = None,
    error: type[Exception] = ParameterError,
) -> int:
    """``value`` as an int inside ``[low, high]``, else ``error`` (``bool`` is not an integer)."""
    if not is_integer(value) or not in_interval(int(value), low, high, "both"):
        raise _fail(error, param, owner, describe_interval(low, high, "both", integer=True), value)
    return int(value)


def check_choice(
    value: Any, param: str, owner: str, choices: Sequence[str], *, error: type[Exception] = ParameterError
) -> str:
    """``value`` if it is one of the strings ``choices``, else ``error`` listing them."""
    if not isinstance(value, str) or value not in choices:
        raise _fail(error, param, owner, "one of " + ", ".join(repr(c) for c in choices), value)
    return value


def check_band(
    band: Any,
    param: str = "band",
    owner: str = "",
    *,
    nyquist: float | None = None,
    error: type[Exception] = ParameterError,
) -> tuple[float, float]:
    """``(f_low, f_high)`` in Hz with ``0 <= f_low < f_high`` finite (``<= nyquist`` if given)."""
    expected = "(f_low, f_high) in Hz with 0 <= f_low < f_high finite"
    if nyquist is not None:
        expected += f" and f_high <= the Nyquist frequency {nyquist:g} Hz"
    try:
        pair = list(band) if isinstance(band, (tuple, list, np.ndarray)) else None
    except TypeError:
        pair = None
    if pair is None or len(pair) != 2 or not all(is_real(v) for v in pair):
        raise _fail(error, param, owner, expected, band)
    lo, hi = float(pair[0]), float(pair[1])
    if not 0.0 <= lo < hi or (nyquist is not None and hi > nyquist * (1 + 1e-12)):
        raise _fail(error, param, owner, expected, _Hz(lo, hi))
    return lo, hi


class _Hz:
    """A numeric band as messages show it: ``20-3000 Hz``."""

    def __init__(self, lo: float, hi: float) -> None:
        self.lo, self.hi = lo, hi

    def __repr__(self) -> str:
        return f"{self.lo:g}-{self.hi:g} Hz"


def check_freqs(freqs_hz: object, dt: float) -> np.ndarray:
    """Frequencies in Hz as a finite 1-D array within ``[0, 1 / (2 dt)]`` (DataError otherwise)."""
    try:
        f = np.asarray(freqs_hz, dtype=float)
    except (TypeError, ValueError):
        raise DataError(
            f"`freqs_hz` must be a 1-D array of frequencies in Hz; got {type(freqs_hz).__name__}."
        ) from None
    if f.ndim != 1 or f.size == 0:
        raise DataError(f"`freqs_hz` must be a non-empty 1-D array of frequencies in Hz; got shape {f.shape}.")
    nyq = 0.5 / dt
    bad = ~np.isfinite(f) | (f < 0) | (f > nyq * (1 + 1e-12))
    if bad.any():
        raise DataError(f"`freqs_hz` must be finite and within 0-{nyq:g} Hz (Nyquist); got {float(f[bad][0])!r}.")
    return f


def check_seed(
    seed: Any,
    param: str = "seed",
    owner: str = "",
    *,
    allow_generator: bool = True,
    allow_none: bool = True,
    error: type[Exception] = ParameterError,
) -> Any:
    """``None``, a ``numpy.random.Generator`` or an integer >= 0 (as allowed), else ``error``."""
    if (seed is None and allow_none) or (allow_generator and isinstance(seed, np.random.Generator)):
        return seed
    if is_integer(seed) and seed >= 0:
        return int(seed)
    expected = "an integer >= 0" + (" or a numpy Generator" if allow_generator else "")
    raise _fail(error, param, owner, expected, seed)
