"""Discrete Preisach model with a continuous density: uniform weight cells on a triangular grid.

``y(k) = y0 + integral over beta <= alpha of mu(alpha, beta) R_{alpha beta}[u](k)`` with relays
``R`` in {0, 1} (up when ``u >= alpha``, down when ``u < beta``; Mayergoyz, *Mathematical Models
of Hysteresis*, ch. 1).  The square ``[lo, hi]^2`` is cut into ``n_levels`` cells per axis of
side ``h = (hi - lo) / n_levels``; below the diagonal, cell ``(i, j)`` spreads its weight
``w_ij`` uniformly over the square ``[v_i, v_i + h] x [v_j, v_j + h]`` (``v_i = lo + i h``), and
the diagonal cell ``i`` spreads ``w_ii`` along the segment ``alpha = beta`` (the reversible
part).  Weights are stored row by row (``alpha`` ascending, ``beta`` ascending within a row),
``n_levels (n_levels + 1) / 2`` of them, and enter the output linearly.

With this density the Everett function ``E(alpha, beta)`` (weight of the triangle ``beta <= b
<= a <= alpha``) is the bilinear interpolation of its values at the grid nodes, the output is
continuous and piecewise linear in the input between nodes and memory points, and a sample
costs O(1) (:mod:`stageid.hysteresis.kernels.preisach`).  A point relay per cell (the earlier form of this model)
made a staircase whose steps of about ``range / (2 n_levels)`` bounded the modelling error.

The state is the memory: the dominant reversal points the wiping-out property keeps, then the
current input (:meth:`PreisachModel.run`); ``None`` is every relay down with the input at
``lo``.  Inputs outside ``[lo, hi]`` act as the nearest end (no relay lies outside).

JSON (``stageid.hysteresis/1``)::

    {"format": "stageid.hysteresis/1", "kind": "preisach", "density": "cells", "inputs": ["V"],
     "outputs": ["y"], "input_range": [lo, hi], "n_levels": n, "weights": [...],
     "output_offset": 0.0, "state": [p1, ..., pm, u] | null, "input_limits": [lo, hi] | null}
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..._errors import ModelError, ModelFormatError
from ...checks import shown
from ...display import html_repr, short_repr
from .common import as_input
from .pi import HYSTERESIS_FORMAT

__all__ = ["PreisachModel", "PREISACH_KIND", "everett", "everett_output", "everett_nodes", "demagnetizing_input"]

PREISACH_KIND = "preisach"
#: The ``density`` field of the JSON: uniform cells (files without it held point relays).
DENSITY = "cells"
#: Step of the alternating input that stands for "demagnetised", in cells: the memory curve is
#: a staircase of this step around the line ``alpha + beta = 2 centre``.
DEMAG_STEP = 1.0 / 8.0


def everett_nodes(weights: np.ndarray, n: int) -> np.ndarray:
    """``En[A, B] = E(v_A, v_B)`` at the grid nodes, shape (n + 1, n + 1) (zero where A <= B)."""
    W = np.zeros((n, n))
    W[np.tril_indices(n)] = weights
    R = np.zeros((n, n + 1))  # R[i, B]: weight of row i in the columns j >= B
    R[:, :n] = np.cumsum(W[:, ::-1], axis=1)[:, ::-1]
    Q = np.zeros((n + 1, n + 1))  # Q[A, B]: rows i < A
    Q[1:] = np.cumsum(R, axis=0)
    En = Q - np.diag(Q)[None, :]
    return np.ascontiguousarray(np.tril(En, -1))


def demagnetizing_input(lo: float, hi: float, n_levels: int, centre: float) -> np.ndarray:
    """Alternating input of decaying amplitude that leaves the plane demagnetised about ``centre``.

    Maxima ``centre + a_k`` and minima ``centre - a_k + step / 2`` with ``a_k`` falling by
    ``step`` = ``DEMAG_STEP`` cells: the memory corners straddle ``alpha + beta = 2 centre`` so
    the staircase leaves as much weight above that line as below it.  Ends at ``centre``.
    """
    step = DEMAG_STEP * (hi - lo) / n_levels
    a = np.arange(max(hi - centre, centre - lo), step, -step)
    seq = np.empty(2 * a.size + 1)
    seq[0:-1:2] = centre + a
    seq[1:-1:2] = centre - a + step / 2
    seq[-1] = centre
    return np.clip(seq, lo, hi)


@dataclass(frozen=True, eq=False)
class PreisachModel:
    """Discrete Preisach model with a uniform density in each cell of a triangular grid.

    Parameters
    ----------
    input_range : (float, float)
        ``(lo, hi)`` covered by the grid.
    weights : array_like of shape (n_levels (n_levels + 1) / 2,)
        Cell weights, row by row (``alpha`` ascending, ``beta <= alpha`` ascending).
    output_offset : float
        ``y0``, the output with every relay down.
    state : array_like of float, optional
        Memory: the reversal points (maxima and minima alternating, first a maximum, each
        inside the interval of the two before) and last the current input; default every
        relay down at input ``lo``.

    Examples
    --------
    >>> import numpy as np
    >>> m = PreisachModel((0.0, 2.0), [0.0, 1.0, 0.0])  # one cell: alpha in [1, 2], beta in [0, 1]
    >>> m.simulate(np.array([0.0, 1.0, 1.5, 2.0, 1.0, 0.5, 0.0]))[:, 0].tolist()
    [0.0, 0.0, 0.5, 1.0, 1.0, 0.5, 0.0]
    """

    input_range: tuple[float, float]
    weights: np.ndarray
    output_offset: float = 0.0
    state: np.ndarray | None = None
    inputs: tuple[str, ...] = ("V",)
    outputs: tuple[str, ...] = ("y",)
    input_limits: tuple[float, float] | None = None

    kind = PREISACH_KIND

    def __repr__(self) -> str:
        return short_repr(self)

    def _repr_html_(self) -> str:
        return html_repr(self)

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
            set_(self, "state", checked_memory(self.state, lo, hi))
        if self.input_limits is not None:
            set_(self, "input_limits", (float(self.input_limits[0]), float(self.input_limits[1])))
        En = everett_nodes(w, n)
        wd = np.ascontiguousarray(w[np.arange(n) * (np.arange(n) + 3) // 2])
        En.setflags(write=False)
        wd.setflags(write=False)
        set_(self, "everett_table", (En, wd))  # not a field: derived from the weights

    @property
    def n_levels(self) -> int:
        return int(round((np.sqrt(8 * self.weights.size + 1) - 1) / 2))

    @property
    def n_operators(self) -> int:
        """Number of cells (for code that reports model sizes)."""
        return int(self.weights.size)

    @property
    def step(self) -> float:
        """Cell side ``h``."""
        return (self.input_range[1] - self.input_range[0]) / self.n_levels

    @property
    def nodes(self) -> np.ndarray:
        """Grid nodes ``lo + i h``, shape (n_levels + 1,)."""
        return self.input_range[0] + self.step * np.arange(self.n_levels + 1)

    def weight_matrix(self) -> np.ndarray:
        """Weights as a lower-triangular matrix ``W[i, j]`` (``alpha`` cell i, ``beta`` cell j)."""
        n = self.n_levels
        W = np.zeros((n, n))
        W[np.tril_indices(n)] = self.weights
        return W

    def memory_arrays(self, extra: int) -> tuple[np.ndarray, np.ndarray, int, float]:
        """``(P, cum, top, cur)`` of the kernels for the stored state, room for ``extra`` samples."""
        from ..kernels.preisach import memory_cum

        mem = np.empty(0) if self.state is None else self.state
        top = max(mem.size - 1, 0)
        P = np.empty(top + extra + 3)
        cum = np.zeros_like(P)
        P[0] = self.input_range[0]
        P[1 : top + 1] = mem[:top]
        En, wd = self.everett_table
        memory_cum(En, wd, self.input_range[0], self.step, P, cum, top)
        cur = float(mem[-1]) if mem.size else P[0]
        return P, cum, top, cur

    def with_state(self, state: Any) -> PreisachModel:
        return replace(self, state=state)

    def consistent_state(self, u0: float, kind: str = "zero") -> np.ndarray:
        """Memory at input ``u0``: ``"zero"`` demagnetised about ``u0``, ``"ascending"`` risen
        to it from every relay down, ``"descending"`` fallen to it from every relay up."""
        lo, hi = self.input_range
        x = min(max(float(u0), lo), hi)
        if kind == "ascending":
            return np.array([x])
        if kind == "descending":
            return np.array([hi, x]) if x < hi else np.array([x])
        if kind != "zero":
            raise ModelError(f"state kind must be 'zero', 'ascending' or 'descending'; got {kind!r}.")
        return replace(self, state=None).run(demagnetizing_input(lo, hi, self.n_levels, x))[1]

    def run(self, u: object, dt: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Outputs, shape (n_samples,), and the final memory (the next run's ``state``)."""
        from ..kernels.preisach import preisach_run

        # writeable too: numba types a read-only array apart, and would compile the kernel again for it
        x = np.require(as_input(u, "u"), np.float64, ["C", "W"])
        P, cum, top, cur = self.memory_arrays(x.size)
        En, wd = self.everett_table
        y, top, cur = preisach_run(x, En, wd, self.input_range[0], self.step, P, cum, top, cur)
        return y + self.output_offset, np.r_[P[1 : top + 1], cur]

    def simulate(self, u: object, dt: float | None = None) -> np.ndarray:
        """Output, shape (n_samples, 1) (rate independent: ``dt`` is ignored)."""
        return self.run(u, dt)[0][:, None]

    def __call__(self, u: object) -> np.ndarray:
        return self.run(u)[0]

    def to_dict(self) -> dict:
        return {
            "format": HYSTERESIS_FORMAT,
            "kind": PREISACH_KIND,
            "density": DENSITY,
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

        keys = {"format", "kind", "density", "inputs", "outputs", "input_range", "n_levels", "weights"}
        keys |= {"output_offset", "state", "input_limits"}
        unknown = set(d) - keys
        if unknown:
            raise ModelFormatError(f"unknown field(s) {', '.join(sorted(map(str, unknown)))} in a preisach model.")
        if d.get("density") != DENSITY:
            raise ModelFormatError(
                f"`density` of a preisach model must be {DENSITY!r}; got {shown(d.get('density'))} "
                "(files without it hold the point-relay model of before: identify again)."
            )
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
                None if state is None else numbers(state, "state"),
                tuple(d.get("inputs", ["V"])),
                tuple(d.get("outputs", ["y"])),
                None if limits is None else tuple(numbers(limits, "input_limits")),
            )
        except ModelError as exc:
            raise ModelFormatError(str(exc)) from None


