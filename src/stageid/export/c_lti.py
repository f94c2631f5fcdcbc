"""C99 code for discrete LTI models: state space and transfer matrices.

State space
    ``y(k) = C x(k) + D u(k)``, ``x(k+1) = A x(k) + B u(k)`` from ``x(0) = 0``, each sum
    evaluated left to right over the columns of ``[C D]`` / ``[A B]`` exactly as the compiled
    recursion of :meth:`stageid.models.StateSpaceModel.simulate` does, with the constants
    written inline and exact zeros left out (adding ``0 * v`` never changes a finite sum), so
    the generated step is straight-line code.

Transfer matrix
    Every entry ``num/den`` is the transposed direct-form-II filter of
    :func:`scipy.signal.lfilter` (coefficients normalised by ``den[0]``, delays updated as
    ``Z[i] = Z[i+1] + u b[i+1] - y a[i+1]``), and each output sums its entries over the inputs in
    order, as :meth:`stageid.models.TransferMatrix.simulate` does.

Single precision: rounding the coefficients to ``float`` moves slow poles visibly unless the
realisation is well conditioned.  A stable, minimal state-space model is therefore exported in
balanced coordinates (equal diagonal Gramians; the state starts at 0 in any basis), and a stable
transfer matrix as a block-diagonal state space of balanced realisations of its entries
(:func:`balanced_blocks`) instead of polynomial filters.  A model without a balanced
realisation (unstable or not minimal) keeps its own form.  Double precision always keeps the
model's own form and order of operations.

Examples
--------
>>> from stageid.models import StateSpaceModel
>>> from stageid.export.c_lti import lti_fields
>>> from stageid.export.c_writer import CType
>>> g = StateSpaceModel([[0.5]], [[1.0]], [[2.0]], [[0.0]], dt=0.1)
>>> print(lti_fields(g, CType("double"))["step_body"])
    const double u0 = in[0];
    const double x0 = s->x[0];
    out[0] = 2.0 * x0;
    s->x[0] = 0.5 * x0 + 1.0 * u0;
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._errors import ModelError
from ..models.conversions import strip_leading_zeros
from .c_writer import CType, literal

__all__ = ["lti_fields", "weighted_sum", "balanced_realisation", "balanced_blocks"]


def weighted_sum(coefficients: object, names: list[str], ctype: CType) -> str:
    """``c0 * v0 + c1 * v1 + ...`` left to right, exact zeros left out (``0.0`` if all are)."""
    terms = [f"{literal(c, ctype)} * {v}" for c, v in zip(np.asarray(coefficients, dtype=float), names) if c != 0.0]
    return " + ".join(terms) if terms else literal(0.0, ctype)


def _statespace(model: Any, ctype: CType) -> dict[str, str]:
    t = ctype.name
    n, m, p = model.n_states, model.n_inputs, model.n_outputs
    u = [f"u{j}" for j in range(m)]
    x = [f"x{i}" for i in range(n)]
    CD = np.hstack([model.C, model.D])
    AB = np.hstack([model.A, model.B])
    used = np.any(CD != 0.0, axis=0) | np.any(AB != 0.0, axis=0)  # an unused local would be a warning
    lines = [f"    const {t} u{j} = in[{j}];" for j in range(m) if used[n + j]]
    lines += [f"    const {t} x{i} = s->x[{i}];" for i in range(n) if used[i]]
    if not used[n:].any():
        lines.append("    (void)in;")
    lines += [f"    out[{i}] = {weighted_sum(CD[i], x + u, ctype)};" for i in range(p)]
    lines += [f"    s->x[{i}] = {weighted_sum(AB[i], x + u, ctype)};" for i in range(n)]
    if n == 0:
        lines.append("    (void)s;")
    return {
        "members": f"    {t} x[{n}];      /* state x(k) */"
        if n
        else "    char unused;  /* a static gain has no state */",
        "init_body": "\n".join([f"    s->x[{i}] = {literal(0.0, ctype)};" for i in range(n)] or ["    (void)s;"]),
        "step_body": "\n".join(lines),
        "init_doc": "to rest (x = 0), where `stageid simulate` starts",
        "summary": f"Discrete state space, {n} states, sample time {model.dt!r} s.",
    }


def _entry(num: object, den: object) -> tuple[np.ndarray, np.ndarray]:
    """Normalised, equal-length b and a of one entry, as lfilter uses them."""
    den = strip_leading_zeros(np.asarray(den, dtype=float).reshape(-1))
    num = strip_leading_zeros(np.asarray(num, dtype=float).reshape(-1))
    if not np.any(den):
        raise ModelError("a transfer entry has an all-zero denominator; cannot export it.")
    num = np.concatenate([np.zeros(max(den.size - num.size, 0)), num])
    size = max(num.size, den.size)
    b = np.concatenate([num, np.zeros(size - num.size)])
    a = np.concatenate([den, np.zeros(size - den.size)])
    return b / a[0], a / a[0]


def _transfer(model: Any, ctype: CType) -> dict[str, str]:
    t = ctype.name
    m, p = model.n_inputs, model.n_outputs
    lines = [f"    const {t} u{j} = in[{j}];" for j in range(m)]
    members, init = [], []
    for i in range(p):
        parts = []
        for j in range(m):
            b, a = _entry(model.num[i][j], model.den[i][j])
            y = f"y{i}_{j}"
            parts.append(y)
            if b.size == 1:
                lines.append(f"    const {t} {y} = u{j} * {literal(b[0], ctype)};")
                continue
            z = f"s->z{i}_{j}"
            members.append(f"    {t} z{i}_{j}[{b.size - 1}];  /* delays of entry ({i}, {j}) */")
            init += [f"    {z}[{k}] = {literal(0.0, ctype)};" for k in range(b.size - 1)]
            lines.append(f"    const {t} {y} = {z}[0] + {literal(b[0], ctype)} * u{j};")
            for k in range(1, b.size):
                head = f"{z}[{k}]" if k < b.size - 1 else ""
                terms = [head] if head else []
                if b[k] != 0.0:
                    terms.append(f"u{j} * {literal(b[k], ctype)}")
                expr = " + ".join(terms) if terms else literal(0.0, ctype)
                if a[k] != 0.0:
                    expr = f"{expr} - {y} * {literal(a[k], ctype)}"
                lines.append(f"    {z}[{k - 1}] = {expr};")
        lines.append(f"    out[{i}] = {' + '.join(parts)};")
    return {
        "members": "\n".join(members) or "    char unused;  /* static gains have no state */",
        "init_body": "\n".join(init or ["    (void)s;"]),
        "step_body": "\n".join(lines + ([] if members else ["    (void)s;"])),
        "init_doc": "to rest (all delays 0), where `stageid simulate` starts",
        "summary": f"Discrete transfer matrix (one direct-form-II-transposed filter per entry), sample time {model.dt!r} s.",
    }


def balanced_realisation(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, ...] | None:
    """Balanced realisation (equal, diagonal Gramians) of a stable minimal (A, B, C), else None."""
    from scipy.linalg import solve_discrete_lyapunov

    if A.shape[0] == 0 or np.max(np.abs(np.linalg.eigvals(A))) >= 1.0:
        return None
    Wc = solve_discrete_lyapunov(A, B @ B.T)
    Wo = solve_discrete_lyapunov(A.T, C.T @ C)
    lc, Vc = np.linalg.eigh((Wc + Wc.T) / 2)
    if lc.min() <= 1e-12 * lc.max():
        return None
    Lc = Vc * np.sqrt(lc)
    U, hsv, _ = np.linalg.svd(Lc.T @ Wo @ Lc)
    if hsv.min() <= 1e-24 * hsv.max():
        return None
    T = Lc @ U / hsv**0.25
    Ti = np.linalg.inv(T)
    return Ti @ A @ T, Ti @ B, C @ T


def balanced_blocks(model: Any) -> Any | None:
    """A discrete transfer matrix as one state space with a balanced block per entry, or None
    when an entry has no balanced realisation (the single-precision form, see module notes)."""
    from ..models import StateSpaceModel

    p, m = model.n_outputs, model.n_inputs
    blocks, D = [], np.zeros((p, m))
    for i in range(p):
        for j in range(m):
            g = model.entry(i, j).to_statespace(minimal=True)
            D[i, j] = g.D[0, 0]
            if g.n_states == 0:
                continue
            bal = balanced_realisation(g.A, g.B, g.C)
            if bal is None:
                return None
            blocks.append((i, j, *bal))
    n = sum(b[2].shape[0] for b in blocks)
    A, B, C = np.zeros((n, n)), np.zeros((n, m)), np.zeros((p, n))
    k = 0
    for i, j, Ab, Bb, Cb in blocks:
        q = Ab.shape[0]
        A[k : k + q, k : k + q], B[k : k + q, j], C[i, k : k + q] = Ab, Bb[:, 0], Cb[0]
        k += q
    return StateSpaceModel(A, B, C, D, dt=model.dt, inputs=model.inputs, outputs=model.outputs)


def lti_fields(model: Any, ctype: CType) -> dict[str, str]:
    """Template fields of a discrete :class:`~stageid.models.StateSpaceModel` or
    :class:`~stageid.models.TransferMatrix` (see :mod:`stageid.export.c_writer`)."""
    from ..models import StateSpaceModel, TransferMatrix

    if model.dt is None:
        raise ModelError("a continuous model cannot be exported as it is; discretise it first (c2d).")
    if isinstance(model, StateSpaceModel):
        balanced = balanced_realisation(model.A, model.B, model.C) if ctype.is_float else None
        if balanced is not None:
            model = StateSpaceModel(*balanced, model.D, dt=model.dt, inputs=model.inputs, outputs=model.outputs)
        fields = _statespace(model, ctype)
        if balanced is not None:
            fields["summary"] = (
                f"Discrete state space in balanced coordinates, {model.n_states} states, sample time {model.dt!r} s."
            )
        title = "discrete state space"
    elif isinstance(model, TransferMatrix):
        blocks = balanced_blocks(model) if ctype.is_float else None
        if blocks is not None:
            fields = _statespace(blocks, ctype)
            fields["summary"] = (
                f"Discrete transfer matrix as balanced state-space blocks per entry, sample time {model.dt!r} s."
            )
        else:
            fields = _transfer(model, ctype)
        title = "discrete transfer matrix"
    else:
        raise ModelError(f"expected a StateSpaceModel or TransferMatrix; got {type(model).__name__}.")
    return {
        **fields,
        "title": title,
        "n_inputs": str(model.n_inputs),
        "n_outputs": str(model.n_outputs),
        "input_names": ", ".join(model.inputs),
        "output_names": ", ".join(model.outputs),
    }
