"""Best-linear-approximation speed: ``stageid frf --method bla`` against a plain numpy composition.

A 3x3 stage (three coupled resonances after a cubic per input) driven by an orthogonal
random-odd multisine design: M = 16 realisations x 3 experiments, each record P = 8 periods of
L = 8192 samples (65536 samples x 6 channels), written as NPZ files.  Both sides compute the same
estimate from the same files - the BLA, its noise and total std, the odd and even detection
levels (Pintelon & Schoukens' robust method):

* **numpy**: what a user writes without stageid - load every record into one array, ``rfft``
  every period, solve ``G^[m] = Y^[m] U^[m]^-1`` per line, the noise from the residuals'
  period-to-period scatter, mean and scatter over realisations, the detection lines' power;
* **stageid**: ``stageid frf --method bla --design`` as a subprocess (Python start, imports,
  reading the files realisation by realisation, writing the result all counted), and
  :func:`stageid.cli.bla.estimate_bla` in-process.  The CLI is also timed with a realisation's
  channels transformed on two threads (``STAGEID_THREADS=2``; one by default).

Both subprocesses import byte-compiled modules (a cache of the benchmark's own, filled by one
untimed run of each), as an installed package does.

Peak memory (VmHWM of a fresh child process) is reported beside one realisation's size.
Timings are medians of ``--repeat`` runs; the largest relative difference of the two estimates
is reported with them.  ``--compare-src`` times the CLI of another source tree (its ``src``)
alongside, e.g. a ``git archive`` of an earlier commit.

    .venv/bin/python benchmarks/bench_bla.py [--repeat 7] [--out FILE] [--compare-src OTHER/src]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

M, P, L, NU = 16, 8, 8192, 3
DT = 1e-4
CHANNELS_IN = ("u1", "u2", "u3")
CHANNELS_OUT = ("y1", "y2", "y3")


def write_records(folder: Path) -> list[Path]:
    """The design's records through the stage, one NPZ per realisation and experiment, and the design JSON."""
    from scipy.signal import lfilter  # here only: the numpy side's own process must not pay for scipy

    from stageid.signals import multisine, multisine_plan

    kw = dict(n_samples=P * L, dt=DT, f_low=5.0, f_high=2000.0, n_periods=P, lines="random-odd", seed=11)
    plan = multisine_plan(**kw, n_inputs=NU, mimo="orthogonal")
    rng = np.random.default_rng(0)
    files = []
    for r in range(M):
        for e in range(plan.n_experiments):
            u = multisine(**kw, rms=1.0, n_channels=NU, mimo="orthogonal", realisation=r, experiment=e)
            v = u + 0.2 * u**3
            y = np.empty_like(u)
            for i in range(NU):
                w, z = 2 * np.pi * 300.0 * (i + 1), 0.05
                a = [1.0, -2 * np.exp(-z * w * DT) * np.cos(w * DT), np.exp(-2 * z * w * DT)]
                mix = v[:, i] + 0.3 * v[:, (i + 1) % NU]
                y[:, i] = lfilter([sum(a)], a, mix) + 0.01 * rng.standard_normal(P * L)
            path = folder / f"ms_r{r + 1:02d}_e{e + 1}.npz"
            cols = {n: u[:, i] for i, n in enumerate(CHANNELS_IN)} | {n: y[:, i] for i, n in enumerate(CHANNELS_OUT)}
            np.savez(path, t=np.arange(P * L) * DT, **cols)
            files.append(path)
    design = {"n_periods": P, "experiments_per_realisation": plan.n_experiments} | {
        k: v.tolist()
        for k, v in (
            ("excited_lines", plan.excited),
            ("detection_odd_lines", plan.detection_odd),
            ("detection_even_lines", plan.detection_even),
        )
    }
    (folder / "ms.multisine.json").write_text(json.dumps(design))
    return files


