"""Output-error refinement of a realised model on the records (simulated output, time domain).

The realisation (eq. 10-15 or the frequency route) fits the response of the eq. 9 model, whose
horizon ``p`` truncates the past: a lightly damped mode that rings longer than ``p`` samples is
placed where the truncated model puts it, and on a short record a shift of such a pole by
1e-4 of its frequency is a few per cent of the peak.  The records themselves say where the pole
is: this step minimises the noise-weighted simulated output error from rest,

    ``sum_records sum_t || W (y_t - C x_t - D u_t) ||^2``,  ``x_{t+1} = A x_t + B u_t``,  ``x_0 = 0``,

over the model's poles and ``B``, ``C`` (``D`` with feedthrough), from the realised model, as
prediction-error methods refine a subspace start (Ljung 1999, "System Identification", 2nd ed.,
sec. 10.6 and 7.3).  The model is written in modal form (one complex state per pole pair, one
real state per real pole), where the states' responses to the inputs and their derivatives by a
pole are first-order recursions: the Jacobian costs ``n m + n`` filterings of the records, and
its normal equations are accumulated over blocks of samples (memory independent of the records'
length).  Levenberg-Marquardt with Nielsen's damping; a step is kept only when it lowers the cost
and keeps a stable model stable; the refinement stops when a step lowers the cost by less than
``OE_TOL`` of it.  A start whose poles are not distinct (a defective ``A``) is returned unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "refine_output_error",
    "output_error_bytes",
    "output_error_work",
    "OE_MAX_WORK",
    "Modal",
    "OutputErrorProblem",
    "OutputErrorFit",
    "fit_output_error",
    "weighted_pass",
    "moved_starts",
    "OE_TOL",
    "OE_MAX_ITER",
    "OE_BLOCK",
]

#: Relative cost decrease below which the refinement stops.
OE_TOL = 1e-6
#: Safety bound on the Levenberg-Marquardt steps (the stop is on the cost; the seeded draws of
#: ``benchmarks/RESULTS-recovery.md`` converge in far fewer).
OE_MAX_ITER = 100
#: Samples per block when the normal equations are accumulated (bounds the memory).
OE_BLOCK = 4096
#: Floating-point operations one step may take (its normal equations, about ``N q P^2`` for ``N``
#: samples, ``q`` outputs, ``P`` parameters) for the refinement to run: past it (e.g. 28 outputs
#: at order 12 on 6k samples: 3e10, minutes a fit) the realisation is kept, and the fit says so.
OE_MAX_WORK = 5e9
#: Condition number of the eigenvector matrix above which the modal form is not used.
MAX_MODAL_CONDITION = 1e8


class Modal:
    """A real model in modal form: poles ``lam`` (complex, one per pair with Im > 0, then the
    real ones), complex ``b`` (n_modes, m), ``c`` (q, n_modes) and real ``d`` (q, m); a pair's
    output is ``2 Re(c x)``."""

    def __init__(self, lam, b, c, d, n_pairs):
        self.lam, self.b, self.c, self.d, self.n_pairs = lam, b, c, d, n_pairs

    @classmethod
    def from_abcd(cls, A, B, C, D) -> Modal | None:
        lam, V = np.linalg.eig(A)
        if not np.all(np.isfinite(lam)) or np.linalg.cond(V) > MAX_MODAL_CONDITION:
            return None
        tol = 1e-10 * max(1.0, float(np.max(np.abs(lam))))
        upper, real = np.flatnonzero(lam.imag > tol), np.flatnonzero(np.abs(lam.imag) <= tol)
        if 2 * upper.size + real.size != lam.size:
            return None
        Vi = np.linalg.inv(V)
        keep = np.concatenate([upper, real])
        b, c = (Vi @ B)[keep], (C @ V)[:, keep]
        lam = lam[keep].astype(complex)
        n_pairs = upper.size
        lam[n_pairs:] = lam[n_pairs:].real  # real poles: real states, real b and c
        b[n_pairs:], c[:, n_pairs:] = b[n_pairs:].real, c[:, n_pairs:].real
        return cls(lam, b.astype(complex), c.astype(complex), np.array(D, dtype=float), n_pairs)

    def to_abcd(self) -> tuple[np.ndarray, ...]:
        """A real realisation: a 2x2 block ``[[Re, -Im], [Im, Re]]`` per pair, then the real poles."""
        k, m, q = self.lam.size, self.b.shape[1], self.c.shape[0]
        n = k + self.n_pairs
        A, B, C = np.zeros((n, n)), np.zeros((n, m)), np.zeros((q, n))
        for j in range(self.n_pairs):
            s, lam = 2 * j, self.lam[j]
            A[s : s + 2, s : s + 2] = [[lam.real, -lam.imag], [lam.imag, lam.real]]
            B[s], B[s + 1] = self.b[j].real, self.b[j].imag
            C[:, s], C[:, s + 1] = 2 * self.c[:, j].real, -2 * self.c[:, j].imag
        r = 2 * self.n_pairs
        A[r:, r:] = np.diag(self.lam[self.n_pairs :].real)
        B[r:], C[:, r:] = self.b[self.n_pairs :].real, self.c[:, self.n_pairs :].real
        return A, B, C, self.d.copy()

    def vector(self, feedthrough: bool) -> np.ndarray:
        """The real parameters: poles (Re, Im of each pair; each real pole), ``b``, ``c``, ``d``."""
        h = self.n_pairs
        parts = [self.lam[:h].real, self.lam[:h].imag, self.lam[h:].real]
        parts += [self.b[:h].real.ravel(), self.b[:h].imag.ravel(), self.b[h:].real.ravel()]
        parts += [self.c[:, :h].real.ravel(), self.c[:, :h].imag.ravel(), self.c[:, h:].real.ravel()]
        if feedthrough:
            parts.append(self.d.ravel())
        return np.concatenate(parts)

    def moved(self, step: np.ndarray, feedthrough: bool) -> Modal:
        """The model with ``step`` added to :meth:`vector`."""
        v = self.vector(feedthrough) + step
        h, k = self.n_pairs, self.lam.size
        m, q, r = self.b.shape[1], self.c.shape[0], k - self.n_pairs
        cuts = np.cumsum([h, h, r, h * m, h * m, r * m, q * h, q * h, q * r])
        lr, li, lre, br, bi, bre, cr, ci, cre, d = np.split(v, cuts)
        lam = np.concatenate([lr + 1j * li, lre.astype(complex)])
        b = np.vstack([(br + 1j * bi).reshape(h, m), bre.reshape(r, m).astype(complex)])
        c = np.hstack([(cr + 1j * ci).reshape(q, h), cre.reshape(q, r).astype(complex)])
        return Modal(lam, b, c, d.reshape(q, m) if feedthrough else self.d, self.n_pairs)


def _block_parts(model: Modal, u: np.ndarray, start: tuple, carry: list, jacobian: bool):
    """Output of one block of samples, and (``jacobian``) its derivatives by the model's
    parameters ``(L, q, P)`` and by the record's own ``(L, q, n + q)`` (initial modal state as
    :func:`moved_starts` orders it, output offsets); ``start`` is the record's ``(z0, offsets)``
    and ``carry`` holds each mode's filter states across blocks (the first block starts them
    from ``z0``)."""
    from scipy.signal import lfilter  # on first use: importing scipy.signal at import costs the CLI's start

    L, m = u.shape
    k = model.lam.size
    uc = u.astype(complex)
    X = np.empty((L, k), dtype=complex)
    F = np.empty((L, k, m), dtype=complex) if jacobian else None
    G, Pw = (np.empty((L, k), dtype=complex), np.empty((L, k), dtype=complex)) if jacobian else (None, None)
    for j in range(k):
        den, state = [1.0, -model.lam[j]], carry[j]
        if not jacobian:  # x alone: the input through b, the free response in the filter's state
            X[:, j], state[0] = lfilter([0.0, 1.0], den, uc @ model.b[j], zi=state[0])
            continue
        F[:, j], state[1] = lfilter([0.0, 1.0], den, uc, axis=0, zi=state[1])  # x of unit b's
        Pw[:, j], state[2] = lfilter([0.0, 1.0], den, np.zeros(L), zi=state[2])  # lam^t: x of a unit z0
        X[:, j] = F[:, j] @ model.b[j] + start[0][j] * Pw[:, j]
        G[:, j], state[3] = lfilter([0.0, 1.0], den, X[:, j], zi=state[3])  # dx / d lam
    scale = np.where(np.arange(k) < model.n_pairs, 2.0, 1.0)
    y = u @ model.d.T + start[1][None, :] + np.real(X * scale) @ model.c.T.real - np.imag(X * scale) @ model.c.T.imag
    if not jacobian:
        return y, None, None
    q = model.c.shape[0]
    eye = np.eye(q)
    d_lam = _re_im(G[:, None, :] * model.c[None], model.n_pairs)
    d_b = _re_im(F[:, None] * model.c[None, :, :, None], model.n_pairs)
    h = model.n_pairs
    groups = (2.0 * X[:, :h].real, -2.0 * X[:, :h].imag, X[:, h:].real)  # c's Re, Im over the pairs, then real
    d_c = np.concatenate([np.einsum("ij,lk->lijk", eye, g).reshape(L, q, -1) for g in groups], axis=-1)
    d_z = _re_im(Pw[:, None, :] * model.c[None], model.n_pairs)
    own = np.concatenate([d_z, np.broadcast_to(eye, (L, q, q))], axis=-1)
    return y, np.concatenate([d_lam, d_b, d_c], axis=-1), own


def _re_im(v: np.ndarray, h: int) -> np.ndarray:
    """Derivatives by the real and imaginary parts of complex parameters from ``v = c dx``-type
    products ``(L, q, ..., k, ...)`` whose mode axis is axis 2: ``2 Re`` and ``-2 Im`` over the
    pairs, ``Re`` over the real modes, each flattened over the axes from 2 on (row-major)."""
    L, q = v.shape[:2]
    pairs, real = v[:, :, :h], v[:, :, h:]
    blocks = [2.0 * pairs.real, -2.0 * pairs.imag, real.real]
    return np.concatenate([b.reshape(L, q, -1) for b in blocks], axis=-1)


def output_error_bytes(order: int, n_inputs: int, n_outputs: int) -> float:
    """Memory the refinement of an ``order``-state model takes: per block of ``OE_BLOCK`` samples
    the filtered inputs and the Jacobian (real, its weighted copy and the complex derivative
    blocks it is built from), and the normal equations over ``P`` parameters."""
    n, m, q = float(order), float(n_inputs), float(n_outputs)
    P = n + n * m + q * n + q * m
    return 8.0 * OE_BLOCK * (2.0 * n * m + 4.0 * q * P + 2.0 * q * q * n) + 8.0 * 3.0 * P * P


def output_error_work(order: int, n_inputs: int, n_outputs: int, n_samples: int, n_records: int) -> float:
    """Floating-point operations of one refinement step's normal equations (compare ``OE_MAX_WORK``)."""
    n, m, q = float(order), float(n_inputs), float(n_outputs)
    P = n + n * m + q * n + q * m + n_records * (n + q)
    return float(n_samples) * q * P * P


