"""Shared pieces of the randomised recovery benchmark: records written as loggers write them,
the command line run in-process, and one result row per draw.

Each estimator has a module ``rec_<name>.py`` beside this one that defines

    ESTIMATOR: str                                   # the table's label, e.g. "FRD fit"
    def case(seed: int, workdir: pathlib.Path, noise: float) -> Row

``case`` draws a random true system of the estimator's own class from ``seed``, writes its
records with :func:`write_record` (a time column in one of :data:`TIME_STYLES`, chosen by
the seed), fits it through the command line (:func:`run_cli`) and compares the fit with the
truth and with a reference fit (the same cost minimised from the truth, or a peer's fit).
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
import shlex

import numpy as np

__all__ = ["TIME_STYLES", "NOISE_MAX", "Row", "draw_noise", "time_column", "write_record", "run_cli", "CliFailure"]

NOISE_MAX = 0.02  # noise drawn per seed in [0, 2 %] of the output's RMS


def draw_noise(seed: int) -> float:
    """The noise level of draw ``seed``: uniform in [0, NOISE_MAX], the same for every estimator."""
    return float(np.random.default_rng([seed, 0x5EED]).uniform(0.0, NOISE_MAX))


# How data loggers write a time column in practice (each a way the period comes out an ulp
# or a rounding away from 1/fs):
#   repr     numpy.arange(n) / fs written with repr (shortest round-trip digits)
#   fixed    "%.6f" fixed decimals, as spreadsheet exports and many DAQ tools write
#   cumsum   t accumulated sample by sample in double (drifts by ulps)
#   offset   repr of t0 + arange(n) / fs with a non-zero start (a trigger time)
#   float32  single-precision time stamps (short records only), repr of the float32 value
TIME_STYLES = ("repr", "fixed", "cumsum", "offset", "float32")


@dataclasses.dataclass
class Row:
    """One draw's outcome.  ``error`` is the estimator's headline error against the truth (in
    the unit ``unit``); ``reference_error`` the reference fit's; ``cost_ratio`` the fit's own
    cost divided by the reference's on the same data (NaN when there is no reference)."""

    seed: int
    recovered: bool
    error: float
    unit: str = "% of peak"
    reference_error: float = math.nan
    cost_ratio: float = math.nan
    noise: float = 0.0
    detail: str = ""
    failed: str = ""  # the CLI's one-line message when the fit itself failed


class CliFailure(RuntimeError):
    """The command exited non-zero; ``args[0]`` is its one-line message."""


def time_column(n: int, fs: float, style: str, rng: np.random.Generator | None = None) -> list[str]:
    """The text of a time column of ``n`` samples at ``fs`` Hz written in ``style``."""
    if style == "repr":
        return [repr(float(v)) for v in np.arange(n) / fs]
    if style == "fixed":
        return [f"{v:.6f}" for v in np.arange(n) / fs]
    if style == "cumsum":
        t = np.cumsum(np.full(n, 1.0 / fs)) - 1.0 / fs
        return [repr(float(v)) for v in t]
    if style == "offset":
        t0 = float((rng or np.random.default_rng(0)).uniform(0.5, 50.0))
        return [repr(float(v)) for v in t0 + np.arange(n) / fs]
    if style == "float32":
        return [repr(float(v)) for v in (np.arange(n) / fs).astype(np.float32)]
    raise ValueError(f"unknown time style {style!r}; expected one of {TIME_STYLES}")


def write_record(
    path: pathlib.Path, columns: dict[str, np.ndarray], fs: float, style: str, rng: np.random.Generator | None = None
) -> pathlib.Path:
    """Write ``columns`` (1-D arrays of one length) to CSV with a ``t`` column in ``style``;
    data written with repr, as a logger storing doubles would."""
    names = list(columns)
    data = np.column_stack([np.asarray(columns[k], dtype=float) for k in names])
    t = time_column(data.shape[0], fs, style, rng)
    lines = [",".join(["t", *names])]
    lines += [",".join([ti, *map(repr, map(float, row))]) for ti, row in zip(t, data)]
    path.write_text("\n".join(lines) + "\n")
    return path


def run_cli(args: list[str] | str) -> tuple[str, str]:
    """Run ``stageid ARGS`` in-process through the script's entry point (its output transaction,
    its one-line errors) and return (stdout, stderr); CliFailure with the one-line message on a
    non-zero exit."""
    import contextlib
    import io

    from stageid.cli.main import main

    argv = shlex.split(args) if isinstance(args, str) else [str(a) for a in args]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    if code != 0:
        lines = err.getvalue().strip().splitlines()
        raise CliFailure(lines[-1] if lines else f"exit {code}")
    return out.getvalue(), err.getvalue()