def checked_memory(state: Any, lo: float, hi: float) -> np.ndarray:
    """A memory as a read-only float array; ModelError unless its reversal points nest.

    With ``p0 = lo``, point ``k`` must lie between points ``k - 2`` and ``k - 1`` (maxima
    decreasing, minima increasing) and the current input between the last two.
    """
    m = np.array(state, dtype=float).reshape(-1)
    if m.size == 0:
        m = np.array([lo])
    seq = np.r_[lo, m]
    ok = bool(np.all(np.isfinite(m)) and np.all((m >= lo) & (m <= hi)))
    for k in range(1, seq.size - 1):
        rising = k % 2 == 1
        ok = ok and (seq[k] >= seq[k - 1] if rising else seq[k] <= seq[k - 1])
        if k >= 2:
            ok = ok and (seq[k] <= seq[k - 2] if rising else seq[k] >= seq[k - 2])
    k = seq.size - 1  # the current input: on the segment from the last reversal point
    if k >= 1:
        lower, upper = sorted((seq[k - 1], seq[k - 2] if k >= 2 else (hi if k % 2 == 1 else lo)))
        ok = ok and lower <= seq[k] <= upper
    if not ok:
        raise ModelError(
            f"`state` of a Preisach model must be nested reversal points and the input in [{lo:g}, {hi:g}]; "
            f"got {shown(state)}."
        )
    m.setflags(write=False)
    return m


def everett(model: PreisachModel, alpha: float, beta: float) -> float:
    """Everett function ``E(alpha, beta)``: weight of the triangle ``beta <= b <= a <= alpha``
    (both clamped to the grid; zero when ``alpha <= beta``)."""
    from ..kernels.preisach import everett_at

    lo, hi = model.input_range
    En, wd = model.everett_table
    a, b = min(max(float(alpha), lo), hi), min(max(float(beta), lo), hi)
    return float(everett_at(En, wd, lo, model.step, a, b))


def everett_output(model: PreisachModel, u: object) -> np.ndarray:
    """Output from every relay down as sums of Everett differences over the memory (plain Python).

    ``y = y0 + E(M1, lo) - E(M1, m1) + E(M2, m1) - ...`` over the dominant extrema that the
    wiping-out property keeps (Mayergoyz eq. 1.52); the current input ends the sum.
    """
    lo, hi = model.input_range
    x = np.clip(as_input(u, "u"), lo, hi)
    stack = [lo]  # reversal points, alternately min (even index) and max
    prev, rising = lo, True
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