def _carry(model: Modal, m: int, z0: np.ndarray) -> list:
    """Each mode's filter states at the record's start: ``x`` (from ``z0``), the unit-``b``
    responses (rest), ``lam^t`` (from 1) and ``dx / d lam`` (rest)."""
    zero = np.zeros(1, dtype=complex)
    return [
        [z0[j : j + 1].astype(complex), np.zeros((1, m), complex), np.ones(1, complex), zero] for j in range(z0.size)
    ]


def _feedthrough_columns(u: np.ndarray, q: int) -> np.ndarray:
    """Derivatives of the outputs by ``D`` (row-major), ``(L, q, q m)``."""
    L, m = u.shape
    Jd = np.zeros((L, q, q * m))
    for i in range(q):
        Jd[:, i, i * m : (i + 1) * m] = u
    return Jd


@dataclass(frozen=True)
class OutputErrorProblem:
    """What the refinement fits: the records ``(u, y)``, the outputs' ``weights`` and whether
    ``D`` is fitted."""

    records: tuple
    weights: np.ndarray
    feedthrough: bool = False


def weighted_pass(
    model: Modal, starts: list, problem: OutputErrorProblem, jacobian: bool = True, block: int = OE_BLOCK
):
    """Weighted cost over the records and (``jacobian``) the normal equations ``J^T J``, ``J^T r``
    over the model's parameters followed by each record's ``(z0, offsets)``."""
    w, feedthrough = problem.weights, problem.feedthrough
    n_shared = model.vector(feedthrough).size
    n_own = model.lam.size + model.n_pairs + model.c.shape[0]
    P = n_shared + len(problem.records) * n_own
    cost, JtJ, Jtr = 0.0, np.zeros((P, P)), np.zeros(P)
    for r_idx, ((u, y), start) in enumerate(zip(problem.records, starts)):
        carry = _carry(model, u.shape[1], start[0])
        idx = np.concatenate([np.arange(n_shared), n_shared + r_idx * n_own + np.arange(n_own)])
        for a in range(0, u.shape[0], block):
            ub, yb = u[a : a + block], y[a : a + block]
            yh, J, Jo = _block_parts(model, ub, start, carry, jacobian)
            r = (yb - yh) * w[None, :]
            cost += float(np.sum(r**2))
            if not jacobian:
                continue
            parts = [J, _feedthrough_columns(ub, w.size), Jo] if feedthrough else [J, Jo]
            Jw = (np.concatenate(parts, axis=-1) * w[None, :, None]).reshape(-1, idx.size)
            JtJ[np.ix_(idx, idx)] += Jw.T @ Jw
            Jtr[idx] += Jw.T @ r.ravel()
    return cost, JtJ, Jtr


