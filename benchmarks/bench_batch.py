"""Batch throughput: ``stageid batch`` on 1 and 2 local Dask workers against the same commands
run one after another in one process, plus the costs that decide a 10 000-unit extrapolation.

The batch: ``--jobs`` P-558 units, each a ``combined`` experiment (3 inputs, 3 outputs, 3000
samples, own noise seed) identified by ``identify statespace --inputs Z,Rx,Ry --outputs
z,rx,ry`` with automatic horizon and order (Hankel-MAP, the held-out selection sweeps): what a
fleet re-identification runs.  Each timing is a whole process (Python start, imports, the
local cluster's start and stop for the batch), in alternating rounds: serial, 1 worker,
2 workers, serial, ...; medians over ``--rounds``.  Also measured: the cluster's start, the
scheduler's cost per task (no-op tasks), hashing the inputs, a rerun that skips every job, and
the per-job seconds the workers report (first job of a worker = imports + JIT).

    .venv/bin/python benchmarks/bench_batch.py [--jobs 40] [--rounds 3] [--out benchmarks/RESULTS-dask.md]
"""

from __future__ import annotations

import argparse
import csv
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from stageid.cli.main import main

ENV = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
COMMAND = "identify statespace unit{i}.csv --inputs Z,Rx,Ry --outputs z,rx,ry"
SERIAL = """
import shlex, sys, contextlib, io
from stageid.cli.main import main
for line in open(sys.argv[1]).read().splitlines()[1:]:
    name, command = line.split(",", 1)
    with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
        rc = main([*shlex.split(command), "-o", f"{sys.argv[2]}/{name}.json"])
    assert rc == 0, (name, rc)
"""


def make_fleet(folder: Path, n_jobs: int) -> Path:
    """``n_jobs`` P-558 records (combined experiment, seeds 0..n-1) and their manifest."""
    for i in range(n_jobs):
        rc = main(["plants", "p558", "--experiment", "combined", "--seed", str(i), "-o", str(folder / f"unit{i}.csv")])
        assert rc == 0
    manifest = folder / "fleet.csv"
    manifest.write_text("name,command\n" + "".join(f"unit{i},{COMMAND.format(i=i)}\n" for i in range(n_jobs)))
    return manifest


CPU: list[float] = []  # CPU seconds (user + system) of each timed process and its descendants


