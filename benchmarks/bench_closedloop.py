"""PEM identification time and fit: stageid.closedloop.pem against SIPPY (sippy-unipi), same data.

The data are the closed loop r -> y of an open-loop-unstable levitation axis
(``K / ((s - 50)(s + 80))`` with our [2, 2] lead-lag, 5 kHz, 1 um chirp DC -> 2500 Hz, output
noise at 60 dB): the paper's step 3.2.1.  Every method fits the same structure orders on the
same estimation record; the fit is the simulation fit (MATLAB ``compare``) on a fresh
validation record (other chirp length, other noise).  Timings are medians of ``--repeat`` runs.

    .venv/bin/python benchmarks/bench_closedloop.py [--repeat 3] [--out benchmarks/RESULTS-closedloop.md]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import platform
import time

import numpy as np
import scipy.signal as ss

from stageid.closedloop import pem, simulate_closed_loop
from stageid.models import TransferMatrix
from stageid.plants.maglev import lead_lag
from stageid.signals import chirp

DT = 2e-4
N_ORDER = 4  # closed loop: plant [0, 2] + controller [2, 2] -> 4 poles


def _loop():
    G = TransferMatrix([[[3.0]]], [[np.poly([50.0, -80.0])]], None)
    num, den = lead_lag(3.0, 50.0, 80.0, 110.0)
    K = TransferMatrix([[num]], [[den]], None).to_statespace(minimal=False).c2d(DT, "tustin")
    return G, K


def data(seed: int, duration: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    G, K = _loop()
    r = chirp(0.0, 2500.0, duration=duration, dt=DT, amplitude=1e-6)
    y, _ = simulate_closed_loop(G, K, r[:, None], DT, 60.0, seed)
    y0, _ = simulate_closed_loop(G, K, r[:, None], DT, None)
    return r, y[:, 0], y0[:, 0]


def fit_percent(y: np.ndarray, yh: np.ndarray) -> float:
    return float(100 * (1 - np.linalg.norm(y - yh) / np.linalg.norm(y - y.mean())))


def _timed(fn, repeat: int):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, float(np.median(times))


def run(repeat: int = 3) -> list[dict]:
    r, y, _ = data(0, 2.0)
    rv, _, yv0 = data(1, 1.5)
    # scale to um so that SIPPY's absolute tolerances are meaningful (stageid scales internally)
    y_um, yv0_um = 1e6 * y, 1e6 * yv0
    r_um, rv_um = 1e6 * r, 1e6 * rv
    n = N_ORDER
    rows = []
    for name, structure, orders in (
        ("OE", "oe", {"nb": n, "nf": n}),
        ("ARMAX", "armax", {"na": n, "nb": n, "nc": n}),
        ("BJ", "bj", {"nb": n, "nf": n, "nc": 2, "nd": 2}),
    ):
        m, t = _timed(lambda s=structure, o=orders: pem(r_um, y_um, s, o, nk=1, dt=DT), repeat)
        rows.append(dict(tool="stageid", method=name, time=t, fit=fit_percent(yv0_um, m.simulate(rv_um))))
    try:
        from sippy_unipi import system_identification
    except ImportError:
        return rows
    specs = (
        ("OE", dict(OE_orders=[n, n, 1], OE_mod="OPT")),
        ("ARMAX", dict(ARMAX_orders=[n, n, n, 1], ARMAX_mod="ILLS")),
        ("BJ", dict(BJ_orders=[n, 2, 2, n, 1])),
    )
    for name, kw in specs:

        def ident(kw=kw, name=name):
            with contextlib.redirect_stdout(io.StringIO()):
                return system_identification(y_um, r_um, name, tsample=DT, **kw)

        try:
            mod, t = _timed(ident, repeat)
            g = mod.G
            bz, az = np.asarray(g.num[0][0], float), np.asarray(g.den[0][0], float)
            pad = az.size - bz.size
            yh = ss.lfilter(np.concatenate([np.zeros(pad), bz]), az, rv_um)
            rows.append(dict(tool="SIPPY", method=name, time=t, fit=fit_percent(yv0_um, yh)))
        except Exception as exc:  # a peer failing is a result too
            rows.append(
                dict(
                    tool="SIPPY",
                    method=name,
                    time=float("nan"),
                    fit=float("nan"),
                    note=f"{type(exc).__name__}: {exc}"[:80],
                )
            )
    return rows


def markdown(rows: list[dict], repeat: int) -> str:
    lines = [
        "# Closed-loop PEM benchmark: stageid vs SIPPY",
        "",
        f"Machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}; "
        f"median of {repeat} runs; written by `benchmarks/bench_closedloop.py`.",
        "",
        "Data: closed loop r -> y of an unstable levitation axis under our lead-lag, 10 000 samples at 5 kHz "
        "(1 um chirp DC -> 2500 Hz), 60 dB output noise; orders 4/4 (BJ noise 2/2), delay 1. Fit = simulation fit on a "
        "fresh noise-free validation record (1.5 s chirp).",
        "",
        "| method | stageid time [s] | stageid fit [%] | SIPPY time [s] | SIPPY fit [%] | time ratio SIPPY/stageid |",
        "|---|---|---|---|---|---|",
    ]
    for method in ("OE", "ARMAX", "BJ"):
        a = next((r for r in rows if r["tool"] == "stageid" and r["method"] == method), None)
        b = next((r for r in rows if r["tool"] == "SIPPY" and r["method"] == method), None)
        if a is None:
            continue
        bt = f"{b['time']:.3f}" if b else "n/a"
        bf = f"{b['fit']:.3f}" if b else "n/a"
        ratio = f"{b['time'] / a['time']:.1f}" if b and np.isfinite(b["time"]) else "n/a"
        note = f" ({b['note']})" if b and "note" in b else ""
        lines.append(f"| {method} | {a['time']:.3f} | {a['fit']:.3f} | {bt} | {bf}{note} | {ratio} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    rows = run(a.repeat)
    text = markdown(rows, a.repeat)
    print(text)
    if a.out:
        with open(a.out, "w") as fh:
            fh.write(text)
