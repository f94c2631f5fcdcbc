"""The failure contract (docs/guide/bad-input.md), one test (or a few) per class of bad input.

Any bad input ends with exit code 2, one line on stderr naming the problem, and no output
file; an interrupt ends with exit code 130 and "stageid: interrupted"; inputs and existing
files are never changed by a failed command.  Hostile inputs run in a subprocess under an
address-space limit, so a missing guard fails the test instead of the machine.
"""

from __future__ import annotations

import io
import os
import signal
import subprocess
import sys
import textwrap
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from conftest import AS_LIMIT, assert_one_line_error, run_cli, run_main, snapshot
from stageid.data import write_csv
from stageid.hysteresis import PIModel
from stageid.models import StateSpaceModel, save_model

DT = 0.01


def run_limited(*args, env_extra=None, timeout=120):
    """Run `stageid` in a subprocess under conftest.AS_LIMIT: (exit code, stdout, stderr)."""
    return run_cli(*args, env=env_extra, memory_limit=AS_LIMIT, timeout=timeout)


@pytest.fixture
def work(tmp_path, monkeypatch):
    """A stable SISO model, a record of it, a hysteresis model and a reference; cwd is tmp_path."""
    g = StateSpaceModel([[0.9]], [[1.0]], [[0.5]], [[0.0]], dt=DT, inputs=("u",), outputs=("y",))
    save_model(g, tmp_path / "g.json")
    u = np.random.default_rng(3).standard_normal(400)
    write_csv(tmp_path / "rec.csv", {"u": u, "y": g.simulate(u[:, None])[:, 0]}, dt=DT)
    h = PIModel(r=[0.0, 20.0, 40.0], weights=[0.01, 0.005, 0.002])
    save_model(h, tmp_path / "h.json")
    v = 50.0 * (1 - np.cos(np.linspace(0, 6 * np.pi, 600)))
    write_csv(tmp_path / "hyst.csv", {"V": v, "y": h.simulate(v)[:, 0]}, dt=DT)
    write_csv(tmp_path / "ref.csv", {"y": 0.3 * (1 - np.cos(np.linspace(0, 2 * np.pi, 200)))}, dt=DT)
    monkeypatch.chdir(tmp_path)
    return tmp_path


# ------------------------------------------------------------------ class 1: data loss
@pytest.mark.parametrize(
    "args",
    [
        ["simulate", "g.json", "rec.csv", "-o", "rec.csv"],
        ["simulate", "g.json", "rec.csv", "-o", "./sub/../rec.csv"],
        ["compensate", "h.json", "ref.csv", "--column", "y", "-o", "ref.csv"],
        ["simulate", "h.json", "hyst.csv", "-o", "hyst.csv"],
    ],
    ids=["simulate", "simulate-dotdot", "compensate", "simulate-hysteresis"],
)
def test_an_output_naming_an_input_is_refused_and_the_input_kept(work, args):
    (work / "sub").mkdir()
    before = snapshot(work)
    rc, out, err = run_main(*args)
    assert_one_line_error(rc, err, "is also an input of this command")
    assert out == "" and snapshot(work) == before


def test_an_output_reaching_an_input_through_a_symlink_is_refused(work):
    os.symlink(work / "rec.csv", work / "link.csv")
    before = snapshot(work)
    rc, _, err = run_main("simulate", "g.json", "rec.csv", "-o", "link.csv")
    assert_one_line_error(rc, err, "is also an input")
    assert snapshot(work) == before


# ------------------------------------------------------------------ class 2: outputs together
@pytest.mark.parametrize("existing", [False, True])
def test_a_failing_report_leaves_no_model_file_and_prints_no_summary(work, monkeypatch, existing):
    import stageid.report.html as html_module
    from stageid import DataError

    def refuse(*args, **kwargs):
        raise DataError("cannot write the report (simulated: permission denied).")

    monkeypatch.setattr(html_module, "metrics_json", refuse)
    if existing:
        (work / "m.json").write_text("old model\n")
    before = snapshot(work)
    rc, out, err = run_main(
        "identify", "statespace", "rec.csv", "--inputs", "u", "--outputs", "y", "--order", "1", "--horizon", "8",
        "-o", "m.json", "--report", "rep",
    )  # fmt: skip
    assert_one_line_error(rc, err, "simulated: permission denied")
    assert out == ""  # the summary waits for the outputs to be committed
    assert snapshot(work) == before  # no m.json (or the old one byte-identical)
    assert not (work / "rep").exists() and not [p for p in work.iterdir() if p.name.startswith(".")]


def test_the_outputs_of_a_successful_command_all_appear(work):
    rc, _, err = run_main(
        "identify", "hysteresis", "hyst.csv", "--input", "V", "--output", "y", "--model", "pi", "--operators", "4",
        "-o", "hy.json", "--report", "rep",
    )  # fmt: skip
    assert rc == 0, err
    assert (work / "hy.json").is_file() and (work / "rep" / "index.html").is_file()
    assert not [p for p in work.iterdir() if p.name.startswith(".")]  # no temporaries left


