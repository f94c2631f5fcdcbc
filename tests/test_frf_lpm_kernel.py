"""The compiled LPM kernel equals its plain-numpy twin (same estimator, same std and coherence):
MIMO records, several records, lines at DC/Nyquist, unexcited lines, degrees and widths."""

import numpy as np
import pytest
import scipy.signal as ss

from stageid.data import Experiment
from stageid.frf import lpm_frf, lpm_kernels
from stageid.frf.lpm import solve_lines_compiled, solve_lines_python
from stageid.frf.lpm_kernels import lpm_lines_kernel

RTOL = 1e-10


def _records(seed, n, m, q, ne, noise=0.05):
    rng = np.random.default_rng(seed)
    exps = []
    for _ in range(ne):
        u = rng.standard_normal((n, m))
        y = np.empty((n, q))
        for c in range(q):
            b, a = ss.butter(2, 0.1 + 0.1 * c)
            y[:, c] = ss.lfilter(b, a, u[:, c % m]) + 0.3 * ss.lfilter([1, 0.5], [1, -0.8], u[:, (c + 1) % m])
        exps.append(Experiment(u, y + noise * rng.standard_normal((n, q)), 1e-3))
    return exps


def _assert_same(a, b):
    np.testing.assert_array_equal(a.freqs, b.freqs)
    np.testing.assert_allclose(a.response, b.response, rtol=RTOL, atol=RTOL * np.abs(b.response).max())
    np.testing.assert_allclose(a.std, b.std, rtol=RTOL, atol=RTOL * b.std.max())
    np.testing.assert_allclose(a.coherence, b.coherence, rtol=0, atol=1e-10)


@pytest.mark.parametrize(
    ("seed", "n", "m", "q", "ne"),
    [(0, 3000, 3, 3, 1), (1, 2001, 2, 3, 2), (2, 1500, 1, 1, 1), (3, 1200, 2, 1, 3), (4, 4000, 3, 2, 1)],
)
def test_kernel_equals_numpy_twin(seed, n, m, q, ne):
    exps = _records(seed, n, m, q, ne)
    _assert_same(lpm_frf(exps), lpm_frf(exps, compiled=False))


@pytest.mark.parametrize(("degree", "half_width"), [(0, 3), (1, 4), (2, 12), (3, None)])
def test_kernel_equals_numpy_twin_other_degrees_and_widths(degree, half_width):
    exps = _records(5, 2500, 2, 2, 1)
    kw = {"degree": degree, "half_width": half_width}
    _assert_same(lpm_frf(exps, **kw), lpm_frf(exps, compiled=False, **kw))


def test_kernel_equals_twin_on_every_line_including_dc_nyquist_and_unexcited():
    # band-limited inputs: lines outside the band are unexcited (status decided alike), and the
    # edge lines (clipped windows near DC and Nyquist) go through the one-line path
    rng = np.random.default_rng(6)
    n = 4000
    U = np.fft.rfft(rng.standard_normal((n, 2)), axis=0)
    U[300:] = 0.0
    u = np.fft.irfft(U, n, axis=0)
    y = np.column_stack([ss.lfilter([0.2, 0.1], [1, -0.7], u[:, 0]) + u[:, 1], u[:, 0] - 0.5 * u[:, 1]])
    y += 1e-3 * rng.standard_normal(y.shape)
    Uf = np.fft.rfft(u, axis=0)[None] / np.sqrt(np.mean(np.abs(np.fft.rfft(u, axis=0)) ** 2, axis=0))
    Yf = np.fft.rfft(y, axis=0)[None]
    ks = np.arange(1, n // 2)
    a = solve_lines_compiled(Uf, Yf, ks, 5, 2, n // 2)
    b = solve_lines_python(Uf, Yf, ks, 5, 2, n // 2)
    np.testing.assert_array_equal(a[3], b[3])
    ok = b[3]
    assert ok[:5].all() and ok[-300:].sum() == 0 and 250 < ok.sum() < 300
    np.testing.assert_allclose(a[0][ok], b[0][ok], rtol=RTOL, atol=RTOL * np.abs(b[0][ok]).max())
    np.testing.assert_allclose(a[1][ok], b[1][ok], rtol=1e-9, atol=1e-9 * b[1][ok].max())
    np.testing.assert_allclose(a[2][ok], b[2][ok], rtol=0, atol=1e-10)
    # any subset of lines, in any order, gives the same answers line by line
    sub = np.array([1, 2, 3, 700, 400, 1999, 1998, 50, 51, 52])
    c = solve_lines_compiled(Uf, Yf, sub, 5, 2, n // 2)
    np.testing.assert_allclose(c[0], a[0][sub - 1], rtol=1e-13, atol=1e-13 * np.abs(a[0]).max())


def test_ill_conditioned_windows_fall_back_to_the_twin():
    # two inputs almost equal: every local regression is ill-conditioned; the kernel hands the
    # lines to the numpy twin, which decides (here: not usable, as before)
    rng = np.random.default_rng(8)
    u0 = rng.standard_normal(3000)
    u = np.column_stack([u0, u0 + 1e-7 * rng.standard_normal(3000)])
    y = np.column_stack([u0, 2 * u0]) + 1e-3 * rng.standard_normal((3000, 2))
    exp = Experiment(u, y, 1e-3)
    Uf = np.fft.rfft(u, axis=0)[None]
    Uf /= np.sqrt(np.mean(np.abs(Uf) ** 2, axis=(0, 1)))
    Yf = np.fft.rfft(y, axis=0)[None]
    ks = np.arange(1, 1500)
    a = solve_lines_compiled(Uf, Yf, ks, 7, 2, 1500)
    b = solve_lines_python(Uf, Yf, ks, 7, 2, 1500)
    np.testing.assert_array_equal(a[3], b[3])
    B = ks.size
    status = np.empty(B, np.int8)
    out = (np.empty((B, 2, 2), complex), np.empty((B, 2, 2)), np.empty((B, 2)), status)
    lpm_lines_kernel(np.ascontiguousarray(Uf.real), np.ascontiguousarray(Uf.imag), Yf, ks, 7, 2, 1500, 1e-6, *out)
    assert np.all(status == 2)  # every line handed over
    try:
        ra = lpm_frf(exp)
    except Exception as err:  # noqa: BLE001 - the twin must fail the same way
        with pytest.raises(type(err)):
            lpm_frf(exp, compiled=False)
    else:
        _assert_same(ra, lpm_frf(exp, compiled=False))


def test_kernel_compiled_for_the_sizes_equals_numpy_twin(monkeypatch):
    # long records run the kernel compiled with (ne, m, q, degree) as constants; force that path
    # on a short MIMO record (two records, so the cross-record blocks are exercised too)
    calls = []
    sized = lpm_kernels.sized_entry
    monkeypatch.setattr(lpm_kernels, "SPECIALISE_LINES", 0)
    monkeypatch.setattr(lpm_kernels, "sized_entry", lambda args: calls.append(args[-4:]) or sized(args))
    exps = _records(9, 1800, 2, 3, 2)
    _assert_same(lpm_frf(exps), lpm_frf(exps, compiled=False))
    assert calls == [(2, 2, 3, 3)]
