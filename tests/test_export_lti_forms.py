"""The forms the LTI export writes: transfer entries normalised by ``den[0]`` (double), balanced
coordinates in single precision (equal, diagonal Gramians), and float arithmetic in float code."""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy.linalg import solve_discrete_lyapunov
from scipy.signal import lfilter

from stageid.export import export_c
from stageid.export.c_lti import balanced_blocks
from stageid.export.host import build, find_compiler
from stageid.models import StateSpaceModel, TransferMatrix

needs_cc = pytest.mark.skipif(find_compiler() is None, reason="no C compiler (gcc, clang or cc) on PATH")

N = 2500


def _gramians(A, B, C):
    return solve_discrete_lyapunov(A, B @ B.T), solve_discrete_lyapunov(A.T, C.T @ C)


def _hankel_singular_values(A, B, C):
    Wc, Wo = _gramians(A, B, C)
    return np.sort(np.sqrt(np.abs(np.linalg.eigvals(Wc @ Wo))))[::-1]


def _assert_balanced(A, B, C, rtol):
    """Equal, diagonal Gramians holding the Hankel singular values (basis-free) on the diagonal."""
    Wc, Wo = _gramians(A, B, C)
    scale = np.max(np.abs(Wc))
    np.testing.assert_allclose(Wc, Wo, rtol=0, atol=rtol * scale)
    np.testing.assert_allclose(Wc - np.diag(np.diag(Wc)), 0.0, atol=rtol * scale)
    np.testing.assert_allclose(np.sort(np.diag(Wc))[::-1], _hankel_singular_values(A, B, C), atol=rtol * scale)


# a stable 2x2 transfer matrix whose leading denominator coefficients are not 1 (nor all alike)
NUM = [[[0.4, 0.2], [1.0, -0.3, 0.05]], [[3.0], [0.0, 0.6, 0.1]]]
DEN = [[[2.0, -1.6, 0.7], [-0.5, 0.45, -0.3, 0.02]], [[4.0, -3.2], [0.25, -0.4, 0.2]]]


def test_the_reference_is_lfilter_with_the_leading_coefficient():
    u = np.random.default_rng(0).normal(size=(N, 2))
    tm = TransferMatrix(NUM, DEN, dt=1e-3)
    # num and den are polynomials in z: num is padded in front to den's length for lfilter (z^-1)
    b = [[np.r_[np.zeros(len(DEN[i][j]) - len(NUM[i][j])), NUM[i][j]] for j in range(2)] for i in range(2)]
    y = np.column_stack([sum(lfilter(b[i][j], DEN[i][j], u[:, j]) for j in range(2)) for i in range(2)])
    np.testing.assert_allclose(tm.simulate(u), y, rtol=0, atol=1e-12 * np.max(np.abs(y)))


@needs_cc
def test_double_transfer_entries_with_den0_not_one_match_simulate(tmp_path):
    rng = np.random.default_rng(1)
    tm = TransferMatrix(NUM, DEN, dt=1e-3)
    u = rng.normal(size=(N, 2))
    y_c = build(export_c(tm, "tfden"), tmp_path).run(u)
    y = tm.simulate(u)
    assert np.max(np.abs(y_c - y)) <= 1e-12 * np.max(np.abs(y))


@needs_cc
def test_double_unstable_entry_keeps_its_polynomial_form_normalised(tmp_path):
    # unstable: no balanced form, so even the float code runs the polynomial filter
    tm = TransferMatrix([[[0.5, 0.1]]], [[[2.0, -2.04]]], dt=1e-3)  # pole at z = 1.02
    u = np.random.default_rng(2).normal(size=(300, 1))
    y = tm.simulate(u)
    for single, tol in ((False, 1e-12), (True, 1e-5)):
        y_c = build(export_c(tm, f"unst{int(single)}", single=single), tmp_path).run(u)
        assert np.max(np.abs(y_c - y)) <= tol * np.max(np.abs(y)), single


def test_balanced_blocks_of_a_transfer_matrix_have_equal_diagonal_gramians():
    tm = TransferMatrix(NUM, DEN, dt=1e-3)
    for i in range(2):
        for j in range(2):
            block = balanced_blocks(tm.entry(i, j))  # one entry: one balanced block
            assert block is not None and block.n_states == len(DEN[i][j]) - 1
            _assert_balanced(block.A, block.B, block.C, rtol=1e-8)
    whole = balanced_blocks(tm)
    f = np.linspace(1.0, 400.0, 50)
    np.testing.assert_allclose(whole.frequency_response(f), tm.frequency_response(f), rtol=1e-9, atol=1e-12)


_TERM = re.compile(r"(-?[0-9.]+(?:e[-+]?[0-9]+)?)f \* ([xu])(\d+)")


def _parse_float_statespace(source: str, n: int, m: int, p: int):
    """A, B, C, D read back from the generated float step (``out[i] = c * x0 + ...``)."""
    A, B, C, D = np.zeros((n, n)), np.zeros((n, m)), np.zeros((p, n)), np.zeros((p, m))
    for kind, row, expr in re.findall(r"(out|s->x)\[(\d+)\] = (.*);", source):
        for value, var, col in _TERM.findall(expr):
            target = (C if var == "x" else D) if kind == "out" else (A if var == "x" else B)
            target[int(row), int(col)] = float(value)
    return A, B, C, D


def test_single_precision_statespace_is_exported_in_balanced_coordinates():
    # a model in badly scaled coordinates: the float form must be the balanced one, not merely some
    # realisation with the right response (input-normal or output-normal would also be exact)
    rng = np.random.default_rng(5)
    A0, B0, C0 = np.diag([0.999, 0.99, 0.9, 0.5]), rng.normal(size=(4, 2)), rng.normal(size=(1, 4))
    T = rng.normal(size=(4, 4)) @ np.diag([1e-3, 1.0, 1e2, 10.0])
    Ti = np.linalg.inv(T)
    g = StateSpaceModel(T @ A0 @ Ti, T @ B0, C0 @ Ti, [[0.0, 0.5]], dt=1e-3)
    A, B, C, D = _parse_float_statespace(export_c(g, "bal", single=True).source, 4, 2, 1)
    _assert_balanced(A, B, C, rtol=1e-4)  # coefficients rounded to float (6e-8), amplified by 1 / (1 - 0.999)
    hsv = _hankel_singular_values(A0, B0, C0)  # of the well-conditioned modal form
    np.testing.assert_allclose(_hankel_singular_values(A, B, C), hsv, rtol=0, atol=1e-4 * hsv[0])
    np.testing.assert_array_equal(D, np.float32(g.D))


@needs_cc
def test_single_precision_code_computes_in_float(tmp_path):
    # the float export must not be double code under another name: its output carries float
    # rounding (about 1e-7 of the signal), the double export's none
    rng = np.random.default_rng(6)
    g = StateSpaceModel([[0.9, 0.2], [-0.2, 0.9]], [[1.0], [0.3]], [[1.0, -0.5]], [[0.1]], dt=1e-3)
    u = rng.normal(size=(N, 1))
    y = g.simulate(u)
    scale = np.max(np.abs(y))
    source = export_c(g, "flt", single=True).source
    assert "double" not in source
    err_single = np.max(np.abs(build(export_c(g, "flt", single=True), tmp_path).run(u) - y)) / scale
    err_double = np.max(np.abs(build(export_c(g, "dbl"), tmp_path).run(u) - y)) / scale
    assert err_double <= 1e-12
    assert 1e-9 < err_single <= 1e-5, err_single
