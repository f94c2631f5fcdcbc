"""Cold start: whole commands with an empty numba kernel cache against a warmed one.

Run:  .venv/bin/python benchmarks/bench_cold_start.py  [--repeat 3] [--cases hysteresis,statespace,demo]

Every timed run is a fresh ``python -m stageid.cli.main`` process (one BLAS thread).  A *cold*
run gets a new, empty ``NUMBA_CACHE_DIR``, so every kernel the command uses is compiled; a
*warm* run reuses a folder that one untimed run of the same command filled.  Python's own
bytecode cache is warm in both (the untimed run writes it), so the difference is numba's.
Cold and warm runs alternate, and each case reports the median wall time and the median CPU
time (user + system of the child; steadier than wall time on a shared machine) of
``--repeat`` runs of each, and the cold/warm ratio of the medians.

Cases (inputs are made before timing, in a temporary folder):

* ``hysteresis``: ``identify hysteresis`` (modified PI, defaults) on the dSPACE 20 Hz FORC
  record of ``../shared/data`` (MAT struct written to CSV here), or on the reference
  actuator's decaying triangle when the folder is absent;
* ``statespace``: ``identify statespace`` on the P-558 band-limited experiment;
* ``stage``: ``identify hysteresis --dynamics 1 --creep 0.05`` on the 20 and 100 Hz records
  (the stage path; long, not in the default set);
* ``demo``: ``stageid demo --only hysteresis`` (the part of the demo with the compiled
  hysteresis kernels); ``demo-full``: the whole demo (long, not in the default set).

The target (time to first result with an empty cache within 2x of warm) and the figures are
in ``benchmarks/RESULTS-cold-start.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "piezo_dspace_preisach"
DEFAULT_CASES = ("hysteresis", "statespace", "demo")


def run_stageid(args: list[str], cache: Path, cwd: Path) -> tuple[float, float]:
    """(wall s, CPU s) of one ``stageid`` process with ``cache`` as its numba cache."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # the bytecode cache is warm in both kinds of run
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "stageid.cli.main", *args], cwd=cwd, env=env, capture_output=True, text=True
    )
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)  # children run one at a time: the delta is this one
    if proc.returncode != 0:
        raise SystemExit(f"stageid {' '.join(args)} failed: {proc.stderr.strip().splitlines()[-1:]}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def dspace_csv(name: str, folder: Path) -> Path | None:
    """The dSPACE record ``name`` as a CSV (t, V, y), or None when the shared data are absent."""
    source = DATA / f"{name}.mat"
    if not source.exists():
        return None
    import numpy as np
    from scipy.io import loadmat

    mat = loadmat(source, squeeze_me=True, struct_as_record=False)
    rec = mat[next(k for k in mat if not k.startswith("__"))]
    t = np.asarray(rec.X.Data, float)
    table = np.column_stack([t - t[0], np.asarray(rec.Y[2].Data, float), np.asarray(rec.Y[0].Data, float)])
    path = folder / f"{name}.csv"
    np.savetxt(path, table, delimiter=",", header="t,V,y", comments="", fmt="%.10g")
    return path


def prepare(case: str, folder: Path) -> tuple[list[str], str]:
    """The command of ``case`` (inputs written into ``folder``) and a line saying what it runs on."""
    if case in ("hysteresis", "stage"):
        records = [dspace_csv("20_hz_no_lp", folder)] + (
            [dspace_csv("100_hz_no_lp", folder)] if case == "stage" else []
        )
        if records[0] is None:
            run_stageid(
                ["plants", "piezo-actuator", "--experiment", "decaying-triangle", "-o", "tri.csv"], folder / "c", folder
            )
            records, what = [folder / "tri.csv"], "reference actuator, decaying triangle"
        else:
            what = "dSPACE " + " + ".join(p.stem for p in records)
        extra = ["--dynamics", "1", "--creep", "0.05"] if case == "stage" else []
        return [
            "identify",
            "hysteresis",
            *map(str, records),
            "--input",
            "V",
            "--output",
            "y",
            *extra,
            "-o",
            "h.json",
        ], what
    if case == "statespace":
        run_stageid(["plants", "p558", "--experiment", "band-limited", "-o", "exp.csv"], folder / "c", folder)
        args = ["identify", "statespace", "exp.csv", "--inputs", "Z,Rx,Ry", "--outputs", "z,rx,ry", "-o", "m.json"]
        return args, "P-558 band-limited, 10000 samples"
    if case == "demo":
        return ["demo", "--out", "demo-out", "--only", "hysteresis"], "demo --only hysteresis"
    if case == "demo-full":
        return ["demo", "--out", "demo-out"], "the whole demo"
    raise SystemExit(f"unknown case {case!r}")


def measure(case: str, repeat: int) -> dict:
    """Median wall and CPU seconds of cold and warm runs of ``case``, alternating."""
    with tempfile.TemporaryDirectory(prefix="stageid-cold-") as tmp:
        folder = Path(tmp)
        args, what = prepare(case, folder)
        warm_cache = folder / "warm-cache"
        run_stageid(args, warm_cache, folder)  # fills the warm cache and the bytecode cache
        runs: dict[str, list[tuple[float, float]]] = {"cold": [], "warm": []}
        for i in range(repeat):
            order = ("cold", "warm") if i % 2 == 0 else ("warm", "cold")
            for kind in order:
                cache = warm_cache if kind == "warm" else folder / f"cold-cache-{i}"
                runs[kind].append(run_stageid(args, cache, folder))
    med = {k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v)) for k, v in runs.items()}
    every = " / ".join(" ".join(f"{c:.1f}" for _, c in runs[k]) for k in ("cold", "warm"))
    return {"case": case, "what": what, "cold": med["cold"], "warm": med["warm"], "runs": every}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="cold and warm runs per case (median)")
    parser.add_argument("--cases", default=",".join(DEFAULT_CASES), help="comma-separated cases")
    opts = parser.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, load {load:.1f}, "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, median of {opts.repeat}"
    )
    print(
        "| case | input | cold wall s | warm wall s | ratio wall | cold CPU s | warm CPU s | ratio CPU "
        "| CPU s of every run, cold / warm |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for case in opts.cases.split(","):
        r = measure(case, opts.repeat)
        (cw, cc), (ww, wc) = r["cold"], r["warm"]
        print(
            f"| {case} | {r['what']} | {cw:.1f} | {ww:.1f} | {cw / ww:.2f} | {cc:.1f} | {wc:.1f} | {cc / wc:.2f} "
            f"| {r['runs']} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
