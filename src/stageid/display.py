"""Notebook display of models, frequency responses and results: a short ``repr`` and rich HTML.

Every displayable class calls two functions of this module: :func:`short_repr` for its
``__repr__`` (one line naming what matters, never arrays) and :func:`html_repr` for its
``_repr_html_`` (a compact table of the same facts and an inline SVG figure: the Bode magnitude
of an LTI model, a frequency response or a result's model with its +-2 std band, the major loop
of a hysteresis model). The facts come from one place, :func:`facts`, so the two cannot
disagree. Objects are recognised by their class name and attributes: this module imports
nothing else of stageid, so the lowest layers can use it.

Examples
--------
>>> from stageid.models import StateSpaceModel
>>> g = StateSpaceModel([[0.9]], [[1.0]], [[1.0]], [[0.0]], dt=0.01, inputs=["u"], outputs=["y"])
>>> facts(g)[:3]
[('states', '1'), ('inputs', 'u'), ('outputs', 'y')]
>>> html = html_repr(g)
>>> html.count("<table"), html.count("<svg")
(1, 1)
"""

from __future__ import annotations

import html
import io
from collections.abc import Callable
from typing import Any

import numpy as np

from ._errors import StageIdError

__all__ = ["facts", "short_repr", "html_repr", "figure_svg", "HtmlRepr"]

MAX_PANELS = 3  # a Bode figure shows at most 3 x 3 entries: a notebook cell, not a report
N_POINTS = 60  # frequencies of a curve: enough for a thumbnail, and the SVG grows with them


def _fmt(value: float) -> str:
    return f"{value:.4g}"


def _names(names: Any) -> str:
    return ", ".join(str(n) for n in names) or "-"


def _sample_time(dt: float | None) -> str:
    return "continuous" if dt is None else f"{_fmt(dt)} s"


def _lti_facts(model: Any) -> list[tuple[str, str]]:
    rows = [("states", str(model.n_states))] if hasattr(model, "n_states") else []
    rows += [("inputs", _names(model.inputs)), ("outputs", _names(model.outputs)), ("dt", _sample_time(model.dt))]
    poles = np.asarray(model.poles()).ravel()
    if poles.size:
        stable = np.all(np.abs(poles) < 1) if model.dt is not None else np.all(poles.real < 0)
        rows.append(("stable", "yes" if stable else "no"))
    return rows


def _frd_facts(frd: Any) -> list[tuple[str, str]]:
    extras = [w for w, v in (("std", frd.std), ("coherence", frd.coherence)) if v is not None]
    return [
        ("frequencies", f"{frd.n_freqs}, {_fmt(frd.freqs[0])}-{_fmt(frd.freqs[-1])} Hz"),
        ("inputs", _names(frd.inputs)),
        ("outputs", _names(frd.outputs)),
        ("with", " and ".join(extras) or "-"),
    ]


def _model_line(model: Any) -> str:
    states = f"{model.n_states} states, " if hasattr(model, "n_states") else ""
    return f"{type(model).__name__}({states}{len(model.outputs)}x{len(model.inputs)}, {_sample_time(model.dt)})"


def _hankel_facts(result: Any) -> list[tuple[str, str]]:
    horizons = sorted({int(h) for h in np.atleast_1d(result.horizon)})
    return [("model", _model_line(result.model)), ("horizon", ", ".join(map(str, horizons)))]


def _frd_result_facts(result: Any) -> list[tuple[str, str]]:
    return [
        ("model", _model_line(result.model)),
        ("order", str(result.order)),
        ("delay", str(result.delay)),
        ("largest error", f"{_fmt(result.max_error)} of the peak"),
    ]


def _closedloop_facts(result: Any) -> list[tuple[str, str]]:
    poles = np.sort(np.asarray(result.plant_unstable_poles).real)
    return [
        ("plant", _model_line(result.model)),
        ("unstable poles", ", ".join(_fmt(p) for p in poles) or "none"),
        ("band", f"{_fmt(result.band[0])}-{_fmt(result.band[1])} Hz"),
    ]


def _hysteresis_fit_facts(fit: Any) -> list[tuple[str, str]]:
    rows = [("model", short_repr(fit.model))]
    rows.append(("max error", ", ".join(f"{_fmt(e)} %" for e in np.atleast_1d(fit.max_error_percent))))
    rows.append(("RMS error", ", ".join(f"{_fmt(e)} %" for e in np.atleast_1d(fit.rms_error_percent))))
    return rows


def _hysteresis_facts(model: Any) -> list[tuple[str, str]]:
    rows = [("kind", str(model.kind))]
    if hasattr(model, "hysteresis"):  # a stage: hysteresis -> creep -> dynamics
        dynamics = model.dynamics
        rows += [
            ("hysteresis", short_repr(model.hysteresis)),
            ("dynamics", "none" if dynamics is None else f"{dynamics.n_states} states, dt {_fmt(dynamics.dt)} s"),
        ]
        return rows
    count = ("levels", model.n_levels) if hasattr(model, "n_levels") else ("operators", model.n_operators)
    rows.append((count[0], str(count[1])))
    if model.input_limits is not None:
        rows.append(("input limits", f"{_fmt(model.input_limits[0])} to {_fmt(model.input_limits[1])}"))
    rows.append(("creep", "yes" if getattr(model, "creep", None) is not None else "no"))
    return rows


