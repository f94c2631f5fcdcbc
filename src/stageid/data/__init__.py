"""Measured records: the immutable :class:`Experiment` container, file readers and writers,
and preprocessing (offset/trend removal, train/validation split, merging).

=====================  ==========================================================
``Experiment``         one sampled input/output record, time-first arrays
``as_experiments``     normalise one or several experiments into a checked tuple
=====================  ==========================================================
"""

from .experiment import Experiment, as_experiments

__all__ = ["Experiment", "as_experiments"]
