"""Every verb reads time columns by the one sample-time rule, from the user's side: records of
unequal lengths with ``t`` written as loggers write it, and bad periods refused in one line."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import run_main
from stageid.models import StateSpaceModel, load_model, save_model

sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks" / "recovery"))
from common import TIME_STYLES, write_record  # noqa: E402

FS = 1e4
#: The lengths of the failing report: the old mean step of a repr column differs by an ulp.
LENGTHS = (24000, 4988)


def _signals(n: int, seed: int) -> dict[str, np.ndarray]:
    """A drive of a few sines and the response of a first-order lag with a hysteretic term."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    u = sum(
        a * np.sin(2 * np.pi * f * t + p)
        for a, f, p in zip(rng.uniform(1, 3, 4), (5, 13, 41, 97), rng.uniform(0, 6, 4))
    )
    x = np.zeros(n)
    for k in range(1, n):
        x[k] = 0.95 * x[k - 1] + 0.05 * u[k - 1]
    return {"u": u, "y": x + 0.1 * np.tanh(u) + 1e-4 * rng.standard_normal(n)}


def _records(folder: Path, style: str, lengths=LENGTHS) -> list[str]:
    rng = np.random.default_rng(len(style))
    return [str(write_record(folder / f"{style}{n}.csv", _signals(n, n), FS, style, rng)) for n in lengths]


def _ok(*args: object) -> str:
    rc, out, err = run_main(*args)
    assert rc == 0, err
    return err


def _one_line_exit_2(*args: object) -> str:
    rc, _, err = run_main(*args)
    lines = err.strip().splitlines()
    assert rc == 2, err
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, str]:
    folder = tmp_path_factory.mktemp("records")
    a, b = _records(folder, "repr")
    model = folder / "m.json"
    save_model(StateSpaceModel([[0.95]], [[0.05]], [[1.0]], [[0.0]], dt=1e-4, inputs=["u"], outputs=["y"]), model)
    return {"a": a, "b": b, "model": str(model), "folder": str(folder)}


def test_hysteresis_creep_auto_accepts_unequal_repr_records(files, tmp_path):
    # before: "fitting creep needs one sampling period for all records; got [9.999999999999999e-05, 0.0001]"
    out = tmp_path / "h.json"
    _ok("identify", "hysteresis", files["a"], files["b"], "--input", "u", "--output", "y", "--creep", "auto",
        "--model", "pi", "--operators", "4", "--disturbance-modes", "none", "-o", out)  # fmt: skip
    assert load_model(out).dt == 1e-4


def test_verbs_accept_unequal_repr_records(files, tmp_path):
    a, b, model = files["a"], files["b"], files["model"]
    _ok("identify", "statespace", a, b, "--inputs", "u", "--outputs", "y", "--order", "1", "--horizon", "8",
        "-o", tmp_path / "s.json")  # fmt: skip
    assert load_model(tmp_path / "s.json").dt == 1e-4
    _ok("frf", a, b, "--inputs", "u", "--outputs", "y", "-o", tmp_path / "f.csv")
    _ok("validate", model, a, b)
    _ok("simulate", model, b, "-o", tmp_path / "sim.csv")
    _ok("identify", "hysteresis", b, "--input", "u", "--output", "y", "--model", "pi", "--operators", "4",
        "-o", tmp_path / "h.json")  # fmt: skip
    ref = write_record(tmp_path / "ref.csv", {"yref": _signals(4988, 1)["y"]}, FS, "repr")
    _ok("compensate", tmp_path / "h.json", ref, "--column", "yref", "-o", tmp_path / "drive.csv")


@pytest.mark.parametrize("style", TIME_STYLES)
def test_every_logger_style_gives_the_nominal_period(style, tmp_path):
    records = _records(tmp_path, style, lengths=(4988, 2400) if style == "float32" else LENGTHS)
    err = _ok("identify", "statespace", *records, "--inputs", "u", "--outputs", "y", "--order", "1",
              "--horizon", "8", "-o", tmp_path / "s.json")  # fmt: skip
    assert load_model(tmp_path / "s.json").dt == 1e-4
    assert "time stamps deviate" not in err  # rounding is not jitter
    _ok("frf", *records, "--inputs", "u", "--outputs", "y", "-o", tmp_path / "f.csv")


