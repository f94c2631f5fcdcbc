"""`stageid export c` / `stageid export mat`: files, agreement with `stageid simulate` and
`stageid compensate` through the command line, and bad input (one line, exit 2, nothing written)."""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest
import scipy.io

from stageid.cli.main import main
from stageid.data import read_table, write_csv
from stageid.export.host import build, find_compiler
from stageid.hysteresis import CreepTerm, ModifiedPIModel, PIModel
from stageid.models import StateSpaceModel, save_model

needs_cc = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (gcc, clang or cc) on PATH")


def run(*args):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main([str(a) for a in args])
    return rc, out.getvalue(), err.getvalue()


def listing(folder):
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*"))


@pytest.fixture
def models(tmp_path):
    rng = np.random.default_rng(0)
    paths = {}
    g = StateSpaceModel(
        [[0.9, 0.2], [-0.2, 0.9]], [[1.0, 0.0], [0.5, 1.0]], [[1.0, 0.0], [0.3, 1.0]], [[0.0, 0.1], [0.0, 0.0]],
        dt=0.001, inputs=["Z", "Rx"], outputs=["z", "rx"],
    )  # fmt: skip
    paths["lti"] = g
    paths["continuous"] = StateSpaceModel([[-10.0]], [[10.0]], [[1.0]], [[0.0]], inputs=["u"], outputs=["y"])
    r = np.r_[0.0, np.sort(rng.uniform(1, 50, 9))]
    paths["mpi"] = ModifiedPIModel(
        r=r, rc=0.5 * r, ra=1.5 * r, rb=r, weights=np.r_[1.0, rng.uniform(0, 0.2, 9)], input_warp=0.1,
        warp_scale=60.0, input_limits=(-80.0, 90.0),
    )  # fmt: skip
    paths["creep"] = PIModel(r=[0.0, 1.0], weights=[1.0, 0.5], creep=CreepTerm([0.1], [0.2], 0.001))
    paths["noninvertible"] = PIModel(r=[0.0, 1.0], weights=[1.0, -2.0])
    out = {}
    for name, model in paths.items():
        out[name] = tmp_path / f"{name}.json"
        save_model(model, out[name])
    out["unknown-kind"] = tmp_path / "zpk.json"
    out["unknown-kind"].write_text(json.dumps({"format": "stageid.lti/1", "kind": "zpk", "dt": 0.1}))
    out["actuator"] = tmp_path / "actuator.json"  # a valid model file of a kind export does not know
    assert run("plants", "piezo-actuator", "-o", out["actuator"])[0] == 0
    return out


@needs_cc
def test_export_c_agrees_with_stageid_simulate(tmp_path, models):
    rng = np.random.default_rng(1)
    write_csv(tmp_path / "u.csv", {"Z": rng.normal(size=2500), "Rx": rng.normal(size=2500)}, dt=0.001)
    assert run("simulate", models["lti"], tmp_path / "u.csv", "-o", tmp_path / "y.csv")[0] == 0
    rc, out, err = run("export", "c", models["lti"], "--prefix", "stage", "-o", tmp_path / "build")
    assert rc == 0 and err == "" and "stage.h" in out
    assert listing(tmp_path / "build") == ["stage.c", "stage.h"]
    y_cli = read_table(tmp_path / "y.csv")
    u = read_table(tmp_path / "u.csv")
    from stageid.export import export_c
    from stageid.models import load_model

    code = export_c(load_model(models["lti"]), "stage", source="lti.json")
    assert (tmp_path / "build" / "stage.c").read_text() == code.source  # the CLI writes export_c's text
    y_c = build(code, tmp_path / "build").run(np.column_stack([u.column("Z"), u.column("Rx")]))
    y = np.column_stack([y_cli.column("z"), y_cli.column("rx")])
    # both sides are written through CSV (17 significant digits): agreement to rounding
    assert np.max(np.abs(y_c - y)) <= 1e-12 * np.max(np.abs(y))


@needs_cc
def test_export_c_inverse_agrees_with_stageid_compensate(tmp_path, models):
    from stageid.models import load_model

    model = load_model(models["mpi"])
    t = np.arange(4000) * 1e-3
    y_ref = model.simulate(70 * np.sin(2 * np.pi * t) + 15 * np.sin(2 * np.pi * 7.3 * t))[:, 0] * 1.1  # clips
    write_csv(tmp_path / "ref.csv", {"y_ref": y_ref}, dt=1e-3)
    rc, _, _ = run("compensate", models["mpi"], tmp_path / "ref.csv", "--column", "y_ref", "-o", tmp_path / "u.csv")
    assert rc == 0
    assert run("export", "c", models["mpi"], "--prefix", "comp", "--inverse", "-o", tmp_path / "b")[0] == 0
    from stageid.export import export_c

    drive = build(export_c(model, "comp", inverse=True), tmp_path / "b").run(y_ref)[:, 0]
    expected = read_table(tmp_path / "u.csv").column("V")
    assert expected.min() == -80.0 and expected.max() == 90.0  # the drive limits are in play
    assert np.max(np.abs(drive - expected)) <= 1e-12 * np.max(np.abs(expected))


def test_export_c_float_and_existing_folder(tmp_path, models):
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / "keep.txt").write_text("x")
    assert run("export", "c", models["lti"], "--prefix", "g", "--float", "-o", folder)[0] == 0
    assert listing(folder) == ["g.c", "g.h", "keep.txt"]
    assert "void g_step(g_state *s, const float *in, float *out);" in (folder / "g.h").read_text()


