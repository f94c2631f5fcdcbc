"""MIMO state-space identification benchmark: stageid HankelMAP against its Python peers.

The P-558 3x3 reference (15 states, Ts = 2 ms), white random-binary inputs on all three
channels, 1 % output noise, order 15.  Every tool runs in its own process, single-threaded
(OMP/OPENBLAS/MKL/NUMBA threads = 1), side by side in one run; each (tool, N) runs once
untimed (imports, first calls), then is repeated, and the median wall time of the
identification call is reported together with the peak
resident memory of the worker process and the frequency-response error against the true
model (largest error over 0-250 Hz relative to each input column's largest true gain).

Peers (``pip install -e '.[bench]'``):

* stageid: ``HankelMAP(order=15)`` with its defaults (horizon chosen by held-out prediction
  error) and ``stageid-p40``: the same with a fixed horizon ``p = 40`` (no selection), the
  counterpart of python-control's fixed 150 Markov parameters;
* python-control: ``markov`` with 150 parameters + ``eigensys_realization`` (order 15);
* SIPPY (``sippy-unipi``): N4SID with ``SS_fixed_order=15`` at its default horizons f = p = 20;
* nfoursid: ``NFourSID(num_block_rows=20)`` then ``system_identification(rank=15)``.

Also measured: the whole ``stageid identify statespace`` process on an NPZ file against the
whole process of an equivalent python-control script, and the per-window cost of the fused
recursive MAP update (eq. 17-18) at regressor dimension 190 against a textbook numpy update.

On a loaded machine single wall-clock figures mislead: ``--paired ROUNDS`` instead runs
stageid (default settings) and python-control in two long-lived workers, one call each per
round in alternating order, and prints the medians of wall and CPU time (``process_time``) with
the median of the per-round ratios; then the same for the two whole processes (CPU time of
the child processes from ``getrusage``).

Usage::

    python benchmarks/bench_subspace.py                 # N = 5e3, 5e4, 5e5, 5e6; writes RESULTS-subspace.md
    python benchmarks/bench_subspace.py --sizes 5000 50000 --repeats 3 --no-write
    python benchmarks/bench_subspace.py --paired 15     # paired rounds at N = 50 000, printed only
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ENV_1THREAD = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NUMBA_NUM_THREADS": "1",
    "VECLIB_MAXIMUM_THREADS": "1",
}
TOOLS = ("stageid", "stageid-p40", "python-control", "sippy", "nfoursid")
ORDER = 15
# per-worker limits: address space and wall time (a peer that exceeds them is reported so)
MEMORY_LIMIT_GB = 12.0
TIMEOUT_S = 600.0


# ---------------------------------------------------------------------------- data
def make_data(n: int, seed: int = 0):
    """White +-1 inputs (Z, Rx, Ry), P-558 response plus 1 % white output noise."""
    import numpy as np

    from stageid.plants import piezo_stage as ps

    rng = np.random.default_rng([seed, n])
    u = np.where(rng.random((n, 3)) < 0.5, -1.0, 1.0)
    y = ps.model().simulate(u)
    y = y + 0.01 * y.std(axis=0) * rng.standard_normal(y.shape)
    return u, y


def response_error(A, B, C, D, dt: float) -> float:
    import numpy as np

    from stageid.models import StateSpaceModel
    from stageid.plants import piezo_stage as ps

    f = np.linspace(0.0, 250.0, 1001)
    Gt = ps.model().frequency_response(f)
    Ge = StateSpaceModel(np.asarray(A), np.asarray(B), np.asarray(C), np.asarray(D), dt).frequency_response(f)
    return float(np.max(np.abs(Ge - Gt).max(axis=0) / np.abs(Gt).max(axis=(0, 1))[None, :]))


# ------------------------------------------------------------------------- workers
def run_tool(tool: str, u, y, dt: float):
    """Identify with one tool; returns (A, B, C, D)."""
    import numpy as np

    if tool in ("stageid", "stageid-p40"):
        from stageid.data import Experiment
        from stageid.subspace import HankelMAP

        horizon = "auto" if tool == "stageid" else 40
        res = HankelMAP(order=ORDER, horizon=horizon).fit(Experiment(u, y, dt))
        g = res.model
        return g.A, g.B, g.C, g.D
    if tool == "python-control":
        import control

        H = control.markov(y.T, u.T, m=150)
        sys_, _ = control.eigensys_realization(H, ORDER)  # dt=True like markov(); returns (system, singular values)
        return sys_.A, sys_.B, sys_.C, sys_.D
    if tool == "sippy":
        from sippy_unipi import system_identification

        mdl = system_identification(y.T, u.T, "N4SID", SS_fixed_order=ORDER, tsample=dt)
        return mdl.A, mdl.B, mdl.C, mdl.D
    if tool == "nfoursid":
        import pandas as pd
        from nfoursid.nfoursid import NFourSID

        df = pd.DataFrame(np.hstack([u, y]), columns=["u1", "u2", "u3", "y1", "y2", "y3"])
        nf = NFourSID(df, output_columns=["y1", "y2", "y3"], input_columns=["u1", "u2", "u3"], num_block_rows=20)
        nf.subspace_identification()
        ss, _ = nf.system_identification(rank=ORDER)
        return ss.a, ss.b, ss.c, ss.d
    raise SystemExit(f"unknown tool {tool!r}")


def worker(tool: str, n: int, repeats: int, warmup: int = 0) -> None:
    """Time ``repeats`` identifications after ``warmup`` untimed ones (imports, first calls)."""
    limit = int(MEMORY_LIMIT_GB * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    import numpy as np  # noqa: F401  (imported before timing)

    u, y = make_data(n)
    dt = 0.002
    times = []
    err = float("nan")
    for _ in range(warmup):
        run_tool(tool, u, y, dt)
    for _ in range(repeats):
        t0 = time.perf_counter()
        A, B, C, D = run_tool(tool, u, y, dt)
        times.append(time.perf_counter() - t0)
        err = response_error(A, B, C, D, dt)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20  # GB (ru_maxrss is KiB on Linux)
    print(json.dumps({"tool": tool, "n": n, "times": times, "peak_gb": peak, "error": err}))


def serve(tool: str, n: int) -> None:
    """Paired-mode worker: one timed identification per input line, one JSON line out."""
    u, y = make_data(n)
    run_tool(tool, u, y, 0.002)  # imports and first calls, untimed
    for _ in sys.stdin:
        t0, c0 = time.perf_counter(), time.process_time()
        A, B, C, D = run_tool(tool, u, y, 0.002)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        print(json.dumps({"wall": wall, "cpu": cpu, "error": response_error(A, B, C, D, 0.002)}), flush=True)


def _paired_lines(name_a: str, a: list[dict], name_b: str, b: list[dict]) -> list[str]:
    """Medians of ``b`` against ``a`` (wall and CPU), the median of the per-round ratios b / a."""
    med = statistics.median
    lines = [f"| {name} | {1e3 * med(x['wall'] for x in xs):.1f} | {1e3 * med(x['cpu'] for x in xs):.1f} |"
             for name, xs in ((name_a, a), (name_b, b))]  # fmt: skip
    ratio = {k: med(y[k] / x[k] for x, y in zip(a, b)) for k in ("wall", "cpu")}
    of_medians = {k: med(y[k] for y in b) / med(x[k] for x in a) for k in ("wall", "cpu")}
    lines.append(
        f"| {name_b} / {name_a} | {of_medians['wall']:.1f}x (paired {ratio['wall']:.1f}x) "
        f"| {of_medians['cpu']:.1f}x (paired {ratio['cpu']:.1f}x) |"
    )
    return lines


def paired(rounds: int, n: int = 50000) -> str:
    """In-process and whole-process comparison of stageid's default against python-control,
    alternating call by call (see the module notes)."""
    env = {**os.environ, **ENV_1THREAD}
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    workers = {
        tool: subprocess.Popen(
            [sys.executable, str(Path(__file__)), "--serve", tool, str(n)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            env=env,
        )  # fmt: skip
        for tool in ("stageid", "python-control")
    }
    runs: dict[str, list[dict]] = {tool: [] for tool in workers}
    for r in range(rounds):
        for tool in list(workers)[:: 1 if r % 2 == 0 else -1]:
            workers[tool].stdin.write("go\n")
            workers[tool].stdin.flush()
            runs[tool].append(json.loads(workers[tool].stdout.readline()))
    for w in workers.values():
        w.stdin.close()
        w.wait()
    errors = {tool: runs[tool][-1]["error"] for tool in runs}
    lines = [
        f"Paired, N = {n}, {rounds} rounds (one call of each per round, order alternating); medians:",
        "",
        "| in-process | wall [ms] | CPU [ms] |",
        "|---|---|---|",
        *_paired_lines("stageid default", runs["stageid"], "python-control", runs["python-control"]),
        "",
        f"FR error: stageid {errors['stageid']:.3e}, python-control {errors['python-control']:.3e}.",
        "",
    ]
    from stageid.data import Experiment, write_npz

    u, y = make_data(n)
    with tempfile.TemporaryDirectory() as d:
        data = Path(d) / "run.npz"
        write_npz(data, Experiment(u, y, 0.002, ("Z", "Rx", "Ry"), ("z", "rx", "ry")))
        script = Path(d) / "pycontrol_id.py"
        script.write_text(PYCONTROL_SCRIPT)
        cmds = _process_commands(data, script, Path(d))
        for cmd in cmds.values():  # untimed: bytecode and file cache
            subprocess.run(cmd, env=env, capture_output=True)
        procs: dict[str, list[dict]] = {name: [] for name in cmds}
        for r in range(rounds):
            for name in list(cmds)[:: 1 if r % 2 == 0 else -1]:
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                t0 = time.perf_counter()
                proc = subprocess.run(cmds[name], env=env, capture_output=True, text=True)
                wall = time.perf_counter() - t0
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
                if proc.returncode != 0:
                    raise SystemExit(f"{name} failed: {proc.stderr.strip()[-300:]}")
                cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
                procs[name].append({"wall": wall, "cpu": cpu})
    lines += [
        "| whole process | wall [ms] | CPU [ms] |",
        "|---|---|---|",
        *_paired_lines("stageid CLI", procs["stageid CLI"], "python-control script", procs["python-control script"]),
        "",
    ]
    return "\n".join(lines)


def spawn(args: list[str], timeout: float = TIMEOUT_S) -> tuple[dict | None, str]:
    env = {**os.environ, **ENV_1THREAD}
    try:
        proc = subprocess.run(
            [sys.executable, str(Path(__file__)), *args], capture_output=True, text=True, env=env, timeout=timeout
        )
    except subprocess.TimeoutExpired:
        return None, f"timeout > {timeout:.0f} s"
    if proc.returncode != 0:
        tail = (proc.stderr.strip().splitlines() or ["failed"])[-1]
        if "MemoryError" in proc.stderr or "Unable to allocate" in proc.stderr or proc.returncode in (-9, 137):
            tail = f"out of memory (> {MEMORY_LIMIT_GB:g} GB)"
        return None, tail[:120]
    for line in proc.stdout.splitlines()[::-1]:
        if line.startswith("{"):
            return json.loads(line), ""
    return None, "no result"


# ------------------------------------------------------------------ process-level
PYCONTROL_SCRIPT = """
import sys, numpy as np, control, json
d = np.load(sys.argv[1])
u = np.column_stack([d[k] for k in ('Z', 'Rx', 'Ry')]); y = np.column_stack([d[k] for k in ('z', 'rx', 'ry')])
H = control.markov(y.T, u.T, m=150)
s, _ = control.eigensys_realization(H, 15)
json.dump({'A': np.asarray(s.A).tolist(), 'B': np.asarray(s.B).tolist(), 'C': np.asarray(s.C).tolist(),
           'D': np.asarray(s.D).tolist()}, open(sys.argv[2], 'w'))
