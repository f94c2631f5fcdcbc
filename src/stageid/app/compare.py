"""The compare and export boards of ``stageid serve``.

Compare runs ``stageid validate`` (fit %, NRMSE, whiteness and independence of the residual)
on a held-out record and overlays the model's simulation on it; export runs ``stageid export``
(C99, MATLAB) or hands out the model file the estimate's command wrote (JSON).
"""

from __future__ import annotations

import io
import json
import zipfile
from typing import Any

from .._errors import DataError
from .estimate import Action, band_figure, channel_args, model_bode, reading
from .records import svg
from .sessions import Session

__all__ = ["compare", "export", "EXPORT_FORMATS", "export_file"]

#: export format -> (file made in the workspace from model ``m``, media type of the download)
EXPORT_FORMATS = {
    "json": ("{m}.json", "application/json"),
    "mat": ("{m}.mat", "application/octet-stream"),
    "c": ("{m}_c.zip", "application/zip"),
}


def _model(session: Session, name: str) -> dict[str, Any]:
    if name not in session.models:
        raise DataError(f"no model {name!r} in this session; expected one of {', '.join(session.models) or 'none'}.")
    return session.models[name]


def compare(session: Session, model: str, data: str, out: str) -> Action:
    """``stageid validate MODEL DATA --json``: per output fit %, and the residual tests."""
    entry = _model(session, model)
    d = session.datasets.get(data)
    if d is None or d["kind"] != "time":
        raise DataError(f"compare needs a time record; {data!r} is {'not a data set' if d is None else d['kind']}.")
    args = ["validate", f"{model}.json", d["file"], *channel_args(d), "--json", f"{out}.json"]
    python = (
        "from stageid.models import load_model\nfrom stageid.validation.residuals import validate_model\n"
        f"{reading(d)}\n"
        f"result = validate_model(load_model({model + '.json'!r}), [exp], 25, 0.01)"
    )

    def then() -> dict[str, Any]:
        summary = json.loads((session.workspace / f"{out}.json").read_text())
        figures = _overlay(session, entry, d) if entry["lti"] else {}
        return {"validation": summary, "figures": figures}

    return args, python, then


def _overlay(session: Session, entry: dict[str, Any], d: dict[str, Any]) -> dict[str, str]:
    """The record's outputs with the model's simulation (its own initial state), the residual
    correlations of each output (MATLAB's ``resid``) and the model's Bode plot."""
    from ..data.io import read_table
    from ..models import load_model
    from ..plots import time_overlay_figure
    from ..plots.residuals import residual_figure
    from ..validation.residuals import ALPHA, MAX_LAG, validate_model

    model = load_model(session.workspace / f"{entry['name']}.json")
    exp = read_table(session.workspace / d["file"]).experiment(d["inputs"], d["outputs"])
    exp = exp.with_(input_names=tuple(model.inputs), output_names=tuple(model.outputs))
    simulated = model.simulate(exp.u)
    overlay = time_overlay_figure(exp.time, exp.y, {entry["name"]: simulated}, list(exp.output_names))
    figures = {"overlay": svg(overlay)}
    tests = validate_model(model, [exp], MAX_LAG, ALPHA)["outputs"]
    for name, test in tests.items():
        figures[f"residuals {name}"] = svg(residual_figure(name, test["whiteness"], test["independence"]))
    return figures | (band_figure(session, entry["name"]) or {"bode": model_bode(model)})


def export(session: Session, model: str, fmt: str, options: dict[str, Any]) -> Action:
    """The export command of ``model`` in format ``fmt`` (``json``: the model file itself)."""
    _model(session, model)
    if fmt not in EXPORT_FORMATS:
        raise DataError(f"export format {fmt!r} is not one of {', '.join(EXPORT_FORMATS)}.")
    loading = f"from stageid.models import load_model\nmodel = load_model({model + '.json'!r})"
    if fmt == "mat":
        args = ["export", "mat", f"{model}.json", "-o", f"{model}.mat"]
        python = (
            f"{loading}\nfrom stageid.export.matlab import export_mat\n"
            f"with open({model + '.mat'!r}, 'wb') as fh:\n    export_mat(model, fh, None, None)  # dt, method"
        )
    elif fmt == "c":
        prefix = str(options.get("prefix") or model)
        args = ["export", "c", f"{model}.json", "--prefix", prefix, "-o", f"{model}_c"]
        python = (
            f"{loading}\nfrom stageid.export import export_c\nfiles = export_c(model, {prefix!r}).files()  # .h and .c"
        )
    else:
        args, python = [], loading

    def then() -> dict[str, Any]:
        if fmt == "c":
            _zip_folder(session, model)
        name = EXPORT_FORMATS[fmt][0].format(m=model)
        return {"download": f"/api/files/{name}", "file": name}

    return args, python, then


def _zip_folder(session: Session, model: str) -> None:
    folder = session.workspace / f"{model}_c"
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for path in sorted(folder.iterdir()):
            archive.write(path, path.name)
    (session.workspace / f"{model}_c.zip").write_bytes(buffer.getvalue())


def export_file(session: Session, name: str) -> tuple[bytes, str]:
    """The bytes and media type of a file the session made: an export, or a data set's file."""
    made = {pattern.format(m=model): media for pattern, media in EXPORT_FORMATS.values() for model in session.models}
    made |= {
        d["file"]: "text/csv" if d["file"].endswith(".csv") else "application/octet-stream"
        for d in session.datasets.values()
    }
    if name in made and (session.workspace / name).is_file():
        return (session.workspace / name).read_bytes(), made[name]
    raise DataError(f"no exported file {name!r} in this session.")