# ------------------------------------------------------------------ class 4: bounded memory
def _npz_declaring(path: Path, shape: tuple[int, ...]) -> None:
    """An .npz whose member's header declares ``shape`` float64 but holds a few bytes."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": shape})
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("u.npy", b"\x93NUMPY\x01\x00" + header.getvalue()[8:] + b"\x00" * 64)


def test_an_npz_member_declaring_16_gb_is_refused_before_reading(work):
    _npz_declaring(work / "bomb.npz", (2_000_000_000,))
    rc, _, err = run_limited("simulate", "g.json", "bomb.npz", "-o", "out.csv")
    assert_one_line_error(rc, err, "reading the arrays of 'bomb.npz' would need about", "GB of memory")
    assert not (work / "out.csv").exists()


def test_a_deflate_bomb_npz_is_refused_by_its_declared_size(work):
    zeros = np.zeros(25_000_000)  # 200 MB inflated, ~200 kB deflated
    np.savez_compressed(work / "zeros.npz", u=zeros, y=zeros)
    assert (work / "zeros.npz").stat().st_size < 2_000_000
    rc, _, err = run_limited(
        "simulate", "g.json", "zeros.npz", "--ts", "0.01", "-o", "out.csv", env_extra={"STAGEID_MEMORY_LIMIT": "100M"}
    )
    assert_one_line_error(rc, err, "reading the arrays of 'zeros.npz' would need about", "of memory")


def test_a_compressed_v73_mat_is_refused_by_its_dataset_shape(work):
    h5py = pytest.importorskip("h5py")
    path = work / "big.mat"
    with h5py.File(path, "w", userblock_size=512) as fh:
        fh.create_dataset("u", shape=(1, 400_000_000), dtype="f8", compression="gzip", chunks=(1, 1_000_000))
    with open(path, "r+b") as fh:  # the MATLAB v7.3 user block
        fh.write(b"MATLAB 7.3 MAT-file".ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02IM")
    assert path.stat().st_size < 1_000_000  # 3.2 GB declared
    rc, _, err = run_limited("simulate", "g.json", "big.mat", "--ts", "0.01", "-o", "out.csv")
    assert_one_line_error(rc, err, "reading the datasets of 'big.mat' would need about", "GB of memory")


def test_a_compressed_v5_mat_is_refused_by_its_declared_size(work):
    import scipy.io

    scipy.io.savemat(work / "z.mat", {"u": np.zeros((20_000_000, 1))}, do_compression=True)
    rc, _, err = run_limited(
        "simulate", "g.json", "z.mat", "--ts", "0.01", "-o", "out.csv", env_extra={"STAGEID_MEMORY_LIMIT": "100M"}
    )
    assert_one_line_error(rc, err, "reading the variables of 'z.mat' would need about", "of memory")


def test_freqresp_with_1e8_frequencies_is_refused_up_front(work):
    start = time.perf_counter()
    rc, _, err = run_limited("freqresp", "g.json", "--fmin", "1", "--fmax", "40", "--n", "100000000", "-o", "fr.csv")
    assert_one_line_error(rc, err, "--n 100000000 frequencies of a 1x1 model would need about")
    assert time.perf_counter() - start < 60 and not (work / "fr.csv").exists()


def test_a_signal_of_1e15_samples_is_refused_up_front(work):
    rc, _, err = run_main(
        "signal", "chirp", "--f0", "1", "--f1", "10", "--duration", "1e12", "--dt", "0.001", "-o", "s.csv"
    )
    assert_one_line_error(rc, err, "chirp with 1000000000000000 samples would need about")


# ------------------------------------------------------------------ class 5: interrupts
def test_a_systemerror_carrying_a_keyboardinterrupt_is_an_interrupt(work, monkeypatch):
    # what a Ctrl-C inside a compiled kernel looks like when the kernel returns to Python
    import stageid.models

    def kernel_interrupted(path):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise SystemError("<numba kernel> returned a result with an exception set") from exc

    monkeypatch.setattr(stageid.models, "load_model", kernel_interrupted)
    rc, out, err = run_main("simulate", "g.json", "rec.csv", "-o", "out.csv")
    assert (rc, out, err) == (130, "", "stageid: interrupted\n")
    assert not (work / "out.csv").exists()


_SPIN = textwrap.dedent(
    """
    import sys, click, numba, numpy as np
    from stageid.cli import main as cli_main
    from stageid.cli.outputs import write_table_output

    @numba.njit(nogil=True)
    def kernel(n):
        s = 0.0
        for i in range(n):
            s += np.sin(i * 1e-9)
        return s

    @click.command("spin")
    def spin():
        kernel(10)
        write_table_output("partial.csv", {"u": np.zeros(3)}, dt=1.0)  # staged, never committed
        open("ready", "w").close()
        for _ in range(10**6):
            kernel(10**6)

    cli_main.cli.add_command(spin)
    sys.exit(cli_main.main(["spin"]))
    """
)


def test_sigint_during_a_compiled_kernel_ends_as_interrupted(tmp_path):
    (tmp_path / "spin.py").write_text(_SPIN)
    proc = subprocess.Popen(
        [sys.executable, "spin.py"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=dict(os.environ, OMP_NUM_THREADS="1"),
    )
    try:
        deadline = time.monotonic() + 120
        while not (tmp_path / "ready").exists() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
        time.sleep(0.3)  # inside the kernel loop
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert (proc.returncode, err) == (130, "stageid: interrupted\n"), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ready", "spin.py"]  # no partial.csv, no temporary


def test_an_interrupted_demo_leaves_no_model_files(work, monkeypatch):
    import stageid.demo.hysteresis as workflow

    def run(report, metrics, out_dir, step):
        save_model(PIModel(r=[0.0, 1.0], weights=[1.0, 0.5]), out_dir / "actuator_pi.json")
        raise KeyboardInterrupt  # Ctrl-C after the first model was written

    monkeypatch.setattr(workflow, "run", run)
    before = snapshot(work)
    rc, out, err = run_main("demo", "--out", "d", "--only", "hysteresis")
    assert (rc, err.splitlines()[-1]) == (130, "stageid: interrupted"), err
    assert snapshot(work) == before and not (work / "d").exists()
    assert not [p for p in work.iterdir() if p.name.startswith(".")]


# ------------------------------------------------------------------ class 6: silently wrong results
def test_repeated_signal_names_are_refused(work):
    rc, _, err = run_main(
        "signal", "prbs", "--n-samples", "100", "--dt", "0.01", "--n-channels", "3", "--names", "a,b,a", "-o", "p.csv"
    )
    assert_one_line_error(rc, err, "--names names 'a' more than once")
    assert not (work / "p.csv").exists()


@pytest.mark.parametrize("args", [["--experiment", "chirp-z", "-o", "o.csv"], ["-o", "o.json"], ["--controller"]])
def test_plants_options_without_a_plant_name_are_refused(work, args):
    rc, out, err = run_main("plants", *args)
    assert_one_line_error(rc, err, "needs a plant NAME")
    assert out == "" and not (work / "o.csv").exists() and not (work / "o.json").exists()


# ------------------------------------------------------------------ class 8: the real problem named
def test_a_1e308_cell_is_named_as_too_large(work):
    (work / "big.csv").write_text("t,u,y\n" + "".join(f"{k * DT:.2f},{1e308 if k == 5 else 1},1\n" for k in range(50)))
    rc, _, err = run_main("identify", "statespace", "big.csv", "--inputs", "u", "--outputs", "y", "-o", "m.json")
    assert_one_line_error(rc, err, "input column 'u' has 1e+308 at row 5", "rescale the data")


def test_a_70000_character_column_name_is_read_and_cut_short_in_messages(work):
    name = "x" * 70000
    (work / "long.csv").write_text(f"t,{name},y\n" + "".join(f"{k * DT:.2f},1,2\n" for k in range(20)))
    rc, _, err = run_main("simulate", "g.json", "long.csv", "-o", "out.csv")
    assert_one_line_error(rc, err, "the model's input(s) u", "its columns: 'xxxx")
    assert len(err) < 400


def test_no_raw_numpy_warning_reaches_stderr(work):
    # an unstable model's simulation overflows (numpy warns, matplotlib then failed on inf):
    # the verb ends by the contract, without numpy's warning lines
    g = StateSpaceModel([[10.0]], [[1.0]], [[1.0]], [[0.0]], dt=DT, inputs=("u",), outputs=("y",))
    save_model(g, work / "unstable.json")  # 10**k overflows to inf within the record's 400 samples
    rc, out, err = run_limited("report", "unstable.json", "rec.csv", "--out", "rep")  # real stderr, no pytest capture
    assert "RuntimeWarning" not in err and "Traceback" not in err, err
    if rc == 0:
        assert err == "" and (work / "rep" / "index.html").is_file()
    else:
        assert_one_line_error(rc, err, "unstable")
        assert not (work / "rep").exists()


# ------------------------------------------------------------------ also: folders and names
def test_demo_refuses_a_missing_parent_folder_like_every_verb(work):
    rc, _, err = run_main("demo", "--out", "a/b")
    assert_one_line_error(rc, err, "directory 'a' does not exist")
    assert not (work / "a").exists()


def test_a_model_channel_with_a_comma_cannot_become_a_column(work):
    g = StateSpaceModel([[0.5]], [[1.0]], [[1.0]], [[0.0]], dt=DT, inputs=("u",), outputs=("y,z",))
    save_model(g, work / "comma.json")
    rc, _, err = run_main("simulate", "comma.json", "rec.csv", "-o", "out.csv")
    assert_one_line_error(rc, err, "column name 'y,z' contains ','")
    assert not (work / "out.csv").exists()
