"""Property-based fuzzing of the failure contract: readers, the model loader, CLI verbs.

For any input: a reader returns a Table or raises a :class:`~stageid.StageIdError`; the model
loader returns a model or raises one; a verb exits 0 with a whole output that reads back, or
exits 2 with exactly one stderr line and nothing written — inputs and pre-existing files
unchanged.  In-process runs set ``STAGEID_MEMORY_LIMIT`` so the memory guards are exercised;
the hostile files (declared sizes of gigabytes) run in a subprocess under an address-space
limit.  A few hundred examples in all, well under a minute.
"""

from __future__ import annotations

import contextlib
import io
import json
import resource
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from conftest import run_main
from stageid import StageIdError
from stageid.data import read_table, write_csv
from stageid.hysteresis import PIModel
from stageid.models import StateSpaceModel, load_model, save_model
from stageid.models.serialization import loads

FUZZ = settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
DT = 0.01


@pytest.fixture(autouse=True)
def _bounded_memory(monkeypatch):
    monkeypatch.setenv("STAGEID_MEMORY_LIMIT", "512M")


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """Valid inputs every CLI example starts from (never written to by the examples)."""
    d = tmp_path_factory.mktemp("fuzz")
    g = StateSpaceModel([[0.8]], [[1.0]], [[0.5]], [[0.0]], dt=DT, inputs=("u",), outputs=("y",))
    save_model(g, d / "g.json")
    u = np.random.default_rng(1).standard_normal(300)
    write_csv(d / "rec.csv", {"u": u, "y": g.simulate(u[:, None])[:, 0]}, dt=DT)
    h = PIModel(r=[0.0, 20.0, 40.0], weights=[0.01, 0.005, 0.002])
    save_model(h, d / "h.json")
    v = 50.0 * (1 - np.cos(np.linspace(0, 6 * np.pi, 400)))
    write_csv(d / "hyst.csv", {"V": v, "y": h.simulate(v)[:, 0]}, dt=DT)
    write_csv(d / "ref.csv", {"y": 0.2 * np.sin(np.linspace(0, 6, 100))}, dt=DT)
    return d


def snapshot(folder: Path) -> dict[str, bytes]:
    """The files directly in ``folder`` (an output folder a verb adds is not compared)."""
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def check_contract(args: list[str], folder: Path, outputs: list[str]) -> int:
    """Run a verb in ``folder`` and assert the contract; returns the exit code."""
    before = snapshot(folder)
    rc, out, err = run_main(*args, cwd=folder)
    event(f"exit {rc}")
    assert rc in (0, 2), (args, rc, err)
    if rc == 2:
        lines = err.splitlines()
        assert len(lines) == 1 and lines[0].startswith("stageid: error: "), (args, err)
        assert out == "", (args, out)
        assert snapshot(folder) == before, args  # nothing written, nothing changed
    else:
        for name in outputs:
            path = folder / name
            assert path.is_file(), (args, name)
            read_back(path)
        for name, data in before.items():  # inputs untouched
            if name not in outputs:
                assert (folder / name).read_bytes() == data, (args, name)
    assert not [p for p in folder.iterdir() if p.name.startswith(".")], args  # no temporaries
    return rc


def read_back(path: Path) -> None:
    """A whole output reads back: a model loads, a table reads (with or without its own time axis)."""
    if path.suffix == ".json":
        load_model(path)
        return
    try:
        read_table(path)
    except StageIdError as exc:
        if "no time column" not in str(exc) and "single sample" not in str(exc):
            raise  # a record of one sample carries no dt: reading it needs ts=, as documented
        read_table(path, ts=1.0)


@pytest.fixture
def folder(tmp_path_factory, base):
    def make() -> Path:
        d = tmp_path_factory.mktemp("ex")
        for p in base.iterdir():
            (d / p.name).write_bytes(p.read_bytes())
        (d / "existing.csv").write_text("pre-existing file\n")
        return d

    return make


# ----------------------------------------------------------------------------- readers
CSV_ALPHABET = "0123456789.,-+eE \t;\n\r\"'tuyabnaif[]_"


