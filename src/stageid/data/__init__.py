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

Modules:

=====================  ==========================================================
``experiment``         the Experiment container and its sample checks
``table``              the Table, and ``assemble_table`` that every reader ends in
``columns``            the readers' shared rules: names, finite samples, the ``t`` column
``sampling``           the sample-time rule: a period from a time column, periods compared
``io``                 the front door of the readers and writers, by extension
``files``              what the formats share: opening and sniffing a file, column lists
``csv_format``         CSV records (``name [unit]`` headers)
``npz_format``         NumPy ``.npz`` records
``mat_format``         MATLAB ``.mat`` records (v4-v7 through scipy, v7.3 through h5py)
``mat_responses``      measured frequency responses in a ``.mat`` file
``chunked``            records larger than memory (HDF5, Zarr, ``.npy``), read range by range
``preprocess``         offset/trend removal, split, merge, decimation
``datasets``           loaders of the real records in ``../shared/data``
=====================  ==========================================================
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
