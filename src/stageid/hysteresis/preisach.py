"""Discrete Preisach model: weighted relay hysterons on a triangular grid of thresholds.

``y(k) = y0 + sum_{i >= j} w_ij R_ij[u](k)`` with relays ``R_ij`` in {0, 1} that switch up
when ``u >= alpha_i`` and down when ``u < beta_j``; ``alpha_i = beta_i = lo + (i + 1/2) h``,
``h = (hi - lo) / n_levels`` (Mayergoyz, *Mathematical Models of Hysteresis*, ch. 1).  The
diagonal relays (``alpha = beta``) carry the reversible part.  Weights are stored row by row
(``alpha`` ascending, ``beta`` ascending within a row): ``n_levels (n_levels + 1) / 2`` of them.

The state is the staircase ``counts`` (the up relays of row ``i`` are its first ``counts[i]``),
the discrete form of the memory curve; :func:`everett` and :func:`everett_output` give the
same output as sums of Everett differences over the dominant extrema (eq. 1.52 of Mayergoyz).

JSON (``stageid.hysteresis/1``)::

    {"format": "stageid.hysteresis/1", "kind": "preisach", "inputs": ["V"], "outputs": ["y"],
     "input_range": [lo, hi], "n_levels": n, "weights": [...], "output_offset": 0.0,
     "state": [counts...] | null, "input_limits": [lo, hi] | null}
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .._errors import ModelError, ModelFormatError
from ..checks import shown
from .common import as_input
from .pi import HYSTERESIS_FORMAT

__all__ = ["PreisachModel", "PREISACH_KIND", "grid_levels", "everett", "everett_output", "demagnetized_counts"]

PREISACH_KIND = "preisach"


def grid_levels(lo: float, hi: float, n_levels: int) -> np.ndarray:
    """The thresholds ``lo + (i + 1/2) h``, ``h = (hi - lo) / n_levels`` (one rounding for all users)."""
    h = (hi - lo) / n_levels
    return lo + (np.arange(n_levels) + 0.5) * h


def demagnetized_counts(levels: np.ndarray, centre: float) -> np.ndarray:
    """Staircase of the state demagnetised about ``centre``: relay up iff ``alpha + beta < 2 centre``."""
    n = len(levels)
    return np.array([int(np.sum(levels[: i + 1] < 2.0 * centre - levels[i])) for i in range(n)], dtype=np.int64)


@dataclass(frozen=True, eq=False)
class PreisachModel:
    """Discrete Preisach model (relays on a triangular threshold grid).

    Parameters
    ----------
    input_range : (float, float)
        ``(lo, hi)`` covered by the threshold grid.
    weights : array_like of shape (n_levels (n_levels + 1) / 2,)
        Relay weights, row by row (``alpha`` ascending, ``beta <= alpha`` ascending).
    output_offset : float
        ``y0``, the output with every relay down.
    state : array_like of int, shape (n_levels,), optional
        Staircase counts to start from; default all relays down.

    Examples
    --------
    >>> import numpy as np
    >>> m = PreisachModel((0.0, 2.0), [0.0, 1.0, 0.0])  # levels 0.5, 1.5; one relay (1.5, 0.5)
    >>> m.simulate(np.array([0.0, 1.0, 2.0, 1.0, 0.0]))[:, 0].tolist()
    [0.0, 0.0, 1.0, 1.0, 0.0]
    """

    input_range: tuple[float, float]
    weights: np.ndarray
    output_offset: float = 0.0
    state: np.ndarray | None = None
    inputs: tuple[str, ...] = ("V",)
    outputs: tuple[str, ...] = ("y",)
    input_limits: tuple[float, float] | None = None

    kind = PREISACH_KIND

    def __post_init__(self) -> None:
        lo, hi = (float(v) for v in self.input_range)
        if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise ModelError(f"`input_range` must be finite with low < high; got {shown(self.input_range)}.")
        w = np.array(self.weights, dtype=float, copy=True).reshape(-1)
        n = int(round((np.sqrt(8 * w.size + 1) - 1) / 2))
        if n < 1 or n * (n + 1) // 2 != w.size or not np.all(np.isfinite(w)):
            raise ModelError(f"`weights` must be n(n+1)/2 finite numbers (a triangle); got {w.size}.")
        w.setflags(write=False)
        set_ = object.__setattr__
        set_(self, "input_range", (lo, hi))
        set_(self, "weights", w)
        set_(self, "output_offset", float(self.output_offset))
        if self.state is not None:
            c = np.array(self.state, dtype=np.int64).reshape(-1)
            if c.size != n or np.any(c < 0) or np.any(c > np.arange(1, n + 1)):
                raise ModelError(f"`state` must hold {n} counts with 0 <= counts[i] <= i + 1; got {shown(self.state)}.")
            c.setflags(write=False)
            set_(self, "state", c)
        if self.input_limits is not None:
            set_(self, "input_limits", (float(self.input_limits[0]), float(self.input_limits[1])))

    @property
    def n_levels(self) -> int:
        return int(round((np.sqrt(8 * self.weights.size + 1) - 1) / 2))

    @property
    def n_operators(self) -> int:
        """Number of relays (for code that reports model sizes)."""
        return int(self.weights.size)

    @property
    def levels(self) -> np.ndarray:
        """Thresholds ``lo + (i + 1/2) h``, shape (n_levels,)."""
        return grid_levels(*self.input_range, self.n_levels)

    def weight_matrix(self) -> np.ndarray:
        """Weights as a lower-triangular matrix ``W[i, j]`` (``alpha_i``, ``beta_j``); zero above."""
        n = self.n_levels
        W = np.zeros((n, n))
        W[np.tril_indices(n)] = self.weights
        return W

    def initial_counts(self) -> np.ndarray:
        return np.zeros(self.n_levels, dtype=np.int64) if self.state is None else self.state.copy()

    def with_state(self, state: Any) -> PreisachModel:
        return replace(self, state=state)

    def consistent_state(self, u0: float, kind: str = "zero") -> np.ndarray:
        """Staircase demagnetised about ``u0`` (``kind="zero"``), then driven to ``u0``."""
        if kind != "zero":
            raise ModelError(f"state kind of a Preisach model must be 'zero'; got {kind!r}.")
        from .kernels.preisach import preisach_counts

        c = demagnetized_counts(self.levels, float(u0))
        return preisach_counts(np.array([float(u0)]), self.levels, c)[-1]

    def run(self, u: object, dt: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Outputs, shape (n_samples,), and the final staircase."""
        from .kernels.preisach import preisach_run

        x = as_input(u, "u")
        W = self.weight_matrix()
        cumw = np.zeros((self.n_levels, self.n_levels + 1))
        cumw[:, 1:] = np.cumsum(W, axis=1)
        y, counts = preisach_run(x, self.levels, cumw, self.initial_counts())
        return y + self.output_offset, counts

    def simulate(self, u: object, dt: float | None = None) -> np.ndarray:
        """Output, shape (n_samples, 1) (rate independent: ``dt`` is ignored)."""
        return self.run(u, dt)[0][:, None]

    def __call__(self, u: object) -> np.ndarray:
        return self.run(u)[0]

    def to_dict(self) -> dict:
        return {
            "format": HYSTERESIS_FORMAT,
            "kind": PREISACH_KIND,
            "inputs": list(self.inputs),
            "outputs": list(self.outputs),
            "input_range": list(self.input_range),
            "n_levels": self.n_levels,
            "weights": self.weights.tolist(),
            "output_offset": self.output_offset,
            "state": None if self.state is None else self.state.tolist(),
            "input_limits": None if self.input_limits is None else list(self.input_limits),
        }

    @classmethod
    def from_dict(cls, d: dict) -> PreisachModel:
        """Build from the ``stageid.hysteresis/1`` dict of kind ``"preisach"`` (entry point)."""
        from .serialization import number, numbers

        keys = {"format", "kind", "inputs", "outputs", "input_range", "n_levels", "weights"}
        keys |= {"output_offset", "state", "input_limits"}
        unknown = set(d) - keys
        if unknown:
            raise ModelFormatError(f"unknown field(s) {', '.join(sorted(map(str, unknown)))} in a preisach model.")
        for key in ("input_range", "n_levels", "weights"):
            if key not in d:
                raise ModelFormatError(f"`{key}` is missing from the preisach model.")
        rng = numbers(d["input_range"], "input_range")
        w = numbers(d["weights"], "weights")
        n = d["n_levels"]
        if len(rng) != 2 or not isinstance(n, int) or isinstance(n, bool) or n * (n + 1) // 2 != len(w):
            raise ModelFormatError(f"`n_levels` {shown(n)} must match {len(w)} weights and a [lo, hi] range.")
        state = d.get("state")
        limits = d.get("input_limits")
        try:
            return cls(
                (rng[0], rng[1]),
                w,
                number(d.get("output_offset", 0.0), "output_offset"),
                None if state is None else [int(v) for v in numbers(state, "state")],
                tuple(d.get("inputs", ["V"])),
                tuple(d.get("outputs", ["y"])),
                None if limits is None else tuple(numbers(limits, "input_limits")),
            )
        except ModelError as exc:
            raise ModelFormatError(str(exc)) from None


