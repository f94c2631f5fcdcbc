"""Best linear approximation against truth: a linear plant, odd and even static nonlinearities before a
resonance, Bussgang's theorem, and distortion levels against a Monte-Carlo truth."""

import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.signal import cont2discrete, lfilter

from stageid import DataError, ParameterError
from stageid.data import Experiment
from stageid.frf import FRDIdentification, FrequencyResponse, read_frd
from stageid.frf.bla import BLAAccumulator, bla_frf, detect_periods, detect_transient_periods
from stageid.frf.records import ChannelRecord
from stageid.signals import multisine

DT, L, P = 1e-3, 1024, 4
# a lightly damped resonance at 80 Hz (the stage's first mode), unit static gain
_B, _A, _ = cont2discrete(
    ([(2 * np.pi * 80) ** 2], [1, 2 * 0.05 * 2 * np.pi * 80, (2 * np.pi * 80) ** 2]), DT, "bilinear"
)
_B = _B.ravel()


def g0(freqs):
    z = np.exp(2j * np.pi * freqs * DT)
    return np.polyval(_B[::-1], 1 / z) / np.polyval(_A[::-1], 1 / z)


def realisations(static, M, noise, seed, lines="random-odd", rms=1.0, extra_periods=1, first=0):
    """M records of the static nonlinearity before the resonance; the leading periods hold the transient.

    The seed fixes the line set (random-odd) and the phases of realisation ``first``, ``first + 1``...
    """
    rng = np.random.default_rng(seed + 1000 + first)
    n = L * (P + extra_periods)
    for r in range(first, first + M):
        u = multisine(n, DT, 1.0, 300.0, seed=seed, realisation=r, n_periods=P + extra_periods, lines=lines, rms=rms)
        yield Experiment(u, lfilter(_B, _A, static(u)) + noise * rng.standard_normal(n), DT, ("u",), ("y",))


def test_linear_plant_total_equals_noise_and_nothing_is_flagged():
    noise = 0.01
    res = bla_frf(realisations(lambda u: u, 16, noise, seed=1), transient_periods=1)
    f = res.frd
    # the BLA of a linear plant is the plant, within its noise std
    err = np.abs(f.response[:, 0, 0] - g0(f.freqs))
    assert np.mean(err < 3 * f.std[:, 0, 0]) > 0.97
    # the noise std against its analytic value: var of one line of a period's DFT is L sigma^2,
    # averaged over P periods and M realisations, divided by |U|^2 (every realisation has the same |U|)
    u = next(realisations(lambda u: u, 1, 0.0, seed=1)).u[L:, 0]
    U = np.abs(np.fft.rfft(u[:L]))[np.round(f.freqs * L * DT).astype(int)]
    expected = np.sqrt(L * noise**2 / P / 16) / U
    assert np.median(f.std[:, 0, 0] / expected) == pytest.approx(1.0, abs=0.1)  # 45 dof per line, 115 lines
    # no nonlinear distortion: the total variance is the noise variance, no detection line stands out
    assert np.median(f.total_std**2 / f.std**2) == pytest.approx(1.0, abs=0.15)
    assert not res.odd.detected[0] and not res.even.detected[0]
    assert abs(res.odd.level_db[0]) < 1.5 and abs(res.even.level_db[0]) < 1.5


def test_cubic_flags_odd_lines_only_and_its_distortion_matches_a_monte_carlo_truth():
    cubic = lambda u: u + 0.3 * u**3  # noqa: E731
    res = bla_frf(realisations(cubic, 64, 0.01, seed=2), transient_periods=1)
    assert res.odd.detected[0] and res.odd.level_db[0] > 30
    assert not res.even.detected[0]
    # truth: the scatter of G^[m] over many noise-free realisations of the same system
    truth = bla_frf(realisations(cubic, 400, 0.0, seed=2, first=1000), transient_periods=1)
    assert np.array_equal(truth.frd.freqs, res.frd.freqs)
    est, ref = res.stochastic_variance[:, 0, 0], truth.stochastic_variance[:, 0, 0]
    f = res.frd.freqs
    # the ratio averaged over the lines of each part of the band; the distortion of one realisation
    # is correlated across lines (its level rises and falls as a whole), so the average has about
    # M - 1 degrees of freedom: M = 64 gives +-6 % (M = 16 spread 0.81-1.28 over five sets)
    ratio = est / ref
    for lo, hi in [(0, 50), (50, 100), (100, 200), (200, 300)]:
        band = (f >= lo) & (f < hi)
        assert ratio[band].mean() == pytest.approx(1.0, abs=0.2), (lo, hi)
    # the odd share from the detection lines tells the same story: well above the noise level
    assert np.median(res.odd_std[:, 0, 0] / res.frd.std[:, 0, 0]) > 10


