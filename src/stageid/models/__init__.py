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

from ..runtime.lazy import lazy_names

# Names load on first use (PEP 562): a command that only reads or writes a measured response
# (``models.frequency_response``) must not pay for scipy.linalg, which the LTI classes import.
_WHERE = {
    "StateSpaceModel": ".lti",
    "TransferMatrix": ".lti",
    "c2d": ".discretization",
    "d2c": ".discretization",
    "minimal_realization": ".minimal",
    "feedback": ".interconnect",
    "series": ".interconnect",
    "LTI_FORMAT": ".serialization",
    "dumps": ".serialization",
    "loads": ".serialization",
    "load_model": ".serialization",
    "save_model": ".serialization",
}

__all__ = list(_WHERE)


__getattr__, __dir__ = lazy_names(__name__, _WHERE)
