"""``cancel_pairs`` computes the pole-zero distances once; it must pick the same pairs, in the
same order, as recomputing them for the remaining roots after every cancellation."""

from __future__ import annotations

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
