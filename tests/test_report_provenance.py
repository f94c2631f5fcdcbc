"""Every report says what made it (command, settings, version), and reads like the command line:
the FRF fit's errors in the same % the CLI prints, its modes in a table, the hysteresis summary
as a table and list, and a stage model's dynamics, creep and modes drawn."""

from __future__ import annotations

import html as html_text
import re

import numpy as np
import pytest

from conftest import run_main
from stageid.data.io import write_csv
from stageid.frf import FrequencyResponse, frd_columns
from stageid.models import StateSpaceModel

DT = 1e-4


def _two_modes() -> StateSpaceModel:
    """Two resonances (300 Hz, damping 0.02; 1200 Hz, damping 0.05), unit DC gain each, sampled at 10 kHz."""
    blocks = []
    for f_n, zeta in ((300.0, 0.02), (1200.0, 0.05)):
        w = 2 * np.pi * f_n
        blocks.append(([[0.0, 1.0], [-w * w, -2 * zeta * w]], [[0.0], [w * w]]))
    A = np.block([[np.array(blocks[0][0]), np.zeros((2, 2))], [np.zeros((2, 2)), np.array(blocks[1][0])]])
    B = np.vstack([blocks[0][1], blocks[1][1]])
    g = StateSpaceModel(A, B, [[1.0, 0.0, 0.5, 0.0]], [[0.0]], inputs=("V",), outputs=("y",))
    return g.c2d(DT)


def _rows(page: str) -> list[list[str]]:
    """The body rows of every table of the page, cells as text (header rows left out)."""
    rows = [re.findall(r"<td>(.*?)</td>", row) for row in re.findall(r"<tr>(.*?)</tr>", page)]
    return [[html_text.unescape(c) for c in row] for row in rows if row]


def _fit_frd(tmp_path, frd, *args):
    write_csv(tmp_path / "frf.csv", frd_columns(frd))
    cmd = ["identify", "frd", "frf.csv", "--dt", DT, "--fmax", 2000, *args, "--report", "rep", "-o", "m.json"]
    code, out, err = run_main(*cmd, cwd=tmp_path)
    assert code == 0, err
    return out, (tmp_path / "rep" / "index.html").read_text()


def test_frd_report_records_the_command_prints_the_cli_percent_and_lists_the_modes(tmp_path):
    g = _two_modes()
    f = np.geomspace(5.0, 4000.0, 300)
    out, page = _fit_frd(
        tmp_path, FrequencyResponse(f, g.frequency_response(f), inputs=("V",), outputs=("y",)), "--order", 4
    )
    assert "stageid identify frd frf.csv --dt 0.0001 --fmax 2000 --order 4 --report rep -o m.json" in page
    rows = {r[0]: r[1:] for r in _rows(page)}
    assert rows["order"] == ["4"] and rows["delay [samples]"] == ["0"] and rows["weight"] == ["none (auto)"]
    stated = out.split("(of its peak): V ")[1].split(" %")[0]
    assert rows["V"] == [stated]  # the error table in %, digit for digit as the command line said it
    modes = [r for r in _rows(page) if len(r) == 4 and r[3] == "complex pair"]
    freqs = sorted(float(r[1]) for r in modes)
    # the data are the model itself, so the fit's modes are its modes (4 significant digits shown)
    assert freqs == pytest.approx([300.0, 1200.0], rel=2e-3)
    assert sorted(float(r[2]) for r in modes) == pytest.approx([0.02, 0.05], rel=5e-3)
    # the figure's caption promises nothing the data lack, and the unfitted lines are greyed
    assert "no band: the data give no std" in page and "no coherence panel: the data give no coherence" in page
    assert re.search(r"grey: outside the fitted band 5-19\d\d Hz \(drawn, not fitted\)", page)


@pytest.mark.realdata
@pytest.mark.slow
def test_afm_report_reads_like_the_command_line(tmp_path):
    import scipy.io

    from stageid.data import datasets

    path = None if datasets.SHARED_DATA is None else datasets.SHARED_DATA / "afm_piezo_stage_frf"
    if path is None or not (path / "FRF_data_current_stage2.mat").exists():
        pytest.skip("shared data folder not found (../shared/data/afm_piezo_stage_frf)")
    frf = scipy.io.loadmat(path / "FRF_data_current_stage2.mat", squeeze_me=True, struct_as_record=False)
    frf = frf["modelFit"].frf
    afm = FrequencyResponse(np.asarray(frf.freqs_Hz), np.asarray(frf.G_uz2stage), inputs=("uz",), outputs=("stage",))
    write_csv(tmp_path / "afm.csv", frd_columns(afm))
    args = ["identify", "frd", "afm.csv", "--order", 16, "--dt", 4e-5, "--fmin", 1, "--fmax", 2000, "--delay", "auto"]
    code, out, err = run_main(*args, "--report", "rep", "-o", "afm.json", cwd=tmp_path)
    assert code == 0, err
    page = (tmp_path / "rep" / "index.html").read_text()
    stated = out.split("(of its peak): uz ")[1].split(" %")[0]
    rows = {r[0]: r[1:] for r in _rows(page)}
    assert rows["uz"] == [stated]  # e.g. 2.42, never the fraction 0.02416
    assert rows["delay [samples]"][0].endswith("(auto)") and rows["order"] == ["16"]
    assert "stageid identify frd afm.csv --order 16 --dt 4e-05" in page
    assert "Modes of the identified model" in page and "damping [-]" in page
    # the measured FRF has neither std nor coherence: the caption says so; the lines past 2 kHz stay, greyed
    assert "no band: the data give no std" in page and "shaded" not in page.split("Figure 1.")[1].split("</fig")[0]
    assert "302 lines" in page and "grey: outside the fitted band" in page


