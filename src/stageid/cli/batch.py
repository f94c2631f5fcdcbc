"""``stageid batch``: run a manifest of stageid command lines on a Dask cluster."""

from __future__ import annotations

import os
import threading
import warnings

import click

from .._errors import DataError
from ._common import say
from .outputs import check_output_folder
from .progress import progress

# One stageid command at a time per worker process: the command line keeps per-process state
# (its message buffer, the warning filters, sys.stdout/sys.stderr while a job runs), so jobs on
# a worker with several threads wait for each other instead of mixing their messages.
_ONE_COMMAND_AT_A_TIME = threading.Lock()


@click.command(
    "batch",
    epilog="""
\b
Manifest (CSV; paths relative to its folder; other columns are ignored):
  name,command
  unit7,identify statespace unit7.csv --inputs Z,Rx,Ry --outputs z,rx,ry --order 6
  unit7-frf,frf unit7.csv --inputs Z --outputs z --segment 1024
\b
Examples:
  stageid batch fleet.csv --out models/                       # local cluster, one worker per core
  stageid batch fleet.csv --out models/ --workers 2
  stageid batch fleet.csv --out models/ --scheduler tcp://10.0.0.5:8786
""",
)
@click.argument("manifest_path", metavar="MANIFEST.csv", type=click.Path(dir_okay=False))
@click.option(
    "--out",
    "out_dir",
    required=True,
    type=click.Path(file_okay=False),
    help="Folder for DIR/<name>.json|.csv and summary.csv (created; its parent must exist).",
)
@click.option(
    "--scheduler", default=None, help="tcp://HOST:PORT of a running Dask scheduler (default: a local cluster)."
)
@click.option(
    "--workers",
    "n_workers",
    type=click.IntRange(min=1),
    default=None,
    help="Worker processes of the local cluster (default: one per CPU core).",
)
def batch_command(manifest_path: str, out_dir: str, scheduler: str | None, n_workers: int | None) -> None:
    """Run every job of MANIFEST.csv (columns name,command) on a Dask cluster.

    A command is a stageid command line without `stageid` and without -o: identify
    statespace|closed-loop|hysteresis|frd (-> DIR/<name>.json), frf, simulate, freqresp,
    compensate, signal KIND (-> DIR/<name>.csv) or plants (.json; .csv with --experiment).
    Each output is the file the command writes when run directly, written atomically as its
    job finishes.  DIR/summary.csv has one row per job, in manifest order:
    name,status,seconds,worker,error with status ok, failed (error: the command's one-line
    error) or skipped, and the job's run time on its worker.  A progress bar shows on stderr
    (on a terminal).  A rerun skips a job
    whose command, input files (SHA-256 of their content), stageid version and output are
    unchanged (state in DIR/.stageid-batch.json); when every job is skipped no cluster starts.

    A worker that dies loses no job (Dask runs it again elsewhere); a failing job never stops
    the others.  Workers must see the input files at the same absolute paths (one machine or
    a shared file system) and run the same stageid; each worker process runs one job at a time.

    Exit code 0 when every job is ok or skipped, 1 when any failed (the summary is complete);
    2 with one line for a bad manifest (nothing written) or an unreachable scheduler.
    """
    from .. import __version__
    from ..batch import SUMMARY_FILE, read_manifest, resolve_job, run_batch
    from ..runtime.cluster import check_scheduler_address, dask_client

    # Dask's sockets closed by the garbage collector are its own business, not the user's
    warnings.filterwarnings("ignore", category=ResourceWarning)
    if scheduler is not None and n_workers is not None:
        raise click.UsageError("--workers sizes the local cluster; got it with --scheduler (that cluster's own).")
    if scheduler is not None:
        check_scheduler_address(scheduler)
    folder = check_output_folder(out_dir, "the batch's outputs")
    rows = read_manifest(manifest_path)
    base = os.path.dirname(os.path.abspath(manifest_path))
    root = click.get_current_context().find_root().command
    assert isinstance(root, click.Group)
    jobs = [resolve_job(row, root, base) for row in rows]
    _check_no_output_is_an_input(jobs, folder, manifest_path)
    outcomes = run_batch(
        jobs,
        folder,
        run_command_line,
        lambda: dask_client(scheduler, n_workers=n_workers),
        __version__,
        lambda total: progress(total, "batch", "job"),
    )
    counts = {status: sum(o.status == status for o in outcomes) for status in ("ok", "skipped", "failed")}
    say(
        f"batch: {counts['ok']} ok, {counts['skipped']} skipped, {counts['failed']} failed; "
        f"summary in {folder / SUMMARY_FILE}"
    )
    if counts["failed"]:
        click.get_current_context().exit(1)


def _check_no_output_is_an_input(jobs, folder, manifest_path: str) -> None:
    """DIR/<name>.ext must not be the manifest or a file some job reads (DIR = the data folder)."""
    from ..atomic import same_file

    sources = [manifest_path, *(absolute for job in jobs for _, absolute in job.inputs)]
    for job in jobs:
        target = folder / job.output_name
        for source in sources:
            if target.exists() and same_file(source, target):
                raise DataError(
                    f"output '{target}' of job {job.name!r} is also an input ('{source}'); "
                    "expected --out to be a folder of its own."
                )


def run_command_line(argv: tuple[str, ...], suffix: str) -> dict:
    """Run ``stageid ARGV -o <temporary>.SUFFIX`` here (on a Dask worker): the job's task.

    The same entry point as the ``stageid`` script, so a job's output is the direct command's
    output byte for byte.  Returns ``{"ok", "seconds", "worker", "error", "data"}``: the output's
    bytes when the command succeeded, else its one-line error (exit code 2 or 3).  The output
    goes to a private temporary folder, never into DIR: the client writes DIR.
    """
    import contextlib
    import io
    import shutil
    import tempfile
    import time

    from .main import main

    with _ONE_COMMAND_AT_A_TIME:
        scratch = tempfile.mkdtemp(prefix="stageid-batch-")
        try:
            target = os.path.join(scratch, "output" + suffix)
            err = io.StringIO()
            start = time.perf_counter()
            with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
                code = main([*argv, "-o", target])
            seconds = time.perf_counter() - start
            data = None
            if code == 0 and os.path.isfile(target):
                with open(target, "rb") as fh:
                    data = fh.read()
        finally:
            shutil.rmtree(scratch, ignore_errors=True)
    worker = _worker_address()
    if data is not None:
        return {"ok": True, "seconds": seconds, "worker": worker, "error": "", "data": data}
    lines = [line for line in err.getvalue().splitlines() if line.startswith("stageid: ")] or [""]
    error = lines[-1].removeprefix("stageid: error: ") or f"exit code {code} without an output file"
    return {"ok": False, "seconds": seconds, "worker": worker, "error": error, "data": None}


def _worker_address() -> str:
    """The Dask worker running this task ('' outside a worker)."""
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return ""
