"""``cancel_pairs`` computes the pole-zero distances once; it must pick the same pairs, in the
same order, as recomputing them for the remaining roots after every cancellation."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from stageid.closedloop.cancellation import cancel_pairs, z_to_s


def _cancel_pairs_reference(poles, zeros, dt, tol=1e-2, unstable_tol=0.25):
    """The loop as first written: distances of the remaining roots recomputed each pass."""
    P, Z = list(np.asarray(poles, complex)), list(np.asarray(zeros, complex))
    pairs = []
    while P and Z:
        sp, sz = z_to_s(np.array(P), dt), z_to_s(np.array(Z), dt)
        d = np.abs(sp[:, None] - sz[None, :]) / np.maximum(np.abs(sp), 1.0)[:, None]
        limit = np.where((sp.real[:, None] > 0) & (sz.real[None, :] > 0), unstable_tol, tol)
        i, j = np.unravel_index(int(np.argmin(d / limit)), d.shape)
        if d[i, j] >= limit[i, j]:
            break
        pairs.append((complex(sp[i]), complex(sz[j]), float(d[i, j])))
        P.pop(i)
        Z.pop(j)
    return np.array(P, complex), np.array(Z, complex), pairs


def _roots(rng, n, dt):
    """Conjugate pairs and real roots in the z-plane, a few of them unstable."""
    s = -rng.uniform(5, 2000, n) + 1j * rng.uniform(0, 3000, n) * (rng.random(n) < 0.7)
    s[rng.random(n) < 0.15] *= -1  # some right-half-plane roots
    z = np.exp(s * dt)
    return np.concatenate([z, np.conj(z[np.abs(z.imag) > 0])])


@pytest.mark.parametrize("seed", range(20))
def test_same_pairs_as_recomputing_the_distances(seed: int) -> None:
    rng = np.random.default_rng(seed)
    dt = 2e-4
    poles = _roots(rng, int(rng.integers(0, 12)), dt)
    zeros = _roots(rng, int(rng.integers(0, 10)), dt)
    # near-copies of some poles among the zeros, so that pairs cancel (some within tol, some not)
    k = min(poles.size, int(rng.integers(0, 6)))
    zeros = np.concatenate([zeros, poles[:k] * (1 + rng.choice([1e-5, 1e-3, 3e-2], k))])
    rng.shuffle(zeros)
    kp, kz, pairs = cancel_pairs(poles, zeros, dt)
    rp, rz, rpairs = _cancel_pairs_reference(poles, zeros, dt)
    # the same floating-point operations on the same numbers: exact equality
    assert np.array_equal(kp, rp) and np.array_equal(kz, rz)
    assert [(c.pole, c.zero, c.distance) for c in pairs] == rpairs


def test_no_roots_on_either_side() -> None:
    kp, kz, pairs = cancel_pairs(np.array([0.9]), np.zeros(0), dt=1e-3)
    assert kp.tolist() == [0.9] and kz.size == 0 and pairs == ()
    kp, kz, pairs = cancel_pairs(np.zeros(0), np.array([0.5]), dt=1e-3)
    assert kp.size == 0 and kz.tolist() == [0.5] and pairs == ()


@pytest.mark.parametrize("seed", range(10))
def test_ties_are_taken_in_the_same_order_as_recomputing(seed: int) -> None:
    # repeated poles and zeros: equal distances, taken first row, then first column
    rng = np.random.default_rng(100 + seed)
    dt = 2e-4
    base = _roots(rng, 4, dt)
    poles = np.concatenate([base, base[:2], base[:1]])
    zeros = np.concatenate([base[1:] * (1 + 1e-4), base[:1] * (1 + 1e-4), base[:1] * (1 + 1e-4)])
    kp, kz, pairs = cancel_pairs(poles, zeros, dt)
    rp, rz, rpairs = _cancel_pairs_reference(poles, zeros, dt)
    assert np.array_equal(kp, rp) and np.array_equal(kz, rz)
    assert [(c.pole, c.zero, c.distance) for c in pairs] == rpairs and len(pairs) >= 4


@pytest.mark.parametrize("stable_zero", [-80.0, -300.0])
def test_zero_tolerance_cancels_only_unstable_pairs_and_returns(stable_zero: float) -> None:
    # tol = 0 (allowed for cancel_tol): stable pairs never cancel, the unstable pair still does under
    # unstable_tol.  The masked-argmin loop of 82e117e..f8c276d stopped at once on the 0/0 of a
    # stable pole-zero coincidence (-80), and otherwise (-300) looped for ever (all remaining ratios
    # inf, argmin back at the cancelled pair), so this runs in a child process with a timeout.
    code = (
        "import numpy as np\n"
        "from stageid.closedloop.cancellation import cancel_pairs\n"
        "dt = 2e-4\n"
        f"P = np.exp(np.array([50.0, -80.0]) * dt); Z = np.exp(np.array([50.05, {stable_zero}]) * dt)\n"
        "kp, kz, pairs = cancel_pairs(P, Z, dt, tol=0.0)\n"
        "print(len(pairs), round(pairs[0].pole.real, 6), kp.size, kz.size)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=20)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["1", "50.0", "1", "1"]
    assert "Warning" not in out.stderr  # d / 0 is meant: no divide-by-zero warning