@FUZZ
@given(st.text(alphabet=CSV_ALPHABET, max_size=300))
def test_csv_reader_returns_a_table_or_one_stageid_error(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("csv") / "x.csv"
    path.write_text(text)
    try:
        read_table(path, ts=0.1)
    except StageIdError as exc:
        assert "\n" not in str(exc)


@FUZZ
@given(st.binary(max_size=400), st.sampled_from([".csv", ".npz", ".mat"]))
def test_readers_survive_arbitrary_bytes(tmp_path_factory, data, suffix):
    path = tmp_path_factory.mktemp("bin") / f"x{suffix}"
    path.write_bytes(data)
    with contextlib.suppress(StageIdError):
        read_table(path, ts=0.1)


def _valid_bytes(kind: str, folder: Path) -> bytes:
    path = folder / f"v.{kind}"
    t = np.arange(20) * DT
    if kind == "npz":
        np.savez_compressed(path, t=t, u=np.sin(t), y=np.cos(t))
    elif kind == "mat":
        import scipy.io

        scipy.io.savemat(path, {"t": t[:, None], "u": np.sin(t)[:, None]}, do_compression=True)
    else:
        write_csv(path, {"u": np.sin(t)}, dt=DT)
    return path.read_bytes()


@FUZZ
@given(
    st.sampled_from(["csv", "npz", "mat"]), st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 255)), max_size=6)
)
def test_readers_survive_corrupted_valid_files(tmp_path_factory, kind, flips):
    folder = tmp_path_factory.mktemp("flip")
    data = bytearray(_valid_bytes(kind, folder))
    for position, value in flips:
        data[position % len(data)] = value
    path = folder / f"x.{kind}"
    path.write_bytes(bytes(data))
    with contextlib.suppress(StageIdError):
        read_table(path, ts=DT)


# ----------------------------------------------------------------------------- model loader
json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-(10**30), 10**30) | st.floats() | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=5), inner, max_size=4),
    max_leaves=20,
)
matrix = st.lists(st.lists(st.one_of(st.floats(-1e3, 1e3), st.integers(-3, 3), json_values), max_size=3), max_size=3)


@st.composite
def model_dicts(draw):
    d = {
        "format": draw(st.sampled_from(["stageid.lti/1", "stageid.hysteresis/1", "x"])),
        "kind": draw(st.sampled_from(["statespace", "transfer", "pi", None])),
        "dt": draw(st.one_of(st.none(), st.floats(), st.text(max_size=4), st.integers(-2, 2))),
    }
    for key in ("A", "B", "C", "D"):
        if draw(st.booleans()):
            d[key] = draw(matrix)
    for key in ("inputs", "outputs"):
        d[key] = draw(st.one_of(st.lists(st.text(max_size=3), max_size=3), json_values))
    if draw(st.booleans()):
        d[draw(st.text(max_size=4))] = draw(json_values)
    return d


@FUZZ
@given(model_dicts())
def test_model_loader_returns_a_model_or_one_stageid_error(d):
    try:
        text = json.dumps(d)
    except ValueError:
        assume(False)
    try:
        loads(text)
    except StageIdError as exc:
        assert "\n" not in str(exc)


# ----------------------------------------------------------------------------- CLI verbs
HOSTILE = ["0", "-1", "1e-320", "1e308", "nan", "inf", "-inf", "abc", "", "3,4", "1e9", "99999999999"]
hostile = st.one_of(st.sampled_from(HOSTILE), st.floats(-1e4, 1e4).map(repr))
#: Values that make a valid command; each example swaps some of them for hostile ones.
GOOD = {
    "dt": "0.01", "duration": "2", "f0": "1", "f1": "10", "freq": "2", "n_samples": "256", "f_low": "1",
    "f_high": "10", "n_cycles": "3", "minimum": "-1", "maximum": "1", "n_reversals": "3", "amplitude": "1",
    "offset": "0", "seed": "1", "n_channels": "2", "order": "8", "clock_period": "1", "n_periods": "1",
    "rms": "0.5", "phase": "0", "idle": "0", "final_fraction": "0.2", "method": "linear", "kind": "random-phase",
    "decay": "linear", "shape": "triangle", "fmin": "1", "fmax": "40", "n": "50",
}  # fmt: skip


def value(draw, name: str) -> str:
    """The good value of ``name`` seven times in eight, else a hostile one."""
    if name in GOOD and draw(st.integers(0, 7)) > 0:
        return GOOD[name]
    return draw(hostile)


good_outputs = st.sampled_from(["o.csv", "o.npz", "existing.csv"])
out_names = st.one_of(
    good_outputs, good_outputs, st.sampled_from(["o.json", "o.mat", "-", "no/dir.csv", "rec.csv", "g.json"])
)


