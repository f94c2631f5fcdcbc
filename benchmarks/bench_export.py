"""Speed of exported C (``stageid export c``) through a compiled driver, per step.

Run:  .venv/bin/python benchmarks/bench_export.py  [--samples 200000] [--runs 15] [--cflags "-O2"]

Every case is exported, compiled with ``$CC`` (default: the first of gcc, clang, cc) and the
strict flags plus ``--cflags``, and timed by a C driver on the same machine:

* ``median``: the driver runs ``--samples`` steps from ``P_init`` ``--runs`` times and times each
  run by the thread's CPU clock (``CLOCK_THREAD_CPUTIME_ID``: the benchmark VM is shared, and
  wall time counts the time it gives to other processes; ``wall`` is the wall-clock median);
  the median of the runs, per step;
* ``p50`` / ``p99.9``: one more pass times every step by itself (the TSC on x86, ticks converted
  with the ticks per wall-clock ns of the pass; a pair of reads costs ``timer`` ns, subtracted);
  the median and the 99.9th percentile of those per-step times -- what a real-time loop must
  budget for.

Cases (issue 17 targets): a 2x2 state space of order 6 (target <= 25 ns per step), against a
naive C loop over the same matrices held in a struct (the textbook ``y = C x + D u;
x = A x + B u`` with runtime sizes) in the same driver; the compensator of a modified PI model
with 20 operators (target <= 100 ns per sample) on four references -- a slow sine, a random
walk, full-range random jumps (every operator can switch at every sample) and a measured
displacement record when ../shared/data is present -- to show how the cost depends on the input
history; and, for reference, the forward modified PI model and the classical-PI compensator.
The outputs are checked against the Python models before timing (1e-12 relative; float 1e-5 of
the range).

``--float`` exports every case in single precision (``--float``; the driver streams floats, no
naive loop; the check before timing is 1e-5 of the output range).

``--paired REV`` times the modified-PI compensator of this tree against the one the package at
git revision ``REV`` generates (``git archive`` of its ``src``), both compiled into one driver
that alternates them (``--runs`` rounds of old, new / new, old): medians of the CPU time per
step, the median of the per-round ratios old / new with its range, and p50 / p99.9 of each.
"""

from __future__ import annotations

import argparse
import os
import platform
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from stageid.export import export_c  # noqa: E402
from stageid.export.host import build, compile_files, find_compiler  # noqa: E402
from stageid.hysteresis import Compensator, ModifiedPIModel, PIModel  # noqa: E402
from stageid.models import StateSpaceModel  # noqa: E402

_DRIVER = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "{p}.h"

static double now(void)  /* wall clock, ns */
{{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}}

static double cpu(void)  /* this thread's CPU time, ns: not counting time the VM gave to others */
{{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}}

#if defined(__x86_64__) || defined(__i386__)
static double ticks(void) {{ return (double)__builtin_ia32_rdtsc(); }}  /* per-step timer */
#else
static double ticks(void) {{ return now(); }}
#endif

static int cmp(const void *a, const void *b)
{{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}}

{naive}

int main(int argc, char **argv)
{{
    const long n = argc > 3 ? atol(argv[1]) : 0;
    const int runs = argc > 3 ? atoi(argv[2]) : 0;
    {t} *in = malloc(sizeof({t}) * n * {p}_N_INPUTS), out[{p}_N_OUTPUTS];
    double *dt = malloc(sizeof(double) * n), sink = 0.0;
    FILE *f = argc > 3 ? fopen(argv[3], "rb") : NULL;
    {p}_state s;
    long k;
    int r;
    if (!f || fread(in, sizeof({t}), n * {p}_N_INPUTS, f) != (size_t)(n * {p}_N_INPUTS)) return 2;
    fclose(f);
    for (r = 0; r < runs; ++r) {{
        double t0, t1, c0, c1;
        {p}_init(&s);
        t0 = now();
        c0 = cpu();
        for (k = 0; k < n; ++k) {{ {p}_step(&s, in + k * {p}_N_INPUTS, out); sink += out[0]; }}
        c1 = cpu();
        t1 = now();
        printf("run %.4f\nwall %.4f\n", (c1 - c0) / n, (t1 - t0) / n);
    }}
    {{  /* per-step times in timer ticks, converted with the ticks per ns of this pass */
        const double w0 = now(), k0 = ticks();
        double scale, w1;
        for (k = 0; k < n; ++k) {{ const double t0 = ticks(); dt[k] = ticks() - t0; }}
        qsort(dt, n, sizeof(double), cmp);
        w1 = now();
        scale = (w1 - w0) / (ticks() - k0);
        printf("timer %.2f\n", dt[n / 2] * scale);
        {p}_init(&s);
        for (k = 0; k < n; ++k) {{
            const double t0 = ticks();
            {p}_step(&s, in + k * {p}_N_INPUTS, out);
            dt[k] = ticks() - t0;
            sink += out[0];
        }}
        qsort(dt, n, sizeof(double), cmp);
        printf("step50 %.2f\nstep999 %.2f\n", dt[n / 2] * scale, dt[(long)(0.999 * n)] * scale);
    }}
{naive_main}
    printf("sink %g\n", sink);
    return 0;
}}
"""

_NAIVE = r"""
typedef struct { int n, m, p; const double *A, *B, *C, *D; } ss_model;

