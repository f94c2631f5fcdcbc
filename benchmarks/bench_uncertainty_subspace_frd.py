"""Cost of ``response_uncertainty`` against the identification it follows (issue 20, point 5).

Alternating paired runs (the machine is shared): for each case, ``fit`` alone, ``fit`` then
``response_uncertainty`` on the default grid (200 log-spaced points over the identified
band), and for Hankel-MAP also ``fit`` then the uncertainty with the former even covariance
grid (``grid="even"``) and with the old ``overlap="inflate"`` covariance, repeated; medians of wall and CPU time and of the per-run ratios to ``fit``.
``--cli`` instead times ``stageid identify statespace`` on one P-558 record with and without
``--uncertainty`` (whole processes, alternating).

``--columns`` times the exact uncertainty alone on the P-558 direct fit for several column caps
(``MAX_OVERLAP_COLUMNS``), CPU medians, with the change of the std against the default cap.
``--profile`` prints where the uncertainty's time goes (cProfile, per Hankel-MAP case).

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_uncertainty_subspace_frd.py [repeats] [--cli|--columns|--profile]
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from stageid.frf import FRDIdentification, FrequencyResponse
from stageid.plants import piezo_stage as ps
from stageid.subspace import HankelMAP
from stageid.subspace.uncertainty import realised_response_uncertainty

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
sys.path.insert(0, str(Path(__file__).parents[1] / "studies" / "uncertainty"))
from run_study import two_mode_plant  # noqa: E402

from _subspace_systems import band_limited, random_stage, record  # noqa: E402


def p558_direct():
    g = ps.model()
    exp = record(g, band_limited(20000, 3, g.dt, 1) * np.array([10.0, 100.0, 100.0]), 0.01, 1)
    return lambda: HankelMAP(order=15).fit(exp)


def p558_direct_long():
    g = ps.model()
    exp = record(g, band_limited(50000, 3, g.dt, 1) * np.array([10.0, 100.0, 100.0]), 0.01, 1)
    return lambda: HankelMAP(order=15).fit(exp)


def unseen(seed: int, m: int, q: int, modes: int, n: int, noise: float, **kw):
    """The unseen stages of ``studies/uncertainty/run_study.py`` (its seed 1), the record made once."""
    g = random_stage(seed, m=m, q=q, modes=modes)
    exp = record(g, band_limited(n, m, g.dt, 1), noise, 1, names=False)
    return lambda: HankelMAP(order=kw.get("order", g.n_states), horizon=kw.get("horizon", "auto")).fit(exp)


def p558_channels():
    exps = [ps.EXPERIMENTS[k](0) for k in ("chirp-z", "chirp-rx", "chirp-ry")]
    return lambda: HankelMAP(order=[7, 4, 4], per_channel=True).fit(exps)


def frd():
    g = two_mode_plant()
    f = np.linspace(1, 200, 300)
    Gt = g.frequency_response(f)
    sd = 0.02 * np.abs(Gt).max() * np.ones(Gt.shape)
    rng = np.random.default_rng(0)
    data = FrequencyResponse(f, Gt + sd * (rng.standard_normal(Gt.shape) + 1j * rng.standard_normal(Gt.shape)), sd)
    return lambda: FRDIdentification(order="auto", sample_time=g.dt).fit(data)


def band_of(res):
    if hasattr(res, "channels"):
        return min(c.band[0] for c in res.channels), max(c.band[1] for c in res.channels)
    return res.band


CASES = {
    "p558 direct (20 000 samples, horizon auto, order 15)": p558_direct,
    "p558 direct (50 000 samples, horizon auto, order 15)": p558_direct_long,
    "p558 per channel (auto horizon)": p558_channels,
    "unseen 1x2 (6000 samples, horizon 25, order 4)": lambda: unseen(9, 1, 2, 2, 6000, 0.02, horizon=25, order=4),
    "unseen 2x2 (20 000 samples)": lambda: unseen(22, 2, 2, 4, 20000, 0.01),
    "unseen SISO (8000 samples)": lambda: unseen(32, 1, 1, 3, 8000, 0.03),
    "unseen 3x2 (12 000 samples)": lambda: unseen(42, 2, 3, 3, 12000, 0.01),
    "frd 1x2 (order auto)": frd,
}


def _timed(run) -> tuple[float, float]:
    t, c = time.perf_counter(), time.process_time()
    run()
    return time.perf_counter() - t, time.process_time() - c


def _variants(fit):
    def grid(res):
        lo, hi = band_of(res)
        return np.geomspace(lo if lo > 0 else 1e-3 * hi, hi, 200)

    out = {"fit": fit, "fit + uncertainty": lambda: (lambda r: r.response_uncertainty(grid(r)))(fit())}
    if hasattr(fit(), "channels"):  # Hankel-MAP: also the former even covariance grid and the old covariance
        out["fit + uncertainty (even grid)"] = lambda: (
            lambda r: realised_response_uncertainty(r, grid(r), grid="even")
        )(fit())
        out["fit + uncertainty (inflate)"] = lambda: (
            lambda r: realised_response_uncertainty(r, grid(r), overlap="inflate")
        )(fit())
    return out


def main() -> None:
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    repeats = int(args[0]) if args else 5
    if "--cli" in sys.argv:
        return cli(repeats)
    if "--columns" in sys.argv:
        return columns(repeats)
    if "--profile" in sys.argv:
        return profile(repeats)
    for name, make in CASES.items():
        variants = _variants(make())
        for run in variants.values():
            run()  # warm-up (compilation, caches)
        wall = {k: [] for k in variants}
        cpu = {k: [] for k in variants}
        for _ in range(repeats):
            for k, run in variants.items():  # alternating A B C A B C ...
                w, c = _timed(run)
                wall[k].append(w)
                cpu[k].append(c)
        print(f"{name}, {repeats} rounds:", flush=True)
        for k in variants:
            rw = [b / a for a, b in zip(wall["fit"], wall[k])]
            rc = [b / a for a, b in zip(cpu["fit"], cpu[k])]
            print(
                f"  {k:30s} wall {statistics.median(wall[k]):.3f} s (ratio {statistics.median(rw):.2f}, "
                f"{min(rw):.2f}-{max(rw):.2f}), CPU {statistics.median(cpu[k]):.3f} s (ratio {statistics.median(rc):.2f}, "
                f"{min(rc):.2f}-{max(rc):.2f})",
                flush=True,
            )


def columns(repeats: int) -> None:
    """The exact uncertainty alone against the fit, for several column caps (alternating)."""
    import stageid.subspace.uncertainty as unc

    fit = p558_direct()
    res = fit()
    lo, hi = band_of(res)
    f = np.geomspace(lo, hi, 200)
    default = unc.MAX_OVERLAP_COLUMNS
    caps = (default, 72, 60, 48, 36)
    ref = realised_response_uncertainty(res, f).std
    cpu = {c: [] for c in ("fit", "inflate", *caps)}
    change = {}
    for _ in range(repeats):
        cpu["fit"].append(_timed(fit)[1])
        cpu["inflate"].append(_timed(lambda: realised_response_uncertainty(res, f, overlap="inflate"))[1])
        for c in caps:
            unc.MAX_OVERLAP_COLUMNS = c
            cpu[c].append(_timed(lambda: realised_response_uncertainty(res, f))[1])
            change[c] = np.percentile(realised_response_uncertainty(res, f).std / ref, [50, 99])
        unc.MAX_OVERLAP_COLUMNS = default
    print(f"P-558 direct, {repeats} rounds, CPU medians: fit {statistics.median(cpu['fit']):.3f} s, "
          f"uncertainty with inflate {statistics.median(cpu['inflate']):.3f} s")  # fmt: skip
    for c in caps:
        print(
            f"  exact, {c} columns: {statistics.median(cpu[c]):.3f} s; std against {default} columns: "
            f"median {change[c][0]:.3f}, 99th percentile {change[c][1]:.3f}",
            flush=True,
        )


def profile(repeats: int) -> None:
    """Where the uncertainty's time goes: cProfile of ``repeats`` calls per Hankel-MAP case (after one)."""
    import cProfile
    import pstats

    for name, make in CASES.items():
        res = make()()
        if not hasattr(res, "channels"):
            continue
        lo, hi = band_of(res)
        f = np.geomspace(lo if lo > 0 else 1e-3 * hi, hi, 200)
        res.response_uncertainty(f)
        prof = cProfile.Profile()
        prof.enable()
        for _ in range(repeats):
            res.response_uncertainty(f)
        prof.disable()
        print(f"{name}, {repeats} calls:")
        pstats.Stats(prof).sort_stats("cumulative").print_stats(r"stageid|linalg|fft", 14)