def numpy_bla(files: list[Path], design: dict) -> dict[str, np.ndarray]:
    """The robust BLA composed from numpy: every record in memory, vectorised over lines."""
    ne = design["experiments_per_realisation"]
    exc = np.asarray(design["excited_lines"])
    det = {k: np.asarray(design[f"detection_{k}_lines"]) for k in ("odd", "even")}
    data = np.stack([np.column_stack([np.load(f)[c] for c in CHANNELS_IN + CHANNELS_OUT]) for f in files])
    data = data.reshape(M, ne, P, L, 2 * NU)  # (M, ne, P, L, ch)
    X = np.fft.rfft(data, axis=3)  # (M, ne, P, F, ch)
    X = np.moveaxis(X, 1, -1)  # (M, P, F, ch, ne)
    U, Y = X[:, :, exc, :NU], X[:, :, exc, NU:]
    Um, Ym = U.mean(axis=1), Y.mean(axis=1)  # (M, K, m, ne)
    Uinv = np.linalg.inv(Um)
    G = Ym @ Uinv  # (M, K, q, m)
    R = Y - G[:, None] @ U
    s2 = np.sum(np.abs(R - R.mean(axis=1, keepdims=True)) ** 2, axis=1) / (P - 1) / P  # (M, K, q, ne)
    var_n = np.einsum("akqe,akem->akqm", s2, np.abs(Uinv) ** 2)
    bla = G.mean(axis=0)
    out = {
        "bla": bla,
        "std": np.sqrt(var_n.sum(axis=0)) / M,
        "total": np.sqrt(np.sum(np.abs(G - bla) ** 2, axis=0) / (M - 1) / M),
    }
    for kind, lines in det.items():
        Yd = X[:, :, lines, NU:]  # (M, P, Kd, q, ne)
        mean = Yd.mean(axis=1)
        out[f"{kind}_power"] = np.mean(np.abs(mean) ** 2, axis=(0, 3))
        out[f"{kind}_noise"] = np.mean(np.sum(np.abs(Yd - mean[:, None]) ** 2, axis=1) / (P - 1) / P, axis=(0, 3))
    return out


def stageid_bla(files: list[Path], design: dict):
    from stageid.cli.bla import estimate_bla

    return estimate_bla(
        [str(f) for f in files], CHANNELS_IN, CHANNELS_OUT, None, P, 0, str(files[0].parent / "ms.multisine.json")
    )


def child_rss(code: str) -> float:
    """Peak RSS [MB] of a fresh Python running ``code`` (a child of its own, so maxima do not mix)."""
    # VmHWM belongs to the process's own address space (ru_maxrss would carry the forking parent's)
    probe = f"{code}\nimport re; print(int(re.search(r'VmHWM:\\s+(\\d+)', open('/proc/self/status').read()).group(1)) / 1024)"
    out = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True, text=True).stdout
    return float(out.strip().splitlines()[-1])


def timed(fn, repeat: int) -> tuple[list[float], list[float]]:
    """Wall and CPU seconds (this process and its children) of ``repeat`` runs."""
    walls, cpus = [], []
    for _ in range(repeat):
        t, c = time.perf_counter(), _cpu()
        fn()
        walls.append(time.perf_counter() - t)
        cpus.append(_cpu() - c)
    return walls, cpus


def _cpu() -> float:
    # getrusage counts microseconds; os.times counts clock ticks (10 ms), as coarse as the differences measured
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--out", default=None)
    ap.add_argument("--compare-src", default=None, help="another stageid source tree (its src/), timed alongside")
    ap.add_argument("--numpy-only", default=None, help=argparse.SUPPRESS)  # the numpy side as a process of its own
    args = ap.parse_args()
    if args.numpy_only:
        folder = Path(args.numpy_only)
        numpy_bla(sorted(folder.glob("ms_r*.npz")), json.loads((folder / "ms.multisine.json").read_text()))
        return
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        files = write_records(folder)
        design = json.loads((folder / "ms.multisine.json").read_text())
        agree = agreement(stageid_bla(files, design), numpy_bla(files, design))
        variants = {
            "np": lambda: numpy_bla(files, design),
            "api": lambda: stageid_bla(files, design),
        } | processes(folder, files, args.compare_src)
        loadavg = [os.getloadavg()[0]]
        runs = alternated(variants, args.repeat)
        loadavg.append(os.getloadavg()[0])
        memory = peak_memory(files)
    text = report(runs, args.repeat, loadavg, agree, memory, args.compare_src)
    print(text)
    if args.out:
        Path(args.out).write_text(text)


def agreement(res, ref: dict[str, np.ndarray]) -> float:
    """The largest relative difference of the two estimates."""
    return max(
        float(np.max(np.abs(res.frd.response - ref["bla"])) / np.max(np.abs(ref["bla"]))),
        float(np.max(np.abs(res.frd.std - ref["std"]) / ref["std"])),
        float(np.max(np.abs(res.frd.total_std - ref["total"]) / ref["total"])),
        float(np.max(np.abs(res.odd.power - ref["odd_power"]) / ref["odd_power"])),
    )