static void ss_step(const ss_model *g, double *x, const double *u, double *y)
{
    double xn[64];
    int i, j;
    for (i = 0; i < g->p; ++i) {
        y[i] = 0.0;
        for (j = 0; j < g->n; ++j) y[i] += g->C[i * g->n + j] * x[j];
        for (j = 0; j < g->m; ++j) y[i] += g->D[i * g->m + j] * u[j];
    }
    for (i = 0; i < g->n; ++i) {
        xn[i] = 0.0;
        for (j = 0; j < g->n; ++j) xn[i] += g->A[i * g->n + j] * x[j];
        for (j = 0; j < g->m; ++j) xn[i] += g->B[i * g->m + j] * u[j];
    }
    for (i = 0; i < g->n; ++i) x[i] = xn[i];
}
"""

_NAIVE_MAIN = r"""
    {{
        static const double A[] = {A}, B[] = {B}, C[] = {C}, D[] = {D};
        const ss_model g = {{{n}, {m}, {q}, A, B, C, D}};
        double x[{n}];
        for (r = 0; r < runs; ++r) {{
            double t0, t1;
            int i;
            for (i = 0; i < {n}; ++i) x[i] = 0.0;
            t0 = cpu();
            for (k = 0; k < n; ++k) {{ ss_step(&g, x, in + k * {m}, out); sink += out[0]; }}
            t1 = cpu();
            printf("naive %.4f\n", (t1 - t0) / n);
        }}
    }}
"""


_PAIRED = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "old.h"
#include "new.h"
typedef double real;  /* the type of the exports */

static double cpu(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

#if defined(__x86_64__) || defined(__i386__)
static double ticks(void) { return (double)__builtin_ia32_rdtsc(); }
#else
static double ticks(void) { return now(); }
#endif

static int cmp(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

#define TIMED(P)                                                                     \
    static double run_##P(const real *in, real *out, long n)                         \
    {                                                                                \
        P##_state s;                                                                 \
        long k;                                                                      \
        double c0;                                                                   \
        P##_init(&s);                                                                \
        c0 = cpu();                                                                  \
        for (k = 0; k < n; ++k) P##_step(&s, in + k, out + k);                       \
        return (cpu() - c0) / n;                                                     \
    }                                                                                \
    static void steps_##P(const real *in, real *out, double *dt, long n)             \
    {                                                                                \
        P##_state s;                                                                 \
        long k;                                                                      \
        P##_init(&s);                                                                \
        for (k = 0; k < n; ++k) {                                                    \
            const double t0 = ticks();                                               \
            P##_step(&s, in + k, out + k);                                           \
            dt[k] = ticks() - t0;                                                    \
        }                                                                            \
    }
TIMED(old)
TIMED(new)

int main(int argc, char **argv)
{
    const long n = argc > 3 ? atol(argv[1]) : 0;
    const int rounds = argc > 3 ? atoi(argv[2]) : 0;
    real *in = malloc(sizeof(real) * n), *out = malloc(sizeof(real) * n);
    double *dt = malloc(sizeof(double) * n);
    FILE *f = argc > 3 ? fopen(argv[3], "rb") : NULL;
    double timer, w0, k0, scale;
    long k;
    int r;
    if (!f || fread(in, sizeof(real), n, f) != (size_t)n) return 2;
    fclose(f);
    for (r = 0; r < rounds; ++r) {  /* alternating: old new, new old, ... */
        double a, b;
        if (r & 1) {
            b = run_new(in, out, n);
            a = run_old(in, out, n);
        } else {
            a = run_old(in, out, n);
            b = run_new(in, out, n);
        }
        printf("old %.4f\nnew %.4f\n", a, b);
    }
    w0 = now();
    k0 = ticks();
    for (k = 0; k < n; ++k) {
        const double t0 = ticks();
        dt[k] = ticks() - t0;
    }
    qsort(dt, n, sizeof(double), cmp);
    timer = dt[n / 2];
    steps_old(in, out, dt, n);
    qsort(dt, n, sizeof(double), cmp);
    printf("old50 %.2f\nold999 %.2f\n", dt[n / 2] - timer, dt[(long)(0.999 * n)] - timer);
    steps_new(in, out, dt, n);
    qsort(dt, n, sizeof(double), cmp);
    printf("new50 %.2f\nnew999 %.2f\n", dt[n / 2] - timer, dt[(long)(0.999 * n)] - timer);
    scale = (now() - w0) / (ticks() - k0);
    printf("scale %.6f\n", scale);
    return 0;
}
"""