def everett(model: PreisachModel, alpha: float, beta: float) -> float:
    """Everett function ``E(alpha, beta)``: weight of the relays with ``alpha_i <= alpha`` and
    ``beta_j > beta`` (the triangle the input sweeps from ``beta`` up to ``alpha``)."""
    v = model.levels
    W = model.weight_matrix()
    return float(W[np.ix_(v <= alpha, v > beta)].sum())


def everett_output(model: PreisachModel, u: object) -> np.ndarray:
    """Output from the all-down state as sums of Everett differences over the memory staircase.

    ``y = y0 + E(M1, -inf) - E(M1, m1) + E(M2, m1) - ... `` over the dominant extrema that
    the wiping-out property keeps (Mayergoyz eq. 1.52); the current input ends the sum.
    """
    x = as_input(u, "u")
    stack = [-np.inf]  # reversal points, alternately min (even index) and max
    prev, rising = -np.inf, True
    out = np.empty(len(x))
    for k, xk in enumerate(x):
        if xk != prev and (xk > prev) != rising:
            stack.append(prev)
            rising = not rising
        while len(stack) >= 3 and (xk >= stack[-2] if rising else xk <= stack[-2]):
            del stack[-2:]
        prev = xk
        points = [*stack, xk]
        s = 0.0
        for p, q in zip(points[:-1], points[1:]):
            s += everett(model, q, p) if q > p else -everett(model, p, q)
        out[k] = model.output_offset + s
    return out
