"""FRF estimation speed: ``stageid frf`` (whole process, from NPZ) against scipy.signal.csd per pair.

3 inputs, 3 outputs, N samples per channel of white inputs through a coupled 3x3 system with
output noise.  The reference composes ``scipy.signal.csd`` in-process for every pair H1,
coherence and std need (the 3x3 input spectra, the 3x3 input-output spectra and the 3 output
auto-spectra: 21 calls), then solves H1 = S_yu S_uu^-1 per frequency: what a user would write
without stageid.  ``stageid frf`` runs as a subprocess (Python start, imports, reading the
NPZ, writing the NPZ result all counted).  The LPM runs in-process on N = 10^6, 3x3, against
Welch on the same record.  Timings are medians of ``--repeat`` runs.

    .venv/bin/python benchmarks/bench_frf.py [--n 4000000] [--segment 4096] [--repeat 3] [--out benchmarks/RESULTS-frf.md]
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np
import scipy.signal as ss

from stageid.data import Experiment
from stageid.frf import lpm_frf, welch_frf


def record(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """White inputs through three coupled second-order filters plus noise, (n, 3) each."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, 3))
    y = np.empty_like(u)
    for i in range(3):
        b, a = ss.butter(2, 0.05 * (i + 1))
        y[:, i] = ss.lfilter(b, a, u[:, i]) + 0.3 * ss.lfilter(b, a, u[:, (i + 1) % 3])
    y += 0.05 * rng.standard_normal(y.shape)
    return u, y


