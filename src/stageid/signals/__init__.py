"""Excitation signals for identifying precision stages.

Every generator returns a float ndarray of shape (n_samples,) (or (n_samples,
n_channels) when ``n_channels`` is given), takes its sample time as ``dt`` in seconds,
is deterministic for a given ``seed`` (``np.random.default_rng(seed)``), accepts
``limits=(lo, hi)`` and raises :class:`~stageid.SignalError` instead of clipping when the
signal would leave them.  A record of ``duration`` seconds has ``round(duration / dt)``
samples at ``t = k dt`` (end point excluded).

Swept sines (``sweeps``)
========================
``chirp``                linear or logarithmic chirp ``offset + amplitude sin(phi(t))``
``log_chirp``            logarithmic chirp (``chirp(method="logarithmic")``)

Broadband random (``random``)
=============================
``band_limited_random``  Gaussian noise with no FFT energy outside ``[f_low, f_high]``
``prbs``                 maximum-length (LFSR) or random binary sequence, multi-channel

Periodic (``periodic``, ``multisine``, ``multisine_design``)
============================================================
``sine``                 sine wave
``triangle``             triangle wave in phase with ``sine``
``multisine``            random-phase or Schroeder multisine: detection lines, realisations, MIMO
``multisine_lines``      the FFT lines inside a multisine's band
``multisine_plan``       excited and detection lines, amplitudes, experiments of a design

Hysteresis identification (``hysteresis``)
==========================================
``decaying_sine``        sine shrinking cycle by cycle from full range (nested minor loops)
``decaying_triangle``    the same with a triangle
``decay_envelope``       the per-cycle amplitudes of the two above
``forc_staircase``       first-order-reversal cycles up to maxima rising in equal steps

Helpers (``_common``) and registry (``registry``)
=================================================
``time_vector``          sample instants ``k dt``
``crest_factor``         peak / RMS of the zero-mean part
``check_limits``         raise ``SignalError`` when a signal leaves ``(lo, hi)``
``SIGNAL_KINDS``         kebab-case kind name -> generator (for ``stageid signal KIND``)
``generate``             call a generator by kind name, checking kind and parameter names
``signal_parameters``    parameters of a kind's generator (to build command-line options)
"""

from ._common import check_limits, crest_factor, time_vector
from .hysteresis import decay_envelope, decaying_sine, decaying_triangle, forc_staircase
from .multisine import multisine, multisine_lines, multisine_plan
from .periodic import sine, triangle
from .random import band_limited_random, prbs
from .registry import SIGNAL_KINDS, generate, signal_parameters
from .sweeps import chirp, log_chirp

__all__ = [
    "chirp",
    "log_chirp",
    "band_limited_random",
    "prbs",
    "sine",
    "triangle",
    "multisine",
    "multisine_lines",
    "multisine_plan",
    "decaying_sine",
    "decaying_triangle",
    "decay_envelope",
    "forc_staircase",
    "time_vector",
    "crest_factor",
    "check_limits",
    "SIGNAL_KINDS",
    "generate",
    "signal_parameters",
]