"""


def _process_commands(data: Path, script: Path, folder: Path) -> dict[str, list[str]]:
    """The two whole processes: ``stageid identify statespace`` and the python-control script."""
    stageid_exe = str(Path(sys.executable).with_name("stageid"))
    cli = [stageid_exe, "identify", "statespace", str(data), "--inputs", "Z,Rx,Ry", "--outputs", "z,rx,ry"]
    return {
        "stageid CLI": [*cli, "--order", "15", "-o", str(folder / "m.json")],
        "python-control script": [sys.executable, str(script), str(data), str(folder / "pc.json")],
    }


def whole_process(n: int, repeats: int) -> dict:
    """Wall time of the whole `stageid identify statespace` process vs a python-control script."""

    from stageid.data import Experiment, write_npz

    u, y = make_data(n)
    env = {**os.environ, **ENV_1THREAD}
    # an installed package has its bytecode compiled; with PYTHONDONTWRITEBYTECODE set (as in some
    # shells) the untimed warm-up run could not cache it and every timed run would recompile stageid
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    out = {}
    with tempfile.TemporaryDirectory() as d:
        data = Path(d) / "run.npz"
        write_npz(data, Experiment(u, y, 0.002, ("Z", "Rx", "Ry"), ("z", "rx", "ry")))
        script = Path(d) / "pycontrol_id.py"
        script.write_text(PYCONTROL_SCRIPT)
        cmds = _process_commands(data, script, Path(d))
        subprocess.run(
            cmds["stageid CLI"], env=env, capture_output=True
        )  # warm the file cache (first run reads the package from disk)
        for name, cmd in cmds.items():
            times = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
                times.append(time.perf_counter() - t0)
                if proc.returncode != 0:
                    raise SystemExit(f"{name} failed: {proc.stderr.strip()[-300:]}")
            out[name] = statistics.median(times)
    return out


def recursive_update_cost() -> dict:
    """Microseconds per window of eq. 17-18 at p = 38, m = 1, q = 3 (d = 190)."""
    import numpy as np

    from stageid.subspace.map.recursion import recursive_map, recursive_map_python

    p, m, q = 38, 1, 3
    d = 2 * p * m + p * q
    rng = np.random.default_rng(0)
    n = 20000
    u, y = rng.standard_normal((n, m)), rng.standard_normal((n, q))
    recursive_map(u[:400], y[:400], p, np.zeros((p * q, d)), np.eye(d))  # compile / load cache
    times = []
    for _ in range(7):  # median: the machine is shared
        t0 = time.perf_counter()
        recursive_map(u, y, p, np.zeros((p * q, d)), np.eye(d))
        times.append((time.perf_counter() - t0) / (n - 2 * p + 1))
    fused = statistics.median(times)
    n_py = 1500
    t0 = time.perf_counter()
    recursive_map_python(u[:n_py], y[:n_py], p, np.zeros((p * q, d)), np.eye(d))
    py = (time.perf_counter() - t0) / (n_py - 2 * p + 1)
    return {"fused_us": fused * 1e6, "fused_min_us": min(times) * 1e6, "numpy_us": py * 1e6, "dimension": d}


# ------------------------------------------------------------------------- driver
def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worker", nargs=2, metavar=("TOOL", "N"))
    ap.add_argument("--sizes", type=int, nargs="+", default=[5000, 50000, 500000, 5000000])
    ap.add_argument("--tools", nargs="+", default=list(TOOLS))
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument(
        "--warmup",
        type=int,
        default=1,
        help="untimed runs before the timed ones, in each worker up to N = 500 000 (default 1)",
    )
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--paired", type=int, metavar="ROUNDS", help="paired rounds at N = 50 000 (printed only)")
    ap.add_argument("--serve", nargs=2, metavar=("TOOL", "N"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.serve:
        serve(args.serve[0], int(args.serve[1]))
        return
    if args.paired:
        print(paired(args.paired))
        return
    if args.worker:
        worker(args.worker[0], int(args.worker[1]), args.repeats, args.warmup)
        return
    rows = []
    skip: set[str] = set()
    for n in args.sizes:
        for tool in args.tools:
            if tool in skip:
                rows.append((tool, n, None, "skipped (failed at a smaller N)"))
                continue
            reps, warm = (args.repeats, args.warmup) if n <= 500000 else (1, 0)
            res, why = spawn(["--worker", tool, str(n), "--repeats", str(reps), "--warmup", str(warm)])
            rows.append((tool, n, res, why))
            if res is None:
                skip.add(tool)
            msg = f"{tool:>15} N={n:>8}: " + (
                f"{statistics.median(res['times']):8.3f} s  {res['peak_gb']:.2f} GB  err {res['error']:.2e}"
                if res
                else why
            )
            print(msg, flush=True)
    proc = whole_process(50000, args.repeats)
    print("whole process at N=50000:", proc, flush=True)
    rec = recursive_update_cost()
    print("recursive MAP update:", rec, flush=True)
    text = report(rows, proc, rec, args)
    print(text)
    if not args.no_write:
        (HERE / "RESULTS-subspace.md").write_text(text)


def report(rows, proc, rec, args) -> str:
    import platform

    by = {(t, n): (r, w) for t, n, r, w in rows}
    lines = [
        "# Benchmark: MIMO state-space identification (P-558 3x3, order 15)",
        "",
        f"Run: `python benchmarks/bench_subspace.py` on {platform.machine()} / Python {platform.python_version()}, "
        f"single-threaded, {args.warmup} untimed warm-up run(s) then the median of {args.repeats} "
        f"(one cold run above N = 500 000).  White +-1 inputs, 1 % output noise.",
        "Error: largest |G_est - G_true| over 0-250 Hz relative to each input column's largest true gain.",
        "",
        "| N | tool | time [s] | peak memory [GB] | FR error | time / stageid |",
        "|---|---|---|---|---|---|",
    ]
    for n in args.sizes:
        base = by.get(("stageid", n), (None, ""))[0]
        bt = statistics.median(base["times"]) if base else None
        for tool in args.tools:
            r, why = by.get((tool, n), (None, "not run"))
            if r is None:
                lines.append(f"| {n} | {tool} | {why} | | | |")
                continue
            t = statistics.median(r["times"])
            ratio = f"{t / bt:.1f}x" if bt else ""
            lines.append(f"| {n} | {tool} | {t:.3f} | {r['peak_gb']:.2f} | {r['error']:.2e} | {ratio} |")
    lines += ["", "Whole process, N = 50 000 (NPZ file in, model out), median wall time:", ""]
    for k, v in proc.items():
        lines.append(f"- {k}: {v:.2f} s")
    if len(proc) == 2:
        a, b = proc["stageid CLI"], proc["python-control script"]
        lines.append(f"- ratio: python-control script / stageid CLI = {b / a:.1f}x")
    lines += [
        "",
        f"Recursive MAP update (eq. 17-18), regressor dimension {rec['dimension']}: compiled (numba) "
        f"{rec['fused_us']:.1f} us per window; textbook numpy {rec['numpy_us']:.1f} us per window.",
        "",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    main()
