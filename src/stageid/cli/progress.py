"""Progress of long commands on stderr: a tqdm bar on a terminal, a line now and then in a log."""

from __future__ import annotations

import click

__all__ = ["progress", "StepProgress", "is_interactive"]


def is_interactive() -> bool:
    """True when stderr is a terminal (progress bars only make sense there)."""
    import sys

    return sys.stderr.isatty()


def progress(total: int | None = None, desc: str = "", unit: str = "it"):
    """A tqdm progress bar on stderr, silent when stderr is not a terminal."""
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, unit=unit, disable=not is_interactive(), leave=False)


class StepProgress:
    """Progress of a long fit on stderr, as the callback ``(step, done, total)`` of
    :meth:`stageid.hysteresis.stage.identification.StageIdentifier.fit`.

    On a terminal: a tqdm bar per counted step, with the time left that tqdm estimates from the
    rate so far, and the step's name for steps without a count (bars are removed when done).
    Otherwise (a log, a pipe): a line ``[elapsed] step done/total, about N s left`` when a
    counted step starts, after its first candidate, at its end and otherwise at most every
    ``interval`` seconds, so a log shows that the fit moves without one line per candidate;
    steps without a count get a line only once counting has begun (the input checks come
    before it, and a command refused there prints only its one-line error).
    """

    def __init__(self, interval: float = 30.0) -> None:
        import time

        self._clock = time.perf_counter
        self._start = self._clock()
        self._interval = interval
        self._step: str | None = None
        self._step_start = self._start
        self._last_line = -float("inf")
        self._bar = None
        self._counted = False

    def __call__(self, step: str, done: int, total: int) -> None:
        now = self._clock()
        if step != self._step:
            self.close()
            self._step, self._step_start, self._last_line = step, now, -float("inf")
            if is_interactive() and total:
                self._bar = progress(total, step, "candidate")
            elif is_interactive():  # no count: the step's name and its elapsed time
                from tqdm.auto import tqdm

                self._bar = tqdm(desc=step, bar_format="{desc} [{elapsed}]", leave=False)
        if self._bar is not None:
            self._bar.update(done - self._bar.n)
            return
        if not total:
            if self._counted:  # before the count starts a failing command must print only its error
                self._line(now, step)
            return
        self._counted = True
        if done <= 1 or done == total or now - self._last_line >= self._interval:
            text = f"{step} {done}/{total}"
            if 0 < done < total:
                text += f", about {(now - self._step_start) / done * (total - done):.0f} s left"
            self._line(now, text)

    def _line(self, now: float, text: str) -> None:
        click.echo(f"[{now - self._start:5.0f} s] {text}", err=True)
        self._last_line = now

    def close(self) -> None:
        """Remove the terminal's bar (the command prints its result after this)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None
