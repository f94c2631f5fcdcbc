"""``stageid demo``: the three workflows on the reference stages, with an HTML report."""

from __future__ import annotations

import sys
import time

import click


@click.command(
    "demo",
    epilog="""
\b
Examples:
  stageid demo --out demo-out          # all three workflows, report in demo-out/index.html
  stageid demo --out d --only maglev   # one workflow
""",
)
@click.option(
    "--out",
    "out_dir",
    default="demo-out",
    show_default=True,
    type=click.Path(file_okay=False),
    help="Folder for index.html, metrics.json and the identified models (its parent must exist).",
)
@click.option(
    "--only",
    type=click.Choice(["piezo_stage", "maglev", "hysteresis"]),
    multiple=True,
    help="Run only these workflows (repeatable).",
)
def demo_command(out_dir: str, only: tuple[str, ...]) -> None:
    """Identify the P-558 piezo stage (Hankel-MAP), the unstable maglev plant (closed loop) and the
    piezo actuator's hysteresis (modified PI + inverse feedforward); print a summary and write a report."""
    from tqdm.auto import tqdm

    from ..demo import WORKFLOWS, run_demo
    from ._common import command_line, say
    from .outputs import check_output_folder
    from .progress import is_interactive

    check_output_folder(out_dir)  # one rule for every verb: the parent folder must exist
    workflows = only or WORKFLOWS
    stages = {"piezo_stage": 5, "maglev": 2, "hysteresis": 4}
    bar = tqdm(
        total=sum(stages[w] for w in workflows),
        desc="stageid demo",
        unit="step",
        file=sys.stderr,
        bar_format="{desc}: {n_fmt}/{total_fmt} [{elapsed}] {postfix}",
        disable=not is_interactive(),
    )
    first = [True]
    start = time.perf_counter()

    def step(text: str) -> None:
        if not is_interactive():
            click.echo(f"[{time.perf_counter() - start:5.0f} s] {text}", err=True)
        if not first[0]:
            bar.update(1)
        first[0] = False
        bar.set_postfix_str(text)

    try:
        result = run_demo(out_dir, step, tuple(workflows), command_line())
        bar.update(1)
    finally:
        bar.close()
    width = [
        max(len(str(r[k])) for r in result.rows + (("workflow", "metric", "measured", "reference"),)) for k in range(4)
    ]
    header = ("workflow", "metric", "measured", "reference")
    say("  ".join(h.ljust(w) for h, w in zip(header, width)))
    say("  ".join("-" * w for w in width))
    for row in result.rows:
        say("  ".join(str(c).ljust(w) for c, w in zip(row, width)))
    say(f"\nreport: {result.report}   metrics: {result.report.parent / 'metrics.json'}   ({result.seconds:.0f} s)")
