"""``--uncertainty B.csv [--uncertainty-grid FMIN:FMAX:N]``, shared by the ``identify`` verbs.

The identified model's frequency response with ``std_<out>_<in> = sqrt(E|G_est - G|^2)``
beside ``re_``/``im_`` (the ``freqresp`` table), on ``N`` log-spaced frequencies, by default
``DEFAULT_POINTS`` over the identified band.  Every result type answers
``response_uncertainty(freqs_hz) -> FrequencyResponse``; this module only parses, checks and
writes.  The option's file is checked with the command's other outputs before any work and
written in the command's transaction (all files or none); the grid's syntax is checked before
any work, its range against the model's Nyquist frequency once the model exists.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import click

from .outputs import check_output, write_table_output

__all__ = ["uncertainty_options", "UncertaintyRequest", "DEFAULT_POINTS"]

#: Frequencies of the uncertainty table when ``--uncertainty-grid`` is not given.
DEFAULT_POINTS = 200
#: Most frequencies ``--uncertainty-grid`` may ask for (a table, not a data set).
MAX_POINTS = 100_000
#: Where a band starting at 0 Hz starts on the log-spaced default grid, relative to its top.
LOW_END = 1e-3


def uncertainty_options(command: Callable[..., Any]) -> Callable[..., Any]:
    """Add ``--uncertainty`` and ``--uncertainty-grid`` (parameters ``uncertainty_file``, ``uncertainty_grid``)."""
    command = click.option(
        "--uncertainty-grid",
        "uncertainty_grid",
        default=None,
        metavar="FMIN:FMAX:N",
        help=f"Frequencies of the --uncertainty table: N log-spaced in FMIN..FMAX Hz "
        f"(default: {DEFAULT_POINTS} over the identified band).",
    )(command)
    return click.option(
        "--uncertainty",
        "uncertainty_file",
        default=None,
        type=click.Path(dir_okay=False),
        help="Also write the model's frequency response with its standard deviation "
        "(f_hz, re_/im_/std_<out>_<in>; .csv or .npz).",
    )(command)


class UncertaintyRequest:
    """The checked ``--uncertainty`` options of one command run (None path: nothing asked)."""

    def __init__(self, path: str | None, grid_text: str | None) -> None:
        if grid_text is not None and path is None:
            raise click.UsageError("--uncertainty-grid needs --uncertainty B.csv (the file it is for).")
        self.path = path
        self.grid = None if grid_text is None else parse_grid(grid_text)
        if path is not None:
            check_output(path, "table")

    @property
    def wanted(self) -> bool:
        return self.path is not None

    def check_nyquist(self, dt: float | None) -> None:
        """Refuse a grid reaching above the Nyquist frequency of ``dt`` (None: continuous, no limit);
        called as soon as the sample time is known, before the fit."""
        nyquist = math.inf if dt is None else 0.5 / dt
        if self.grid is not None and self.grid[1] > nyquist * (1 + 1e-12):
            raise click.UsageError(
                f"--uncertainty-grid must lie within (0, {nyquist:g}] Hz (the Nyquist frequency of the "
                f"{dt:g} s sample time); got FMAX {self.grid[1]:g} Hz."
            )

    def freqs(self, band: tuple[float, float], dt: float | None) -> Any:
        """The grid: the given one (checked against the Nyquist frequency of ``dt``) or
        ``DEFAULT_POINTS`` log-spaced over ``band`` (a band from 0 Hz starts at ``LOW_END`` of its top)."""
        import numpy as np

        self.check_nyquist(dt)
        nyquist = math.inf if dt is None else 0.5 / dt
        if self.grid is None:
            lo, hi = float(band[0]), min(float(band[1]), nyquist)
            lo = lo if lo > 0 else LOW_END * hi
            return np.geomspace(lo, hi, DEFAULT_POINTS)
        fmin, fmax, n = self.grid
        return np.geomspace(fmin, min(fmax, nyquist), n)

    def write(self, result: Any, band: tuple[float, float], dt: float | None) -> str | None:
        """Compute ``result.response_uncertainty`` on the grid and write it (in the command's
        transaction); returns a line for the summary, or None when nothing was asked."""
        if self.path is None:
            return None
        fr = result.response_uncertainty(self.freqs(band, dt))
        write_table_output(self.path, fr.to_columns())
        return f"uncertainty ({fr.n_freqs} frequencies, {fr.freqs[0]:.4g}-{fr.freqs[-1]:.4g} Hz) written to {self.path}"


def parse_grid(text: str) -> tuple[float, float, int]:
    """``"FMIN:FMAX:N"`` -> ``(fmin, fmax, n)`` with ``0 < fmin < fmax`` finite and an integer ``n >= 2``."""
    parts = text.split(":")
    expected = f"FMIN:FMAX:N with 0 < FMIN < FMAX in Hz and an integer 2 <= N <= {MAX_POINTS}, e.g. 1:100:200"
    try:
        if len(parts) != 3:
            raise ValueError
        fmin, fmax = float(parts[0]), float(parts[1])
        n = int(parts[2])
    except ValueError:
        raise click.UsageError(f"--uncertainty-grid must be {expected}; got {text!r}.") from None
    if not (math.isfinite(fmin) and math.isfinite(fmax) and 0.0 < fmin < fmax) or not 2 <= n <= MAX_POINTS:
        raise click.UsageError(f"--uncertainty-grid must be {expected}; got {text!r}.")
    return fmin, fmax, n
