"""Figures (matplotlib, Agg backend; nothing here opens a window).

=========================  ==============================================================
``bode_figure``            Bode magnitude/phase grid of several MIMO responses, with bands
``pzmap_figure``           pole-zero map of one or more models
``time_overlay_figure``    measured vs predicted outputs with error traces
=========================  ==============================================================

``bode_figure`` is :mod:`.bode`, the one Bode figure.  Method-specific figures live beside
these: ``plots.frf`` (a measured FRF with its std band and coherence, drawn by
``bode_figure``: ``FrequencyResponse.plot``), ``plots.subspace``, ``plots.closedloop``,
``plots.hysteresis``, ``plots.records``, ``plots.residuals``; ``plots.style`` holds the
shared axes helpers; ``plots.scale`` gives every figure its magnitude units, log limits
(a millionth of the peak at the bottom) and zoom windows for long records.
"""

from .bode import bode_figure
from .lti import pzmap_figure, time_overlay_figure

__all__ = ["bode_figure", "pzmap_figure", "time_overlay_figure"]