def _old_export(rev: str, model, folder: Path, single: bool = False) -> None:
    """``old.h`` / ``old.c``: the compensator of ``model`` as the package at git ``rev`` exports it."""
    import pickle

    root = Path(__file__).resolve().parents[1]
    src = folder / "old_src"
    src.mkdir()
    archive = subprocess.run(["git", "-C", str(root), "archive", rev, "src"], capture_output=True, check=True)
    subprocess.run(["tar", "-x", "-C", str(src)], input=archive.stdout, check=True)
    (folder / "model.pkl").write_bytes(pickle.dumps(model))
    script = (
        "import pickle, sys; from pathlib import Path; from stageid.export import export_c; "
        "out = Path(sys.argv[1]); code = export_c(pickle.loads((out / 'model.pkl').read_bytes()), 'old', inverse=True, "
        f"single={single}); "
        "[(out / k).write_text(v) for k, v in code.files().items()]"
    )
    env = dict(os.environ, PYTHONPATH=str(src / "src"))
    subprocess.run([sys.executable, "-c", script, str(folder)], check=True, env=env, cwd=str(folder))


def paired(
    rev: str, model, refs: dict, n: int, rounds: int, cflags: list[str], folder: Path, single: bool = False
) -> list[tuple]:
    """Old (git ``rev``) against new compensator of ``model``, alternating in one driver, per reference."""
    _old_export(rev, model, folder, single)
    for name, text in export_c(model, "new", inverse=True, single=single).files().items():
        (folder / name).write_text(text)
    (folder / "paired.c").write_text(_PAIRED.replace("typedef double real;", f"typedef {_real(single)} real;"))
    exe = folder / "paired"
    compile_files([folder / "old.c", folder / "new.c", folder / "paired.c"], exe, flags=(*cflags, f"-I{folder}"))
    rows = []
    for name, ref in refs.items():
        data = folder / "ref.bin"
        np.ascontiguousarray(ref[:n], dtype=np.float32 if single else np.float64).tofile(data)
        out = subprocess.run([str(exe), str(n), str(rounds), str(data)], capture_output=True, text=True, check=True)
        vals: dict[str, list[float]] = {}
        for line in out.stdout.splitlines():
            key, value = line.split()
            vals.setdefault(key, []).append(float(value))
        old, new, scale = np.array(vals["old"]), np.array(vals["new"]), vals["scale"][0]
        ratio = old / new
        tsc = {k: vals[k][0] * scale for k in ("old50", "old999", "new50", "new999")}
        rows.append((name, np.median(old), np.median(new), np.median(ratio), ratio.min(), ratio.max(), tsc))
    return rows


def _real(single: bool) -> str:
    return "float" if single else "double"


def _c_array(a: np.ndarray) -> str:
    return "{" + ", ".join(repr(float(v)) for v in np.asarray(a).reshape(-1)) + "}"


