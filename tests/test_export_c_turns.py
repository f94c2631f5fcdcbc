"""The exported modified-PI compensator on long moves: the reversal curve's first iterate
(``stageid.export.c_reversal_curve``) and the references that stress it -- full-range jumps,
drive limits and saturation, roots exactly on operator corners, holds and one-ulp moves after
jumps.  Tolerances as in test_export_c.py (double: 1e-12 of the largest |drive|; float: 1e-5 of
the drive's range)."""

from __future__ import annotations

import ctypes

import numpy as np
import pytest

from stageid.export import export_c
from stageid.export.c_reversal_curve import curve_table
from stageid.export.host import build, compile_files, find_compiler
from stageid.hysteresis import Compensator, ModifiedPIModel

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (gcc, clang or cc) on PATH")


def model_with(rng, m=12, warp=0.0, limits=(-14.0, 13.0), state=None):
    r = np.r_[0.0, np.sort(rng.uniform(0.3, 10.0, m - 1))]
    ra = r * rng.uniform(1, 1.6, m)
    w = np.r_[0.6, rng.uniform(-0.02, 0.3, m - 1)]
    return ModifiedPIModel(
        r=r, rc=r * rng.uniform(0.5, 1, m), ra=ra, rb=ra * rng.uniform(0.6, 1, m), weights=w, input_offset=0.4,
        output_offset=-0.7, input_warp=warp, warp_scale=9.0, input_limits=limits, state=state,
    )  # fmt: skip


def check(model, y_ref, tmp_path, single=False, name="comp"):
    drive_c = build(export_c(model, name, inverse=True, single=single), tmp_path).run(y_ref)[:, 0]
    drive = Compensator(model).run(y_ref)[:, 0]
    if single:
        assert np.max(np.abs(drive_c - drive)) <= 1e-5 * float(np.ptp(drive))
    else:
        assert np.max(np.abs(drive_c - drive)) <= 1e-12 * float(np.max(np.abs(drive)))
    return drive_c


def test_curve_table_is_the_reversal_curve_and_its_inverse():
    rng = np.random.default_rng(0)
    widths, w = np.r_[0.0, rng.uniform(0, 9, 7)], np.r_[0.5, rng.uniform(-0.05, 0.4, 7)]
    knot, value, islope = curve_table(widths, w)
    D = lambda d: float(np.sum(w * np.maximum(d - widths, 0.0)))  # noqa: E731
    assert np.all(np.diff(knot) >= 0) and np.allclose(value, [D(d) for d in knot], rtol=0, atol=1e-13)
    for d in np.r_[rng.uniform(0, 12, 50), knot]:  # the table's inverse at D(d) gives d back
        k = max(int(np.sum(value <= D(d))) - 1, 0)
        assert knot[k] + (D(d) - value[k]) * islope[k] == pytest.approx(d, abs=1e-12)
    assert curve_table(np.array([0.0, 1.0]), np.array([-0.1, 1.0])) is None  # D falls first: no table


_GUESS_DRIVER = """
#include "{p}.c"
/* the static first iterate of the exported file, from the state comp_init sets */
void guesses(long n, const double *target, double sg, double *x)
{{
    {p}_state s;
    long k;
    {p}_init(&s);
    for (k = 0; k < n; ++k) x[k] = sg * {p}_turn_guess(&s, target[k] - {p}_OUTPUT_OFFSET, sg);
}}
"""


@pytest.mark.parametrize("direction", ["rise from x >= 0", "fall from x <= 0"])
def test_first_iterate_is_the_root_after_a_wiping_move(tmp_path, direction):
    # Masing's rule, as the table uses it: every operator on the branch of the move before the
    # turn, a move away from it follows the reversal curve, so its first iterate is the exact
    # root (no pass needed beyond the check).  Fails if the tables' rows or widths are mixed up.
    rng = np.random.default_rng(1)
    base = model_with(rng, limits=None)
    rising = direction.startswith("rise")
    u_t = base.input_offset + (2.5 if rising else -2.5)
    model = base.with_state(base.consistent_state(u_t, "descending" if rising else "ascending"))
    x = model.state.x + (1 if rising else -1) * np.r_[rng.uniform(0.01, 25, 40), 0.0]
    x[-1] = model.state.x + (1 if rising else -1) * float(np.sort(model.r + model.rb)[5])  # a knot itself
    targets = np.array([model.simulate([model.from_operator_input(v)])[0, 0] for v in x])
    code = export_c(model, "g", inverse=True)
    for name, text in code.files().items():
        (tmp_path / name).write_text(text)
    (tmp_path / "guesses.c").write_text(_GUESS_DRIVER.format(p="g"))
    lib = tmp_path / "libguess.so"
    compile_files([tmp_path / "guesses.c"], lib, flags=("-O2", "-fPIC", "-shared", f"-I{tmp_path}"))
    fn = ctypes.CDLL(str(lib)).guesses
    fn.restype = None
    fn.argtypes = [ctypes.c_long, ctypes.c_void_p, ctypes.c_double, ctypes.c_void_p]
    out = np.empty_like(targets)
    fn(targets.size, targets.ctypes.data, 1.0 if rising else -1.0, out.ctypes.data)
    assert np.max(np.abs(out - x)) <= 1e-12 * np.max(np.abs(x))


_MEMORY_DRIVER = """
#include "{p}.c"
/* steps through `n` targets, then the static first iterate for each of `m` queries (rising) */
void after(long n, const double *steps, long m, const double *query, double *x)
{{
    {p}_state s;
    double out;
    long k;
    {p}_init(&s);
    for (k = 0; k < n; ++k) {p}_step(&s, steps + k, &out);
    for (k = 0; k < m; ++k) x[k] = {p}_turn_guess(&s, query[k] - {p}_OUTPUT_OFFSET, 1.0);
}}
"""


