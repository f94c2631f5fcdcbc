"""Stage models (hysteresis -> creep -> unit-DC-gain dynamics) exported to C and MATLAB.

The C is compiled with the system compiler and streamed one sample at a time; it must agree with
:meth:`StageModel.simulate` sample by sample.  Tolerances: double within 1e-10 of the record's
largest |output| (the C keeps the package's filter arithmetic; what remains is the ~1e-16
reassociation of the hysteresis kernels' weighted sum, amplified by the dynamics' resonant gain
-- about 1e-13 measured); single within 1e-5 of the output's range (as the other float exports).
"""

from __future__ import annotations

import contextlib
import io
import json
from dataclasses import replace

import numpy as np
import pytest
import scipy.io
from scipy.signal import lfilter

from stageid import ModelError
from stageid.cli.main import main
from stageid.data import read_table, write_csv
from stageid.export import export_c, export_mat
from stageid.export.host import build, find_compiler
from stageid.export.matlab import mat_variables
from stageid.hysteresis import Compensator, CreepTerm, ModifiedPIModel, PIModel, PreisachModel
from stageid.hysteresis.stage import StageModel
from stageid.hysteresis.stage.dynamics import transfer_to_statespace, zoh_resonance
from stageid.models import StateSpaceModel, save_model

needs_cc = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (gcc, clang or cc) on PATH")
DT = 1e-4


def run(*args):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main([str(a) for a in args])
    return rc, out.getvalue(), err.getvalue()


def assert_double(y_c, y_ref):
    assert np.max(np.abs(y_c - y_ref)) <= 1e-10 * np.max(np.abs(y_ref))