def test_even_nonlinearity_flags_even_lines_only():
    res = bla_frf(realisations(lambda u: u + 0.3 * u**2, 8, 0.01, seed=4), transient_periods=1)
    assert res.even.detected[0] and res.even.level_db[0] > 30
    assert not res.odd.detected[0]
    # with an odd multisine an even nonlinearity adds nothing at the excited lines
    assert np.median(res.frd.total_std**2 / res.frd.std**2) == pytest.approx(1.0, abs=0.3)


@pytest.mark.parametrize("static, gain", [(lambda u: u + 0.2 * u**3, 1.6), (lambda u: u + 0.5 * u**2, 1.0)])
def test_bla_of_a_static_nonlinearity_before_a_plant_follows_bussgang(static, gain):
    # Bussgang: for Gaussian u of variance s^2, BLA = G0 E[u f(u)] / s^2 = G0 (1 + 3 a s^2) for
    # u + a u^3, and G0 for u + b u^2; a random-phase multisine of many lines is Gaussian enough
    res = bla_frf(realisations(static, 8, 0.0, seed=5, lines="full"), transient_periods=1)
    ratio = res.frd.response[:, 0, 0] / g0(res.frd.freqs)
    # the mean over 300 lines x 8 realisations: the stochastic distortions average out to ~1 %
    assert abs(np.mean(ratio) - gain) < 0.03 * gain


def test_orthogonal_mimo_design_recovers_every_entry_of_a_linear_plant():
    B = np.array([[1.0, 0.3], [-0.5, 0.8]])  # static 2x2 coupling before the resonance
    recs = []
    for r in range(3):
        exps = []
        for e in range(2):
            u = multisine(
                L * 3, DT, 1.0, 200.0, seed=6, realisation=r, n_periods=3, n_channels=2, mimo="orthogonal", experiment=e
            )
            y = lfilter(_B, _A, u @ B.T, axis=0)
            exps.append(Experiment(u, y, DT, ("a", "b"), ("x", "y")))
        recs.append(exps)
    res = bla_frf(recs, transient_periods=1)
    truth = g0(res.frd.freqs)[:, None, None] * B[None]
    # 1e-6: what is left of the transient after one period of the 80 Hz mode
    np.testing.assert_allclose(res.frd.response, truth, atol=1e-6 * np.abs(truth).max())
    assert res.frd.n_outputs == 2 and res.frd.n_inputs == 2


def test_periods_and_transient_are_detected():
    u = multisine(L * 6, DT, 1.0, 300.0, seed=1, n_periods=6)
    assert detect_periods(u) == 6
    assert detect_periods(np.random.default_rng(0).standard_normal(L * 6)) == 1
    # from rest, the resonance rings for about two periods before the steady state
    y = lfilter(_B, _A, u) + 1e-4 * np.random.default_rng(1).standard_normal(u.size)
    assert 1 <= detect_transient_periods(y, 6) <= 3
    res = bla_frf([Experiment(u, y, DT)] * 2)
    assert res.transient_periods >= 1 and res.n_periods == 6 - res.transient_periods


def test_realisations_must_match_and_give_two_steady_periods():
    acc = BLAAccumulator(periods=P + 1)
    exps = list(realisations(lambda u: u, 2, 0.01, seed=1))
    acc.add(exps[0])
    with pytest.raises(
        DataError, match="records of whole 1024-sample periods and one length are needed; got 4096 samples"
    ):
        acc.add(Experiment(exps[1].u[:-L], exps[1].y[:-L], DT, ("u",), ("y",)))
    with pytest.raises(DataError, match="leaves 1; at least 2 are needed"):
        bla_frf(exps, periods=5, transient_periods=4)
    with pytest.raises(DataError, match="needs at least one realisation"):
        BLAAccumulator().result()
    with pytest.raises(DataError, match="`detection_even` must be increasing line indices >= 1; got \\[4, 2\\]"):
        BLAAccumulator(excited=[1, 3], detection_even=[4, 2])
    with pytest.raises(DataError, match="both excited and a detection line"):
        BLAAccumulator(excited=[1, 3], detection_odd=[3, 5])
    with pytest.raises(DataError, match="above Nyquist of a 1024-sample period"):
        bla_frf(exps, periods=5, excited=[3, 600])


