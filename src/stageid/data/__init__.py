"""Measured records: the immutable :class:`Experiment` container, file readers and writers,
and preprocessing (offset/trend removal, train/validation split, merging).

=====================  ==========================================================
``Experiment``         one sampled input/output record, time-first arrays
``as_experiments``     normalise one or several experiments into a checked tuple
``Table``              named columns read from a file; ``.experiment(inputs, outputs)``
``read_table``         read ``.csv`` / ``.npz`` / ``.mat`` into a Table (by extension)
``read_csv``           read a CSV file into a Table
``read_npz``           read a NumPy ``.npz`` archive into a Table
``read_mat``           read a MATLAB ``.mat`` file (v5 or v7.3) into a Table
``write_csv``          write columns, a Table or an Experiment to CSV (atomic, exact)
``write_npz``          the same as a NumPy ``.npz`` archive
``remove_offset``      subtract means or linear trends; returns ``(experiment, Offsets)``
``Offsets``            the removed trend, to re-apply or restore
``split``              identification / validation split in time
``merge``              several records of one system as a checked tuple
``decimate``           anti-aliased down-sampling
=====================  ==========================================================

The sampling period of a record follows one rule, in :mod:`stageid.data.sampling`: the
least-squares period of a time column, uniformity to a stated tolerance, periods of records
compared to one relative tolerance.

Loaders for the real records in ``../shared/data`` live in :mod:`stageid.data.datasets`;
the readers and writers are in :mod:`stageid.data.io` (one module per format family:
:mod:`~stageid.data.csv_format`, :mod:`~stageid.data.npz_format`, :mod:`~stageid.data.mat_format`).
"""

from .experiment import Experiment, as_experiments
from .io import read_csv, read_mat, read_npz, read_table, write_csv, write_npz
from .preprocess import Offsets, decimate, merge, remove_offset, split
from .table import Table

__all__ = [
    "Experiment",
    "as_experiments",
    "Table",
    "read_table",
    "read_csv",
    "read_npz",
    "read_mat",
    "write_csv",
    "write_npz",
    "remove_offset",
    "Offsets",
    "split",
    "merge",
    "decimate",
]
