"""Batch identification: a manifest of stageid command lines run on a Dask cluster.

==========================  ===========================================================
module                      concept
==========================  ===========================================================
:mod:`.manifest`            the ``name,command`` CSV file, its names and words checked
:mod:`.commands`            a row -> a :class:`~.commands.Job` (verb, input paths, output)
:mod:`.state`               content hashes and the state file that lets a rerun skip jobs
:mod:`.runner`              submit, collect, write each output atomically, ``summary.csv``
==========================  ===========================================================

The command is ``stageid batch MANIFEST.csv --out DIR [--scheduler tcp://HOST:PORT]``
(:mod:`stageid.cli.batch`); the cluster comes from :func:`stageid.runtime.cluster.dask_client`.
"""

from .commands import BATCH_VERBS, Job, resolve_job
from .manifest import ManifestRow, read_manifest
from .runner import SUMMARY_COLUMNS, SUMMARY_FILE, Outcome, run_batch
from .state import STATE_FILE

__all__ = [
    "BATCH_VERBS",
    "Job",
    "resolve_job",
    "ManifestRow",
    "read_manifest",
    "Outcome",
    "run_batch",
    "SUMMARY_COLUMNS",
    "SUMMARY_FILE",
    "STATE_FILE",
]