def random_dynamics(rng, order):
    """Unit-DC-gain dynamics of ``order`` (1-4): a fast lag and/or lightly damped resonances."""
    b, a = np.array([1.0]), np.array([1.0])
    if order % 2:
        p = np.exp(-2 * np.pi * rng.uniform(300.0, 3000.0) * DT)
        b, a = np.array([1 - p, 0.0]), np.array([1.0, -p])
    for _ in range(order // 2):
        br, ar = zoh_resonance(rng.uniform(100.0, 1500.0), rng.uniform(0.005, 0.05), DT)
        b, a = np.convolve(b, br), np.convolve(a, ar)
    return transfer_to_statespace(b, a, DT)


def random_stage(seed, kind="pi"):
    """A random PI or modified-PI stage with two creep lags and dynamics of order 1-4, by seed."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(5, 15))
    r = np.r_[0.0, np.sort(rng.uniform(0.1, 10.0, m - 1))]
    w = np.r_[1.0, rng.uniform(0.0, 0.3, m - 1)]
    creep = CreepTerm(rng.uniform(0.01, 1.0, 2), rng.uniform(0.0, 0.1, 2), DT)
    common = dict(weights=w, creep=creep, input_offset=rng.normal(), output_offset=rng.normal())
    if kind == "pi":
        h = PIModel(r=r, **common)
    else:
        ra = r * rng.uniform(1, 2, m)
        h = ModifiedPIModel(r=r, rc=r * rng.uniform(0, 1, m), ra=ra, rb=ra * rng.uniform(0, 1, m),
                            input_warp=0.1, warp_scale=8.0, **common)  # fmt: skip
    return StageModel(h, random_dynamics(rng, int(rng.integers(1, 5))))


def drive(seed, n=6000):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    return np.cumsum(rng.normal(size=n)) * 0.2 + 8 * np.sin(2 * np.pi * 20 * t)


@pytest.fixture
def run_c(tmp_path):
    count = iter(range(1000))

    def go(model, u, **kw):
        code = export_c(model, f"s{next(count)}", **kw)
        return build(code, tmp_path).run(np.asarray(u, dtype=float).reshape(-1, 1))[:, 0]

    return go


@needs_cc
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("kind", ["pi", "modified-pi"])
def test_random_stage_c_matches_simulate(run_c, seed, kind):
    model, u = random_stage(seed, kind), drive(seed)
    y = model.simulate(u)[:, 0]
    assert_double(run_c(model, u), y)
    assert np.max(np.abs(run_c(model, u, single=True) - y)) <= 1e-5 * np.ptp(y)


@needs_cc
def test_identified_stage_c_matches_simulate(run_c):
    from stageid.hysteresis.stage.identification import StageIdentifier
    from stageid.signals import decaying_triangle

    true = random_stage(7)
    u = decaying_triangle(20.0, 6, DT, amplitude=10.0)
    rng = np.random.default_rng(8)
    y = true.simulate(u)[:, 0] + 1e-3 * rng.normal(size=u.size)
    fit = StageIdentifier("pi", n_operators=6, dynamics=2, creep=[0.1], sample_time=DT).fit((u, y))
    model = fit.model
    assert model.dynamics_order == 2 and model.creep_term is not None  # all three parts exported
    u_val = drive(9)
    assert_double(run_c(model, u_val), model.simulate(u_val)[:, 0])


@needs_cc
def test_stage_without_dynamics_and_static_dynamics(run_c):
    h = random_stage(4).hysteresis
    u = drive(4, 2000)
    static = StateSpaceModel(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[1.0]], dt=DT)
    for model in (StageModel(h), StageModel(h, static)):
        assert_double(run_c(model, u), model.simulate(u)[:, 0])


@needs_cc
def test_stage_inverse_is_the_hysteresis_compensator(run_c):
    rng = np.random.default_rng(5)
    h = PIModel(r=np.r_[0.0, np.cumsum(rng.uniform(0.1, 1.0, 9))], weights=np.r_[1.0, rng.uniform(0, 0.3, 9)])
    model = StageModel(h, random_dynamics(rng, 2))
    y_ref = h.simulate(drive(5, 3000))[:, 0]
    code = export_c(model, "inv", inverse=True)
    assert "dynamics are not inverted" in code.header
    assert_double(run_c(model, y_ref, inverse=True), Compensator(h).run(y_ref)[:, 0])


@needs_cc
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_creep_stage_inverse_is_the_package_compensator(run_c, seed):
    """The creep's lags and the first sample's static gain in the C compensator, as CreepInverse
    runs them: the same drives in double (offsets, two lags), float within 1e-5 of the range."""
    model = random_stage(seed)
    h = model.hysteresis
    y_ref = model.simulate(drive(seed, 3000))[:, 0]
    u = Compensator(h).run(y_ref)[:, 0]
    assert np.max(np.abs(h.simulate(u)[:, 0] - y_ref)) <= 1e-9 * np.max(np.abs(y_ref))  # it inverts the creep
    assert_double(run_c(model, y_ref, inverse=True), u)
    assert np.max(np.abs(run_c(model, y_ref, inverse=True, single=True) - u)) <= 1e-5 * np.ptp(u)
    # drive limits that clip the first drive and later ones: the state rebuilt as the package does
    limits = (float(u[0]) + 0.5, float(np.quantile(u, 0.9)))
    clipped = Compensator(h, limits).run(y_ref)[:, 0]
    assert np.isclose(clipped[0], limits[0], rtol=1e-12) and np.mean(np.isclose(clipped, limits[1], rtol=1e-12)) > 0.05
    assert_double(run_c(model, y_ref, inverse=True, limits=limits), clipped)


@needs_cc
def test_creep_stage_inverse_starts_from_stored_lags(run_c):
    model = random_stage(5)
    h = replace(model.hysteresis, creep=model.hysteresis.creep.with_state([1.5, -2.0]))
    stored = replace(model, hysteresis=h)
    y_ref = stored.simulate(drive(5, 2000))[:, 0]
    assert_double(run_c(stored, y_ref, inverse=True), Compensator(h).run(y_ref)[:, 0])


def test_refused_with_one_line():
    creep_stage = random_stage(0, "modified-pi")
    with pytest.raises(ModelError, match="modified-PI hysteresis with creep has no C form"):
        export_c(creep_stage, "s", inverse=True)
    shifted = replace(random_stage(0).hysteresis, r=random_stage(0).hysteresis.r + 0.1)
    with pytest.raises(ModelError, match="first threshold is 0.1"):
        export_c(replace(random_stage(0), hysteresis=shifted), "s", inverse=True)
    with pytest.raises(ModelError, match="differs"):
        export_c(creep_stage, "s", dt=2 * DT)
    preisach = PreisachModel((-1.0, 1.0), np.full(3, 0.5))
    with pytest.raises(ModelError, match="Preisach hysteresis has no C export"):
        export_c(StageModel(preisach), "s")


def test_mat_round_trip(tmp_path):
    model = random_stage(3, "modified-pi")
    export_mat(model, tmp_path / "s.mat")
    m = scipy.io.loadmat(tmp_path / "s.mat")
    g = model.dynamics
    for key in "ABCD":
        assert np.array_equal(m[key], getattr(g, key))  # stored exactly, not converted
    assert m["Ts"][0, 0] == DT and str(m["kind"][0]) == "stage"
    h = m["hysteresis"][0, 0]
    assert np.array_equal(h["r"][:, 0], model.hysteresis.r)
    assert np.array_equal(h["weights"][:, 0], model.hysteresis.weights)
    assert np.array_equal(h["creep"][0, 0]["time_constants"][:, 0], model.hysteresis.creep.time_constants)
    # the stage's output from the file's parts: y = v0 + lfilter(num, den, v - v0)
    u = drive(3, 3000)
    v = model.hysteresis.simulate(u)[:, 0]
    y = v[0] + lfilter(m["num"][0], m["den"][0], v - v[0])
    assert np.max(np.abs(y - model.simulate(u)[:, 0])) <= 1e-12 * np.max(np.abs(y))


@pytest.fixture
def stage_file(tmp_path):
    path = tmp_path / "stage.json"
    save_model(random_stage(1), path)
    return path


@needs_cc
def test_cli_export_c_agrees_with_stageid_simulate(tmp_path, stage_file):
    u = drive(2, 3000)
    write_csv(tmp_path / "u.csv", {"V": u}, dt=DT)
    assert run("simulate", stage_file, tmp_path / "u.csv", "-o", tmp_path / "y.csv")[0] == 0
    rc, out, err = run("export", "c", stage_file, "--prefix", "stage", "-o", tmp_path / "b")
    assert rc == 0 and err == "" and "stage.h" in out
    from stageid.models import load_model

    y_c = build(export_c(load_model(stage_file), "stage"), tmp_path / "b").run(u[:, None])[:, 0]
    assert_double(y_c, read_table(tmp_path / "y.csv").column("y"))  # CSV keeps 17 digits
    rc, out, _ = run("export", "mat", stage_file, "-o", tmp_path / "s.mat")
    assert rc == 0 and sorted(k for k in scipy.io.loadmat(tmp_path / "s.mat") if not k.startswith("__")) == [
        "A", "B", "C", "D", "InputName", "OutputName", "Ts", "den", "hysteresis", "kind", "num",
    ]  # fmt: skip


def test_cli_inverse_of_stage_says_what_it_omits(tmp_path):
    rng = np.random.default_rng(6)
    path = tmp_path / "s.json"
    save_model(StageModel(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]), random_dynamics(rng, 2)), path)
    rc, out, err = run("export", "c", path, "--prefix", "comp", "--inverse", "-o", tmp_path / "b")
    assert rc == 0 and err == "" and "note:" in out and "dynamics are not inverted" in out


def test_cli_inverse_of_a_creep_stage_is_exported(tmp_path):
    path = tmp_path / "s.json"
    save_model(random_stage(1), path)
    rc, out, err = run("export", "c", path, "--prefix", "comp", "--inverse", "-o", tmp_path / "b")
    assert rc == 0 and err == "" and "dynamics are not inverted" in out
    header = (tmp_path / "b" / "comp.h").read_text()
    assert "Creep: 2 first-order lags" in header and "lag[2]" in header


BAD_FILES = [(d, c) for d in ("no-hysteresis", "no-dynamics", "bad-matrix", "truncated") for c in ("c", "mat")]


@pytest.mark.parametrize("damage, command", [*BAD_FILES, ("preisach-c", "c")])  # a Preisach stage has a MAT form
def test_cli_bad_stage_files_one_line_exit_2(tmp_path, stage_file, damage, command):
    d = json.loads(stage_file.read_text())
    bad = tmp_path / "bad.json"
    if damage == "no-hysteresis":
        del d["hysteresis"]
    elif damage == "no-dynamics":
        del d["dynamics"]
    elif damage == "bad-matrix":
        d["dynamics"]["A"] = [[1.0]]
    elif damage == "preisach-c":
        save_model(StageModel(PreisachModel((-1.0, 1.0), np.full(3, 0.5))), bad)
    if damage == "truncated":
        bad.write_text(stage_file.read_text()[:300])
    elif damage != "preisach-c":
        bad.write_text(json.dumps(d))
    target = tmp_path / ("b" if command == "c" else "s.mat")
    extra = ["--prefix", "p"] if command == "c" else []
    rc, out, err = run("export", command, bad, *extra, "-o", target)
    assert rc == 2 and out == "" and err.count("\n") == 1 and err.startswith("stageid: error:")
    assert not target.exists()


def test_mat_of_a_preisach_stage_with_creep_and_disturbance_modes(tmp_path):
    g = transfer_to_statespace([0.5, 0.0], [1.0, -0.5], DT)
    creep = CreepTerm([0.1], [0.1], DT)
    model = StageModel(PreisachModel((-1.0, 1.0), np.full(3, 0.5)), g, creep=creep, disturbance_modes=((50.0, 0.02),))
    export_mat(model, tmp_path / "p.mat")
    m = scipy.io.loadmat(tmp_path / "p.mat")
    assert str(m["hysteresis"][0, 0]["kind"][0]) == "preisach"
    assert m["creep"][0, 0]["weights"][0, 0] == 0.1  # the stage's own creep term, beside the hysteresis
    assert np.array_equal(m["disturbance_modes"], [[50.0, 0.02]])
    assert np.array_equal(m["den"][0], model.transfer()[1])


@needs_cc
def test_creep_runs_at_the_dynamics_sample_time(run_c):
    # a creep term identified at a sample time that differs within tolerance: the stage runs
    # its lags at the dynamics' dt, and so must the C
    model = random_stage(5)
    creep = model.hysteresis.creep
    off = CreepTerm(creep.time_constants, creep.weights, DT * (1 + 5e-7))  # within PERIOD_RTOL (1e-6)
    model = StageModel(replace(model.hysteresis, creep=off), model.dynamics)
    u = drive(5, 3000)
    assert_double(run_c(model, u), model.simulate(u)[:, 0])


@pytest.mark.parametrize(
    ("settings", "parameter"),
    [
        ({"method": "zoh"}, "`method=`"),
        ({"inverse": True, "dt": 0.001}, "`dt=`"),
        ({"limits": (-1.0, 1.0)}, "`inverse=True`"),
        ({"dt": 0.5}, "`dt=0.5`"),
    ],
)
def test_refusals_name_the_parameter_as_in_a_call_not_a_flag(settings, parameter):
    model = StageModel(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]), random_dynamics(np.random.default_rng(3), 2))
    with pytest.raises(ModelError) as err:
        export_c(model, "s", **settings)
    assert parameter in str(err.value) and "--" not in str(err.value)


def test_matlab_export_of_a_stage_names_the_parameters_it_refuses():
    model = StageModel(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]), random_dynamics(np.random.default_rng(3), 2))
    with pytest.raises(ModelError) as err:
        mat_variables(model, dt=0.1)
    assert "`dt=`/`method=` discretise a continuous LTI model" in str(err.value) and "--" not in str(err.value)