def test_first_iterate_remembers_older_turns(tmp_path):
    # return-point memory: wiped out at x0, up 20 to x1, down 10 to x2, up again.  Up to x1 the
    # rise follows the curve of the turn x2; past x1 it continues the curve of x0 (the turns x1,
    # x2 wiped out), so the first iterate is the root on both sides of x1 -- past x1 only if the
    # compensator remembers x0 (fails with the last turn alone: checked)
    rng = np.random.default_rng(6)
    base = model_with(rng, limits=None)
    model = base.with_state(base.consistent_state(base.input_offset + 1.0, "descending"))
    x0 = model.state.x
    x1, x2 = x0 + 20.0, x0 + 10.0
    path = [x1, x2, x2 + 1e-3]  # the last one turns the move upwards (the turn x2 is kept)
    y = model.simulate(model.from_operator_input(np.array(path)))[:, 0]
    x = np.r_[x2 + rng.uniform(0.5, 9.5, 10), x1 + rng.uniform(0.5, 15, 10)]
    targets = np.array([model.simulate(model.from_operator_input(np.r_[path, v]))[-1, 0] for v in x])
    code = export_c(model, "g", inverse=True)
    for name, text in code.files().items():
        (tmp_path / name).write_text(text)
    (tmp_path / "after.c").write_text(_MEMORY_DRIVER.format(p="g"))
    lib = tmp_path / "libafter.so"
    compile_files([tmp_path / "after.c"], lib, flags=("-O2", "-fPIC", "-shared", f"-I{tmp_path}"))
    fn = ctypes.CDLL(str(lib)).after
    fn.restype = None
    fn.argtypes = [ctypes.c_long, ctypes.c_void_p, ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p]
    out = np.empty_like(targets)
    fn(y.size, y.ctypes.data, targets.size, targets.ctypes.data, out.ctypes.data)
    assert np.max(np.abs(out - x)) <= 1e-12 * np.max(np.abs(x))


def test_limits_saturation_and_beyond(tmp_path):
    # references the drive limits cannot reach (the answer is the limit, from either side, the
    # first iterate beyond the far end), a hold at the limit, the way back and limits hit exactly
    rng = np.random.default_rng(2)
    model = model_with(rng, warp=-0.2)
    lo, hi = model.input_limits
    y_lo, y_hi = (model.with_state(None).simulate(np.r_[0.0, v])[1, 0] for v in (lo, hi))
    reach = y_hi - y_lo
    y = np.r_[y_hi + reach, y_hi + 2 * reach, y_hi, y_lo - reach, y_lo, y_lo - 3 * reach]
    y = np.r_[y, rng.uniform(y_lo - reach, y_hi + reach, 400), np.repeat(y_hi + reach, 5), rng.uniform(y_lo, y_hi, 50)]
    drive = check(model, y, tmp_path)
    assert drive.min() == lo and drive.max() == hi and np.mean((drive == lo) | (drive == hi)) > 0.4
    check(model, y, tmp_path, single=True, name="comp_f")


@pytest.mark.parametrize("warp", [0.0, 0.25])
def test_roots_on_operator_corners(tmp_path, warp):
    # drives that land exactly on corners of the reversal curve (turn +- a width) and on the
    # operators' own thresholds, alternating from turns on both sides of 0: the iterate that
    # starts on a corner must not stop on the wrong side of it
    rng = np.random.default_rng(3)
    model = model_with(rng, warp=warp, limits=None)
    widths = np.unique(np.r_[model.r + model.rb, model.ra + model.rc, model.r, model.rc, model.ra, model.rb])
    turns = rng.choice([-1, 1], 300) * rng.uniform(0, 4, 300)
    x = np.empty(600)
    x[0::2] = turns
    x[1::2] = turns - np.sign(turns + 1e-300) * rng.choice(widths, 300)
    y = model.simulate(model.from_operator_input(x))[:, 0]
    drive_c = check(model, y, tmp_path)
    assert np.max(np.abs(model.simulate(drive_c)[:, 0] - y)) <= 1e-13 * np.max(np.abs(y))
    check(model, y, tmp_path, single=True, name="comp_f")


def test_holds_and_ulp_moves_after_jumps(tmp_path):
    rng = np.random.default_rng(4)
    model = model_with(rng)
    lo, hi = model.input_limits
    u = np.repeat(rng.uniform(lo, hi, 150), 3)
    y = model.with_state(None).simulate(u)[:, 0]
    y[1::3] = np.nextafter(y[1::3], np.inf)  # one ulp up after each jump, then one down
    y[2::3] = np.nextafter(y[2::3], -np.inf)
    check(model, y, tmp_path)


def test_without_a_table(tmp_path):
    # one operator of nonzero weight (no spacing of thresholds: no long moves) and a reversal
    # curve that falls at first (a negative weight at the smallest width): the plain iteration
    rng = np.random.default_rng(5)
    one = ModifiedPIModel(r=[0.0, 2.0], rc=[0.0, 1.0], ra=[0.0, 3.0], rb=[0.0, 2.5], weights=[1.0, 0.0])
    falls = ModifiedPIModel(r=[0.0, 0.5, 3.0], rc=[0.0, 0.2, 2.0], ra=[3.0, 0.6, 3.5], rb=[3.0, 0.1, 3.2],
                            weights=[1.0, -0.2, 0.3])  # fmt: skip
    assert falls.min_slope() > 0 and curve_table(falls.r + falls.rb, falls.weights) is None
    for k, model in enumerate((one, falls)):
        assert "turn_guess" not in export_c(model, "c", inverse=True).source
        y = model.simulate(rng.uniform(-9, 9, 500))[:, 0]
        check(model, y, tmp_path, name=f"plain{k}")