@st.composite
def signal_commands(draw):
    from stageid.signals import SIGNAL_KINDS, signal_parameters

    kind = draw(st.sampled_from(sorted(SIGNAL_KINDS)))
    args = ["signal", kind]
    for name, p in signal_parameters(kind).items():
        if name == "limits":
            if draw(st.booleans()):
                args += ["--limits", draw(st.sampled_from(["-50:50", "0:1", "x", "5:-5"]))]
            continue
        if name == "method" and kind == "prbs":
            continue  # prbs methods differ from chirp's; the default is fine
        if p.default is p.empty or draw(st.integers(0, 3)) == 0:
            args += ["--" + name.replace("_", "-"), value(draw, name)]
    if draw(st.booleans()):
        args += ["--names", draw(st.sampled_from(["a", "a,b", "a,a", "t", "x y", ",", "a,b,c"]))]
    out = draw(out_names)
    return args + ["-o", out], out


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
@given(signal_commands())
def test_signal_verb_keeps_the_contract(folder, command):
    args, out = command
    check_contract(args, folder(), [out])


@st.composite
def freqresp_commands(draw):
    model = draw(st.sampled_from(["g.json", "g.json", "g.json", "g.json", "h.json", "rec.csv", "missing.json"]))
    out = draw(out_names)
    args = ["freqresp", model, "--fmin", value(draw, "fmin"), "--fmax", value(draw, "fmax"), "--n", value(draw, "n")]
    return [*args, "-o", out], out


@settings(max_examples=30, deadline=None, suppress_health_check=list(HealthCheck))
@given(freqresp_commands())
def test_freqresp_verb_keeps_the_contract(folder, command):
    args, out = command
    check_contract(args, folder(), [out])


@st.composite
def csv_records(draw):
    n = draw(st.integers(0, 40))
    names = draw(
        st.sampled_from([["t", "u"], ["t", "u"], ["t", "V"], ["u"], ["t", "u", "y"], ["t", "x"], ["t", "u", "u"]])
    )
    use_time = draw(st.integers(0, 7)) > 0
    values = draw(st.lists(st.floats(-1e3, 1e3), min_size=n * len(names), max_size=n * len(names)))
    rows = [
        [repr(k * DT) if (c == "t" and use_time) else repr(values[k * len(names) + j]) for j, c in enumerate(names)]
        for k in range(n)
    ]
    if rows and draw(st.integers(0, 2)) == 0:  # one hostile cell
        k, j = draw(st.integers(0, n - 1)), draw(st.integers(0, len(names) - 1))
        rows[k][j] = draw(st.sampled_from(["nan", "1e308", "", "x", "inf", "1,2", '"3"']))
    return ",".join(names) + "\n" + "".join(",".join(r) + "\n" for r in rows)


@settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
@given(
    csv_records(),
    out_names,
    st.sampled_from(["g.json", "h.json"]),
    st.sampled_from([[], [], [], ["--ts", "0.01"], ["--ts", "-1"]]),
)
def test_simulate_verb_keeps_the_contract(folder, text, out, model, ts):
    d = folder()
    (d / "in.csv").write_text(text)
    check_contract(["simulate", model, "in.csv", *ts, "-o", out], d, [out])


@settings(max_examples=20, deadline=None, suppress_health_check=list(HealthCheck))
@given(
    out_names,
    st.sampled_from([[], ["--limits", "0,50"], ["--limits", "5,1"], ["--limits", "a"]]),
    st.sampled_from(["y", "u", "q"]),
)
def test_compensate_verb_keeps_the_contract(folder, out, limits, column):
    check_contract(["compensate", "h.json", "ref.csv", "--column", column, *limits, "-o", out], folder(), [out])


@settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
@given(
    st.sampled_from([None, "p558", "p558", "maglev", "piezo-actuator", "nope"]),
    st.sampled_from([[], [], ["--experiment", "chirp-z"], ["--experiment", "x"], ["--controller"], ["--seed", "3"]]),
    st.sampled_from(
        [[], ["-o", "o.json"], ["-o", "o.json"], ["-o", "o.csv"], ["-o", "existing.csv"], ["-o", "no/d.json"]]
    ),
)
def test_plants_verb_keeps_the_contract(folder, name, extra, out):
    args = ["plants", *([name] if name else []), *extra, *out]
    outputs = [out[1]] if out else []
    check_contract(args, folder(), outputs if name else [])


@settings(max_examples=12, deadline=None, suppress_health_check=list(HealthCheck))
@given(
    st.sampled_from(["1", "1", "2", "auto", "0", "x", "1,2"]),
    st.sampled_from(["8", "8", "auto", "1", "400", "-3"]),
    st.sampled_from(["m.json", "m.json", "rec.csv", "existing.csv", "g.json"]),
    st.sampled_from([[], [], ["--report", "rep"], ["--report", "rec.csv"], ["--band", "1:20"], ["--band", "5:1"]]),
)
def test_identify_statespace_verb_keeps_the_contract(folder, order, horizon, out, extra):
    args = ["identify", "statespace", "rec.csv", "--inputs", "u", "--outputs", "y", "--order", order]
    rc = check_contract([*args, "--horizon", horizon, *extra, "-o", out], folder(), [out])
    assert rc == 2 or out not in ("rec.csv",)  # an input is never overwritten