def test_continuous_model_needs_dt(tmp_path, models):
    rc, out, err = run("export", "c", models["continuous"], "--prefix", "g", "-o", tmp_path / "o")
    assert rc == 2 and err.count("\n") == 1 and "--dt S [--method zoh|tustin]" in err
    assert not (tmp_path / "o").exists()
    assert (
        run(
            "export",
            "c",
            models["continuous"],
            "--prefix",
            "g",
            "--dt",
            "0.001",
            "--method",
            "tustin",
            "-o",
            tmp_path / "o",
        )[0]
        == 0
    )
    assert listing(tmp_path / "o") == ["g.c", "g.h"]


@pytest.mark.parametrize(
    "model, extra, fragment",
    [
        ("unknown-kind", [], "kind"),
        ("actuator", [], "cannot export"),
        ("lti", ["--inverse"], "no exported causal inverse"),
        ("noninvertible", ["--inverse"], "not invertible"),
        ("creep", ["--inverse"], "rate-independent"),
        ("mpi", ["--prefix", "1comp"], "C identifier"),
        ("mpi", ["--prefix", "my-comp"], "C identifier"),
        ("mpi", ["--prefix", "int"], "C keyword"),
        ("mpi", ["--prefix", "static"], "C keyword"),
        ("lti", ["--dt", "0.5"], "discrete"),
        ("mpi", ["--limits", "5,1", "--inverse"], "LOW < HIGH"),
        ("mpi", ["--method", "euler"], "euler"),
        ("lti", ["--dt", "-1"], "--dt"),
    ],
)
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, models, model, extra, fragment):
    args = ["export", "c", models[model], *(["--prefix", "comp"] if "--prefix" not in extra else []), *extra]
    before = listing(tmp_path)
    rc, out, err = run(*args, "-o", tmp_path / "build")
    assert rc == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("stageid: error:") and fragment in err
    assert listing(tmp_path) == before


def test_output_naming_a_file_is_refused(tmp_path, models):
    (tmp_path / "file.c").write_text("int x;\n")
    before = listing(tmp_path)
    rc, _, err = run("export", "c", models["mpi"], "--prefix", "comp", "-o", tmp_path / "file.c")
    assert rc == 2 and err.count("\n") == 1 and "is a file; expected a folder" in err
    assert listing(tmp_path) == before and (tmp_path / "file.c").read_text() == "int x;\n"
    rc, _, err = run("export", "c", models["mpi"], "--prefix", "comp", "-o", tmp_path / "no" / "such")
    assert rc == 2 and "does not exist" in err and listing(tmp_path) == before


def test_failed_write_leaves_nothing(tmp_path, models, monkeypatch):
    import pathlib

    calls = []
    real = pathlib.Path.write_text

    def failing(self, text, *a, **k):  # the second file fails after the first was written
        calls.append(self)
        if len(calls) == 2:
            raise OSError("disk full")
        return real(self, text, *a, **k)

    monkeypatch.setattr(pathlib.Path, "write_text", failing)
    rc, _, err = run("export", "c", models["mpi"], "--prefix", "comp", "-o", tmp_path / "build")
    monkeypatch.undo()
    assert rc == 2 and "disk full" in err
    assert not (tmp_path / "build").exists()


# ------------------------------------------------------------------ MATLAB
def test_export_mat_statespace(tmp_path, models):
    assert run("export", "mat", models["lti"], "-o", tmp_path / "g.mat")[0] == 0
    m = scipy.io.loadmat(tmp_path / "g.mat")
    from stageid.models import load_model

    g = load_model(models["lti"])
    for key in "ABCD":
        np.testing.assert_array_equal(m[key], getattr(g, key))  # exact: v5 stores doubles
    assert m["Ts"].item() == 0.001
    assert [str(v[0]) for v in m["InputName"][:, 0]] == ["Z", "Rx"]
    assert [str(v[0]) for v in m["OutputName"][:, 0]] == ["z", "rx"]


def test_export_mat_continuous_and_discretised(tmp_path, models):
    assert run("export", "mat", models["continuous"], "-o", tmp_path / "c.mat")[0] == 0
    assert scipy.io.loadmat(tmp_path / "c.mat")["Ts"].item() == 0.0  # MATLAB's continuous convention
    assert run("export", "mat", models["continuous"], "--dt", "0.01", "-o", tmp_path / "d.mat")[0] == 0
    m = scipy.io.loadmat(tmp_path / "d.mat")
    assert m["Ts"].item() == 0.01 and np.isclose(float(m["A"][0, 0]), np.exp(-0.1), rtol=1e-14)


def test_export_mat_hysteresis_struct(tmp_path, models):
    assert run("export", "mat", models["mpi"], "-o", tmp_path / "h.mat")[0] == 0
    h = scipy.io.loadmat(tmp_path / "h.mat", squeeze_me=True, struct_as_record=False)["hysteresis"]
    from stageid.models import load_model

    model = load_model(models["mpi"])
    assert h.kind == "modified-pi"
    np.testing.assert_array_equal(h.r, model.r)
    np.testing.assert_array_equal(h.weights, model.weights)
    np.testing.assert_array_equal(h.input_limits, [-80.0, 90.0])
    assert h.input_warp == 0.1 and h.warp_scale == 60.0
    np.testing.assert_array_equal(h.state.z, model.state.z)


@pytest.mark.parametrize("out", ["g.txt", "g", "-"])
def test_export_mat_bad_output(tmp_path, models, out):
    before = listing(tmp_path)
    rc, _, err = run("export", "mat", models["lti"], "-o", tmp_path / out if out != "-" else out)
    assert rc == 2 and err.count("\n") == 1 and ".mat" in err
    assert listing(tmp_path) == before


def test_export_mat_unknown_kind(tmp_path, models):
    before = listing(tmp_path)
    rc, _, err = run("export", "mat", models["actuator"], "-o", tmp_path / "a.mat")
    assert rc == 2 and err.count("\n") == 1 and "cannot export" in err and listing(tmp_path) == before
