"""LTI model objects and the ``stageid.lti/1`` file format.

========================  ==================================================================
``StateSpaceModel``       immutable MIMO state space, discrete or continuous
``TransferMatrix``        immutable MIMO transfer matrix, [output][input] num/den
``c2d``, ``d2c``          ZOH and Tustin conversions (d2c ZOH by matrix logarithm)
``minimal_realization``   remove uncontrollable/unobservable states (no slycot)
``feedback``, ``series``  interconnections used by the closed-loop tools and plants
``load_model``            read any stageid model file (LTI or registered formats)
``save_model``            write a model file atomically; ``dumps``/``loads`` for text
``frequency_response``    ``FrequencyResponse`` (a measured or computed FRF) and its
                          CSV/NPZ table (``read_frd``); re-exported by :mod:`stageid.frf`
========================  ==================================================================

Layers, each importing only those below it: ``_validate``, ``_kernels``, ``minimal``,
``conversions`` (one-way functions on matrices), ``json_text`` (the file text),
``simulation`` (time responses) -> ``lti`` (both model classes; ``statespace`` and
``transfer`` re-export them) ->
``discretization``, ``interconnect``, ``serialization``; ``frequency_response`` stands apart
(no LTI model class), and ``control_bridge`` turns arrays into python-control objects.
"""

from .discretization import c2d, d2c
from .interconnect import feedback, series
from .lti import StateSpaceModel, TransferMatrix
from .minimal import minimal_realization
from .serialization import LTI_FORMAT, dumps, load_model, loads, save_model

__all__ = [
    "StateSpaceModel",
    "TransferMatrix",
    "c2d",
    "d2c",
    "minimal_realization",
    "feedback",
    "series",
    "LTI_FORMAT",
    "dumps",
    "loads",
    "load_model",
    "save_model",
]
