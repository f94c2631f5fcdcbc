"""Reference piezo actuator with asymmetric, rate-independent hysteresis over -500...500 V.

A stand-in for the actuator of the modified Prandtl-Ishlinskii letter (Figs. 5, 10): about
8 % hysteresis over the full -500...500 V range, asymmetric loops, loops flatter (concave)
near the origin, output of a few micrometres.  It is deliberately *not* a PI model of the
kind being identified, so identification has something to get wrong:

* the hysteresis is a fine bank of ``n_fine`` (default 80) coupled-play operators with
  thresholds at ``(j + 1/2) 500 / n_fine`` V -- none of them on the 25 V grid a 20-operator
  model uses -- whose ratios ``rc/r``, ``ra/r``, ``rb/ra`` vary *nonlinearly* with the
  threshold (``c(t) = c0 + c1 t^2`` and likewise, ``t = r / 500``), and whose weights decay
  like ``exp(-density t)`` (a continuous-density approximation of a Preisach-type model);
* the normalised sum ``s = (lin x + sum_j w_j z_j) / 500`` passes through a static
  asymmetric polynomial ``y = gain (s + quad s^2 + cubic s^3)``, which no sum of
  (coupled-)play operators represents;
* an optional measurement noise (seeded) and optional linear stage dynamics after the
  hysteresis: a second-order low-pass with unity DC gain, natural frequency ``f_n`` and
  damping ``zeta`` (discretised by ZOH at the record's ``dt``).

With the defaults: output -1.60...+2.18 um, hysteresis of the full-range loop 9.3 % (the
letter: 8.3 %); a classical PI with 20 operators fits the decaying-triangle record to 5.0 %
of range (the letter: 5.31 %); see ``tests/test_plants_piezo_actuator.py`` and
``studies/hysteresis/RESULTS.md`` for the numbers.

``model()`` returns the actuator (an immutable object with ``inputs``, ``outputs`` and
``simulate(u, dt=None)``); ``EXPERIMENTS`` maps names to simulated records:

=====================  ==================================================================
``decaying-triangle``  identification input like the letter's Fig. 4: 1 Hz triangle from
                       +-500 V decaying linearly over 10 cycles, 1 kHz
``triangle-1hz``       validation: 1 Hz +-450 V triangle, 3 cycles, 1 kHz
``decaying-sine``      validation with nested minor loops: 0.5 Hz sine from 480 V decaying
                       exponentially over 6 cycles, 1 kHz
=====================  ==================================================================
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .._errors import ModelError, ModelFormatError
from ..checks import is_real, shown
from ..data.experiment import Experiment
from ..hysteresis.models.pi import ModifiedPIModel
from ..hysteresis.models.serialization import register_kind
from ..hysteresis.stage.dynamics import zoh_resonance
from . import experiment_seed, noise_entropy

__all__ = ["PiezoActuator", "model", "EXPERIMENTS", "open_loop_gain"]


V_MAX = 500.0


@dataclass(frozen=True)
class PiezoActuator:
    """Asymmetric rate-independent piezo actuator (see module notes for the equations).

    Parameters
    ----------
    n_fine : int
        Number of fine coupled-play operators.
    density : float
        Weight decay ``exp(-density t)`` over the normalised threshold ``t``.
    hysteresis_weight : float
        Sum of the fine operators' weights (relative to the linear part ``lin``).
    lin : float
        Weight of the linear (``r = 0``) part.
    c, a, b : (float, float)
        Ratio laws ``rc/r = c0 + c1 t^2``, ``ra/r = a0 + a1 t^2``, ``rb/ra = b0 + b1 t^2``.
    gain : float
        Output scale in um.
    quad, cubic : float
        Static polynomial ``s + quad s^2 + cubic s^3``.
    noise : float
        Standard deviation of additive measurement noise in um (experiments only).
    f_n, zeta : float or None
        Linear stage dynamics after the hysteresis; ``None`` (default) for none.

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.plants.piezo_actuator import model
    >>> act = model()
    >>> act.simulate(np.array([0.0, 500.0, 0.0, -500.0])).shape
    (4, 1)
    """

    n_fine: int = 80
    density: float = 1.2
    hysteresis_weight: float = 1.0
    lin: float = 1.45
    c: tuple[float, float] = (0.25, 0.35)
    a: tuple[float, float] = (1.6, -0.5)
    b: tuple[float, float] = (0.55, 0.3)
    gain: float = 0.95
    quad: float = 0.06
    cubic: float = 0.0
    noise: float = 0.0
    f_n: float | None = None
    zeta: float = 0.3
    inputs: tuple[str, ...] = ("V",)
    outputs: tuple[str, ...] = ("y",)
    _bank: object = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if int(self.n_fine) < 2:
            raise ModelError(f"`n_fine` of PiezoActuator must be >= 2; got {self.n_fine}.")
        n = int(self.n_fine)
        t = (np.arange(n) + 0.5) / n
        r = t * V_MAX
        c = np.clip(self.c[0] + self.c[1] * t**2, 0.0, 1.0)
        a = np.clip(self.a[0] + self.a[1] * t**2, 0.0, None)
        b = np.clip(self.b[0] + self.b[1] * t**2, 0.0, 1.0)
        w = np.exp(-self.density * t)
        w = self.hysteresis_weight * w / w.sum()
        ra = a * r
        bank = ModifiedPIModel(
            r=np.r_[0.0, r], rc=np.r_[0.0, c * r], ra=np.r_[0.0, ra], rb=np.r_[0.0, b * ra], weights=np.r_[self.lin, w]
        )
        object.__setattr__(self, "_bank", bank)

    _PARAMS = (
        "n_fine",
        "density",
        "hysteresis_weight",
        "lin",
        "c",
        "a",
        "b",
        "gain",
        "quad",
        "cubic",
        "noise",
        "f_n",
        "zeta",
    )

    def to_dict(self) -> dict:
        """The ``stageid.hysteresis/1`` dictionary (kind ``"piezo-actuator"``: the parameters)."""
        params = {}
        for name in self._PARAMS:
            v = getattr(self, name)
            params[name] = list(v) if isinstance(v, tuple) else v
        return {
            "format": "stageid.hysteresis/1",
            "kind": "piezo-actuator",
            "inputs": list(self.inputs),
            "outputs": list(self.outputs),
            "parameters": params,
        }

    @classmethod
    def from_dict(cls, d: dict) -> PiezoActuator:
        """Inverse of :meth:`to_dict`; :class:`~stageid.ModelFormatError` names a bad field.

        Registered with :func:`stageid.hysteresis.models.serialization.register_kind` for the kind
        ``"piezo-actuator"``; every parameter is a JSON number, a list of two, or null.
        """
        params = d.get("parameters")
        if not isinstance(params, dict) or set(params) - set(cls._PARAMS):
            raise ModelFormatError(
                f"`parameters` of a piezo-actuator model must be an object with keys among {', '.join(cls._PARAMS)}."
            )
        for key, v in params.items():
            if not (v is None or is_real(v) or (isinstance(v, list) and len(v) == 2 and all(is_real(e) for e in v))):
                raise ModelFormatError(f"`parameters.{key}` must be a number, a list of two or null; got {shown(v)}.")
        kw = {k: tuple(v) if isinstance(v, list) else v for k, v in params.items()}
        try:
            return cls(**kw, inputs=tuple(d.get("inputs", ["V"])), outputs=tuple(d.get("outputs", ["y"])))
        except (TypeError, ValueError) as exc:
            raise ModelFormatError(f"bad piezo-actuator parameters: {exc}") from None

    def hysteresis(self, u: object) -> np.ndarray:
        """The normalised hysteresis ``s`` (before the static polynomial), shape (n_samples,)."""
        return self._bank.simulate(u)[:, 0] / V_MAX

    def simulate(self, u: object, dt: float | None = None) -> np.ndarray:
        """Displacement in um for a drive record in volts, from the demagnetised state at 0 V.

        Parameters
        ----------
        u : array_like of shape (n_samples, 1) or (n_samples,)
        dt : float, optional
            Sample time; needed only when the actuator has linear dynamics (``f_n``).

        Returns
        -------
        ndarray of shape (n_samples, 1)
        """
        s = self.hysteresis(u)
        y = self.gain * (s + self.quad * s**2 + self.cubic * s**3)
        if self.f_n is not None:
            if dt is None:
                raise ModelError("this actuator has linear dynamics (f_n set); `dt` is required.")
            y = _lowpass(y, float(dt), float(self.f_n), float(self.zeta))
        return y[:, None]


def _lowpass(y: np.ndarray, dt: float, f_n: float, zeta: float) -> np.ndarray:
    from scipy.signal import lfilter

    return lfilter(*zoh_resonance(f_n, zeta, dt), y)


def model() -> PiezoActuator:
    """The reference actuator (default parameters)."""
    return PiezoActuator()


def open_loop_gain(actuator: PiezoActuator | None = None) -> float:
    """Nominal gain in um/V for uncompensated drive: output range over input range of the +-500 V loop."""
    from ..signals import triangle

    act = actuator or model()
    u = triangle(1.0, 2, 1e-3, amplitude=V_MAX)
    y = act.simulate(u)[:, 0]
    return float(np.ptp(y) / np.ptp(u))


def _experiment(u: np.ndarray, dt: float, name: str, seed: int, actuator: PiezoActuator | None = None) -> Experiment:
    act = actuator or model()
    y = act.simulate(u, dt)[:, 0]
    if act.noise > 0:
        y = y + np.random.default_rng(noise_entropy(seed, name)).normal(0.0, act.noise, size=y.size)
    return Experiment(
        u=u[:, None],
        y=y[:, None],
        dt=dt,
        input_names=act.inputs,
        output_names=act.outputs,
        input_units=("V",),
        output_units=("um",),
        name=name,
    )


def _decaying_triangle(seed: int = 0) -> Experiment:
    from ..signals import decaying_triangle

    seed = experiment_seed(seed, "decaying-triangle")
    return _experiment(decaying_triangle(1.0, 10, 1e-3, amplitude=V_MAX), 1e-3, "decaying-triangle", seed)


def _triangle(seed: int = 0) -> Experiment:
    from ..signals import triangle

    seed = experiment_seed(seed, "triangle-1hz")
    return _experiment(triangle(1.0, 3, 1e-3, amplitude=450.0), 1e-3, "triangle-1hz", seed)


def _decaying_sine(seed: int = 0) -> Experiment:
    from ..signals import decaying_sine

    seed = experiment_seed(seed, "decaying-sine")
    u = decaying_sine(0.5, 6, 1e-3, amplitude=480.0, decay="exponential", final_fraction=0.2)
    return _experiment(u, 1e-3, "decaying-sine", seed)


EXPERIMENTS: dict[str, Callable[..., Experiment]] = {
    "decaying-triangle": _decaying_triangle,
    "triangle-1hz": _triangle,
    "decaying-sine": _decaying_sine,
}


register_kind("piezo-actuator", PiezoActuator.from_dict)