def processes(folder: Path, files: list[Path], compare_src: str | None) -> dict:
    """The whole-process variants: the numpy script, the CLI (and the CLI of ``compare_src``)."""
    cli = [sys.executable, "-m", "stageid", "frf", *map(str, files), "--inputs", ",".join(CHANNELS_IN)]
    cli += ["--outputs", ",".join(CHANNELS_OUT), "--method", "bla", "--design", str(folder / "ms.multisine.json")]
    cli += ["--periods", str(P), "--transient-periods", "0", "-o", str(folder / "bla.npz")]
    np_cli = [sys.executable, __file__, "--numpy-only", str(folder)]
    # both processes start from byte-compiled modules, as an installed package does: a cache
    # of their own (so the source tree is left alone), filled by one untimed run of each
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONDONTWRITEBYTECODE", "STAGEID_THREADS")}
    env["PYTHONPYCACHEPREFIX"] = str(folder / "pycache")
    commands = {"np_cli": (np_cli, env), "cli": (cli, env), "cli_2": (cli, env | {"STAGEID_THREADS": "2"})}
    if compare_src:
        other = env | {"PYTHONPATH": os.pathsep.join([compare_src, *filter(None, [env.get("PYTHONPATH")])])}
        commands["cli_other"] = (cli, other)
    for command, environment in commands.values():
        subprocess.run(command, check=True, capture_output=True, env=environment)
    return {
        key: (lambda c=command, e=environment: subprocess.run(c, check=True, capture_output=True, env=e))
        for key, (command, environment) in commands.items()
    }


def alternated(variants: dict, repeat: int) -> dict[str, tuple[list[float], list[float]]]:
    """Wall and CPU seconds of every variant, run in turn ``repeat`` times so the machine's load falls on all alike."""
    runs = {k: ([], []) for k in variants}
    for _ in range(repeat):
        for key, fn in variants.items():
            w, c = timed(fn, 1)
            runs[key][0].extend(w)
            runs[key][1].extend(c)
    return runs


def peak_memory(files: list[Path]) -> dict[str, float]:
    """VmHWM [MB] of fresh processes: each estimate, and each side's imports alone."""
    setup = f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); import bench_bla as b, json, pathlib"
    files_repr = repr([str(f) for f in files])
    load = f"files = [pathlib.Path(f) for f in {files_repr}]; d = json.loads(files[0].with_name('ms.multisine.json').read_text())"
    return {
        "np": child_rss(f"{setup}; {load}; b.numpy_bla(files, d)"),
        "st": child_rss(f"{setup}; {load}; b.stageid_bla(files, d)"),
        "st_base": child_rss(f"{setup}; import stageid.frf.bla, stageid.cli.bla, stageid.frf.records"),
        "np_base": child_rss(setup),
    }


def report(runs, repeat: int, loadavg: list[float], agree: float, memory: dict[str, float], compare_src) -> str:
    """The Markdown table of the runs."""
    one_realisation = 3 * P * L * 2 * NU * 8 / 2**20
    lines = [
        "# BLA estimation speed (benchmarks/bench_bla.py)",
        "",
        f"Machine: {platform.machine()}, Python {platform.python_version()}, numpy {np.__version__}, "
        f"{len(os.sched_getaffinity(0))} CPUs, OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}; "
        f"median of {repeat} runs; "
        f"load average {loadavg[0]:.1f} before, {loadavg[1]:.1f} after.",
        "",
        f"3x3, orthogonal random-odd design: {M} realisations x 3 experiments x {P} periods x {L} samples "
        f"({M * 3} NPZ records of {P * L} samples x 6 channels); estimates agree to {agree:.1e} (max relative).",
        "",
        "| method | wall median [s] | CPU median [s] | wall, all runs [s] | speed-up vs numpy (wall / CPU) |",
        "|---|---|---|---|---|",
    ]
    names = {
        "np": ("plain numpy composition, in-process", "np"),
        "api": ("stageid BLA in-process (`stageid.cli.bla.estimate_bla`)", "np"),
        "np_cli": ("plain numpy composition as a script (start, import, read)", "np_cli"),
        "cli": ("`stageid frf --method bla` whole process (start, read, write)", "np_cli"),
        "cli_2": ("the same on two threads (`STAGEID_THREADS=2`)", "np_cli"),
        "cli_other": (f"the same, stageid from `{compare_src}`", "np_cli"),
    }
    for key, (name, base) in names.items():
        if key not in runs:
            continue
        w, c = (float(np.median(x)) for x in runs[key])
        bw, bc = (float(np.median(x)) for x in runs[base])
        all_w = " ".join(f"{x:.2f}" for x in runs[key][0])
        lines.append(f"| {name} | {w:.3f} | {c:.3f} | {all_w} | {bw / w:.2f} / {bc / c:.2f} |")
    lines += [
        "",
        f"Peak memory (VmHWM of a fresh process): numpy {memory['np']:.0f} MB ({memory['np'] - memory['np_base']:.0f} "
        f"MB over its imports), stageid {memory['st']:.0f} MB ({memory['st'] - memory['st_base']:.0f} MB over its "
        f"imports); one realisation's records are {one_realisation:.0f} MB, all of them {M * one_realisation:.0f} MB.",
    ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