def timed(args: list[str], cwd: Path | None = None) -> float:
    """Wall seconds of a whole process; its CPU seconds (workers included) go to ``CPU``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run(args, check=True, env=ENV, capture_output=True, cwd=cwd)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    CPU.append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
    return wall


def run_serial(manifest: Path, out: Path) -> float:
    out.mkdir()
    return timed(
        [sys.executable, "-c", SERIAL, str(manifest), str(out)], cwd=manifest.parent
    )  # paths as in the manifest


def run_batch(manifest: Path, out: Path, workers: int) -> tuple[float, list[float]]:
    wall = timed(
        [sys.executable, "-m", "stageid", "batch", str(manifest), "--out", str(out), "--workers", str(workers)]
    )
    with open(out / "summary.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert all(r["status"] == "ok" for r in rows), rows
    return wall, [float(r["seconds"]) for r in rows]


def scheduler_overhead(n_tasks: int = 2000) -> tuple[float, float]:
    """Seconds to start and stop a 2-worker local cluster; seconds per no-op task through it."""
    from distributed import as_completed

    from stageid.runtime.cluster import dask_client

    start = time.perf_counter()
    with dask_client(n_workers=2) as client:
        started = time.perf_counter() - start
        client.submit(int, 0).result()  # connections made
        t0 = time.perf_counter()
        futures = [client.submit(int, i, pure=False) for i in range(n_tasks)]
        for _ in as_completed(futures, loop=client.loop):
            pass
        per_task = (time.perf_counter() - t0) / n_tasks
    return started, per_task


def worker_settings(manifest: Path, pairs: int = 5) -> tuple[float, float, float]:
    """Median job seconds on a 1-worker cluster with Dask's default worker settings and with
    stageid's (:data:`stageid.cluster.LOCAL_WORKER_CONFIG`), submissions alternating, and the
    same job in this process: (dask defaults, stageid settings, in-process)."""
    import dask
    from distributed import Client, LocalCluster

    from stageid.cli.batch import run_command_line
    from stageid.runtime.cluster import LOCAL_WORKER_CONFIG

    argv = tuple(COMMAND.format(i=0).replace("unit0.csv", str(manifest.parent / "unit0.csv")).split())
    kw = {"n_workers": 1, "threads_per_worker": 1, "dashboard_address": None, "silence_logs": 40}
    # the tuned cluster first: a nanny also sets its pre-spawn variables in this process's
    # environment, which later workers would inherit
    with dask.config.set(LOCAL_WORKER_CONFIG):
        tuned = LocalCluster(**kw)
    with tuned, LocalCluster(**kw) as default:
        with Client(default, set_as_default=False) as a, Client(tuned, set_as_default=False) as b:
            trim = b.run(lambda: os.environ.get("MALLOC_TRIM_THRESHOLD_"))
            assert set(trim.values()) == {None}, trim
            runs: dict[str, list[float]] = {"default": [], "stageid": [], "in-process": []}
            for _ in range(pairs + 1):  # the first pair pays imports and JIT: dropped
                for label, client in (("default", a), ("stageid", b)):
                    runs[label].append(client.submit(run_command_line, argv, ".json", pure=False).result()["seconds"])
                runs["in-process"].append(run_command_line(argv, ".json")["seconds"])
    return tuple(statistics.median(v[1:]) for v in runs.values())  # type: ignore[return-value]


def hashing_rate(folder: Path) -> tuple[float, float]:
    """(MB hashed, MB/s) for every record of the fleet: what the client reads to decide skips."""
    from stageid.batch.state import content_hash

    files = sorted(folder.glob("unit*.csv"))
    size = sum(f.stat().st_size for f in files) / 1e6
    start = time.perf_counter()
    for f in files:
        content_hash(f)
    return size, size / (time.perf_counter() - start)


def main_bench() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=40)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--out", default=None, help="Append the results as markdown to this file.")
    opts = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench-batch-"))
    try:
        manifest = make_fleet(work, opts.jobs)
        times: dict[str, list[float]] = {"serial": [], "1 worker": [], "2 workers": []}
        cpu: dict[str, list[float]] = {k: [] for k in times}
        job_seconds: dict[str, list[float]] = {"1 worker": [], "2 workers": []}
        for r in range(opts.rounds):
            times["serial"].append(run_serial(manifest, work / f"serial{r}"))
            cpu["serial"].append(CPU[-1])
            for n, label in ((1, "1 worker"), (2, "2 workers")):
                wall, seconds = run_batch(manifest, work / f"batch{n}-{r}", n)
                times[label].append(wall)
                cpu[label].append(CPU[-1])
                job_seconds[label] += seconds
            print(
                f"round {r + 1}: " + ", ".join(f"{k} {v[-1]:.1f} s (CPU {cpu[k][-1]:.1f} s)" for k, v in times.items()),
                flush=True,
            )
        rerun = timed([sys.executable, "-m", "stageid", "batch", str(manifest), "--out", str(work / "batch2-0")])
        started, per_task = scheduler_overhead()
        size, rate = hashing_rate(work)
        settings = worker_settings(manifest)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    report(opts, times, cpu, job_seconds, rerun, started, per_task, size, rate, settings)


def report(opts, times, cpu, job_seconds, rerun, started, per_task, size, rate, settings) -> None:
    med = {k: statistics.median(v) for k, v in times.items()}
    med_cpu = {k: statistics.median(v) for k, v in cpu.items()}
    lines = [
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}; {opts.jobs} jobs, {opts.rounds} alternating rounds, medians.",
        "",
        "| run | wall [s] | jobs/s | vs serial | CPU [s] (all processes) | CPU s/job |",
        "|---|---|---|---|---|---|",
    ]
    for k, v in med.items():
        lines.append(
            f"| {k} | {v:.1f} | {opts.jobs / v:.2f} | {med['serial'] / v:.2f}x | {med_cpu[k]:.1f} "
            f"| {med_cpu[k] / opts.jobs:.2f} |"
        )
    for label, seconds in job_seconds.items():
        s = sorted(seconds)
        lines.append(
            f"\nJob seconds on the workers ({label}): median {statistics.median(s):.2f}, "
            f"max {s[-1]:.2f} (a worker's first job: imports + JIT), sum/round {sum(s) / opts.rounds:.1f}."
        )
    lines += [
        "",
        f"Local 2-worker cluster start+stop: {started:.1f} s.  Scheduler cost per no-op task "
        f"(2000 tasks, 2 workers): {per_task * 1e3:.2f} ms.  Hashing the inputs: {size:.1f} MB at "
        f"{rate:.0f} MB/s.  Rerun with every job skipped (no cluster started): {rerun:.1f} s.",
        "",
        f"One job (median of 5, alternating): on a worker with Dask's default settings {settings[0]:.2f} s, "
        f"with stageid's LOCAL_WORKER_CONFIG {settings[1]:.2f} s, in this process {settings[2]:.2f} s.",
    ]
    text = "\n".join(lines)
    print(text)
    if opts.out:
        with open(opts.out, "a") as fh:
            fh.write("\n" + text + "\n")


if __name__ == "__main__":
    main_bench()
