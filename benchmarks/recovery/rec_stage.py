"""Randomised recovery of the rate-dependent stage model (``stageid identify hysteresis --dynamics N``).

A draw (``case``) is a random classical PI hysteresis on the identification's own threshold
grid (``r_i = i R / n``, ``R`` the identification drives' half range, 4-8 operators), an optional creep lag
(``tau`` 0.05-0.5 s), and unit-DC-gain dynamics of order 0, 1 (a lag at 300-3000 Hz) or 2 (a
resonance at 100-800 Hz, damping 0.3-5 %), at 10 kHz.  Two identification records (a decaying
triangle at 10-40 Hz and a band-limited random drive) are written with the seed's time-column
style and white output noise of RMS ``noise`` times the output's RMS (about its mean); a third record (a
decaying sine at another rate) is held out.

The fit runs through the command line with the truth's structure given explicitly (the
automatic choice of order and creep costs minutes a draw): ``--model pi --operators n
--dynamics max(order, 1) --creep TAU|none`` and the default disturbance-mode rule; an order-0
truth is fitted with ``--dynamics 1``, which held-out evidence must drop.

- **error**: RMS of the fitted model's output minus the true noise-free output on the held-out
  record, % of its range (zero starting state, the record's own offset).
- **reference_error**: the same for the reference fit.
- **reference fit**: the fit's cost (sum of squared output errors over the identification
  records, each with its own offset) minimised by ``scipy.optimize.least_squares`` over the
  weights, creep weight, offsets and dynamics coefficients, started from the true parameters
  (thresholds fixed at the truth's, which are the fit's grid).
- **cost_ratio**: the fit's cost over the reference's, on the same records (NaN without noise,
  where both are rounding).
- **recovered**: error <= ``ERROR_LIMIT`` % of range and cost_ratio <= ``COST_LIMIT``.
"""

from __future__ import annotations

import json
import math
import pathlib

import numpy as np
from common import TIME_STYLES, CliFailure, Row, run_cli, write_record

ESTIMATOR = "Stage model"
FS = 1e4
DT = 1.0 / FS
AMPLITUDE = 10.0
#: Recovered: held-out RMS error at most this (% of range) ...
ERROR_LIMIT = 1.0
#: ... and the fit's cost at most this multiple of the reference's.
COST_LIMIT = 1.05


def _true_stage(rng: np.random.Generator, half_range: float, centre: float):
    """``(StageModel, order, creep tau or None, n_operators)`` drawn from ``rng``, thresholds on
    the grid the identification puts over the drives' half range, plays centred where it
    centres them (the middle of the range), at rest at input 0."""
    from scipy.signal import cont2discrete

    from stageid.hysteresis import PIModel
    from stageid.hysteresis.models.creep import CreepTerm
    from stageid.hysteresis.stage import StageModel
    from stageid.hysteresis.stage.dynamics import transfer_to_statespace

    n = int(rng.integers(4, 9))
    r = np.arange(n) * half_range / n
    w = np.r_[rng.uniform(0.6, 1.2), rng.uniform(0.02, 0.4, n - 1) / np.sqrt(np.arange(1, n))]
    tau = float(rng.uniform(0.05, 0.5)) if rng.random() < 0.5 else None
    creep = None if tau is None else CreepTerm(time_constants=[tau], weights=[rng.uniform(0.02, 0.08)], sample_time=DT)
    order = int(rng.integers(0, 3))
    dyn = None
    if order == 1:
        p = math.exp(-2 * math.pi * rng.uniform(300.0, 3000.0) * DT)
        dyn = transfer_to_statespace([1 - p, 0.0], [1.0, -p], DT)
    elif order == 2:
        wn = 2 * math.pi * rng.uniform(100.0, 800.0)
        zeta = rng.uniform(0.003, 0.05)
        b, a, _ = cont2discrete(([wn**2], [1.0, 2 * zeta * wn, wn**2]), DT, "zoh")
        b = np.ravel(b)
        dyn = transfer_to_statespace(b * np.sum(a) / np.sum(b), a, DT)
    h = PIModel(r=r, weights=w, creep=creep, input_offset=centre)
    return StageModel(h.with_state(h.consistent_state(0.0, "zero")), dyn), order, tau, n


def _drives(rng: np.random.Generator) -> list[np.ndarray]:
    """Two identification drives over the full range and a held-out one at another rate."""
    from scipy.signal import butter, sosfiltfilt

    from stageid.signals import decaying_sine, decaying_triangle

    f1 = float(rng.uniform(10.0, 40.0))
    tri = decaying_triangle(f1, 6, DT, amplitude=AMPLITUDE)
    n = int(rng.integers(6000, 10000))
    sos = butter(4, float(rng.uniform(100.0, 400.0)) / (FS / 2), output="sos")
    noise = sosfiltfilt(sos, rng.standard_normal(n))
    rand = AMPLITUDE * noise / np.max(np.abs(noise))
    rand = np.r_[np.linspace(0.0, rand[0], 200), rand]  # from rest at 0, as a drive starts
    held = decaying_sine(float(rng.uniform(15.0, 60.0)), 5, DT, amplitude=0.9 * AMPLITUDE)
    return [tri, rand, held]


