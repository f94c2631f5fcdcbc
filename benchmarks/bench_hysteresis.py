"""Speed of the hysteresis kernels: compiled kernels against a numpy loop vectorised over operators.

Run:  .venv/bin/python benchmarks/bench_hysteresis.py  [--samples 1000000] [--repeat 5]

Single thread (NUMBA_NUM_THREADS=1, BLAS threads 1), double precision.  Reports the median of
``--repeat`` runs in ns per sample per operator for 20 and 100 operators and two inputs:

* ``smooth``: 10^6 samples of a decaying 100-cycle sine (a record like the letter's: few
  reversals per sample) -- the case the event-driven kernels are built for;
* ``random-walk``: 10^6 samples of a Gaussian random walk (steps of 5 V) reflected into
  +-450 V: it turns at every other sample and never stands still -- the worst case for the
  event-driven kernels;
* ``clipped-walk``: the same walk clipped to +-450 V (what earlier runs called
  ``random-walk``): it leaves the range after a few thousand samples, so 82 % of its samples
  stand still at the clip and it turns at only 9 % of them.

Kernels: ``play loop`` (vectorised loop over operators, every sample), ``play events``
(event-driven, O(1) amortised), ``play banded`` (blocks of 4 operators, only the blocks whose
band the input leaves are updated), ``play auto`` (what ``PIModel.simulate`` uses),
``CP loop`` / ``CP events`` / ``CP banded`` / ``CP auto`` (the same for the modified PI of
eq. 3-4; ``banded`` touches only the operator blocks whose band the input leaves; ``auto``
is what ``ModifiedPIModel.simulate`` uses: events when the input turns in < 0.5 % of the
samples, else banded), ``numpy`` (a Python loop over samples with numpy over operators,
timed on the first 10^5 samples).  Every kernel is checked against the
plain-Python reference (first 20000 samples; 1e-12 relative) and against the loop kernel on
all samples.  The streaming compensator is timed per sample through ``Compensator.step``
(Python call per sample) and through the compiled step called in a compiled loop.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from functools import partial

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402


def numpy_play_sum(x, r, w, z0):
    z = z0.copy()
    y = np.empty(x.size)
    for k in range(x.size):
        np.maximum(x[k] - r, np.minimum(x[k] + r, z), out=z)
        y[k] = w @ z
    return y


def numpy_cp_sum(x, r, rc, ra, rb, w, z0):
    z = z0.copy()
    y = np.empty(x.size)
    for k in range(x.size):
        xk = x[k]
        up = np.maximum(xk - r, np.minimum(xk - rc, 0.0))
        down = np.minimum(xk + ra, np.maximum(xk + rb, 0.0))
        np.maximum(up, np.minimum(down, z), out=z)
        y[k] = w @ z
    return y


def timed(f, repeat):
    out = f()
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts), out


def _inputs(n):
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 1.0, n)
    walk = np.cumsum(rng.normal(0, 5, n))
    inputs = {
        "smooth": 400 * np.sin(2 * np.pi * 100 * t) * (1 - 0.9 * t),
        "random-walk": 450 - np.abs(np.mod(walk + 450, 1800) - 900),
        "clipped-walk": np.clip(walk, -450, 450),
    }
    return rng, inputs


def compare_with(path, n, repeat, all_kernels=False):
    """Before/after table: the auto kernels (with ``all_kernels`` every sum kernel) of an older
    single-file ``_kernels.py`` against the current ones, in one process, same inputs, runs
    interleaved (old/new, new/old, ...): medians, least times and the median ratio of the
    paired rounds, fair on a machine whose load changes."""
    import importlib.util

    from stageid.hysteresis import kernels as K

    spec = importlib.util.spec_from_file_location("kernels_before", path)
    old = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = old  # numba's cache finds the module again by name
    spec.loader.exec_module(old)
    rng, inputs = _inputs(n)
    print(f"# before: {path}; {n} samples, median of {repeat}, interleaved; load average {os.getloadavg()[0]:.2f}")
    print(
        f"{'input':12s} {'ops':>4s} {'kernel':12s} {'before':>8s} {'after':>8s} {'least b':>8s} {'least a':>8s} "
        f"{'ratio':>6s}  ns/sample/op (medians, least times, median of the per-round ratios after/before)"
    )
    for name, x in inputs.items():
        x = np.ascontiguousarray(x)
        for m in (20, 100):
            r = np.arange(m) * 450.0 / m
            rc, ra = 0.5 * r, 1.3 * r
            rb = 0.6 * ra
            w = rng.uniform(0.0, 1.0, m) / m
            z0 = np.zeros(m)
            play_args, cp_args = (x, r, w, z0), (x, r, rc, ra, rb, w, z0)
            rows = [("play auto", "play_sum_auto", (*play_args, 0.0)), ("CP auto", "cp_sum_auto", (*cp_args, 0.0))]
            if all_kernels:
                rows += [
                    ("play loop", "play_sum", play_args),
                    ("play events", "play_sum_events", (*play_args, 0.0)),
                    ("play banded", "play_sum_banded", (*play_args, 0.0)),
                    ("CP loop", "cp_sum", cp_args),
                    ("CP events", "cp_sum_events", (*cp_args, 0.0)),
                    ("CP banded", "cp_sum_banded", (*cp_args, 0.0)),
                ]
            for label, name_, args in rows:

                def mod_call(M, name_=name_, args=args):  # this row's kernel and arguments
                    return getattr(M, name_)(*args)

                yo, zo = mod_call(old)
                yn, zn = mod_call(K)
                diff = np.abs(yo - yn).max() / np.abs(yo).max()
                assert diff <= 1e-12, f"{label}: before and after differ by {diff:.3g}"
                ts = {old: [], K: []}
                for i in range(repeat):
                    for M in (old, K) if i % 2 == 0 else (K, old):  # alternate who goes first
                        t0 = time.perf_counter()
                        mod_call(M)
                        ts[M].append(time.perf_counter() - t0)
                before, after, least_before, least_after = (
                    f(ts[M]) / n / m * 1e9 for f in (statistics.median, min) for M in (old, K)
                )
                ratio = statistics.median(a / b for a, b in zip(ts[K], ts[old]))
                print(
                    f"{name:12s} {m:4d} {label:12s} {before:8.3f} {after:8.3f} "
                    f"{least_before:8.3f} {least_after:8.3f} {ratio:6.2f}"
                )
    print(f"# load average at the end {os.getloadavg()[0]:.2f}")
    return 0


def identification_times(repeat: int) -> int:
    """Whole-process identification times on the 20 Hz FORC record (issue 16, point 6), medians."""
    from stageid.data.datasets import load_dspace_piezo, shared_data_dir
    from stageid.hysteresis import PIIdentifier, PreisachIdentifier
    from stageid.hysteresis.stage.identification import StageIdentifier

    root = shared_data_dir()
    path = None if root is None else root / "piezo_dspace_preisach" / "20_hz_no_lp.mat"
    if path is None or not path.is_file():
        print("dSPACE records not found; skipped")
        return 0
    exp = load_dspace_piezo(path)
    print(
        f"# 20_hz_no_lp: {exp.n_samples} samples; median of {repeat} alternating rounds; load {os.getloadavg()[0]:.2f}"
    )
    cases = {
        "classical PI (20 operators)": lambda: PIIdentifier("pi").fit(exp),
        "modified PI (20 operators, warp)": lambda: PIIdentifier("modified-pi").fit(exp),
        "Preisach (20 levels)": lambda: PreisachIdentifier(n_levels=20).fit(exp),
        "stage: classical PI + dynamics 2": lambda: StageIdentifier("pi", dynamics=2, creep=None).fit(exp),
        "stage: modified PI + dynamics 2": lambda: StageIdentifier("modified-pi", dynamics=2, creep=None).fit(exp),
        "stage: Preisach + dynamics 2": lambda: StageIdentifier("preisach", dynamics=2, creep=None).fit(exp),
        "stage: Preisach + dynamics 2 + creep 0.01/0.1/1 s": lambda: StageIdentifier(
            "preisach", dynamics=2, creep=(0.01, 0.1, 1.0)
        ).fit(exp),
    }
    for run in cases.values():  # compile and warm every path once, untimed
        run()
    wall: dict[str, list[float]] = {name: [] for name in cases}
    cpu: dict[str, list[float]] = {name: [] for name in cases}
    for i in range(repeat):  # rounds with the cases alternating in order
        for name in list(cases)[:: 1 if i % 2 == 0 else -1]:
            t0, c0 = time.perf_counter(), time.process_time()
            cases[name]()
            cpu[name].append(time.process_time() - c0)
            wall[name].append(time.perf_counter() - t0)
    first = next(iter(cases))
    print("| identification | wall | CPU | CPU ratio to classical PI (median of rounds) |")
    print("|---|---|---|---|")
    for name in cases:
        ratio = float(np.median(np.array(cpu[name]) / np.array(cpu[first])))
        print(f"| {name} | {np.median(wall[name]):.2f} s | {np.median(cpu[name]):.2f} s | {ratio:.1f}x |")
    print(f"# load average {os.getloadavg()[0]:.2f} at the end")
    return 0


WHOLE_PROCESS = """
import sys
from stageid.data.datasets import load_dspace_piezo, shared_data_dir
from stageid.hysteresis import PIIdentifier
exp = load_dspace_piezo(shared_data_dir() / "piezo_dspace_preisach" / "20_hz_no_lp.mat")
if sys.argv[1].endswith("-stage"):  # the joint fit with dynamics of order 2
    from stageid.hysteresis.stage_identification import StageIdentifier
    StageIdentifier(sys.argv[1][: -len("-stage")], dynamics=2, creep=None).fit(exp)