def moved_starts(model: Modal, starts: list, step: np.ndarray) -> list:
    """Each record's ``(z0, offsets)`` moved by its part of ``step``."""
    h, k, q = model.n_pairs, model.lam.size, model.c.shape[0]
    n_own = k + h + q
    out = []
    for r_idx, (z0, offset) in enumerate(starts):
        s = step[r_idx * n_own : (r_idx + 1) * n_own]
        dz = np.concatenate([s[:h] + 1j * s[h : 2 * h], s[2 * h : k + h].astype(complex)])
        out.append((z0 + dz, offset + s[k + h :]))
    return out


@dataclass(frozen=True)
class OutputErrorFit:
    """A refined model in modal form, each record's ``(z0, offsets)``, and the weighted cost
    before and after (with the records' starts fitted)."""

    model: Modal
    starts: list
    cost0: float
    cost: float
    iterations: int


def fit_output_error(
    A, B, C, D, problem: OutputErrorProblem, max_iter: int = OE_MAX_ITER, tol: float = OE_TOL
) -> OutputErrorFit | None:
    """Levenberg-Marquardt on the weighted simulated output error of ``(A, B, C, D)`` (any
    coordinates) on ``problem``, each record with its own initial state and output offsets,
    until a step lowers the cost by less than ``tol`` of it; None when the poles are not
    distinct (no modal form)."""
    q = np.asarray(C).shape[0]
    model = Modal.from_abcd(np.asarray(A), np.asarray(B), np.asarray(C), np.asarray(D))
    if model is None:
        return None
    stable = bool(np.all(np.abs(model.lam) < 1.0))
    starts = [(np.zeros(model.lam.size, dtype=complex), np.zeros(q)) for _ in problem.records]
    n_shared = model.vector(problem.feedthrough).size
    cost, JtJ, g = weighted_pass(model, starts, problem)
    cost0, mu, nu, it = cost, 1e-3, 2.0, 0
    while it < max_iter:
        it += 1
        dg = np.diag(JtJ).copy()
        dg[dg <= 0] = max(float(dg.max(initial=0.0)), 1.0) * 1e-12
        step_taken, rel = False, 0.0
        for _ in range(12):
            try:
                step = np.linalg.solve(JtJ + np.diag(mu * dg), g)
            except np.linalg.LinAlgError:
                mu, nu = mu * nu, nu * 2.0
                continue
            trial = model.moved(step[:n_shared], problem.feedthrough)
            trial_starts = moved_starts(model, starts, step[n_shared:])
            if not (stable and np.any(np.abs(trial.lam) >= 1.0)):
                c1 = weighted_pass(trial, trial_starts, problem, jacobian=False)[0]
                if np.isfinite(c1) and c1 < cost:
                    predicted = float(2.0 * step @ g - step @ (JtJ @ step))
                    rho = (cost - c1) / predicted if predicted > 0 else 0.0
                    rel = (cost - c1) / max(cost, 1e-300)
                    model, starts, cost, step_taken = trial, trial_starts, c1, True
                    mu, nu = max(mu * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 1e-12), 2.0
                    break
            mu, nu = mu * nu, nu * 2.0
        if not step_taken or rel < tol:
            break
        cost, JtJ, g = weighted_pass(model, starts, problem)
    return OutputErrorFit(model, starts, cost0, cost, it)