def cli(repeats: int) -> None:
    """Whole ``stageid identify statespace`` processes on one P-558 CSV, without and with ``--uncertainty``."""
    from stageid.data.io import write_csv

    g = ps.model()
    exp = record(g, band_limited(20000, 3, g.dt, 1) * np.array([10.0, 100.0, 100.0]), 0.01, 1)
    exe = str(Path(sys.executable).parent / "stageid")
    with tempfile.TemporaryDirectory() as tmp:
        cols = {n: exp.u[:, k] for k, n in enumerate(exp.input_names)}
        cols.update({n: exp.y[:, k] for k, n in enumerate(exp.output_names)})
        write_csv(f"{tmp}/p.csv", cols, dt=exp.dt)
        base = [exe, "identify", "statespace", f"{tmp}/p.csv", "--inputs", ",".join(exp.input_names)]
        base += ["--outputs", ",".join(exp.output_names), "--order", "15", "-o", f"{tmp}/m.json"]
        runs = {"without": base, "with": [*base, "--uncertainty", f"{tmp}/b.csv"]}
        times = {k: [] for k in runs}
        for _ in range(repeats):
            for k, cmd in runs.items():
                t = time.perf_counter()
                subprocess.run(cmd, check=True, capture_output=True)
                times[k].append(time.perf_counter() - t)
        ratios = [b / a for a, b in zip(times["without"], times["with"])]
        print(
            f"CLI P-558 (20 000 samples, order 15, horizon auto), {repeats} pairs: without "
            f"{statistics.median(times['without']):.2f} s, with {statistics.median(times['with']):.2f} s, "
            f"ratio {statistics.median(ratios):.2f} ({min(ratios):.2f}-{max(ratios):.2f})",
            flush=True,
        )


if __name__ == "__main__":
    main()
