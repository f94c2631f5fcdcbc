"""`stageid signal multisine` -> measured records -> `stageid frf --method bla` -> `identify frd` / `report`."""

import numpy as np
import pytest
from scipy.signal import lfilter

from conftest import run_main as run
from stageid.data import read_table, write_csv
from stageid.frf import read_frd

DT = 1e-3
BLA = ("--inputs", "u", "--outputs", "y", "--method", "bla")
B, A = [0.02, 0.04, 0.02], [1.0, -1.6, 0.8]  # a resonance near 90 Hz at dt = 1 ms


@pytest.fixture
def measured(tmp_path):
    """Four random-odd realisations of 4 periods through a cubic before the resonance."""
    args = "--n-samples 4096 --dt 1e-3 --f-low 1 --f-high 200 --n-periods 4 --lines random-odd --rms 1"
    rc, out, err = run(
        "signal", "multisine", *args.split(), "--seed", 3, "--realisations", 4, "-o", tmp_path / "ms.csv"
    )
    assert rc == 0, err
    rng = np.random.default_rng(0)
    files = sorted(tmp_path.glob("ms_r*.csv"))
    for f in files:
        u = read_table(f).column("u")
        y = lfilter(B, A, u + 0.3 * u**3) + 0.01 * rng.standard_normal(u.size)
        write_csv(f, {"u": u, "y": y}, dt=DT)
    return tmp_path, files


def test_frf_bla_writes_the_levels_and_says_what_it_found(measured):
    tmp_path, files = measured
    design = tmp_path / "ms.multisine.json"
    rc, out, err = run(
        "frf",
        *files,
        *BLA,
        "--design",
        design,
        "-o",
        tmp_path / "bla.csv",
    )
    assert rc == 0, err
    header = (tmp_path / "bla.csv").read_text().splitlines()[0].split(",")
    assert header == ["f_hz", "re_y_u", "im_y_u", "std_y_u", "stdtot_y_u", "stdnl_y_u", "stdodd_y_u", "stdeven_y_u"]
    assert "4 realisation(s) x 3 periods (1 transient period(s) dropped)" in out
    assert "y: odd nonlinearity detected" in out and "y: even nonlinearity not detected" in out
    frd = read_frd(tmp_path / "bla.csv")
    assert frd.total_std is not None and np.median(frd.total_std / frd.std) > 10
    # the fit says which variance weighted it; the report draws the BLA figure
    rc, out, err = run(
        "identify",
        "frd",
        tmp_path / "bla.csv",
        "--order",
        2,
        "--dt",
        DT,
        "-o",
        tmp_path / "m.json",
        "--report",
        tmp_path / "fit",
    )
    assert rc == 0, err
    assert "weight 1/total variance (noise + nonlinear distortion" in out
    assert "Best linear approximation" in (tmp_path / "fit" / "index.html").read_text()
    rc, out, err = run("report", tmp_path / "m.json", "--frf", tmp_path / "bla.csv", "--out", tmp_path / "rep")
    assert rc == 0, err
    assert "Best linear approximation" in (tmp_path / "rep" / "index.html").read_text()
    # without the design the lines and periods come from the records themselves
    rc, out2, err = run("frf", *files, "--inputs", "u", "--outputs", "y", "--method", "bla", "-o", tmp_path / "b2.csv")
    assert rc == 0, err
    np.testing.assert_allclose(read_frd(tmp_path / "b2.csv").response, frd.response, rtol=1e-12)


def test_identify_frd_says_noise_variance_for_a_plain_frf(measured):
    tmp_path, files = measured
    rc, _, err = run(
        "frf",
        files[0],
        "--inputs",
        "u",
        "--outputs",
        "y",
        "--method",
        "periodic",
        "--periods",
        4,
        "-o",
        tmp_path / "p.csv",
    )
    assert rc == 0, err
    rc, out, err = run("identify", "frd", tmp_path / "p.csv", "--order", 2, "--dt", DT, "-o", tmp_path / "m.json")
    assert rc == 0, err
    assert "weight 1/noise variance (std_ columns)" in out


@pytest.mark.parametrize(
    "extra, fragment",
    [
        (["--method", "welch", "--design", "ms.multisine.json"], "--design applies to --method bla"),
        (["--method", "bla", "--periods", "4", "--transient-periods", "3"], "leaves 1; at least 2 are needed"),
        (["--method", "welch", "--transient", "lpm"], "--transient applies to --method bla"),
        (["--method", "bla", "--transient", "lpm", "--transient-periods", "1"], "applies to --transient drop"),
    ],
)
def test_frf_bla_errors_are_one_line_and_write_nothing(measured, extra, fragment):
    tmp_path, files = measured
    extra = [str(tmp_path / e) if e.endswith(".json") else e for e in extra]
    rc, out, err = run("frf", *files, "--inputs", "u", "--outputs", "y", *extra, "-o", tmp_path / "x.csv")
    assert rc == 2 and fragment in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "x.csv").exists()