def _test_facts(test: Any) -> list[tuple[str, str]]:
    return [
        ("passed", "yes" if test.passed else "no"),
        ("chi2", f"{_fmt(test.statistic)} (limit {_fmt(test.threshold)}, {test.dof} lags)"),
        ("p-value", _fmt(test.p_value)),
        ("samples", str(test.n_samples)),
    ]


def _outcome_facts(outcome: Any) -> list[tuple[str, str]]:
    rows = [("name", outcome.name), ("status", outcome.status)]
    if outcome.seconds is not None:
        rows.append(("seconds", _fmt(outcome.seconds)))
    if outcome.error:
        rows.append(("error", outcome.error))
    return rows


def _report_facts(report: Any) -> list[tuple[str, str]]:
    kinds = [block.kind for block in report.blocks]
    return [
        ("title", report.title),
        ("sections", str(kinds.count("h"))),
        ("tables", str(kinds.count("table"))),
        ("figures", str(report.n_figures)),
    ]


FACTS: dict[str, Callable[[Any], list[tuple[str, str]]]] = {
    "StateSpaceModel": _lti_facts,
    "TransferMatrix": _lti_facts,
    "FrequencyResponse": _frd_facts,
    "HankelMAPResult": _hankel_facts,
    "FRDResult": _frd_result_facts,
    "ClosedLoopResult": _closedloop_facts,
    "HysteresisResult": _hysteresis_fit_facts,
    "PreisachResult": _hysteresis_fit_facts,
    "StageResult": _hysteresis_fit_facts,
    "PIModel": _hysteresis_facts,
    "ModifiedPIModel": _hysteresis_facts,
    "PreisachModel": _hysteresis_facts,
    "StageModel": _hysteresis_facts,
    "CorrelationTest": _test_facts,
    "Outcome": _outcome_facts,
    "Report": _report_facts,
}


def facts(obj: Any) -> list[tuple[str, str]]:
    """The ``(label, text)`` pairs that describe ``obj`` in its repr and its HTML table.

    Raises
    ------
    TypeError
        For an object of a class this module does not describe.
    """
    describe = FACTS.get(type(obj).__name__)
    if describe is None:
        raise TypeError(f"no display for {type(obj).__name__}; expected one of {', '.join(FACTS)}.")
    return describe(obj)


def short_repr(obj: Any) -> str:
    """One line: the class name and :func:`facts`, e.g. ``HankelMAPResult(model=..., horizon=8)``."""
    return f"{type(obj).__name__}({', '.join(f'{label}={text}' for label, text in facts(obj))})"


def figure_svg(fig: Any) -> str:
    """A matplotlib figure as inline SVG markup (without the XML prologue)."""
    import matplotlib

    buffer = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "none"}):  # text as text: a tenth of the size of glyph paths
        fig.savefig(buffer, format="svg")  # the figure is laid out already (tight_layout)
    text = buffer.getvalue()
    return text[text.find("<svg") :]


def html_repr(obj: Any) -> str:
    """A compact table of :func:`facts` and, where there is one, an inline SVG figure.

    A :class:`~stageid.report.Report` shows its own content instead: the body of its HTML
    document (sections, tables, embedded figures), without the page style.
    """
    if type(obj).__name__ == "Report":
        document = obj.to_html()
        return f"<div>{document[document.index('<body>') + 6 : document.rindex('</body>')]}</div>"
    rows = "".join(
        f"<tr><th style='text-align:left;padding-right:1em'>{html.escape(label)}</th>"
        f"<td style='text-align:left'>{html.escape(text)}</td></tr>"
        for label, text in facts(obj)
    )
    table = f"<table><caption style='text-align:left'><b>{type(obj).__name__}</b></caption>{rows}</table>"
    fig = _figure(obj)
    if fig is None:
        return f"<div>{table}</div>"
    return (
        "<div style='display:flex;flex-wrap:wrap;gap:1em;align-items:flex-start'>"
        f"<div>{table}</div><div style='max-width:36em'>{figure_svg(fig)}</div></div>"
    )


def _figure(obj: Any) -> Any:
    """The figure that goes with ``obj``, or None when it has none."""
    name = type(obj).__name__
    if name in ("StateSpaceModel", "TransferMatrix"):
        return _bode(obj, _grid(obj), None)
    if name == "FrequencyResponse":
        return _bode(None, obj.freqs, obj)
    if name == "ClosedLoopResult":
        return _bode(obj.model, np.geomspace(obj.band[0], obj.band[1], N_POINTS), None)
    if name in ("HankelMAPResult", "FRDResult"):
        freqs = _grid(obj.model)
        return _bode(obj.model, freqs, _band(obj, freqs))
    if name in ("PIModel", "ModifiedPIModel", "PreisachModel", "StageModel"):
        return _loop(obj)
    if name in ("HysteresisResult", "PreisachResult", "StageResult"):
        return _loop(obj.model)
    return None