def _cost_terms(model, recs) -> float:
    """Sum over records of the squared output error with each record's own (optimal) offset."""
    total = 0.0
    for u, y in recs:
        e = y - model.simulate(u)[:, 0]
        e = e - e.mean()
        total += float(e @ e)
    return total


def _reference(true, recs, order: int):
    """The fit's cost minimised from the true parameters (thresholds fixed): (model, cost)."""
    from dataclasses import replace

    from scipy.optimize import least_squares

    from stageid.hysteresis.stage.dynamics import statespace_to_transfer, transfer_to_statespace

    h = true.hysteresis
    nw = h.weights.size
    creep = h.creep
    b0, a0 = (np.ones(1), np.ones(1)) if true.dynamics is None else statespace_to_transfer(true.dynamics)
    x0 = np.r_[h.weights, [] if creep is None else creep.weights, a0[1:], b0[1:]]

    def build(x):
        hh = replace(h, weights=x[:nw])
        k = nw
        if creep is not None:
            hh = replace(hh, creep=replace(creep, weights=np.abs(x[k : k + 1])))
            k += 1
        if order == 0:
            return replace(true, hysteresis=hh)
        a = np.r_[1.0, x[k : k + order]]
        tail = x[k + order :]
        if np.any(np.abs(np.roots(a)) >= 1):
            return None
        return replace(true, hysteresis=hh, dynamics=transfer_to_statespace(np.r_[np.sum(a) - tail.sum(), tail], a, DT))

    def residual(x):
        m = build(x)
        if m is None:
            return np.full(sum(u.size for u, _ in recs), 1e3)
        parts = []
        for u, y in recs:
            e = y - m.simulate(u)[:, 0]
            parts.append(e - e.mean())
        return np.concatenate(parts)

    sol = least_squares(residual, x0, method="lm", max_nfev=200 * x0.size)
    model = build(sol.x)
    return model, _cost_terms(model, recs)


def _held_out_error(model, true, u) -> float:
    y = true.simulate(u)[:, 0]
    e = y - model.simulate(u)[:, 0]
    e = e - e.mean()
    return float(100 * np.sqrt(np.mean(e**2)) / np.ptp(y))


def case(seed: int, workdir: pathlib.Path, noise: float) -> Row:
    """One draw: the true stage from ``seed``, fitted through the CLI, compared as the module says."""
    from stageid.hysteresis.stage import StageModel

    rng = np.random.default_rng(seed)
    tri, rand, held = _drives(rng)
    # the fit's thresholds are i R / n with R the identification drives' half range, centred
    lo, hi = min(tri.min(), rand.min()), max(tri.max(), rand.max())
    true, order, tau, n_ops = _true_stage(rng, 0.5 * (hi - lo), 0.5 * (hi + lo))
    style = TIME_STYLES[seed % len(TIME_STYLES)]
    if style == "float32":  # float32 time stamps only resolve short records at 10 kHz
        style = "repr"
    recs, paths = [], []
    for k, u in enumerate((tri, rand)):
        clean = true.simulate(u)[:, 0]
        y = clean + noise * np.std(clean) * rng.standard_normal(u.size)
        recs.append((u, y))
        paths.append(write_record(workdir / f"stage{seed}_{k}.csv", {"V": u, "y": y}, FS, style, rng))
    out = workdir / f"stage{seed}.json"
    argv = ["identify", "hysteresis", *paths, "--input", "V", "--output", "y", "--model", "pi"]
    argv += [
        "--operators",
        str(n_ops),
        "--dynamics",
        str(max(order, 1)),
        "--creep",
        "none" if tau is None else f"{tau!r}",
    ]
    detail = f"order {order}, creep {'none' if tau is None else f'{tau:.3g} s'}, {n_ops} operators, {style} time"
    try:
        run_cli([*argv, "--quiet", "-o", str(out)])
    except CliFailure as exc:
        return Row(seed, False, math.nan, "% of range", noise=noise, detail=detail, failed=str(exc))
    fitted = StageModel.from_dict(json.loads(out.read_text()))
    reference, ref_cost = _reference(true, recs, order)
    error = _held_out_error(fitted, true, held)
    # without noise both costs are rounding and their ratio says nothing
    ratio = _cost_terms(fitted, recs) / ref_cost if noise > 0 else math.nan
    detail += f"; fitted order {fitted.dynamics_order}"
    ok = error <= ERROR_LIMIT and (math.isnan(ratio) or ratio <= COST_LIMIT)
    return Row(seed, bool(ok), error, "% of range", _held_out_error(reference, true, held), ratio, noise, detail)
