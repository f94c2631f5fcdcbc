"""The main job: the three workflows of stageid on the built-in reference stages.

``run_demo(out_dir)`` identifies the P-558 piezo stage (Hankel-MAP with online update), the
unstable maglev plant in closed loop, and the piezo actuator's hysteresis with inverse
compensation; it writes ``index.html`` (figures embedded), ``metrics.json`` and the identified
models into ``out_dir`` and returns the summary rows.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["run_demo", "DemoResult", "WORKFLOWS"]

WORKFLOWS = ("piezo_stage", "maglev", "hysteresis")


@dataclass(frozen=True)
class DemoResult:
    """What the demo produced: the summary table rows, all metrics, and the report path."""

    rows: tuple[tuple[str, str, str, str], ...]
    metrics: dict
    report: Path
    seconds: float


def run_demo(
    out_dir: str | Path,
    step: Callable[[str], None] | None = None,
    workflows: tuple[str, ...] = WORKFLOWS,
    command: str | None = None,
) -> DemoResult:
    """Run the workflows and write the report; ``step`` is called with a description before each stage.

    The report opens with ``command`` (the command line that ran the demo, when given), the
    workflows run and the stageid version.

    Everything is written into a temporary folder next to ``out_dir`` and moved into place at
    the end (:func:`stageid.atomic.staged_folder`), so an error or an interrupt leaves no
    partial models behind.  The parent of ``out_dir`` must exist.
    """
    import importlib

    from ..atomic import staged_folder
    from ..report import Report, write_metrics
    from ..report.provenance import settings_section

    step = step or (lambda text: None)
    report = Report("stageid demo: identification of precision positioning stages")
    report.paragraph(
        "Three workflows on the reference stages of the papers, all simulated with realistic sensor noise: open-loop MIMO "
        "state-space identification of a 3-DOF piezo stage (Cao & Chen 2013), closed-loop identification of an "
        "open-loop-unstable maglev stage with a known controller (Shakir & Kim), and modified Prandtl-Ishlinskii "
        "hysteresis identification with inverse feedforward compensation. Every number below was computed in this run."
    )
    metrics: dict[str, Any] = {}
    settings_section(report, {"workflows": workflows}, command)
    rows: list[list[Any]] = []
    t0 = time.perf_counter()
    with staged_folder(out_dir) as tmp:
        for name in workflows:
            module = importlib.import_module(f"{__name__}.{name}")
            t1 = time.perf_counter()
            rows += module.run(report, metrics, tmp, step)
            metrics[f"seconds/{name}"] = round(time.perf_counter() - t1, 2)
        seconds = time.perf_counter() - t0
        report.section("Summary")
        report.table(["workflow", "metric", "measured", "reference"], rows, caption=f"Run time {seconds:.0f} s.")
        metrics["seconds/total"] = round(seconds, 2)
        report.write(tmp)
        write_metrics(tmp, metrics)
    return DemoResult(tuple(tuple(r) for r in rows), metrics, Path(out_dir) / "index.html", seconds)