def _band(result: Any, freqs: np.ndarray) -> Any:
    """The result's response with its std, or None when the result cannot give one."""
    try:
        return result.response_uncertainty(freqs)
    except (StageIdError, ValueError, np.linalg.LinAlgError):  # a band is a bonus; the table still shows the result
        return None


def _grid(model: Any) -> np.ndarray:
    """Frequencies [Hz] that show a model: up to 0.9 x Nyquist, or around its poles."""
    if model.dt is not None:
        nyquist = 0.5 / model.dt
        return np.geomspace(nyquist * 1e-3, 0.9 * nyquist, N_POINTS)
    poles = np.abs(np.asarray(model.poles()).ravel()) / (2 * np.pi)
    poles = poles[poles > 0]
    low, high = (poles.min() / 10, poles.max() * 10) if poles.size else (0.01, 100.0)
    return np.geomspace(low, high, N_POINTS)


def _bode(model: Any, freqs: np.ndarray, frd: Any) -> Any:
    """Bode magnitude of the first 3 x 3 entries: the data (with +-2 std) and/or the model."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import NullLocator

    source = frd if frd is not None else model
    n_out, n_in = min(len(source.outputs), MAX_PANELS), min(len(source.inputs), MAX_PANELS)
    fig = Figure(figsize=(1.9 * n_in + 0.8, 1.5 * n_out + 0.6))
    axes = fig.subplots(n_out, n_in, squeeze=False, sharex=True)
    response = model.frequency_response(freqs) if model is not None else None
    shown = _thinned(frd.n_freqs) if frd is not None else None
    for i in range(n_out):
        for j in range(n_in):
            ax = axes[i, j]
            if frd is not None:
                f, magnitude = frd.freqs[shown], np.abs(frd.response[shown, i, j])
                ax.loglog(f, magnitude, color="C0", lw=1)
                if frd.std is not None:
                    two_std = 2 * frd.std[shown, i, j]
                    low = np.maximum(magnitude - two_std, magnitude * 1e-3)
                    ax.fill_between(f, low, magnitude + two_std, color="C0", alpha=0.25, lw=0)
            if response is not None:
                ax.loglog(freqs, np.abs(response[:, i, j]), color="C1" if frd is not None else "C0", lw=1)
            ax.set_title(f"{source.inputs[j]} -> {source.outputs[i]}", fontsize=8)
            ax.xaxis.set_minor_locator(NullLocator())  # log axes' minor ticks are most of an SVG's bytes
            ax.yaxis.set_minor_locator(NullLocator())
            ax.tick_params(labelsize=7)
            ax.grid(True, alpha=0.3)
        axes[i, 0].set_ylabel("|G|", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("frequency [Hz]", fontsize=8)
    fig.tight_layout()
    return fig


def _thinned(n_freqs: int) -> np.ndarray:
    """At most ``N_POINTS`` indices of a frequency grid, log-spaced: the picture, not every line."""
    if n_freqs <= N_POINTS:
        return np.arange(n_freqs)
    return np.unique(np.geomspace(1, n_freqs, N_POINTS).astype(int) - 1)


def _loop(model: Any) -> Any:
    """The major loop of a hysteresis model: a triangle over its input limits (or -1..1)."""
    from matplotlib.figure import Figure

    rate_independent = getattr(model, "hysteresis", model)
    limits = getattr(rate_independent, "input_limits", None) or getattr(rate_independent, "input_range", None)
    if limits is None and hasattr(rate_independent, "r"):  # a PI model without limits: past its largest threshold
        reach = 1.5 * float(np.max(rate_independent.r)) or 1.0
        limits = (rate_independent.input_offset - reach, rate_independent.input_offset + reach)
    low, high = (float(limits[0]), float(limits[1])) if limits is not None else (-1.0, 1.0)
    up = np.linspace(low, high, 200)
    u = np.concatenate([up, up[::-1], up])
    y = np.asarray(model.simulate(u)).reshape(u.size, -1)[:, 0]
    fig = Figure(figsize=(3.2, 2.6))
    ax = fig.subplots()
    ax.plot(u[200:], y[200:], color="C0", lw=1)  # after the first rise: the closed loop
    ax.set_xlabel(f"input {_names(rate_independent.inputs)}", fontsize=8)
    ax.set_ylabel(f"output {_names(rate_independent.outputs)}", fontsize=8)
    ax.set_title("major loop", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


class HtmlRepr:
    """Base of the objects that show in a notebook as :func:`html_repr` (``_repr_html_``)."""

    def _repr_html_(self) -> str:
        return html_repr(self)
