"""``stageid plants NAME``: write a reference stage's model, controller or a simulated experiment."""

from __future__ import annotations

import click

from .._errors import StageIdError
from ._common import say
from .outputs import check_output, write_model_output, write_table_output


@click.command(
    "plants",
    epilog="""
\b
Examples:
  stageid plants                                   # list stages and their experiments
  stageid plants p558 -o p558.json                 # the P-558 model (stageid.lti/1)
  stageid plants p558 --experiment chirp-z -o z.csv
  stageid plants maglev --controller -o K.json     # the known stabilising controller
  stageid plants maglev --experiment chirp-x --seed 3 -o ex.csv
""",
)
@click.argument("name", required=False)
@click.option("--experiment", default=None, help="Simulate this experiment instead of writing the model.")
@click.option("--controller", is_flag=True, help="Write the stage's stabilising controller (closed-loop stages).")
@click.option(
    "--seed",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="Noise/excitation seed of the experiment, >= 0.",
)
@click.option(
    "-o",
    "--output",
    "output",
    type=click.Path(dir_okay=False),
    default=None,
    help="Output .json (model) or .csv/.npz (experiment).",
)
def plants_command(name: str | None, experiment: str | None, controller: bool, seed: int, output: str | None) -> None:
    """Reference stages of the papers: P-558 piezo stage, maglev stage, piezo actuator."""
    from ..plants import PLANTS, plant_module

    if name is None:
        if experiment is not None or controller or output is not None:
            given = "--experiment" if experiment is not None else "--controller" if controller else "-o"
            raise click.UsageError(f"{given} needs a plant NAME (one of {', '.join(PLANTS)}); got none.")
        for plant in PLANTS:
            try:
                exps = ", ".join(getattr(plant_module(plant), "EXPERIMENTS", {}))
            except ImportError:
                exps = "(not installed)"
            say(f"{plant:16s} experiments: {exps}")
        return
    if output is None:
        raise click.UsageError("Missing option '-o' / '--output'.")
    if experiment is not None and controller:
        raise click.UsageError("--experiment and --controller exclude each other.")
    check_output(output, "table" if experiment is not None else "model")
    module = plant_module(name)
    if experiment is not None:
        experiments = getattr(module, "EXPERIMENTS", {})
        if experiment not in experiments:
            raise StageIdError(
                f"plant {name!r} has no experiment {experiment!r}; expected one of {', '.join(experiments)}."
            )
        record = experiments[experiment](seed=seed)
        write_table_output(output, record)
        return
    if controller:
        if not hasattr(module, "controller"):
            raise StageIdError(f"plant {name!r} has no controller; only closed-loop stages do.")
        write_model_output(output, module.controller())
    else:
        write_model_output(output, module.model())