else:
    PIIdentifier(sys.argv[1]).fit(exp)
"""


def whole_process_times(pairs: int, other: str = "modified-pi") -> int:
    """Classical vs modified PI identification of the 20 Hz FORC record, each in a fresh
    interpreter (imports, numba cache, load, fit), in alternating pairs: medians of the wall
    and CPU times (``getrusage`` of the children) and of the per-pair ratios."""
    import resource
    import subprocess

    from stageid.data.datasets import shared_data_dir

    root = shared_data_dir()
    if root is None or not (root / "piezo_dspace_preisach" / "20_hz_no_lp.mat").is_file():
        print("dSPACE records not found; skipped")
        return 0
    wall: dict[str, list[float]] = {"pi": [], other: []}
    cpu: dict[str, list[float]] = {"pi": [], other: []}
    print(f"# {pairs} alternating pairs; load average {os.getloadavg()[0]:.2f} at the start")
    for i in range(pairs):
        for kind in ("pi", other) if i % 2 == 0 else (other, "pi"):
            r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", WHOLE_PROCESS, kind], check=True)
            wall[kind].append(time.perf_counter() - t0)
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu[kind].append(r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime)
    print(f"| time | classical PI | {other} | ratio (median of pairs) |")
    print("|---|---|---|---|")
    for name, d in (("wall", wall), ("CPU", cpu)):
        ratio = np.median(np.array(d[other]) / np.array(d["pi"]))
        print(f"| {name} | {np.median(d['pi']):.2f} s | {np.median(d[other]):.2f} s | {ratio:.2f}x |")
    print(f"# load average {os.getloadavg()[0]:.2f} at the end")
    return 0


def preisach_times(n: int, repeat: int) -> int:
    """Preisach model (continuous cells, 20 and 60 levels) against the PI kernels, side by side.

    ``simulate`` of each model on the benchmark's inputs, runs alternating model by model,
    CPU time of this thread; and the exact Preisach inverse against the modified-PI
    compensator (``run``) on each model's own output of the input.
    """
    from stageid.hysteresis import Compensator, ModifiedPIModel, PIModel, PreisachCompensator, PreisachModel

    rng, inputs = _inputs(n)
    models = {}
    for levels in (20, 60):
        w = rng.uniform(0.0, 1.0, levels * (levels + 1) // 2) / levels
        models[f"Preisach {levels} levels"] = PreisachModel((-500.0, 500.0), w)
    for m in (20, 100):
        r = np.arange(m) * 450.0 / m
        w = rng.uniform(0.0, 1.0, m) / m
        models[f"PI {m} ops"] = PIModel(r=r, weights=w)
        models[f"modified PI {m} ops"] = ModifiedPIModel(r=r, rc=0.5 * r, ra=1.3 * r, rb=0.78 * r, weights=w)
    print(f"# {n} samples, median of {repeat} alternating rounds, CPU ns per sample; load {os.getloadavg()[0]:.2f}")
    print("| input | " + " | ".join(models) + " |")
    print("|---|" + "---|" * len(models))
    for name, x in inputs.items():
        x = np.ascontiguousarray(x)
        times: dict[str, list[float]] = {k: [] for k in models}
        for mod in models.values():
            mod.simulate(x[:100])
        for _ in range(repeat):
            for key, mod in models.items():
                t0 = time.thread_time()
                mod.simulate(x)
                times[key].append(time.thread_time() - t0)
        print(f"| {name} | " + " | ".join(f"{np.median(v) / n * 1e9:.1f}" for v in times.values()) + " |")
    print("\n| inverse, 20 levels / 20 operators | ns per sample | model(drive) - reference, max |")
    print("|---|---|---|")
    x = inputs["random-walk"][: min(n, 200_000)]
    pre, mpi = models["Preisach 20 levels"], models["modified PI 20 ops"]
    for label, mod, make in (
        ("Preisach exact inverse (PreisachCompensator.run)", pre, lambda m: PreisachCompensator(m)),
        ("modified PI compensator (Compensator.run)", mpi, lambda m: Compensator(m, limits=(-np.inf, np.inf))),
    ):
        y = mod.simulate(x)[:, 0]
        make(mod).run(y[:10])
        ts = []
        for _ in range(repeat):
            comp = make(mod)
            t0 = time.thread_time()
            u = comp.run(y)
            ts.append(time.thread_time() - t0)
        err = float(np.max(np.abs(mod.simulate(u)[:, 0] - y)))
        print(f"| {label} | {np.median(ts) / x.size * 1e9:.1f} | {err:.1e} |")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument(
        "--compare-with",
        metavar="KERNELS_PY",
        default=None,
        help="an older copy of stageid/hysteresis/_kernels.py (the kernels before they became the "
        "stageid.hysteresis.kernels package; e.g. from `git show`): time its "
        "play_sum_auto / cp_sum_auto against the current ones, interleaved, and stop",
    )
    ap.add_argument("--all-kernels", action="store_true", help="with --compare-with: every sum kernel, not only auto")
    ap.add_argument(
        "--identification",
        action="store_true",
        help="time whole identifications on the dSPACE 20 Hz FORC record (classical PI, modified PI, "
        "stage with dynamics 2) and stop",
    )
    ap.add_argument(
        "--whole-process",
        type=int,
        default=0,
        metavar="PAIRS",
        help="time classical vs modified PI identification of the 20 Hz FORC record, each in a fresh "
        "interpreter, in PAIRS alternating pairs, and stop",
    )
    ap.add_argument(
        "--whole-process-stage",
        type=int,
        default=0,
        metavar="PAIRS",
        help="as --whole-process, classical PI against a stage fit with dynamics of order 2 (--stage-model)",
    )
    ap.add_argument(
        "--stage-model",
        choices=["preisach", "pi", "modified-pi"],
        default="preisach",
        help="the stage's hysteresis for --whole-process-stage (default preisach)",
    )
    ap.add_argument(
        "--preisach",
        action="store_true",
        help="time the Preisach model and its exact inverse side by side with the PI kernels and stop",
    )
    args = ap.parse_args(argv)
    if args.whole_process:
        return whole_process_times(args.whole_process)
    if args.whole_process_stage:
        return whole_process_times(args.whole_process_stage, f"{args.stage_model}-stage")
    if args.preisach:
        return preisach_times(args.samples, args.repeat)
    if args.identification:
        return identification_times(args.repeat)
    if args.compare_with:
        return compare_with(args.compare_with, args.samples, args.repeat, args.all_kernels)

    from stageid.hysteresis import Compensator, ModifiedPIModel
    from stageid.hysteresis import kernels as K
    from stageid.hysteresis.models.operators import coupled_play_reference, play_reference

    n = args.samples
    rng, inputs = _inputs(n)
    print(
        f"# {platform.processor() or platform.machine()}, Python {sys.version.split()[0]}, numpy {np.__version__}, "
        f"{n} samples, median of {args.repeat}; load average {os.getloadavg()[0]:.2f}"
    )
    for name, x in inputs.items():
        dx = np.diff(x)
        moving = dx[dx != 0]
        print(
            f"# {name}: turns at {np.mean(moving[1:] * moving[:-1] < 0):.1%} of the moving samples, "
            f"stands still at {np.mean(dx == 0):.1%}"
        )
    print(f"{'input':12s} {'ops':>4s} {'kernel':14s} {'ns/sample/op':>13s} {'max rel. diff':>14s}")
    rows = []
    n_np = min(n, 100_000)
    n_ref = min(n, 20_000)
    for name, x in inputs.items():
        x = np.ascontiguousarray(x)
        for m in (20, 100):
            r = np.arange(m) * 450.0 / m
            rc, ra = 0.5 * r, 1.3 * r
            rb = 0.6 * ra
            w = rng.uniform(0.0, 1.0, m) / m
            z0 = np.zeros(m)
            yref = play_reference(x[:n_ref], r, z0)[0] @ w
            ycref = coupled_play_reference(x[:n_ref], r, rc, ra, rb, z0)[0] @ w
            play_args, cp_args = (x, r, w, z0), (x, r, rc, ra, rb, w, z0)
            cases = [
                ("play loop", K.play_sum, play_args, yref),
                ("play events", K.play_sum_events, (*play_args, 0.0), yref),
                ("play banded", K.play_sum_banded, (*play_args, 0.0), yref),
                ("play auto", K.play_sum_auto, (*play_args, 0.0), yref),
                ("CP loop", K.cp_sum, cp_args, ycref),
                ("CP events", K.cp_sum_events, (*cp_args, 0.0), ycref),
                ("CP banded", K.cp_sum_banded, (*cp_args, 0.0), ycref),
                ("CP auto", K.cp_sum_auto, (*cp_args, 0.0), ycref),
            ]
            loops = {}
            for label, kernel, kernel_args, ref in cases:
                sec, (y, _) = timed(partial(kernel, *kernel_args), args.repeat)
                diff = np.abs(y[:n_ref] - ref).max() / max(np.abs(ref).max(), 1e-300)
                family = label.split()[0]
                if label.endswith("loop"):
                    loops[family] = y
                else:
                    diff = max(diff, np.abs(y - loops[family]).max() / np.abs(loops[family]).max())
                assert diff <= 1e-12, f"{label} differs from the reference by {diff:.3g}"
                rows.append((name, m, label, sec / n / m * 1e9, diff))
                print(f"{name:12s} {m:4d} {label:14s} {sec / n / m * 1e9:13.4f} {diff:14.2e}")
            for label, f, ref in (
                ("numpy play", partial(numpy_play_sum, x[:n_np], r, w, z0), yref),
                ("numpy CP", partial(numpy_cp_sum, x[:n_np], r, rc, ra, rb, w, z0), ycref),
            ):
                sec, y = timed(f, 1)
                diff = np.abs(y[:n_ref] - ref).max() / max(np.abs(ref).max(), 1e-300)
                rows.append((name, m, label, sec / n_np / m * 1e9, diff))
                print(f"{name:12s} {m:4d} {label:14s} {sec / n_np / m * 1e9:13.4f} {diff:14.2e}")

    # streaming compensator (inverse), 20 operators, modified PI
    m = 20
    r = np.arange(m) * 25.0
    model = ModifiedPIModel(r=r, rc=0.5 * r, ra=1.3 * r, rb=0.78 * r, weights=np.r_[1.0, rng.uniform(0, 0.3, m - 1)])
    yref = model.simulate(inputs["smooth"][:n])[:, 0]
    Compensator(model).step(yref[0])  # warm-up: the first call loads the compiled step
    n_py = min(n, 200_000)

    def step_rate(values) -> float:
        """Median samples/s of a Python loop over Compensator.step."""
        rates = []
        for _ in range(max(3, args.repeat)):
            step = Compensator(model).step
            t0 = time.perf_counter()
            for v in values:
                step(v)
            rates.append(n_py / (time.perf_counter() - t0))
        return float(np.median(rates))

    py_rate = step_rate(yref[:n_py].tolist())  # Python floats
    py_rate_np = step_rate(yref[:n_py])  # numpy float64 scalars (iterating an array)
    comp = Compensator(model)
    sec, u = timed(lambda: Compensator(model).run(yref), args.repeat)
    err = np.abs(model.simulate(u)[:, 0] - yref).max() / np.ptp(yref)
    print(
        f"compensator, modified PI, {m} operators: compiled per-sample step in a compiled loop "
        f"{n / sec / 1e6:.2f} M samples/s (model(inverse(y)) - y: {err:.1e} of range); "
        f"Python Compensator.step per sample {py_rate / 1e6:.3f} M samples/s on Python floats, "
        f"{py_rate_np / 1e6:.3f} M samples/s on numpy scalars (median of {max(3, args.repeat)})"
    )
    from stageid.hysteresis import PIModel

    pi_model = PIModel(r=r, weights=model.weights)
    ypi = pi_model.simulate(inputs["smooth"])[:, 0]
    sec, u = timed(lambda: Compensator(pi_model).run(ypi), args.repeat)
    print(f"compensator, classical PI (closed-form inverse), {m} operators: {n / sec / 1e6:.2f} M samples/s")
    # with a creep term (rate dependent: per-sample inversion with the creep memory)
    from stageid.hysteresis import CreepTerm

    creep_model = ModifiedPIModel(
        r=r,
        rc=0.5 * r,
        ra=1.3 * r,
        rb=0.78 * r,
        weights=model.weights,
        creep=CreepTerm([0.05, 0.2, 1.0, 5.0, 20.0], [0.002] * 5, 1e-4),
    )
    yc = creep_model.simulate(inputs["smooth"][:n])[:, 0]
    sec, u = timed(lambda: Compensator(creep_model).run(yc), args.repeat)
    err = np.abs(creep_model.simulate(u)[:, 0] - yc).max() / np.ptp(yc)
    comp = Compensator(creep_model)
    comp.step(yc[0])
    comp.step(yc[1])  # warm-up of the compiled path
    n_step = min(n, 50_000)
    t0 = time.perf_counter()
    for v in yc[2 : 2 + n_step]:
        comp.step(v)
    creep_rate = n_step / (time.perf_counter() - t0)
    print(
        f"compensator, modified PI + creep (5 lags), {m} operators: {n / sec / 1e6:.2f} M samples/s "
        f"(model(inverse(y)) - y: {err:.1e} of range); Python Compensator.step {creep_rate / 1e6:.3f} M samples/s"
    )
    print(f"# load average at the end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