def refine_output_error(A, B, C, D, records, weights=None, feedthrough: bool = False, max_iter: int = OE_MAX_ITER):
    """Levenberg-Marquardt on the simulated output error of ``(A, B, C, D)`` over ``records``.

    Each record has its own initial state and output offsets, fitted with the model: records
    whose means were removed, or which do not start from rest, are then what the model says.

    Parameters
    ----------
    A, B, C, D : ndarray
        The start (a discrete model in any coordinates).
    records : sequence of (u, y)
        Inputs ``(n_samples, n_inputs)`` and outputs ``(n_samples, n_outputs)``.
    weights : ndarray of shape (n_outputs,), optional
        Per-output weights of the error (the inverse noise std).
    feedthrough : bool
        Also fit ``D`` (otherwise ``D`` is kept).

    Returns
    -------
    A, B, C, D, info : the refined model (modal coordinates when refined; the start unchanged
        when its poles are not distinct) and ``{"cost0", "cost", "iterations"}``, the costs with
        the records' initial states and offsets fitted.
    """
    q = np.asarray(C).shape[0]
    w = np.ones(q) if weights is None else np.asarray(weights, dtype=float)
    fit = fit_output_error(A, B, C, D, OutputErrorProblem(tuple(records), w, feedthrough), max_iter)
    if fit is None:
        return A, B, C, D, {"cost0": np.nan, "cost": np.nan, "iterations": 0}
    return (*fit.model.to_abcd(), {"cost0": fit.cost0, "cost": fit.cost, "iterations": fit.iterations})