def test_identification_weights_by_the_total_variance_when_the_frd_has_it(tmp_path):
    res = bla_frf(realisations(lambda u: u + 0.3 * u**3, 8, 0.01, seed=7), transient_periods=1)
    from stageid.data import write_csv

    write_csv(tmp_path / "bla.csv", res.to_columns())
    frd = read_frd(tmp_path / "bla.csv")
    np.testing.assert_allclose(frd.total_std, res.frd.total_std, rtol=1e-12)
    np.testing.assert_allclose(frd.std, res.frd.std, rtol=1e-12)
    total = FRDIdentification(order=2, sample_time=DT).fit(frd)
    noise_only = FrequencyResponse(frd.freqs, frd.response, frd.std, None, frd.inputs, frd.outputs)
    noise = FRDIdentification(order=2, sample_time=DT).fit(noise_only)
    assert total.weight == "total-std" and noise.weight == "std"
    # the fit's uncertainty then covers the nonlinear scatter: far wider than from the noise alone
    f = frd.freqs[::10]
    wide = total.response_uncertainty(f).std[:, 0, 0]
    narrow = noise.response_uncertainty(f).std[:, 0, 0]
    assert np.median(wide / narrow) > 10


def test_a_nan_sample_is_named_by_column_and_row_and_npz_channels_read_alike(tmp_path):
    from stageid.frf.records import read_npz_record

    exps = list(realisations(lambda u: u, 2, 0.01, seed=1))
    y = exps[1].y.copy()
    y[L + 17, 0] = np.nan
    with pytest.raises(DataError, match=f"column 'y' has NaN at row {L + 17}"):
        bla_frf([exps[0], Experiment(exps[1].u, y, DT, ("u",), ("y",))], transient_periods=1)
    # memory-mapped NPZ channels give the estimate the in-memory records give
    paths = []
    for k, e in enumerate(exps):
        paths.append(tmp_path / f"r{k}.npz")
        np.savez(paths[-1], t=np.arange(e.n_samples) * DT, u=e.u[:, 0], y=e.y[:, 0])
    recs = [read_npz_record(p, ["u"], ["y"], None, 1e-6) for p in paths]
    assert all(isinstance(c, np.memmap) for r in recs for c in r.channels)
    a, b = bla_frf(recs, transient_periods=1), bla_frf(exps, transient_periods=1)
    np.testing.assert_array_equal(a.frd.response, b.frd.response)


def test_channels_transformed_in_threads_give_the_single_thread_result_and_its_first_error(tmp_path):
    exps = list(realisations(lambda u: u + 0.2 * u**2, 6, 0.01, seed=4))
    one = BLAAccumulator(transient_periods=1, n_threads=1)
    many = BLAAccumulator(transient_periods=1, n_threads=4)
    for e in exps:
        one.add(e)
        many.add(e)
    a, b = one.result(), many.result()
    for x, y in ((a.frd.response, b.frd.response), (a.frd.std, b.frd.std), (a.frd.total_std, b.frd.total_std)):
        np.testing.assert_array_equal(x, y)  # the same operations on the same numbers: bit for bit
    np.testing.assert_array_equal(a.even.power, b.even.power)
    # both experiments of a realisation spoilt (records as channels: an Experiment refuses them itself):
    # the error names the first in record order, as one thread does
    spoilt = [exps[0].y[:, 0].copy(), exps[1].y[:, 0].copy()]
    spoilt[1][L + 3], spoilt[0][2 * L + 9] = np.inf, np.nan
    ins = (exps[0].u[:, 0], exps[1].u[:, 0])
    bad = [ChannelRecord((*ins, y), 2, DT, ("u1", "u2"), ("y",), f"e{k}") for k, y in enumerate(spoilt)]
    messages = []
    for n_threads in (1, 4):
        with pytest.raises(DataError) as caught:
            BLAAccumulator(transient_periods=1, n_threads=n_threads, excited=np.arange(1, 200, 2)).add(bad)
        messages.append(str(caught.value))
    assert messages[0] == messages[1] == f"e0: column 'y' has NaN at row {2 * L + 9}; every sample must be finite."
    with pytest.raises(ParameterError, match="`n_threads` of BLAAccumulator must be a positive integer"):
        BLAAccumulator(n_threads=0)