@settings(max_examples=12, deadline=None, suppress_health_check=list(HealthCheck))
@given(
    st.sampled_from(["pi", "pi", "modified-pi"]),
    st.sampled_from(["3", "3", "2", "1", "1000", "x"]),
    st.sampled_from([[], [], ["--creep", "0.1,1"], ["--creep", "-1"], ["--creep", "1e308"], ["--creep", ","]]),
    st.sampled_from(["hy.json", "hy.json", "hyst.csv", "h.json", "o.csv"]),
    st.sampled_from([[], [], ["--report", "rep"], ["--initial-state", "ascending"], ["--no-input-warp"]]),
)
def test_identify_hysteresis_verb_keeps_the_contract(folder, kind, n_operators, creep, out, extra):
    args = ["identify", "hysteresis", "hyst.csv", "--input", "V", "--output", "y", "--model", kind]
    check_contract([*args, "--operators", n_operators, *creep, *extra, "-o", out], folder(), [out])


@settings(max_examples=6, deadline=None, suppress_health_check=list(HealthCheck))
@given(
    st.sampled_from(["g.json", "h.json", "rec.csv"]),
    st.sampled_from([["rec.csv"], ["hyst.csv", "--inputs", "V", "--outputs", "y"], [], ["ref.csv"]]),
    st.sampled_from(["rep", "rep", "existing.csv", "no/rep"]),
)
def test_report_verb_keeps_the_contract(folder, model, data, out):
    d = folder()
    before = snapshot(d)
    rc, out_text, err = run_main("report", model, *data, "--out", out, cwd=d)
    event(f"exit {rc}")
    assert rc in (0, 2), err
    if rc == 2:
        assert len(err.splitlines()) == 1 and out_text == "" and snapshot(d) == before, err
        assert not (d / "rep").exists()
    else:
        assert (d / out / "index.html").is_file() and (d / out / "metrics.json").is_file()
        assert snapshot(d) == before  # the inputs and other files untouched
    assert not [p for p in d.iterdir() if p.name.startswith(".")]


# ----------------------------------------------------------------------------- hostile files
AS_LIMIT = 3 * 2**30


def _declaring_file(folder: Path, fmt: str, shape: tuple[int, int], descr: str) -> str:
    """An .npz or v7.3 .mat whose header declares ``shape`` but whose content is a few bytes."""
    if fmt == "npz":
        header = io.BytesIO()
        np.lib.format.write_array_header_1_0(header, {"descr": descr, "fortran_order": False, "shape": shape})
        with zipfile.ZipFile(folder / "b.npz", "w") as zf:
            zf.writestr("u.npy", b"\x93NUMPY\x01\x00" + header.getvalue()[8:] + b"\x00" * 64)
        return "b.npz"
    h5py = pytest.importorskip("h5py")
    with h5py.File(folder / "b.mat", "w", userblock_size=512) as fh:  # chunks never written: no data
        fh.create_dataset("u", shape=shape[::-1], dtype=descr, compression="gzip", chunks=(1, min(shape[0], 10**6)))
    with open(folder / "b.mat", "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file".ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02IM")
    return "b.mat"


@settings(max_examples=6, deadline=None, suppress_health_check=list(HealthCheck))
@given(
    st.tuples(st.integers(10**8, 4 * 10**9), st.integers(1, 4)).map(lambda s: (s[0], s[1])),
    st.sampled_from(["<f8", "<i4", "|u1"]),
    st.sampled_from(["npz", "mat"]),
)
def test_files_declaring_huge_arrays_are_refused_in_bounded_memory(tmp_path_factory, shape, descr, fmt):
    folder = tmp_path_factory.mktemp("bomb")
    save_model(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5], inputs=("u",)), folder / "h.json")
    name = _declaring_file(folder, fmt, shape, descr)
    proc = subprocess.run(
        [sys.executable, "-m", "stageid.cli.main", "simulate", "h.json", name, "--ts", "1", "-o", "o.csv"],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (AS_LIMIT, AS_LIMIT)),
    )
    assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1, proc.stderr
    assert "would need about" in proc.stderr, proc.stderr
    assert sorted(p.name for p in folder.iterdir()) == sorted([name, "h.json"])
