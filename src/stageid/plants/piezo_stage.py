"""The 3-DOF piezo stage P-558.TCD identified by Cao & Chen (2013), eq. 23-25 (Ts = 2 ms).

Inputs ``Z`` [um], ``Rx``, ``Ry`` [urad] (the stage's reference channels 1-3), outputs
``z`` [um], ``rx``, ``ry`` [urad] (capacitive sensors).  The paper identifies one
single-input, three-output model per channel (orders 7, 4 and 4) and stacks them (eq. 20-22):
``A = diag(A1, A2, A3)``, ``B = diag(B1, B2, B3)``, ``C = [C1 C2 C3]``, ``D = 0``: 15 states.

Reading of the OCR text (the mathematically consistent choice, checked in
``tests/test_plants_piezo_stage.py``):

* eq. 23-25 give ``D_1 = 0_{3x3}`` and, for channel 3, a second "``D_2``"; each channel's
  feedthrough is a 3x1 zero column (eq. 19: ``D_i`` is q x 1), so ``D = 0_{3x3}``;
* eq. 19 says ``A_i in R^{3x3}``; the matrices printed are 7x7, 4x4 and 4x4 (the text's
  chosen orders 7, 4, 4) -- the 3x3 is a typo;
* entry ``A1[6, 4]`` reads ``0.00008`` and the tiny entries of ``C2``, ``C3`` are kept as
  printed.  With this reading every sub-model is stable, the DC gains of the diagonal are
  0.991 um/um, 1.015 urad/urad and 0.937 urad/urad (a position-controlled stage should be
  near 1), and the poles are well damped (slowest 2.2 Hz real pole in channel 1).

``EXPERIMENTS`` (each ``f(seed=0) -> Experiment``; output noise is white Gaussian with
std 1 nm on ``z`` and 0.1 urad on ``rx``/``ry``, twice the resolution of Table 1, drawn from the seed
and the experiment's name, so that no two experiments share it):

==================  ===========================================================================
``chirp-z``         Z: 20 um linear chirp 1-100 Hz with 20 um offset, 10 s (section 3.2)
``chirp-rx``        Rx: 200 urad chirp 1-100 Hz, 10 s
``chirp-ry``        Ry: 200 urad chirp 1-100 Hz, 10 s
``random-z``        Z: band-limited random (1-100 Hz), 40 um peak, 10 s (Table 3)
``random-rx``       Rx: band-limited random, 200 urad peak, 10 s
``random-ry``       Ry: band-limited random, 200 urad peak, 10 s
``band-limited``    all inputs at once, independent band-limited random 1-100 Hz, 20 s
``prbs``            all inputs at once, PRBS (white) 10 um / 100 urad, 20 s
``sine-<f>hz-<c>``  validation sinusoids of Tables 7-8: f = 1, 5, 10 Hz; c = z (10 um with
                    10 um offset), rx, ry (200 urad), 4 s each
``combined``        section 3.4 experiment 1: 1 Hz 20 um sine + 20 um offset on Z, 2 Hz
                    200 urad sine delayed 2 s on Rx, 100 urad step at 3 s on Ry, 6 s
==================  ===========================================================================
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..data.experiment import Experiment
from ..models.statespace import StateSpaceModel
from . import experiment_seed, noise_entropy

__all__ = ["model", "channel_models", "EXPERIMENTS", "DT", "INPUTS", "OUTPUTS", "NOISE_STD"]


DT = 0.002
INPUTS = ("Z", "Rx", "Ry")
OUTPUTS = ("z", "rx", "ry")
INPUT_UNITS = ("um", "urad", "urad")
OUTPUT_UNITS = ("um", "urad", "urad")
NOISE_STD = np.array([0.001, 0.1, 0.1])

# eq. 23
_A1 = [
    [0.9239, -0.1747, 0.0057, -0.0297, -0.0026, -0.0045, -0.0004],
    [0.1757, 0.6973, 0.0604, -0.2463, -0.0262, -0.0333, -0.0031],
    [0.0219, -0.1592, 0.8761, -0.0622, -0.0504, -0.0266, 0.011],
    [-0.0291, 0.2297, 0.4, 0.4512, -0.1, 0.1691, 0.0169],
    [-0.0101, 0.0321, 0.095, -0.1506, 0.9447, 0.1266, 0.0155],
    [-0.0068, 0.0231, 0.0439, -0.3232, -0.1645, 0.6283, -0.0277],
    [-0.0044, 0.0093, 0.116, -0.085, 0.00008, -0.1766, 0.8136],
]
_B1 = [[0.3094], [-0.2819], [-0.0608], [0.0912], [0.0185], [0.0199], [0.0061]]
_C1 = [
    [0.3052, 0.2798, -0.0221, 0.0891, 0.0073, 0.0153, 0.0018],
    [0.0134, 0.0259, 0.0453, 0.0533, 0.0381, -0.0397, -0.0108],
    [0.0033, -0.0215, 0.0189, -0.0416, -0.0061, 0.0375, -0.0039],
]
# eq. 24
_A2 = [
    [0.9493, 0.1175, 0.0173, 0.0233],
    [-0.1161, 0.7929, -0.1205, -0.1509],
    [-0.0001, 0.072, 0.9273, -0.2011],
    [0.0238, 0.1573, 0.0285, 0.7314],
]
_B2 = [[0.2595], [0.2232], [-0.0325], [-0.0693]]
_C2 = [
    [-0.00002, -0.00001, -0.00002, -0.00024],
    [0.2402, -0.2215, -0.0502, -0.0687],
    [-0.0002, -0.00053, -0.00049, -0.0011],
]
# eq. 25
_A3 = [
    [0.9485, 0.1204, -0.0134, 0.0261],
    [-0.1184, 0.7981, 0.0779, -0.1711],
    [0.003, -0.0094, 0.9656, 0.1719],
    [0.0225, 0.1825, -0.0783, 0.711],
]
_B3 = [[-0.2574], [-0.2229], [-0.015], [0.0775]]
_C3 = [[-0.00002, -0.00001, -0.0001, -0.00022], [0.0043, -0.0018, -0.0031, -0.0028], [-0.239, 0.2205, -0.0376, 0.0762]]


def channel_models() -> tuple[StateSpaceModel, StateSpaceModel, StateSpaceModel]:
    """The three single-input sub-models of eq. 19 (orders 7, 4, 4), inputs Z, Rx, Ry.

    Examples
    --------
    >>> [g.n_states for g in channel_models()]
    [7, 4, 4]
    """
    out = []
    for name, (A, B, C) in zip(INPUTS, ((_A1, _B1, _C1), (_A2, _B2, _C2), (_A3, _B3, _C3))):
        out.append(StateSpaceModel(A, B, C, np.zeros((3, 1)), DT, (name,), OUTPUTS))
    return tuple(out)  # type: ignore[return-value]


def model() -> StateSpaceModel:
    """The 15-state 3x3 reference model of eq. 20-25 (``D = 0``), ``dt = 0.002`` s.

    Examples
    --------
    >>> g = model()
    >>> g.n_states, g.inputs, g.outputs
    (15, ('Z', 'Rx', 'Ry'), ('z', 'rx', 'ry'))
    """
    import scipy.linalg as sla

    subs = channel_models()
    A = sla.block_diag(*[g.A for g in subs])
    B = sla.block_diag(*[g.B for g in subs])
    C = np.hstack([g.C for g in subs])
    return StateSpaceModel(A, B, C, np.zeros((3, 3)), DT, INPUTS, OUTPUTS)


def _record(u: np.ndarray, name: str, seed: int, noise: bool = True) -> Experiment:
    y = model().simulate(u)
    if noise:
        rng = np.random.default_rng([*noise_entropy(seed, name), 558])
        y = y + NOISE_STD[None, :] * rng.standard_normal(y.shape)
    return Experiment(u, y, DT, INPUTS, OUTPUTS, INPUT_UNITS, OUTPUT_UNITS, name=name)


def _t(duration: float) -> np.ndarray:
    return np.arange(int(round(duration / DT))) * DT


def _chirp_input(channel: int, amplitude: float, offset: float, duration: float = 10.0) -> np.ndarray:
    t = _t(duration)
    f0, f1 = 1.0, 100.0
    phase = 2 * np.pi * (f0 * t + 0.5 * (f1 - f0) / duration * t**2)
    u = np.zeros((t.size, 3))
    u[:, channel] = offset + amplitude * np.sin(phase)
    return u


def _random_input(channels: list[int], peak: float | list[float], seed: int, duration: float) -> np.ndarray:
    n = int(round(duration / DT))
    rng = np.random.default_rng([seed, 100])
    u = np.zeros((n, 3))
    peaks = [peak] * len(channels) if np.isscalar(peak) else list(peak)
    f = np.fft.rfftfreq(n, DT)
    keep = (f >= 1.0) & (f <= 100.0)
    for c, pk in zip(channels, peaks):
        spec = np.fft.rfft(rng.standard_normal(n))
        spec[~keep] = 0.0
        x = np.fft.irfft(spec, n)
        u[:, c] = pk * x / np.max(np.abs(x))
    return u


def _sine_input(channel: int, freq: float, amplitude: float, offset: float, duration: float = 4.0) -> np.ndarray:
    t = _t(duration)
    u = np.zeros((t.size, 3))
    u[:, channel] = offset + amplitude * np.sin(2 * np.pi * freq * t)
    return u


def _chirp(channel: int, amplitude: float, offset: float) -> Callable[..., Experiment]:
    def make(seed: int = 0) -> Experiment:
        seed = experiment_seed(seed, f"chirp-{OUTPUTS[channel]}")
        return _record(_chirp_input(channel, amplitude, offset), f"chirp-{OUTPUTS[channel]}", seed)

    make.__doc__ = f"Chirp 1-100 Hz on {INPUTS[channel]} (amplitude {amplitude}, offset {offset}), 10 s."
    return make


def _random(channel: int, peak: float) -> Callable[..., Experiment]:
    def make(seed: int = 0) -> Experiment:
        seed = experiment_seed(seed, f"random-{OUTPUTS[channel]}")
        return _record(_random_input([channel], peak, seed, 10.0), f"random-{OUTPUTS[channel]}", seed)

    make.__doc__ = f"Band-limited random 1-100 Hz on {INPUTS[channel]}, peak {peak}, 10 s."
    return make


def _sine(channel: int, freq: float) -> Callable[..., Experiment]:
    amp, off = (10.0, 10.0) if channel == 0 else (200.0, 0.0)

    def make(seed: int = 0) -> Experiment:
        seed = experiment_seed(seed, f"sine-{freq:g}hz-{OUTPUTS[channel]}")
        return _record(_sine_input(channel, freq, amp, off), f"sine-{freq:g}hz-{OUTPUTS[channel]}", seed)

    make.__doc__ = f"{freq:g} Hz sinusoid on {INPUTS[channel]} (amplitude {amp}, offset {off}), 4 s."
    return make


def _band_limited(seed: int = 0) -> Experiment:
    """All three inputs at once: independent band-limited random 1-100 Hz, 20 s."""
    seed = experiment_seed(seed, "band-limited")
    return _record(_random_input([0, 1, 2], [20.0, 200.0, 200.0], seed, 20.0), "band-limited", seed)


def _prbs(seed: int = 0) -> Experiment:
    """All three inputs at once: random binary (white) sequences, 10 um / 100 urad, 20 s."""
    seed = experiment_seed(seed, "prbs")
    n = int(round(20.0 / DT))
    rng = np.random.default_rng([seed, 200])
    u = np.where(rng.random((n, 3)) < 0.5, -1.0, 1.0) * np.array([10.0, 100.0, 100.0])
    return _record(u, "prbs", seed)


def combined_input(duration: float = 6.0) -> np.ndarray:
    """Section 3.4 experiment 1 (and the linearity check of section 3.1), shape (n, 3)."""
    t = _t(duration)
    u = np.zeros((t.size, 3))
    u[:, 0] = 20.0 + 20.0 * np.sin(2 * np.pi * 1.0 * t)
    u[:, 1] = np.where(t >= 2.0, 200.0 * np.sin(2 * np.pi * 2.0 * (t - 2.0)), 0.0)
    u[:, 2] = np.where(t >= 3.0, 100.0, 0.0)
    return u


def _combined(seed: int = 0) -> Experiment:
    """Section 3.4 experiment 1: the three references applied together, 6 s."""
    seed = experiment_seed(seed, "combined")
    return _record(combined_input(), "combined", seed)


EXPERIMENTS: dict[str, Callable[..., Experiment]] = {
    "chirp-z": _chirp(0, 20.0, 20.0),
    "chirp-rx": _chirp(1, 200.0, 0.0),
    "chirp-ry": _chirp(2, 200.0, 0.0),
    "random-z": _random(0, 40.0),
    "random-rx": _random(1, 200.0),
    "random-ry": _random(2, 200.0),
    "band-limited": _band_limited,
    "prbs": _prbs,
    "combined": _combined,
}
for _f in (1.0, 5.0, 10.0):
    for _c in range(3):
        EXPERIMENTS[f"sine-{_f:g}hz-{OUTPUTS[_c]}"] = _sine(_c, _f)