def test_hysteresis_report_has_the_summary_as_table_and_list_and_draws_the_creep(tmp_path):
    from stageid.plants.piezo_actuator import EXPERIMENTS

    write_csv(tmp_path / "ident.csv", EXPERIMENTS["decaying-triangle"](seed=0))
    args = ["identify", "hysteresis", "ident.csv", "--input", "V", "--output", "y", "--model", "pi"]
    args += ["--operators", 10, "--creep", "0.05,0.5", "-o", "h.json", "--report", "rep"]
    code, out, err = run_main(*args, cwd=tmp_path)
    assert code == 0, err
    page = (tmp_path / "rep" / "index.html").read_text()
    assert "stageid identify hysteresis ident.csv --input V --output y --model pi" in page
    # the summary's per-record line becomes a table row with the same three-decimal numbers
    printed = re.search(r"record 0: max error ([\d.]+) % of range, RMS ([\d.]+) %", out)
    fit_table = page.split("Fit on each identification record")[1].split("</table>")[0]
    assert _rows(fit_table) == [["ident.csv", printed.group(1), printed.group(2), "zero"]]
    items = re.findall(r"<li>(.*?)</li>", page.split("<ul>")[-1])
    assert len(items) >= 2 and not any("record 0" in i for i in items)  # the rest of the summary, one item a line
    assert "Creep term: output after a unit step of the input, 2 first-order lags" in page
    assert f"(max {printed.group(1)} % of range)" in page  # the loop caption gives the summary's %


def test_stage_model_report_draws_dynamics_modes_and_creep(monkeypatch):
    from stageid.data import Experiment
    from stageid.hysteresis import PIModel
    from stageid.hysteresis.models.creep import CreepTerm
    from stageid.hysteresis.stage import StageModel
    from stageid.report import html as report_html
    from stageid.report.model_report import hysteresis_model_report

    drawn = []
    real = report_html.Report.figure
    monkeypatch.setattr(
        report_html.Report, "figure", lambda self, fig, caption, dpi=110: (drawn.append(fig), real(self, fig, caption))
    )
    w = 2 * np.pi * 700.0
    dynamics = StateSpaceModel([[0, 1], [-w * w, -2 * 0.02 * w]], [[0], [w * w]], [[1, 0]], [[0]]).c2d(DT)
    creep = CreepTerm([0.01, 0.1], [0.01, 0.02], DT)
    stage = StageModel(
        PIModel(r=[0.0, 1.0], weights=[1.0, 0.5], creep=creep), dynamics, disturbance_modes=((700.0, 0.02),)
    )
    u = np.sin(np.linspace(0, 20 * np.pi, 4000))[:, None]
    exp = Experiment(u, stage.simulate(u), DT, ("V",), ("y",), input_units=("V",), output_units=("um",), name="r")
    report, metrics = hysteresis_model_report(stage, [exp], settings={"--dynamics": 2}, command="stageid x")
    page = report.to_html()
    assert "<td>stageid x</td>" in page and "<td>--dynamics</td><td>2</td>" in page
    assert "dotted: the modes taken from the records' disturbance spectrum" in html_text.unescape(page)
    assert metrics["dynamics/modes/frequency_hz"] == pytest.approx([700.0], rel=1e-9)
    assert metrics["disturbance_modes/frequency_hz"] == [700.0]
    assert metrics["creep/total_gain"] == pytest.approx(0.03)
    labels = [ax.get_ylabel() for fig in drawn for ax in fig.axes]
    assert "|G| [um/um]" in labels and "creep after a unit input step [um/V]" in labels
    assert "y [um]" in labels and "error [% of range]" in labels


def test_report_command_records_its_command_line(tmp_path):
    from stageid.models import save_model

    save_model(_two_modes(), tmp_path / "g.json")
    code, _, err = run_main("report", "g.json", "--out", "rep", cwd=tmp_path)
    assert code == 0, err
    page = (tmp_path / "rep" / "index.html").read_text()
    assert "<td>command</td><td>stageid report g.json --out rep</td>" in page
    assert "Modes of the identified model" in page and "|G| [output/input]" not in page  # labels are in the PNG
