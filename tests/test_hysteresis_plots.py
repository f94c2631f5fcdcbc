"""Hysteresis figures build on the Agg backend and carry the expected content."""

import numpy as np

from stageid.plots.hysteresis import loop_figure, model_errors_figure, tracking_figure


def test_figures():
    t = np.linspace(0, 1, 200)
    u = np.sin(2 * np.pi * t)
    fig = loop_figure(u, {"a": u**3, "b": u}, title="loops")
    assert len(fig.axes[0].lines) == 2 and fig.axes[0].get_title() == "loops"
    fig = model_errors_figure(t, {"e": 0.1 * u})
    assert fig.axes[0].get_xlabel() == "time [s]"
    fig = tracking_figure(t, u, 0.9 * u, title="x")
    assert len(fig.axes) == 2 and len(fig.axes[0].lines) == 3
    np.testing.assert_allclose(fig.axes[0].lines[2].get_ydata(), -0.1 * u)
