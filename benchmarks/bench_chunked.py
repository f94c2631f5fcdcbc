"""Chunked records: time and peak resident memory of ``stageid identify statespace`` (and ``frf``)
on a record larger than the memory target, here and on 1 or 2 local Dask workers.

    .venv/bin/python benchmarks/bench_chunked.py [--samples 60000000] [--repeats 3] [--folder /tmp/x]

Writes a 2-input, 2-output HDF5 record (white-noise inputs through a 4-state stage, noisy
outputs, float64: 32 bytes a sample) into ``--folder`` (never committed; removed at the end
unless ``--keep``), then runs the command in alternating order: in this process's child without
a scheduler, and with ``--scheduler`` on a local scheduler with 1 and with 2 workers (started
as processes here).  Peak RSS: ``/usr/bin/time -v`` of the command, plus each worker's VmHWM.
Figures go to benchmarks/RESULTS-dask.md.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
STAGEID = [sys.executable, "-m", "stageid"]
BLOCK = 1 << 20


def write_record(path: Path, n: int, seed: int = 0) -> None:
    """The 2x2 record, block by block (the state of every filter carried across blocks)."""
    import h5py
    from scipy.signal import lfilter

    rng = np.random.default_rng(seed)
    # G_ij = b_ij / a_i: two resonant output channels with cross-coupling
    a = [np.array([1.0, -1.8, 0.85]), np.array([1.0, -1.6, 0.73])]
    b = [
        [np.array([0.0, 0.1, 0.05]), np.array([0.0, 0.02, 0.0])],
        [np.array([0.0, 0.03, 0.01]), np.array([0.0, 0.2, -0.1])],
    ]
    zi = [[np.zeros(2), np.zeros(2)], [np.zeros(2), np.zeros(2)]]
    with h5py.File(path, "w") as f:
        f.attrs["dt"] = 1e-4
        ds = {k: f.create_dataset(k, (n,), dtype="f8", chunks=(BLOCK // 4,)) for k in ("u1", "u2", "y1", "y2")}
        for s in range(0, n, BLOCK):
            e = min(n, s + BLOCK)
            u = rng.standard_normal((e - s, 2))
            ds["u1"][s:e], ds["u2"][s:e] = u[:, 0], u[:, 1]
            for i, name in enumerate(("y1", "y2")):
                y = np.zeros(e - s)
                for j in range(2):
                    part, zi[i][j] = lfilter(b[i][j], a[i], u[:, j], zi=zi[i][j])
                    y += part
                ds[name][s:e] = y + 0.01 * rng.standard_normal(e - s) + 3.0


def _peak_kb(stderr: str) -> int:
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", stderr)
    return int(m.group(1)) if m else -1


class LocalCluster:
    """A scheduler and ``n`` worker processes on 127.0.0.1 (the way a cluster is run by hand)."""

    def __init__(self, n: int, folder: Path):
        self.n, self.folder = n, folder
        self.file = folder / f"scheduler-{n}.json"
        self.procs: list[subprocess.Popen] = []

    def __enter__(self) -> LocalCluster:
        env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
        self.file.unlink(missing_ok=True)
        sched = [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0"]
        sched += ["--no-dashboard", "--scheduler-file", str(self.file)]
        self.procs.append(subprocess.Popen(sched, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env))
        while not self.file.exists():
            time.sleep(0.1)
        time.sleep(0.5)
        self.address = json.loads(self.file.read_text())["address"]
        work = [sys.executable, "-m", "distributed.cli.dask_worker", "--nthreads", "1", "--no-nanny"]
        work += ["--no-dashboard", "--host", "127.0.0.1", "--scheduler-file", str(self.file)]
        for _ in range(self.n):
            self.procs.append(subprocess.Popen(work, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env))
        from distributed import Client

        with Client(self.address, timeout="60s") as c:
            c.wait_for_workers(self.n, timeout=120)
        return self

    def worker_peaks_kb(self) -> list[int]:
        out = []
        for p in self.procs[1:]:
            status = Path(f"/proc/{p.pid}/status").read_text()
            out.append(int(re.search(r"VmHWM:\s+(\d+)", status).group(1)))
        return out

    def __exit__(self, *exc) -> None:
        for p in reversed(self.procs):  # workers first, then the scheduler
            p.terminate()
            try:
                p.wait(timeout=5)
            except subprocess.TimeoutExpired:  # a worker retrying its scheduler does not stop on SIGTERM
                p.kill()
                p.wait(timeout=30)


def run(args: list[str], cwd: Path) -> tuple[float, int, str]:
    t0 = time.perf_counter()
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    proc = subprocess.run(["/usr/bin/time", "-v", *STAGEID, *args], cwd=cwd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"failed: {' '.join(args)}\n{proc.stderr[-2000:]}")
    return wall, _peak_kb(proc.stderr), proc.stdout + proc.stderr


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=60_000_000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--folder", default=None)
    ap.add_argument("--keep", action="store_true")
    ap.add_argument("--horizon", default="20")
    opts = ap.parse_args()
    folder = Path(opts.folder or tempfile.mkdtemp(prefix="stageid-chunked-"))
    folder.mkdir(parents=True, exist_ok=True)
    need = 32 * opts.samples * 1.1
    free = shutil.disk_usage(folder).free
    if free < need + 2e9:
        raise SystemExit(f"{folder}: {free / 1e9:.1f} GB free; the record needs {need / 1e9:.1f} GB plus 2 GB spare.")
    rec = folder / "record.h5"
    if not rec.exists():
        t0 = time.perf_counter()
        write_record(rec, opts.samples)
        print(f"wrote {rec} ({rec.stat().st_size / 1e9:.2f} GB) in {time.perf_counter() - t0:.0f} s", flush=True)
    ident = ["identify", "statespace", str(rec), "--inputs", "u1,u2", "--outputs", "y1,y2", "--order", "4"]
    ident += ["--horizon", opts.horizon, "--band", "0:5000"]
    results: dict[str, list[tuple[float, int]]] = {"here": [], "1 worker": [], "2 workers": []}
    for rep in range(opts.repeats):
        order = ["here", "1 worker", "2 workers"] if rep % 2 == 0 else ["2 workers", "1 worker", "here"]
        for how in order:
            out = folder / f"model-{how.replace(' ', '')}-{rep}.json"
            if how == "here":
                wall, kb, _ = run([*ident, "-o", str(out)], folder)
            else:
                with LocalCluster(int(how[0]), folder) as cl:
                    wall, kb, _ = run([*ident, "--scheduler", cl.address, "-o", str(out)], folder)
                    kb += sum(cl.worker_peaks_kb())
            results[how].append((wall, kb))
            print(f"repeat {rep} {how:>9}: {wall:7.1f} s, peak RSS {kb / 1024:7.0f} MiB", flush=True)
    # once each, here: the horizon chosen by held-out error, and Welch's spectra
    auto = [*ident[: ident.index("--horizon")], "--horizon", "auto", "--band", "0:5000"]
    for label, cmd in (("horizon auto", auto), ("frf welch", ["frf", str(rec), *ident[4:8]])):
        wall, kb, text = run([*cmd, "-o", str(folder / ("auto.json" if "horizon" in label else "frf.csv"))], folder)
        chosen = re.search(r"horizon (\d+)", text) if "horizon" in label else None
        extra = f", chosen horizon {chosen.group(1)}" if chosen else ""
        print(f"{label:>12} here: {wall:7.1f} s, peak RSS {kb / 1024:7.0f} MiB{extra}", flush=True)
    print("\nmedians (command + workers peak RSS):")
    for how, vals in results.items():
        w = statistics.median(v[0] for v in vals)
        k = statistics.median(v[1] for v in vals)
        print(f"  {how:>9}: {w:7.1f} s  ({opts.samples / w / 1e6:.2f} M samples/s), peak RSS {k / 1024:.0f} MiB")
    from stageid.models import load_model

    models = sorted(folder.glob("model-*.json"))  # same settings: here, 1 and 2 workers
    G = []
    for m in models:
        G.append(load_model(m).frequency_response(np.linspace(10.0, 4000.0, 50)))
    print(
        f"largest relative difference of the models' responses: {max(np.abs(g - G[0]).max() / np.abs(G[0]).max() for g in G):.2e}"
    )
    if not opts.keep:
        shutil.rmtree(folder)


if __name__ == "__main__":
    main()
