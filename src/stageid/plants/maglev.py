"""Maglev nanopositioner, lateral axes (x, y, phi) of Shakir & Kim, eq. 22-24.

The plant is the identified continuous 3x3 transfer matrix of the paper: inputs the modal
forces/torque ``Fx [N], Fy [N], Tphi [N m]``, outputs ``x [m], y [m], phi [rad]``.  The
paper names ``G_ab`` the transfer from axis ``a`` to axis ``b`` (eq. 8: the ``x`` row is
``[G_xx, G_yx, G_phix]``), so entry ``[output b][input a] = G_ab``:

=============  =========  ===========  ==========
output \\ in    Fx         Fy           Tphi
=============  =========  ===========  ==========
x              22a G_xx   23b G_yx     24b G_phix
y              22b G_xy   23a G_yy     24c G_phiy
phi            22c G_xphi 23c G_yphi   24a G_phiphi
=============  =========  ===========  ==========

Unstable poles (magnetic negative springs): +54.62 (x), +82.21 (y), +86.73 (phi) rad/s.

The x-to-phi coupling (22c) as printed has a right-half-plane pole at +9.74 rad/s that no
other entry shares.  In a minimal realisation of the 3x3 matrix that mode is controllable
from ``Fx`` only and observable in ``phi`` only, and a decentralised controller can move
it only through products of couplings: closing our three loops leaves a closed-loop pole
at about +9.7 rad/s (``model(published=True)`` reproduces this, and the tests check it).
The paper's own experiments were stable, so the printed pole must be an artefact of the
identification or a sign lost in print.  **Choice:** the reference plant ``model()``
mirrors it to -9.74 rad/s (``|G_xphi(j w)|`` is unchanged, so every magnitude plot of
the paper is too); ``model(published=True)`` keeps the printed sign.

The controller is ours (the paper does not print it): per axis a lead-lag of order
[2, 2] (eq. 16), ``k (s + z_lag)(s + z_lead) / ((s + p_lag)(s + p_lead))``, with the lead
centred on a 110 Hz crossover (zero at wc/3, pole at 3 wc) and a lag of DC boost 10 (zero
at wc/10, pole at wc/100); the gain makes ``|G_ii M_i| = 1`` at 110 Hz; Tustin at 5 kHz.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._errors import SignalError
from ..models import StateSpaceModel, TransferMatrix
from . import experiment_seed, noise_entropy

__all__ = [
    "model",
    "controller",
    "controller_continuous",
    "lead_lag",
    "simulate_chirp",
    "EXPERIMENTS",
    "DT",
    "CROSSOVER_HZ",
    "UNSTABLE_POLES",
    "INPUTS",
    "OUTPUTS",
]


DT = 1.0 / 5000.0
CROSSOVER_HZ = 110.0
INPUTS = ("Fx", "Fy", "Tphi")
OUTPUTS = ("x", "y", "phi")
UNSTABLE_POLES = (54.62, 82.21, 86.73)  # rad/s, eq. 22a, 23a, 24a


def _p(*factors: Any) -> np.ndarray:
    out = np.array([1.0])
    for f in factors:
        out = np.polymul(out, np.asarray(f, dtype=float))
    return out


def model(published: bool = False) -> TransferMatrix:
    """The continuous 3x3 plant of eq. 22-24 (SI units), see the module notes.

    Parameters
    ----------
    published : bool
        Keep the printed +9.74 rad/s pole of G_xphi (eq. 22c); default mirrors it to -9.74.

    Examples
    --------
    >>> g = model()
    >>> round(float(g.dc_gain()[0, 0]), 10)                  # 3.1845 / (-54.62 * 76.91)
    -0.0007580655
    """
    s_xphi = 9.74 if published else -9.74
    num = [
        [[3.1845], [114.9298], [0.1411, -0.1411 * 934.60]],
        [[42.4017], [3.1623], [0.9065]],
        [[0.4266, -0.4266 * 6977.00], [964.3725], [1530.1985]],
    ]
    den = [
        [_p([1, -54.62], [1, 76.91]), _p([1, 105.91], [1, 131.00, 1.09e6]), _p([1, 76.91], [1, 586.20, 2.53e5])],
        [_p([1, 13.83], [1, 219.40, 1.98e6]), _p([1, -82.21], [1, 76.91]), _p([1, 76.91], [1, 315.60])],
        [_p([1, -s_xphi], [1, 451.50, 1.17e6]), _p([1, 322.80], [1, 65.59, 7.29e5]), _p([1, -86.73], [1, 76.91])],
    ]
    return TransferMatrix(num, den, None, INPUTS, OUTPUTS)


def lead_lag(
    k_plant: float, unstable_pole: float, stable_pole: float, crossover_hz: float = CROSSOVER_HZ
) -> tuple[np.ndarray, np.ndarray]:
    """[2, 2] lead-lag for ``k / ((s - a)(s + b))``: ``(num, den)`` in descending powers of ``s``.

    Lead zero ``wc/3``, lead pole ``3 wc``, lag zero ``wc/10``, lag pole ``wc/100``; gain
    so that the loop gain is 1 at ``crossover_hz``.

    Examples
    --------
    >>> num, den = lead_lag(3.1845, 54.62, 76.91)
    >>> s = 2j * np.pi * 110
    >>> float(round(abs(3.1845 / ((s - 54.62) * (s + 76.91)) * np.polyval(num, s) / np.polyval(den, s)), 9))
    1.0
    """
    wc = 2 * np.pi * crossover_hz
    zl, pl, zi, pi_ = wc / 3, 3 * wc, wc / 10, wc / 100
    s = 1j * wc
    loop = k_plant / ((s - unstable_pole) * (s + stable_pole)) * (s + zl) / (s + pl) * (s + zi) / (s + pi_)
    gain = 1.0 / abs(loop)
    return gain * _p([1, zl], [1, zi]), _p([1, pl], [1, pi_])


def controller_continuous() -> TransferMatrix:
    """Our decentralised continuous lead-lag controller, errors (x, y, phi) -> (Fx, Fy, Tphi)."""
    parts = [lead_lag(3.1845, 54.62, 76.91), lead_lag(3.1623, 82.21, 76.91), lead_lag(1530.1985, 86.73, 76.91)]
    num = [[parts[i][0] if i == j else [0.0] for j in range(3)] for i in range(3)]
    den = [[parts[i][1] if i == j else [1.0] for j in range(3)] for i in range(3)]
    return TransferMatrix(num, den, None, ("e_x", "e_y", "e_phi"), INPUTS)


def controller(dt: float = DT) -> StateSpaceModel:
    """The controller discretised by Tustin at ``dt`` (5 kHz by default), as a state-space model.

    Examples
    --------
    >>> k = controller()
    >>> k.dt, k.n_states, k.inputs
    (0.0002, 6, ('e_x', 'e_y', 'e_phi'))
    """
    return controller_continuous().to_statespace(minimal=False).c2d(dt, "tustin")


def simulate_chirp(
    axis: str,
    seed: int = 0,
    snr_db: float | None = 80.0,
    amplitude: float = 1e-6,
    f1: float = 2500.0,
    duration: float = 2.0,
    published: bool = False,
    noise_reference: str = "channel",
):
    """The paper's identification run (sec. 3.1): a chirp on one reference, DC to ``f1``.

    Returns
    -------
    stageid.data.Table
        Columns ``r_x, r_y, r_phi`` (references), ``Fx, Fy, Tphi`` (plant inputs) and
        ``x, y, phi`` (measured outputs, noise at ``snr_db`` per channel), ``dt`` = 0.2 ms.

    Raises
    ------
    SignalError
        When ``seed`` (of the measurement noise) is not an integer >= 0.
    """
    from ..closedloop.validation import simulate_closed_loop
    from ..data.table import Table
    from ..signals import chirp

    if not isinstance(axis, str) or axis not in OUTPUTS:
        raise SignalError(f"`axis` of the maglev chirp must be one of {', '.join(OUTPUTS)}; got {axis!r}.")
    seed = experiment_seed(seed, f"chirp-{axis}")
    r1 = chirp(0.0, f1, duration=duration, dt=DT, amplitude=amplitude)
    R = np.zeros((r1.size, 3))
    R[:, OUTPUTS.index(axis)] = r1
    y, u = simulate_closed_loop(model(published), controller(), R, DT, snr_db, seed, noise_reference)
    names = ["r_x", "r_y", "r_phi", *INPUTS, *OUTPUTS]
    units = ["m", "m", "rad", "N", "N", "N m", "m", "m", "rad"]
    return Table(names, np.hstack([R, u, y]), dt=DT, units=units, source=f"maglev chirp-{axis} seed {seed}")


def _experiment(axis: str, seed: int):
    """``simulate_chirp`` with a noise seed drawn from ``seed`` and the experiment's name: the three
    records of one seed, pooled by the closed-loop identification, never share their noise."""
    name = f"chirp-{axis}"
    entropy = noise_entropy(experiment_seed(seed, name), name)
    return simulate_chirp(axis, int(np.random.SeedSequence(entropy).generate_state(1)[0]))


EXPERIMENTS = {
    "chirp-x": lambda seed=0: _experiment("x", seed),
    "chirp-y": lambda seed=0: _experiment("y", seed),
    "chirp-phi": lambda seed=0: _experiment("phi", seed),
}
