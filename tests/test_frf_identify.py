"""Identification from FRF data: a 2x2 flexure stage recovered within 1 % of each column's peak
(continuous and discrete), delays, automatic order, and the measured AFM stage."""

import numpy as np
import pytest

from stageid import ParameterError
from stageid.data import datasets
from stageid.frf import FRDIdentification, FrequencyResponse
from stageid.models import StateSpaceModel

AFM = (
    None
    if datasets.SHARED_DATA is None
    else datasets.SHARED_DATA / "afm_piezo_stage_frf" / "FRF_data_current_stage2.mat"
)


def flexure_stage() -> StateSpaceModel:
    """Continuous 2x2 stage with three lightly damped modes (80, 210, 450 Hz) coupling both axes."""
    wn = 2 * np.pi * np.array([80.0, 210.0, 450.0])
    zeta = np.array([0.02, 0.015, 0.01])
    shapes = np.array([[1.0, 0.6], [0.8, -0.9], [0.5, 0.7]])
    A = np.zeros((6, 6))
    B = np.zeros((6, 2))
    C = np.zeros((2, 6))
    for k in range(3):
        A[2 * k, 2 * k + 1] = 1.0
        A[2 * k + 1, 2 * k] = -(wn[k] ** 2)
        A[2 * k + 1, 2 * k + 1] = -2 * zeta[k] * wn[k]
        B[2 * k + 1] = shapes[k] * wn[0] ** 2
        C[:, 2 * k] = shapes[k]
    return StateSpaceModel(A, B, C, np.zeros((2, 2)), inputs=("X", "Y"), outputs=("x", "y"))


def noisy(G, seed, level=0.005):
    """``G`` plus complex noise of ``level`` times each column's peak, and that std."""
    rng = np.random.default_rng(seed)
    peak = np.max(np.abs(G), axis=(0, 1))
    std = np.broadcast_to(level * peak[None, None, :], G.shape)
    return G + std / np.sqrt(2) * (rng.standard_normal(G.shape) + 1j * rng.standard_normal(G.shape)), std


F = np.geomspace(5.0, 1000.0, 400)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("dt", [None, 1e-4])
def test_flexure_stage_within_one_percent(seed, dt):
    g = flexure_stage() if dt is None else flexure_stage().c2d(dt)
    G = g.frequency_response(F)
    Gn, std = noisy(G, seed)
    res = FRDIdentification(order=6, sample_time=dt).fit(
        FrequencyResponse(F, Gn, std, inputs=g.inputs, outputs=g.outputs)
    )
    assert res.model.is_stable() and res.model.dt == dt
    assert res.model.inputs == ("X", "Y") and res.model.outputs == ("x", "y")
    err = np.max(np.abs(res.model.frequency_response(F) - G), axis=(0, 1)) / np.max(np.abs(G), axis=(0, 1))
    assert np.all(err <= 0.01), err  # the target: 1 % of each column's peak, against the truth


def test_automatic_order_finds_the_three_modes():
    g = flexure_stage()
    Gn, std = noisy(g.frequency_response(F), 0)
    res = FRDIdentification(order="auto", sample_time=None).fit(FrequencyResponse(F, Gn, std))
    assert res.order == 6
    assert res.order_errors[0][0] == 1


def test_input_delay_recovered():
    # a feedthrough makes the delay decidable: a strictly proper ZOH model delayed by 5 is also
    # exactly an order-6 model with feedthrough delayed by 6 (z^-6 (z G)), and the two tie to rounding
    d = flexure_stage().c2d(1e-4)
    g = StateSpaceModel(d.A, d.B, d.C, [[0.05, 0.0], [0.0, -0.03]], dt=1e-4)
    z = np.exp(2j * np.pi * F * 1e-4)
    G = g.frequency_response(F) * (z**-5)[:, None, None]  # five samples of input delay
    res = FRDIdentification(order=6, sample_time=1e-4, delay="auto").fit(FrequencyResponse(F, G))
    assert res.delay == 5
    held_out = dict(res.delay_errors)
    assert min(held_out[4], held_out[6]) > 1e6 * held_out[5]  # the record decides, not the rounding
    assert res.model.n_states == 6 + 5 * 2
    assert res.max_error < 1e-6  # noise-free: the delayed model is exact


def test_weights_and_settings_checked():
    frd = FrequencyResponse(F, flexure_stage().frequency_response(F))
    with pytest.raises(ParameterError, match="`delay` of FRDIdentification must be 0 for a continuous model"):
        FRDIdentification(order=6, delay=2).fit(frd)
    with pytest.raises(ParameterError, match="`band` of FRDIdentification must be a band up to the Nyquist"):
        FRDIdentification(order=6, sample_time=1e-3, band=(None, 900.0)).fit(frd)
    with pytest.raises(ParameterError, match=r"`band` of FRDIdentification must be None or \(f_low, f_high\)"):
        FRDIdentification(order=6, band=(900.0, 10.0)).fit(frd)
    with pytest.raises(ValueError, match="needs std_"):
        FRDIdentification(order=6, weight="std").fit(frd)


def _afm():
    scipy_io = pytest.importorskip("scipy.io")
    if AFM is None or not AFM.exists():
        pytest.skip("shared data folder not found (../shared/data/afm_piezo_stage_frf)")
    frf = scipy_io.loadmat(AFM, squeeze_me=True, struct_as_record=False)["modelFit"].frf
    return FrequencyResponse(np.asarray(frf.freqs_Hz), np.asarray(frf.G_uz2stage), inputs=("uz",), outputs=("stage",))


def test_afm_stage_order_16_within_three_percent():
    frd = _afm()
    res = FRDIdentification(order=16, sample_time=4e-5, band=(1.0, 2000.0)).fit(frd)
    raw = FRDIdentification(order=16, sample_time=4e-5, band=(1.0, 2000.0), max_iter=0).fit(frd)
    assert res.model.is_stable()
    assert res.max_error <= 0.03, res.max_error  # the target on the measured stage
    assert res.max_error < 0.7 * raw.max_error  # the output-error refinement is what gets there


def test_former_names_dt_fmin_fmax_still_fit_the_same_with_a_deprecation_warning():
    frd = FrequencyResponse(F, flexure_stage().frequency_response(F))
    with pytest.warns(DeprecationWarning) as caught:
        old = FRDIdentification(order=6, dt=1e-4, fmax=2000.0)
    assert sorted(str(w.message).split(" of ")[0] for w in caught) == ["`dt`", "`fmax`"]
    new = FRDIdentification(order=6, sample_time=1e-4, band=(None, 2000.0))
    assert old.get_params() == new.get_params()
    a, b = old.fit(frd), new.fit(frd)
    assert a.band == b.band and a.band[1] <= 2000.0  # one end given: the other is the response's own
    np.testing.assert_array_equal(a.model.frequency_response(F[:50]), b.model.frequency_response(F[:50]))


def test_result_summary_diagnostics_and_settings_copy():
    frd = FrequencyResponse(F, flexure_stage().frequency_response(F))
    est = FRDIdentification(order=6, sample_time=1e-4, band=(10.0, None))
    res = est.fit(frd)
    est.order = 2  # changing the estimator afterwards changes nothing in the result
    assert res.estimator.order == 6 and res.estimator.band == (10.0, None)
    assert dict(res.diagnostics) == {
        "order": 6,
        "delay": 0,
        "weight": res.weight,
        "band": res.band,
        "max_error": res.max_error,
    }
    with pytest.raises(TypeError):
        res.diagnostics["order"] = 3
    text = res.summary()
    assert text.startswith("FRD fit: 6 states (discrete, sample time 0.0001 s)") and "  band: (" in text