def time_case(code, u: np.ndarray, runs: int, cflags: list[str], folder: Path, naive: StateSpaceModel | None = None):
    """Compile ``code`` with the driver and time it on ``u`` (n_samples, n_inputs); a dict of figures."""
    p = code.prefix
    single = "const float *in" in code.header
    for name, text in code.files().items():
        (folder / name).write_text(text)
    naive_main = ""
    if naive is not None:
        naive_main = _NAIVE_MAIN.format(
            A=_c_array(naive.A), B=_c_array(naive.B), C=_c_array(naive.C), D=_c_array(naive.D),
            n=naive.n_states, m=naive.n_inputs, q=naive.n_outputs,
        )  # fmt: skip
    (folder / f"{p}_bench.c").write_text(
        _DRIVER.format(p=p, t=_real(single), naive=_NAIVE if naive is not None else "", naive_main=naive_main)
    )
    exe = folder / f"{p}_bench"
    compile_files([folder / f"{p}.c", folder / f"{p}_bench.c"], exe, flags=(*cflags, f"-I{folder}"))
    data = folder / f"{p}_in.bin"
    np.ascontiguousarray(u, dtype=np.float32 if single else np.float64).tofile(data)
    out = subprocess.run([str(exe), str(u.shape[0]), str(runs), str(data)], capture_output=True, text=True, check=True)
    vals: dict[str, list[float]] = {}
    for line in out.stdout.splitlines():
        key, value = line.split()
        vals.setdefault(key, []).append(float(value))
    res = {
        "median": float(np.median(vals["run"])),
        "wall": float(np.median(vals["wall"])),
        "timer": vals["timer"][0],
        "p50": vals["step50"][0] - vals["timer"][0],
        "p999": vals["step999"][0] - vals["timer"][0],
    }
    if "naive" in vals:
        res["naive"] = float(np.median(vals["naive"]))
    return res


def _check(y_c: np.ndarray, y: np.ndarray, single: bool) -> None:
    """The export agrees with the package: 1e-12 of the largest |y| (double), 1e-5 of its range (float)."""
    tol = 1e-5 * np.ptp(y) if single else 1e-12 * np.max(np.abs(y))
    assert np.max(np.abs(y_c - y)) <= tol, np.max(np.abs(y_c - y)) / tol


def stage_model(rng) -> StateSpaceModel:
    """A stable 2x2 discrete model of order 6 (three rotated lightly damped modes)."""
    n = 6
    A = np.zeros((n, n))
    for k in range(0, n, 2):
        rho, th = rng.uniform(0.95, 0.999), rng.uniform(0.01, 0.5)
        A[k : k + 2, k : k + 2] = rho * np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    T = rng.normal(size=(n, n))
    return StateSpaceModel(T @ A @ np.linalg.inv(T), rng.normal(size=(n, 2)), rng.normal(size=(2, n)),
                           rng.normal(size=(2, 2)), dt=1e-4)  # fmt: skip


