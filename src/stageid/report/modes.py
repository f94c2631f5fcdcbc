"""The modes of a linear model as a table: natural frequency and damping of each pole (pair)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .html import Report

__all__ = ["Mode", "model_modes", "modal_section"]


@dataclass(frozen=True)
class Mode:
    """One mode: a complex pole pair or a real pole, in continuous-time terms."""

    frequency_hz: float
    damping: float
    kind: str


def model_modes(model: Any) -> list[Mode]:
    """The modes of ``model`` (anything with ``poles()`` and ``dt``), lowest frequency first.

    Discrete poles are mapped by ``s = ln(z) / dt``; each conjugate pair is one mode.  A real
    pole at ``z < 0`` (a mode at the Nyquist frequency of the sampling) and a pole at ``z = 0``
    (a pure delay) are named so, not given a damping that means nothing.

    >>> from stageid.models import StateSpaceModel
    >>> w = 2 * np.pi * 100.0
    >>> g = StateSpaceModel([[0, 1], [-w * w, -2 * 0.05 * w]], [[0], [1]], [[1, 0]], [[0]])
    >>> [(round(m.frequency_hz, 3), round(m.damping, 4), m.kind) for m in model_modes(g)]
    [(100.0, 0.05, 'complex pair')]
    """
    dt = getattr(model, "dt", None)
    out = []
    for p in np.asarray(model.poles(), dtype=complex):
        if dt is not None and abs(p) == 0:
            out.append(Mode(float("nan"), float("nan"), "z = 0 (delay)"))
            continue
        s = p if dt is None else np.log(p) / dt
        if dt is not None and abs(p.imag) <= 1e-12 * abs(p) and p.real < 0:
            out.append(Mode(0.5 / dt, float("nan"), "real z < 0 (at Nyquist)"))
            continue
        if s.imag < -1e-9 * abs(s):  # the other half of a pair already counted
            continue
        mag = abs(s)
        kind = "complex pair" if s.imag > 1e-9 * mag else "real"
        out.append(Mode(float(mag / (2 * np.pi)), float(-s.real / mag) if mag > 0 else float("nan"), kind))
    return sorted(out, key=lambda m: (np.isnan(m.frequency_hz), m.frequency_hz))


def modal_section(report: Report, metrics: dict[str, Any], model: Any, level: int = 3, prefix: str = "") -> None:
    """A table of the model's modes (frequency [Hz], damping, kind) and ``modes/...`` metrics."""
    modes = model_modes(model)
    report.section("Modes of the identified model", level)
    report.table(
        ["mode", "frequency [Hz]", "damping [-]", "kind"],
        [[k + 1, m.frequency_hz, m.damping, m.kind] for k, m in enumerate(modes)],
        caption="Natural frequency and damping ratio of every pole pair"
        + ("" if getattr(model, "dt", None) is None else " (discrete poles mapped by s = ln(z) / Ts)"),
    )
    metrics[f"{prefix}modes/frequency_hz"] = [m.frequency_hz for m in modes]
    metrics[f"{prefix}modes/damping"] = [m.damping for m in modes]