def test_lpm_variant_removes_the_transient_of_two_period_records_from_rest():
    # two periods from rest: dropping one would leave one period, keeping both biases the FRF
    recs = list(realisations(lambda u: u, 16, 0.01, seed=1, extra_periods=-2))
    with pytest.raises(DataError, match="leaves 1; at least 2 are needed"):
        bla_frf(recs, transient_periods=1)
    lpm = bla_frf(recs, transient="lpm")
    kept = bla_frf(recs, transient_periods=0)
    G = g0(lpm.frd.freqs)
    err_lpm = np.abs(lpm.frd.response[:, 0, 0] - G)
    err_kept = np.abs(kept.frd.response[:, 0, 0] - G)
    assert np.median(err_lpm) < 0.25 * np.median(err_kept)  # 0.0023 against 0.013 relative
    assert np.mean(err_lpm < 3 * lpm.frd.std[:, 0, 0]) > 0.95
    # the noise std against its analytic value (2 periods, 16 realisations); the local fit
    # overestimates it by about 10 %
    u = recs[0].u[:L, 0]
    U = np.abs(np.fft.rfft(u))[np.round(lpm.frd.freqs * L * DT).astype(int)]
    expected = np.sqrt(L * 0.01**2 / 2 / 16) / U
    assert np.median(lpm.frd.std[:, 0, 0] / expected) == pytest.approx(1.0, abs=0.2)
    assert not lpm.odd.detected[0] and not lpm.even.detected[0]
    assert "transient removed by the local polynomial method" in lpm.summary().splitlines()[0]
    # a cubic is still told from noise, and as odd
    cubic = bla_frf(list(realisations(lambda u: u + 0.3 * u**3, 8, 0.01, seed=2, extra_periods=-2)), transient="lpm")
    assert cubic.odd.detected[0] and not cubic.even.detected[0]
    with pytest.raises(ParameterError, match="`transient` of BLAAccumulator must be 'drop' or 'lpm'; got 'x'"):
        BLAAccumulator(transient="x")


def test_local_fit_of_white_noise_gives_its_variance():
    from stageid.frf.bla_lpm import transient_free_lines

    # no transient: X - T at the centre lines and the fitted variance agree on white noise,
    # including the lines next to DC that take a one-sided window
    X = np.fft.rfft(np.random.default_rng(0).standard_normal((4096, 200)), axis=0)
    Xc, var = transient_free_lines(X, np.arange(1, 400), 4)
    assert np.mean(np.abs(Xc) ** 2) / np.mean(var) == pytest.approx(1.0, abs=0.05)
    with pytest.raises(DataError, match="at least 2 periods per record; got 1"):
        transient_free_lines(X, np.arange(1, 10), 1)


def test_reading_an_npz_record_primes_the_heap_as_reading_a_table_does(tmp_path):
    # the estimate's temporaries then reuse freed pages (stageid.runtime.heap); a fresh process,
    # since priming happens once per process
    np.savez(tmp_path / "r.npz", t=np.arange(64) * DT, u=np.zeros(64), y=np.zeros(64))
    code = (
        "from stageid.frf.records import read_npz_record; from stageid.runtime.heap import prime_heap; "
        f"read_npz_record({str(tmp_path / 'r.npz')!r}, ['u'], ['y'], None, 1e-3); print(prime_heap())"
    )
    env = {k: v for k, v in os.environ.items() if k != "STAGEID_HEAP_PRIMING"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env).stdout
    assert out.strip() == "False"  # already primed by the read (always False off glibc)


def test_result_has_the_model_a_text_summary_and_read_only_diagnostics():
    res = bla_frf(realisations(lambda u: u + 0.3 * u**2, 3, 0.01, seed=4), transient_periods=1)
    assert isinstance(res.model, FrequencyResponse)
    assert res.frd is res.model  # the former name still reads the BLA
    text = res.summary()
    assert isinstance(text, str) and text.splitlines()[0].startswith("bla: 3 realisation(s)")
    ratio = np.median(res.model.total_std**2 / res.model.std**2, axis=0)[0, 0]  # the band's median, as numpy's
    assert (
        f"bla: y: total variance over noise variance (median over the band): u {10 * np.log10(ratio):+.1f} dB" in text
    )
    assert dict(res.diagnostics) == {"n_realisations": 3, "n_periods": P, "transient_periods": 1, "transient": "drop"}
    with pytest.raises(TypeError):
        res.diagnostics["n_periods"] = 1