def hysteresis_models(rng):
    """A 20-operator modified PI model identified on the dSPACE piezo record when present, else a
    random one over +-100 V; and a 20-operator classical PI model."""
    try:
        from stageid.data import datasets
        from stageid.hysteresis import PIIdentifier

        root = datasets.shared_data_dir()
        rec = datasets.load_dspace_piezo(root / "piezo_dspace_preisach" / "prbn_1.mat")
        mpi = PIIdentifier(model="modified-pi", n_operators=20).fit(rec).model
        pi = PIIdentifier(model="pi", n_operators=20).fit(rec).model
        return mpi, pi, "identified on piezo_dspace_preisach/prbn_1", rec
    except Exception:  # noqa: BLE001 - no shared data: synthetic models
        r = np.r_[0.0, np.linspace(5, 95, 19)]
        mpi = ModifiedPIModel(r=r, rc=0.5 * r, ra=1.5 * r, rb=0.8 * r, weights=np.r_[1.0, rng.uniform(0, 0.1, 19)],
                              input_limits=(-100.0, 100.0))  # fmt: skip
        pi = PIModel(r=r, weights=np.r_[1.0, rng.uniform(0, 0.1, 19)], input_limits=(-100.0, 100.0))
        return mpi, pi, "synthetic (no shared data)", None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=200_000)
    ap.add_argument("--runs", type=int, default=15)
    ap.add_argument("--cflags", default="-O2")
    ap.add_argument("--paired", metavar="REV", help="time the compensator against git revision REV's, alternating")
    ap.add_argument("--float", action="store_true", help="single-precision exports (--float)")
    args = ap.parse_args(argv)
    single = args.float
    cc = find_compiler()
    if cc is None:
        print("no C compiler found; nothing to time", file=sys.stderr)
        return 1
    cflags = shlex.split(args.cflags)
    version = subprocess.run([cc, "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    print(
        f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores; {version}; flags {args.cflags}"
        f"; {_real(single)}"
    )
    rng = np.random.default_rng(0)
    n = args.samples
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_export_") as tmp:
        folder = Path(tmp)
        g = stage_model(rng)
        u = rng.normal(size=(n, 2))
        code = export_c(g, "stage", single=single)
        _check(build(code, folder).run(u[:5000]), g.simulate(u[:5000]), single)
        res = time_case(code, u, args.runs, cflags, folder, naive=None if single else g)
        rows.append(("state space 2x2, order 6", "white noise", res))
        mpi, pi, origin, rec = hysteresis_models(rng)
        lo, hi = mpi.input_limits
        t = np.arange(n) * 1e-4
        drives = {
            "slow sine (1 Hz at 10 kHz)": 0.5 * (lo + hi) + 0.45 * (hi - lo) * np.sin(2 * np.pi * t),
            "random walk": np.clip(np.cumsum(rng.normal(scale=0.02 * (hi - lo), size=n)), lo, hi),
            "full-range jumps": rng.uniform(lo, hi, n),
        }
        refs = {name: mpi.simulate(d)[:, 0] for name, d in drives.items()}
        if rec is not None:
            reps = int(np.ceil(n / rec.n_samples))
            refs["measured displacement (dSPACE)"] = np.tile(rec.y[:, 0], reps)[:n]
        if args.paired:
            print(
                f"| reference | old ({args.paired}) ns/step | new ns/step | old / new [range] | p50 / p99.9 old | p50 / p99.9 new |"
            )
            print("|---|---:|---:|---:|---:|---:|")
            for name, old, new, ratio, rlo, rhi, t in paired(
                args.paired, mpi, refs, n, args.runs, cflags, folder, single
            ):
                print(
                    f"| {name} | {old:.1f} | {new:.1f} | {ratio:.2f} [{rlo:.2f}, {rhi:.2f}] "
                    f"| {t['old50']:.0f} / {t['old999']:.0f} | {t['new50']:.0f} / {t['new999']:.0f} |"
                )
            return 0
        comp = export_c(mpi, "comp", inverse=True, single=single)
        for name, ref in refs.items():
            _check(build(comp, folder).run(ref[:5000]), Compensator(mpi).run(ref[:5000]), single)
            rows.append(
                (
                    f"modified-PI compensator, 20 operators ({origin})",
                    name,
                    time_case(comp, ref[:, None], args.runs, cflags, folder),
                )
            )
        fwd = export_c(mpi, "fwd", single=single)
        rows.append(
            (
                "modified-PI forward, 20 operators",
                "random walk",
                time_case(fwd, drives["random walk"][:, None], args.runs, cflags, folder),
            )
        )
        picomp = export_c(pi, "picomp", inverse=True, single=single)
        ref = pi.simulate(drives["random walk"])[:, 0]
        rows.append(
            (
                "classical-PI compensator, 20 operators",
                "random walk",
                time_case(picomp, ref[:, None], args.runs, cflags, folder),
            )
        )
    head = "| case | input | median ns/step (CPU) | wall ns/step | p50 ns/step | p99.9 ns/step | timer ns | naive C ns/step | naive / ours |"
    print(head)
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for case, name, r in rows:
        naive = f"{r['naive']:.1f} | {r['naive'] / r['median']:.2f}" if "naive" in r else "- | -"
        print(
            f"| {case} | {name} | {r['median']:.1f} | {r['wall']:.1f} | {r['p50']:.1f} | {r['p999']:.1f} "
            f"| {r['timer']:.1f} | {naive} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