def test_jitter_beyond_rounding_is_noted_in_one_line(tmp_path):
    n = 4988
    t = np.arange(n) / FS
    t[1000] += 3e-4 / FS
    cols = _signals(n, 3)
    text = "t,u,y\n" + "".join(f"{float(a)!r},{float(b)!r},{float(c)!r}\n" for a, b, c in zip(t, cols["u"], cols["y"]))
    (tmp_path / "j.csv").write_text(text)
    err = _ok("frf", tmp_path / "j.csv", "--inputs", "u", "--outputs", "y", "-o", tmp_path / "f.csv")
    notes = [line for line in err.splitlines() if "time stamps deviate" in line]
    assert len(notes) == 1 and "0.0003 of the period" in notes[0], err


def test_records_with_clocks_1e4_apart_are_refused_with_distinct_digits(tmp_path):
    a = write_record(tmp_path / "a.csv", _signals(4988, 1), FS, "repr")
    b = write_record(tmp_path / "b.csv", _signals(4988, 2), FS * (1 + 1e-4), "repr")
    line = _one_line_exit_2(
        "identify", "statespace", a, b, "--inputs", "u", "--outputs", "y", "-o", tmp_path / "s.json"
    )
    assert "0.0001 s" in line and "9.999000099990002e-05 s" in line and "1e-06" in line


def test_chunked_npy_folder_time_column(tmp_path):
    folder = tmp_path / "rec.npy.d"
    folder.mkdir()
    cols = _signals(24000, 4)
    for k, v in cols.items():
        np.save(folder / f"{k}.npy", v)
    np.save(folder / "t.npy", 12.5 + np.arange(24000) / FS)  # an offset start: the period still 1e-4
    _ok("identify", "statespace", folder, "--inputs", "u", "--outputs", "y", "--order", "1", "--horizon", "8",
        "-o", tmp_path / "s.json")  # fmt: skip
    assert load_model(tmp_path / "s.json").dt == 1e-4
    np.save(folder / "t.npy", np.arange(24000) * 1e-320)
    line = _one_line_exit_2(
        "identify", "statespace", folder, "--inputs", "u", "--outputs", "y", "-o", tmp_path / "x.json"
    )
    assert "period between 1e-15 s and 1e+12 s" in line


def _bad_time_file(folder: Path, scale: float | None) -> str:
    """A record whose ``t`` steps by ``scale`` (no ``t`` column for None)."""
    cols = _signals(500, 5)
    head = "u,y" if scale is None else "t,u,y"
    rows = [
        ",".join(
            ([] if scale is None else [repr(float(k * scale))]) + [repr(float(cols["u"][k])), repr(float(cols["y"][k]))]
        )
        for k in range(500)
    ]
    path = folder / f"bad{scale}.csv"
    path.write_text(head + "\n" + "\n".join(rows) + "\n")
    return str(path)


#: every verb reading records, with {f} the record and {o} an output folder
VERBS = [
    "identify statespace {f} --inputs u --outputs y --order 1 --horizon 8 -o {o}/s.json",
    "identify hysteresis {f} --input u --output y --creep auto -o {o}/h.json",
    "identify closed-loop {f} --references u --outputs y --controller {k} -o {o}/g.json",
    "frf {f} --inputs u --outputs y -o {o}/f.csv",
    "validate {m} {f}",
    "simulate {m} {f} -o {o}/sim.csv",
    "compensate {h} {f} --column y -o {o}/d.csv",
]


