"""The files of ``stageid signal multisine``: one per realisation and experiment, and the design beside them.

One realisation of a single-experiment design goes to ``-o FILE`` itself; otherwise each
record goes to ``FILE_r01`` ... (``FILE_r01_e1`` ... for the experiments of an orthogonal
MIMO design), and ``FILE.multisine.json`` lists the files with their realisation and
experiment, the seed, the excited lines and the odd and even detection lines, which
``stageid frf --method bla --design FILE.multisine.json`` reads.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["write_multisine_files", "design_path"]


def design_path(output: Path) -> Path:
    """``ms.csv`` -> ``ms.multisine.json``: the design beside the signal files."""
    return output.with_suffix(".multisine.json")


def write_multisine_files(
    output: Path,
    kwargs: dict[str, Any],
    realisations: int,
    to_columns: Callable[[np.ndarray], dict[str, np.ndarray]],
    dt: float | None,
) -> None:
    """Generate every realisation and experiment of the design, write them and the design JSON."""
    from ..atomic import atomic_write_text
    from ..signals import crest_factor, multisine, multisine_plan
    from ._common import say
    from .outputs import check_output, write_table_output

    kwargs = dict(kwargs)
    if realisations > 1 and kwargs.get("kind", "random-phase") != "random-phase":
        from .._errors import SignalError

        raise SignalError(f"--realisations {realisations} needs --kind random-phase (Schroeder phases do not vary).")
    if kwargs.get("seed") is None and kwargs.get("kind", "random-phase") == "random-phase":
        # recorded in the design, so every realisation can be made again
        kwargs["seed"] = int(np.random.SeedSequence().entropy % 2**31)
        say(f"multisine: seed {kwargs['seed']} (set it with --seed)")
    n_inputs = kwargs.get("n_channels") or 1
    plan_args = ("n_samples", "dt", "f_low", "f_high", "n_periods", "lines", "detection_group", "shape", "seed", "mimo")
    plan = multisine_plan(**{k: kwargs[k] for k in plan_args if k in kwargs}, n_inputs=n_inputs)
    single = realisations == 1 and plan.n_experiments == 1
    files = []
    records = []
    for r in range(realisations):
        for e in range(plan.n_experiments):
            x = np.asarray(multisine(**kwargs, realisation=r, experiment=e))
            suffix = "" if single else f"_r{r + 1:02d}" + (f"_e{e + 1}" if plan.n_experiments > 1 else "")
            path = check_output(output.with_name(output.stem + suffix + output.suffix), "table")
            cf = [crest_factor(c) for c in (x[:, None] if x.ndim == 1 else x).T]
            records.append((path, to_columns(x)))
            files.append({"file": path.name, "realisation": r + 1, "experiment": e + 1, "crest_factor": cf})
    for path, columns in records:  # all generated first: a bad option fails before any file
        write_table_output(path, columns, dt=dt)
    design = {
        "kind": kwargs.get("kind", "random-phase"),
        "lines": kwargs.get("lines", "full"),
        "seed": kwargs.get("seed"),
        "mimo": kwargs.get("mimo", "independent"),
        "n_inputs": n_inputs,
        "realisations": realisations,
        **plan.to_dict(),
        "files": files,
    }
    target = design_path(output)
    # one key a line, the line lists on theirs: readable and diffable
    atomic_write_text(
        target, "{\n" + ",\n".join(f" {json.dumps(k)}: {json.dumps(v)}" for k, v in design.items()) + "\n}\n"
    )
    worst = max(max(f["crest_factor"]) for f in files)
    say(
        f"multisine: {len(files)} file(s), {plan.excited.size} excited lines, "
        f"{plan.detection_odd.size} odd and {plan.detection_even.size} even detection lines, "
        f"crest factor <= {worst:.2f}; design written to {target}"
    )
