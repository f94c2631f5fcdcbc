"""The residual-analysis figure of MATLAB ``resid``: autocorrelation of the residual and its
cross-correlation with each input, with the per-lag 99 % bounds as a shaded band."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from .style import subplots

__all__ = ["residual_figure"]


def _stem(ax: Any, test: Any, title: str) -> None:
    lags, r = np.asarray(test.lags), np.asarray(test.correlations)
    ax.axhspan(-test.bound, test.bound, color="tab:blue", alpha=0.15, lw=0, label="per-lag bound")
    ax.vlines(lags, 0, r, color="k", lw=1.0)
    ax.plot(lags, r, "o", ms=3, color="k")
    verdict = "pass" if test.passed else "FAIL"
    ax.set_title(f"{title}  (chi2 {test.statistic:.1f} / {test.threshold:.1f}: {verdict})")
    ax.set_xlabel("lag [samples]")


def residual_figure(output: str, whiteness: Any, independence: Mapping[str, Any]) -> Any:
    """``resid``-style figure of one output: ``r_ee(k)`` on top, ``r_eu(k)`` for each input below.

    Parameters
    ----------
    output : str
        The output's name (titles).
    whiteness : CorrelationTest
    independence : mapping of input name to CorrelationTest

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import numpy as np
    >>> from stageid.validation.residuals import whiteness_test, independence_test
    >>> from stageid.plots.residuals import residual_figure
    >>> rng = np.random.default_rng(0)
    >>> e, u = rng.standard_normal(500), rng.standard_normal(500)
    >>> fig = residual_figure("y", whiteness_test([e]), {"u": independence_test([e], [u])})
    >>> len(fig.axes)
    2
    """
    n = 1 + len(independence)
    fig, axes = subplots(n, 1, figsize=(6.4, 2.2 * n), squeeze=False)
    _stem(axes[0, 0], whiteness, f"autocorrelation of the residual of {output}")
    axes[0, 0].legend(loc="upper right")
    for ax, (name, test) in zip(axes[1:, 0], independence.items()):
        _stem(ax, test, f"cross-correlation {name} -> residual of {output}")
    return fig
