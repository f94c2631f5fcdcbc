"""Recovery of random stable MIMO stages by ``stageid identify statespace`` (Hankel-Toeplitz
statistics, MAP estimate, in-band SVD realisation; Cao & Chen 2013).

The true system per seed: 1-3 inputs and outputs, 1-4 lightly damped modes (damping 0.3-5 %,
natural frequencies spread over a decade below a fifth of the sampling rate) and, for odd
orders, one real pole, so orders 2-8 (continuous, sampled by zero-order hold); random mode
shapes. Inputs white or a random-phase multisine; 1-3 records of 2-8k samples each, lengths
unequal, with logger time columns; white output noise at ``noise`` times each output's RMS.
The fit runs with the defaults a user meets first (order and horizon ``auto``).

Error: the largest frequency-response error over the band (a tenth of the lowest mode to the
highest mode plus a half, below Nyquist) as a percentage of the true response's peak.
Reference: the same output-error cost minimised from the truth over the output matrices ``C``
and ``D`` with the true ``A``, ``B`` (a linear least-squares problem, so its optimum is exact);
cost ratio = the fit's simulated output error (sum of squares over all records) / the
reference's. Recovered when the error is at most 2 % of the peak plus three times the
reference's error (the noise floor of the draw).
"""

from __future__ import annotations

import pathlib

import numpy as np
from common import TIME_STYLES, CliFailure, Row, run_cli, write_record

ESTIMATOR = "Hankel-MAP"
FS = 1000.0


def true_system(rng: np.random.Generator):
    """A random stable discrete MIMO system (A, B, C, D at 1/FS) and its mode frequencies in Hz."""
    from scipy.signal import cont2discrete

    m, p = int(rng.integers(1, 4)), int(rng.integers(1, 4))
    order = int(rng.integers(2, 9))
    n_modes = order // 2
    f_low = rng.uniform(FS / 200, FS / 50)
    freqs = np.sort(f_low * 10 ** rng.uniform(0.0, 1.0, n_modes))
    blocks = []
    for f in freqs:
        w, z = 2 * np.pi * f, 10 ** rng.uniform(np.log10(0.003), np.log10(0.05))
        blocks.append(np.array([[0.0, 1.0], [-(w**2), -2 * z * w]]))
    if order % 2:
        blocks.append(np.array([[-2 * np.pi * rng.uniform(f_low / 2, 2 * f_low)]]))
    Ac = _block_diag(blocks)
    Bc = rng.standard_normal((order, m))
    Cc = rng.standard_normal((p, order))
    # scale each mode's output so modes of different frequency have comparable peaks
    for k, f in enumerate(freqs):
        Cc[:, 2 * k : 2 * k + 2] *= (2 * np.pi * f) ** 2 * np.array([1.0, 1.0 / (2 * np.pi * f)])
    if order % 2:
        Cc[:, -1] *= -Ac[-1, -1]
    Dc = np.zeros((p, m))
    A, B, C, D, _ = cont2discrete((Ac, Bc, Cc, Dc), 1 / FS, method="zoh")
    return (A, B, C, D), freqs


def _block_diag(blocks):
    n = sum(b.shape[0] for b in blocks)
    out, k = np.zeros((n, n)), 0
    for b in blocks:
        out[k : k + b.shape[0], k : k + b.shape[0]] = b
        k += b.shape[0]
    return out


def inputs(rng: np.random.Generator, n: int, m: int) -> np.ndarray:
    """White noise or a random-phase multisine on every input (independent per input)."""
    if rng.random() < 0.5:
        return rng.standard_normal((n, m))
    t = np.arange(n) / FS
    f = np.linspace(1.0, 0.45 * FS, 200)
    phases = rng.uniform(0, 2 * np.pi, (m, f.size))
    u = np.stack([np.sin(2 * np.pi * f[None, :] * t[:, None] + ph[None, :]).sum(1) for ph in phases], axis=1)
    return u / u.std(0)