def scipy_reference(u: np.ndarray, y: np.ndarray, segment: int) -> np.ndarray:
    """H1, multiple coherence and std from 21 scipy.signal.csd calls (the composed baseline)."""
    kw = {"fs": 1.0, "nperseg": segment}
    m, q = u.shape[1], y.shape[1]
    nf = segment // 2 + 1
    Suu = np.empty((nf, m, m), complex)
    Suy = np.empty((nf, m, q), complex)
    Syy = np.empty((nf, q))
    for a in range(m):
        for b in range(m):
            Suu[:, a, b] = ss.csd(u[:, a], u[:, b], **kw)[1]
        for b in range(q):
            Suy[:, a, b] = ss.csd(u[:, a], y[:, b], **kw)[1]
    for b in range(q):
        Syy[:, b] = ss.csd(y[:, b], y[:, b], **kw)[1].real
    HT = np.linalg.solve(Suu[1:], Suy[1:])
    explained = np.real(np.einsum("kaq,kaq->kq", np.conj(Suy[1:]), HT))
    coh = 1.0 - (Syy[1:] - explained) / Syy[1:]
    L = 2 * (u.shape[0] // segment) - 1
    std = np.sqrt(
        (Syy[1:] - explained)[:, :, None]
        * np.real(np.diagonal(np.linalg.inv(Suu[1:]), axis1=1, axis2=2))[:, None, :]
        / L
    )
    return HT.transpose(0, 2, 1), coh, std


def median_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def lpm_against_welch(u: np.ndarray, y: np.ndarray, n: int, segment: int, repeat: int) -> list[str]:
    """LPM (compiled kernel) and Welch timed alternately in one run, wall and CPU time of each
    call; medians and the median of the per-pair ratios, plus one run of the numpy twin and the
    kernel's agreement with it."""
    exp = Experiment(u[:n], y[:n], 1.0)
    lpm_frf(exp)  # numba: compile or load the cache first (long records use a kernel compiled for their sizes)
    welch_frf(exp, segment)
    wall = {"welch": [], "lpm": []}
    cpu = {"welch": [], "lpm": []}
    for _ in range(repeat):
        for name, fn in (("welch", lambda: welch_frf(exp, segment)), ("lpm", lambda: lpm_frf(exp))):
            t, c = time.perf_counter(), time.process_time()
            fn()
            cpu[name].append(time.process_time() - c)
            wall[name].append(time.perf_counter() - t)
    t = time.perf_counter()
    ref = lpm_frf(exp, compiled=False)
    t_py = time.perf_counter() - t
    got = lpm_frf(exp)
    agree_g = float(np.max(np.abs(got.response - ref.response)) / np.max(np.abs(ref.response)))
    agree_s = float(np.max(np.abs(got.std - ref.std) / ref.std))
    rows = []
    for label, d in (("wall", wall), ("CPU", cpu)):
        w, ll = np.array(d["welch"]), np.array(d["lpm"])
        ratio = float(np.median(ll / w))
        rows += [
            f"| Welch (segment {segment}), {label} | {np.median(w):.3f} | {' '.join(f'{x:.3f}' for x in w)} | 1.0 |",
            f"| LPM (degree 2, full resolution), {label} | {np.median(ll):.3f} | {' '.join(f'{x:.3f}' for x in ll)} "
            f"| {np.median(ll) / np.median(w):.2f} (median of per-pair ratios {ratio:.2f}) |",
        ]
    tw = float(np.median(wall["welch"]))
    return [
        f"## LPM against Welch, 3x3, N = {n:,} per channel (in-process, alternating, {repeat} pairs)",
        "",
        "| method, clock | median time [s] | all runs [s] | ratio to Welch |",
        "|---|---|---|---|",
        *rows,
        f"| LPM, numpy twin (reference, one run), wall | {t_py:.2f} | | {t_py / tw:.1f} |",
        "",
        f"Kernel against the numpy twin on this record: G {agree_g:.1e} (max abs / max |G|), "
        f"std {agree_s:.1e} (max relative); same lines kept: {bool(np.array_equal(got.freqs, ref.freqs))}.",
        "",
    ]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=4_000_000)
    ap.add_argument("--segment", type=int, default=4096)
    ap.add_argument("--lpm-n", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=None)
    ap.add_argument("--lpm-only", action="store_true", help="only the LPM against Welch section")
    args = ap.parse_args()
    u, y = record(args.n)
    lines = [
        "# FRF estimation speed (benchmarks/bench_frf.py)",
        "",
        f"Machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}, "
        f"numpy {np.__version__}, OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}; "
        f"median of {args.repeat} runs.",
        "",
    ]
    if args.lpm_only:
        lines += lpm_against_welch(u, y, args.lpm_n, args.segment, args.repeat)
        print("\n".join(lines))
        return
    with tempfile.TemporaryDirectory() as tmp:
        src = os.path.join(tmp, "rec.npz")
        cols = {f"u{k + 1}": u[:, k] for k in range(3)} | {f"y{k + 1}": y[:, k] for k in range(3)}
        np.savez(src, t=np.arange(args.n) * 1.0, **cols)
        cmd = [
            sys.executable, "-m", "stageid", "frf", src, "--inputs", "u1,u2,u3", "--outputs", "y1,y2,y3",
            "--segment", str(args.segment), "-o", os.path.join(tmp, "frf.npz"),
        ]  # fmt: skip
        t_cli = median_time(lambda: subprocess.run(cmd, check=True, capture_output=True), args.repeat)
        t_ref = median_time(lambda: scipy_reference(u, y, args.segment), args.repeat)
        exp = Experiment(u, y, 1.0)
        t_api = median_time(lambda: welch_frf(exp, args.segment), args.repeat)
        H_ref = scipy_reference(u, y, args.segment)[0]
        H = welch_frf(exp, args.segment).response
        agree = float(np.max(np.abs(H - H_ref)) / np.max(np.abs(H_ref)))
    lines += [
        f"## Welch H1 + coherence + std, 3x3, N = {args.n:,} per channel, segment {args.segment}",
        "",
        "| method | time [s] | speed-up vs scipy |",
        "|---|---|---|",
        f"| scipy.signal.csd per pair (21 calls) + solve, in-process | {t_ref:.2f} | 1.0 |",
        f"| `stageid frf` whole process from NPZ (start, read, write) | {t_cli:.2f} | {t_ref / t_cli:.1f} |",
        f"| `stageid.frf.welch_frf` in-process | {t_api:.2f} | {t_ref / t_api:.1f} |",
        "",
        f"H1 agreement with the scipy composition: {agree:.1e} (max relative).",
        "",
    ]
    lines += lpm_against_welch(u, y, args.lpm_n, args.segment, args.repeat)
    text = "\n".join(lines)
    print(text)
    if args.out:
        with open(args.out, "w") as fh:
            fh.write(text)


if __name__ == "__main__":
    main()