@pytest.fixture(scope="module")
def models(files, tmp_path_factory) -> dict[str, str]:
    folder = tmp_path_factory.mktemp("models")
    k = folder / "K.json"
    save_model(StateSpaceModel([[0.0]], [[0.0]], [[0.0]], [[1.0]], dt=None, inputs=["y"], outputs=["F"]), k)
    h = folder / "h.json"
    _ok("identify", "hysteresis", files["b"], "--input", "u", "--output", "y", "--model", "pi", "--operators", "3",
        "-o", h)  # fmt: skip
    return {"k": str(k), "h": str(h), "m": files["model"]}


@pytest.mark.parametrize("verb", VERBS, ids=lambda v: v.split(" {")[0])
@pytest.mark.parametrize(
    ("scale", "ts"),
    [(1e-320, None), (1e300, None), (1e13, None), (None, "1e-320"), (None, "inf"), (None, "0"), (1e-4, "1e-320")],
)
def test_bad_periods_exit_2_in_one_line_in_every_verb(verb, scale, ts, models, tmp_path):
    argv = verb.format(f=_bad_time_file(tmp_path, scale), o=tmp_path, **models).split()
    if ts is not None:
        argv += ["--ts", ts]
    line = _one_line_exit_2(*argv)
    assert "second" in line or "period" in line, line


@pytest.mark.parametrize("dt", ["1e-320", "inf", "1e300"])
def test_frd_fit_with_a_bad_period_exits_2(dt, tmp_path):
    freqs = np.linspace(10, 400, 40)
    g = 1 / (1 + 1j * freqs / 100)
    (tmp_path / "frf.csv").write_text(
        "f_hz,y/u_re,y/u_im\n" + "".join(f"{f!r},{v.real!r},{v.imag!r}\n" for f, v in zip(freqs, g))
    )
    _one_line_exit_2("identify", "frd", tmp_path / "frf.csv", "--order", "1", "--dt", dt, "-o", tmp_path / "m.json")


@pytest.mark.realdata
def test_real_dspace_forc_records_share_one_period(tmp_path):
    """The FORC records trimmed as the hysteresis study trims them, written to CSV and read back
    as `identify hysteresis` reads them: one period for the creep fit."""
    from _dspace_records import dspace_record
    from stageid.cli._common import read_experiments
    from stageid.data import write_csv
    from stageid.hysteresis.identify.records import sampling_period

    paths = []
    for name in ("20_hz_no_lp", "40_hz_no_lp", "100_hz_no_lp"):
        u, y, dt = dspace_record(name)
        t0 = 1.4  # the trimmed records start at a trigger time, so the column carries an offset
        paths.append(tmp_path / f"{name}.csv")
        write_csv(paths[-1], {"t": t0 + dt * np.arange(u.size), "V": u, "y": y})
    exps = read_experiments([str(p) for p in paths], ["V"], ["y"], None)
    assert sampling_period(list(exps), None) == 1e-4


def test_batch_jobs_follow_the_rule(files, tmp_path):
    """A batch runs the verbs on workers: unequal repr records fit, a subnormal period fails its row in one line."""
    from _batch_records import read_summary, write_manifest
    from dask_cluster import TestCluster

    bad = _bad_time_file(tmp_path, 1e-320)
    manifest = write_manifest(
        tmp_path / "jobs.csv",
        [
            ("two", f"identify statespace {files['a']} {files['b']} --inputs u --outputs y --order 1 --horizon 8"),
            ("bad", f"frf {bad} --inputs u --outputs y"),
        ],
    )
    with TestCluster(n_workers=1) as cluster:
        rc, _, err = run_main("batch", manifest, "--out", tmp_path / "out", "--scheduler", cluster.address)
    rows = {r["name"]: r for r in read_summary(tmp_path / "out")}
    assert rc == 1, err  # one job failed, the summary is complete
    assert rows["two"]["status"] == "ok" and load_model(tmp_path / "out" / "two.json").dt == 1e-4
    assert rows["bad"]["status"] == "failed" and "period between 1e-15 s and 1e+12 s" in rows["bad"]["error"]
    assert "\n" not in rows["bad"]["error"]
