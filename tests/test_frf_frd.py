"""The FrequencyResponse object: table round trips (CSV, NPZ, freqresp files), python-control,
its figure, and bad tables refused with one line."""

import numpy as np
import pytest

from stageid import DataError, ParameterError
from stageid.data import write_csv, write_npz
from stageid.frf import FrequencyResponse, frd_columns, read_frd


def _frd(with_extras=True):
    rng = np.random.default_rng(0)
    f = np.linspace(1.0, 100.0, 40)
    G = rng.standard_normal((40, 2, 3)) + 1j * rng.standard_normal((40, 2, 3))
    std = np.abs(rng.standard_normal((40, 2, 3))) if with_extras else None
    coh = rng.uniform(0, 1, (40, 2)) if with_extras else None
    return FrequencyResponse(f, G, std, coh, ("Z", "Rx", "Ry"), ("z", "r_x"))


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
@pytest.mark.parametrize("extras", [True, False])
def test_table_round_trip(tmp_path, suffix, extras):
    frd = _frd(extras)
    path = tmp_path / f"frf{suffix}"
    (write_csv if suffix == ".csv" else write_npz)(path, frd_columns(frd))
    back = read_frd(path)
    assert back.inputs == frd.inputs and back.outputs == frd.outputs  # an output name with "_" too
    np.testing.assert_allclose(back.response, frd.response, rtol=1e-15)  # CSV writes repr-exact floats
    if extras:
        np.testing.assert_allclose(back.std, frd.std, rtol=1e-15)
        np.testing.assert_allclose(back.coherence, frd.coherence, rtol=1e-15)
    else:
        assert back.std is None and back.coherence is None


def test_reads_a_freqresp_file(tmp_path):
    from stageid.cli.main import main
    from stageid.models import StateSpaceModel, save_model

    g = StateSpaceModel([[0.9]], [[1.0]], [[1.0]], [[0.0]], dt=0.01, inputs=("u",), outputs=("y",))
    save_model(g, tmp_path / "g.json")
    assert (
        main(
            [
                "freqresp",
                str(tmp_path / "g.json"),
                "--fmin",
                "1",
                "--fmax",
                "40",
                "--n",
                "30",
                "-o",
                str(tmp_path / "fr.csv"),
            ]
        )
        == 0
    )
    frd = read_frd(tmp_path / "fr.csv")
    np.testing.assert_allclose(frd.response, g.frequency_response(frd.freqs), rtol=1e-12)


def test_python_control_round_trip():
    pytest.importorskip("control")
    frd = _frd(False)
    back = FrequencyResponse.from_control(frd.to_control())
    np.testing.assert_allclose(back.freqs, frd.freqs, rtol=1e-14)
    np.testing.assert_allclose(back.response, frd.response, rtol=1e-14)
    assert back.inputs == frd.inputs and back.outputs == frd.outputs


def test_figure_has_std_band_and_coherence_panel():
    fig = _frd().plot()
    # per input column: magnitude and phase of each of the 2 outputs, then the coherence row
    assert len(fig.axes) == 15
    assert all(len(ax.collections) for ax in fig.axes[:3])  # the shaded +-2 std band of each entry
    assert fig.axes[-1].get_ylabel() == "coherence [-]" and len(fig.axes[-1].lines) == 2


def test_the_measured_response_is_drawn_by_the_one_bode_figure(monkeypatch):
    from stageid.plots import bode, lti
    from stageid.plots import frf as frf_plots

    assert lti.bode_figure is bode.bode_figure and frf_plots.bode_figure is bode.bode_figure
    calls = []
    monkeypatch.setattr(frf_plots, "bode_figure", lambda *args, **kwargs: calls.append(kwargs) or "figure")
    assert _frd().plot() == "figure" and calls[0]["band_label"] == "+-2 std" and calls[0]["coherence"] is not None


@pytest.mark.parametrize(
    "columns, fragment",
    [
        ({"f_hz": [1.0, 2.0, 1.5], "re_y_u": [1, 2, 3], "im_y_u": [0, 0, 0]}, "strictly increasing"),
        ({"f_hz": [1.0, 2.0], "re_y_u": [1, 2]}, "no matching 'im_y_u'"),
        ({"f_hz": [1.0, 2.0], "im_y_u": [1, 2]}, "no matching 're_y_u'"),
        ({"re_y_u": [1, 2], "im_y_u": [1, 2]}, "'f_hz'"),
        (
            {"f_hz": [1.0, 2.0], "re_a_u": [1, 2], "im_a_u": [1, 2], "re_b_v": [1, 2], "im_b_v": [1, 2]},
            "full output x input grid",
        ),
    ],
)
def test_bad_tables(tmp_path, columns, fragment):
    path = tmp_path / "bad.csv"
    write_csv(path, {k: np.asarray(v, float) for k, v in columns.items()})
    with pytest.raises(DataError, match=fragment) as info:
        read_frd(path)
    assert "\n" not in str(info.value)


def test_nan_in_table(tmp_path):
    path = tmp_path / "nan.csv"
    path.write_text("f_hz,re_y_u,im_y_u\n1,1,0\n2,nan,0\n")
    with pytest.raises(DataError, match="NaN"):
        read_frd(path)


def test_copy_false_takes_the_arrays_over_and_the_default_copies():
    f = np.array([1.0, 2.0, 3.0])
    G = np.ones((3, 1, 1), complex)
    std = np.full((3, 1, 1), 0.1)
    coh = np.array([[0.5], [1.2], [0.9]])
    kept = FrequencyResponse(f, G, std, coh)
    assert G.flags.writeable and coh[1, 0] == 1.2 and not np.shares_memory(kept.response, G)
    taken = FrequencyResponse(f, G, std, coh, copy=False)
    assert np.shares_memory(taken.response, G) and np.shares_memory(taken.std, std)
    assert not G.flags.writeable and coh[1, 0] == 1.0  # frozen, clipped in place


def test_plot_draws_in_the_axes_it_is_given():
    from matplotlib.figure import Figure

    frd = FrequencyResponse([1.0, 2.0, 4.0], np.ones((3, 1, 1), complex), std=np.full((3, 1, 1), 0.1))
    fig = Figure()
    mag, phase = fig.subplots(2, 1)
    assert frd.plot(ax=[mag, phase]) is fig and len(fig.axes) == 2  # no new axes, no new figure
    assert mag.get_ylabel() == "|G| [output/input]" and len(mag.lines) == 1 and len(phase.lines) == 1
    with pytest.raises(ParameterError, match="`ax` must hold 2 x 1 axes"):
        frd.plot(ax=mag)  # magnitude and phase need two