def test_frf_bla_lpm_keeps_every_period(measured):
    tmp_path, files = measured
    rc, out, err = run(
        "frf",
        *files,
        *BLA,
        "--transient",
        "lpm",
        "-o",
        tmp_path / "l.csv",
    )
    assert rc == 0, err
    assert "x 4 periods (every period kept, the transient removed by the local polynomial method)" in out
    assert "y: odd nonlinearity detected" in out


def as_npz(files, spoil_time=None):
    """The CSV records as NPZ files beside them (the memory-mapped reader's path), the time column of
    record ``k`` passed through ``spoil_time[k]``."""
    paths = []
    for k, f in enumerate(files):
        table = read_table(f)
        t = np.arange(table.n_samples) * DT
        paths.append(f.with_suffix(".npz"))
        np.savez(paths[-1], t=(spoil_time or {}).get(k, lambda x: x)(t), u=table.column("u"), y=table.column("y"))
    return paths


@pytest.mark.parametrize(
    "spoil, fragment",
    [
        (lambda t: np.where(np.arange(t.size) == 1234, t + 0.01 * DT, t), "is not uniform: the stamp at row 1234"),
        (lambda t: np.concatenate([t[:300], t[299:300], t[301:]]), "must be strictly increasing; row 300 "),
        (lambda t: np.concatenate([t[:300], t[300:] + DT]), "has a gap at row 300 "),  # a lost sample
    ],
)
def test_frf_bla_refuses_a_bad_time_column_in_one_npz_record(measured, spoil, fragment):
    # NPZ records take the memory-mapped reader: its time-column check is the sample-time rule's
    tmp_path, files = measured
    paths = as_npz(files, {2: spoil})
    rc, out, err = run("frf", *paths, *BLA, "--design", tmp_path / "ms.multisine.json", "-o", tmp_path / "x.npz")
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert f"{paths[2].name}: time column 't' " in err and fragment in err, err
    assert not (tmp_path / "x.npz").exists()
    # with a uniform column the NPZ records give what the CSV ones give
    paths = as_npz(files)
    rc, _, err = run("frf", *paths, *BLA, "--design", tmp_path / "ms.multisine.json", "-o", tmp_path / "n.csv")
    assert rc == 0, err
    rc, _, err = run("frf", *files, *BLA, "--design", tmp_path / "ms.multisine.json", "-o", tmp_path / "c.csv")
    assert rc == 0, err
    np.testing.assert_allclose(read_frd(tmp_path / "n.csv").response, read_frd(tmp_path / "c.csv").response, rtol=1e-12)


def test_frf_bla_refuses_a_cut_npz_record_in_one_line(measured):
    tmp_path, files = measured
    paths = as_npz(files)
    whole = paths[1].read_bytes()
    paths[1].write_bytes(whole[: len(whole) // 2])  # a copy that stopped half-way
    rc, out, err = run("frf", *paths, *BLA, "--design", tmp_path / "ms.multisine.json", "-o", tmp_path / "x.npz")
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert f"{paths[1].name}: cannot read the archive" in err, err
    assert not (tmp_path / "x.npz").exists()


def test_frf_bla_in_threads_writes_what_one_thread_writes_and_names_a_bad_sample_in_one_line(measured, monkeypatch):
    import stageid.frf.bla as bla
    from stageid.runtime.threads import default_threads, map_in_threads

    tmp_path, files = measured
    paths, design = as_npz(files), tmp_path / "ms.multisine.json"
    threads_asked = []

    def counted(fn, n_items, n_threads=None):
        threads_asked.append(default_threads() if n_threads is None else n_threads)
        return map_in_threads(fn, n_items, n_threads)

    monkeypatch.setattr(bla, "map_in_threads", counted)
    written = {}
    for n in (1, 4):  # the channels of a realisation transformed by one thread, then by four
        monkeypatch.setenv("STAGEID_THREADS", str(n))
        rc, out, err = run("frf", *paths, *BLA, "--design", design, "-o", tmp_path / f"b{n}.npz")
        assert rc == 0, err
        written[n] = (tmp_path / f"b{n}.npz").read_bytes()
    assert written[1] == written[4]
    assert threads_asked == [1] * 4 + [4] * 4  # one call per realisation
    with np.load(paths[2]) as z:
        y = z["y"].copy()
        y[3 * 1024 + 5] = np.nan
        np.savez(paths[2], t=z["t"], u=z["u"], y=y)
    rc, out, err = run("frf", *paths, *BLA, "--design", design, "-o", tmp_path / "x.npz")
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert f"{paths[2].name}: column 'y' has NaN at row {3 * 1024 + 5}" in err, err
    assert not (tmp_path / "x.npz").exists()