def simulate(A, B, C, D, u: np.ndarray) -> np.ndarray:
    """Output from rest of the discrete system (A, B, C, D) to ``u`` of shape (n, m)."""
    from scipy.signal import dlsim

    _, y, _ = dlsim((A, B, C, D, 1 / FS), u)
    return np.asarray(y).reshape(u.shape[0], -1)


def response(A, B, C, D, f: np.ndarray) -> np.ndarray:
    """Frequency response of shape (n_freqs, p, m)."""
    z = np.exp(2j * np.pi * f / FS)
    n = A.shape[0]
    return np.stack([C @ np.linalg.solve(zk * np.eye(n) - A, B) + D for zk in z])


def reference_fit(A, B, records) -> tuple[np.ndarray, np.ndarray, float]:
    """C, D minimising the summed squared output error with the true A, B, and that cost."""
    p = records[0][1].shape[1]
    regs, ys = [], []
    for u, y in records:
        m = u.shape[1]
        # state responses to unit C: x from rest, one column per state; y = x C^T + u D^T
        X = simulate(A, B, np.eye(A.shape[0]), np.zeros((A.shape[0], m)), u)
        regs.append(np.hstack([X, u]))
        ys.append(y)
    R, Y = np.vstack(regs), np.vstack(ys)
    theta, *_ = np.linalg.lstsq(R, Y, rcond=None)
    n = A.shape[0]
    cost = float(np.sum((Y - R @ theta) ** 2))
    return theta[:n].T.reshape(p, n), theta[n:].T, cost


def case(seed: int, workdir: pathlib.Path, noise: float) -> Row:
    rng = np.random.default_rng([seed, 101])
    (A, B, C, D), freqs = true_system(rng)
    p, m = C.shape[0], B.shape[1]
    style = TIME_STYLES[int(rng.integers(len(TIME_STYLES)))]
    n_rec = int(rng.integers(1, 4))
    names_u = [f"u{k + 1}" for k in range(m)]
    names_y = [f"y{k + 1}" for k in range(p)]
    records, paths = [], []
    for r in range(n_rec):
        n = int(rng.integers(2000, 8001))
        u = inputs(rng, n, m)
        y0 = simulate(A, B, C, D, u)
        y = y0 + noise * y0.std(0) * rng.standard_normal(y0.shape)
        records.append((u, y))
        cols = {**dict(zip(names_u, u.T)), **dict(zip(names_y, y.T))}
        paths.append(write_record(workdir / f"rec{r}.csv", cols, FS, style if n <= 16000 else "repr", rng))
    detail = f"{m}x{p} order {A.shape[0]}, {n_rec} records, t {style}"
    try:
        run_cli([
            "identify", "statespace", *paths, "--inputs", ",".join(names_u), "--outputs", ",".join(names_y),
            "-o", workdir / "model.json",
        ])  # fmt: skip
    except CliFailure as exc:
        return Row(seed, False, float("nan"), noise=noise, detail=detail, failed=str(exc))
    from stageid.models import load_model

    fit = load_model(workdir / "model.json")
    band = np.linspace(max(freqs[0] / 10, 0.5) if freqs.size else 1.0, min(1.5 * freqs[-1], 0.45 * FS), 600)
    G_true = response(A, B, C, D, band)
    peak = np.abs(G_true).max()
    error = 100 * np.abs(fit.frequency_response(band) - G_true).max() / peak
    Cr, Dr, ref_cost = reference_fit(A, B, records)
    ref_error = 100 * np.abs(response(A, B, Cr, Dr, band) - G_true).max() / peak
    cost = sum(float(np.sum((y - fit.simulate(u)) ** 2)) for u, y in records)
    energy = sum(float(np.sum(y**2)) for _, y in records)
    # noise-free draws: the reference reaches rounding level, where a ratio says nothing
    ratio = cost / ref_cost if ref_cost > 1e-12 * energy else float("nan")
    detail += f", fit order {fit.n_states}"
    return Row(seed, error <= 2.0 + 3 * ref_error, error, "% of peak", ref_error, ratio, noise, detail)
