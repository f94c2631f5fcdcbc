"""The estimate board of ``stageid serve``: each estimate is one ``stageid`` command.

Every function here turns the page's settings into the command's arguments, the equivalent
Python call (shown on the page, so the app teaches the scripted route) and a finishing step
that reads what the command wrote and draws it.  The command itself checks the settings, so
a bad option shows the command's own one-line message.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from .._errors import DataError
from .records import frd_description, svg
from .sessions import Session

__all__ = ["ESTIMATES", "Action", "model_bode", "band_figure", "singular_values", "channel_args", "reading"]

#: (command arguments, Python call, finishing step returning the page's result)
Action = tuple[list[str], str, Callable[[], dict[str, Any]]]


def _text(options: dict[str, Any], key: str, default: str | None = None) -> str | None:
    value = options.get(key)
    return default if value in (None, "") else str(value).strip()


def _dataset(session: Session, name: str, kind: str) -> dict[str, Any]:
    data = session.datasets.get(name)
    if data is None:
        raise DataError(
            f"no data set {name!r} in this session; expected one of {', '.join(session.datasets) or 'none'}."
        )
    if data["kind"] != kind:
        wanted = "a time record" if kind == "time" else "a frequency response"
        raise DataError(f"data set {name!r} is {data['kind']} data; this estimate needs {wanted}.")
    return data


def _optional(args: list[str], options: dict[str, Any], pairs: list[tuple[str, str]]) -> list[str]:
    for key, flag in pairs:
        value = _text(options, key)
        if value is not None:
            args += [flag, value]
    return args


def channel_args(d: dict[str, Any]) -> list[str]:
    """``--inputs A,B --outputs Y`` of a time data set, as the commands take them."""
    return ["--inputs", ",".join(d["inputs"]), "--outputs", ",".join(d["outputs"])]


def reading(d: dict[str, Any]) -> str:
    """The Python lines that read a time data set as an experiment ``exp``."""
    return f"from stageid.data.io import read_table\nexp = {experiment_call(d)}"


def experiment_call(d: dict[str, Any]) -> str:
    """The Python expression that reads a time data set as an Experiment."""
    return f"read_table({d['file']!r}).experiment({d['inputs']!r}, {d['outputs']!r})"


def model_bode(model: Any, frd: Any = None) -> str:
    """The Bode plot of an LTI model (over its data's band when given), as SVG."""
    if frd is not None:
        return svg(frd.plot(model=model))
    from ..plots import bode_figure

    top = 0.5 / model.dt if model.dt else 1e3
    f = np.geomspace(top * 1e-3, top * 0.999, 400)
    return svg(bode_figure(f, {"model": model.frequency_response(f)}, model.inputs, model.outputs))


def band_figure(session: Session, name: str) -> dict[str, str]:
    """``{"bands": svg}``: the model's response with +-2 std bands from its ``--uncertainty`` table
    (``{}`` when the command wrote none)."""
    from ..frf import read_frd

    path = session.workspace / f"{name}_bands.csv"
    return {"bands": svg(read_frd(path).plot())} if path.is_file() else {}


def _register_model(session: Session, name: str, kind: str, source: str, summary_of: Callable[[], str]) -> dict:
    from ..models import load_model

    model = load_model(session.workspace / f"{name}.json")
    lti = hasattr(model, "frequency_response")
    entry = {
        "name": name,
        "kind": kind,
        "lti": lti,
        "data": source,
        "inputs": list(model.inputs),
        "outputs": list(model.outputs),
        "summary": summary_of(),
    }
    session.models[name] = entry
    return {"model": entry, "object": model}


def frf(session: Session, data: str, options: dict[str, Any], out: str) -> Action:
    d = _dataset(session, data, "time")
    method = _text(options, "method", "welch")
    args = ["frf", d["file"], *channel_args(d), "--method", method]
    _optional(args, options, [("segment", "--segment"), ("periods", "--periods")])
    args += ["-o", f"{out}.csv"]
    python = f"{reading(d)}\n{_frf_call(method, options, tuple(d['inputs']), tuple(d['outputs']))}\n"
    python += f"from stageid.data.io import write_csv\nwrite_csv({out + '.csv'!r}, frd.to_columns())"

    def then() -> dict[str, Any]:
        from ..frf import read_frd

        target = session.workspace / f"{out}.csv"
        entry = frd_description(read_frd(target), target, python) | {"name": out, "from": data}
        session.datasets[out] = entry
        return {"dataset": {k: v for k, v in entry.items() if k != "figures"}, "figures": entry["figures"]}

    return args, python, then


def _frf_call(method: str | None, options: dict[str, Any], inputs: tuple, outputs: tuple) -> str:
    """The library call of ``stageid frf --method`` (its defaults written out)."""
    if method == "lpm":
        return "from stageid.frf.lpm import lpm_frf\nfrd = lpm_frf([exp])"
    if method == "periodic":
        periods = _literal(_text(options, "periods", "None"))
        return f"from stageid.frf.periodic import periodic_frf\nfrd = periodic_frf([exp], {periods}, 1)"
    segment = _text(options, "segment")
    return (
        "from stageid.frf.welch import cross_spectra, default_segment, h1_from_spectra\n"
        f"segment = {segment if segment is not None else 'default_segment(exp.n_samples)'}\n"
        f"frd = h1_from_spectra(cross_spectra([exp], segment, 0.5, 'hann'), {inputs!r}, {outputs!r})"
    )


def statespace(session: Session, data: str, options: dict[str, Any], out: str) -> Action:
    d = _dataset(session, data, "time")
    order, horizon = _text(options, "order", "auto"), _text(options, "horizon", "auto")
    args = ["identify", "statespace", d["file"], *channel_args(d), "--order", order, "--horizon", horizon]
    args += ["-o", f"{out}.json", "--uncertainty", f"{out}_bands.csv"]
    python = (
        f"from stageid.models import save_model\nfrom stageid.subspace import HankelMAP\n{reading(d)}\n"
        f"result = HankelMAP(horizon={_literal(horizon)}, order={_literal(order)}).fit(exp)\n"
        f"save_model(result.model, {out + '.json'!r})\n"
        "# the --uncertainty table: result.response_uncertainty(freqs_hz), the response and its std"
    )

    def then() -> dict[str, Any]:
        made = _register_model(session, out, "state space (Hankel-MAP)", data, lambda: _log(session, out))
        return {"model": made["model"], "figures": {"bode": model_bode(made["object"]), **band_figure(session, out)}}

    return args, python, then


def frd_fit(session: Session, data: str, options: dict[str, Any], out: str) -> Action:
    d = _dataset(session, data, "frd")
    args = ["identify", "frd", d["file"], "--order", _text(options, "order", "auto")]
    if options.get("continuous"):
        args.append("--continuous")
    _optional(args, options, [("dt", "--dt"), ("fmin", "--fmin"), ("fmax", "--fmax"), ("delay", "--delay")])
    args += ["-o", f"{out}.json", "--uncertainty", f"{out}_bands.csv"]
    python = (
        "from stageid.frf import FRDIdentification, read_frd\nfrom stageid.models import save_model\n"
        f"result = FRDIdentification({_frd_settings(options)})"
        f".fit(read_frd({d['file']!r}))\nsave_model(result.model, {out + '.json'!r})"
    )

    def then() -> dict[str, Any]:
        from ..frf import read_frd

        made = _register_model(session, out, "state space (FRD fit)", data, lambda: _log(session, out))
        frd = read_frd(session.workspace / d["file"])
        figures = {"bode": model_bode(made["object"], frd), **band_figure(session, out)}
        return {"model": made["model"], "figures": figures}

    return args, python, then


def hysteresis(session: Session, data: str, options: dict[str, Any], out: str) -> Action:
    d = _dataset(session, data, "time")
    if len(d["inputs"]) != 1 or len(d["outputs"]) != 1:
        raise DataError(
            f"a hysteresis model needs one input and one output; data set {data!r} has "
            f"{len(d['inputs'])} and {len(d['outputs'])}."
        )
    kind = _text(options, "model", "modified-pi")
    args = [
        "identify",
        "hysteresis",
        d["file"],
        "--input",
        d["inputs"][0],
        "--output",
        d["outputs"][0],
        "--model",
        kind,
        "-o",
        f"{out}.json",
    ]
    python = (
        "# the command fits stageid.hysteresis's estimator for --model "
        f"{kind} on the record\nfrom stageid.models import load_model\nmodel = load_model({out + '.json'!r})"
    )

    def then() -> dict[str, Any]:
        import numpy as np

        from ..data.io import read_table
        from ..plots.hysteresis import loop_error_figure

        made = _register_model(session, out, f"hysteresis ({kind})", data, lambda: _log(session, out))
        exp = read_table(session.workspace / d["file"]).experiment(d["inputs"], d["outputs"])
        y_hat = made["object"].simulate(exp.u[:, 0], exp.dt)
        # a long record of a fast input shows its last cycles beside the whole record's error envelope
        loops = loop_error_figure(
            np.arange(exp.n_samples) * exp.dt,
            exp.u[:, 0],
            exp.y[:, 0],
            y_hat,
            (d["inputs"][0], d["outputs"][0]),
            f"error [{exp.output_units[0]}]" if exp.output_units and exp.output_units[0] else "error",
        )
        return {"model": made["model"], "figures": {"loops": svg(loops)}}

    return args, python, then


def closedloop(session: Session, data: str, options: dict[str, Any], out: str) -> Action:
    """Closed-loop identification from the records and the controller's model file, or ``unknown``.

    Known controller: one data set per excited reference, their inputs the references, their
    outputs the measured outputs (same order).  ``unknown``: the direct prediction-error method
    on the data sets' plant inputs and outputs (references not needed).
    """
    names = [n.strip() for n in data.split(",") if n.strip()]
    sets = [_dataset(session, n, "time") for n in names]
    controller = _text(options, "controller")
    if controller is None:
        raise DataError("closed-loop identification needs the controller's model file or 'unknown'; got none.")
    args = ["identify", "closed-loop", *(d["file"] for d in sets)]
    if controller == "unknown":
        args += ["--plant-inputs", ",".join(sets[0]["inputs"]), "--outputs", ",".join(sets[0]["outputs"])]
        args += ["--controller", "unknown", "--method", "direct"]
        _optional(args, options, [("order", "--order"), ("band", "--band")])
        reads = "".join(f"    {experiment_call(d)},\n" for d in sets)
        python = (
            "from stageid.closedloop import DirectPredictionError\nfrom stageid.data.io import read_table\n"
            f"exps = [\n{reads}]\n"
            f"result = DirectPredictionError(order={_literal(_text(options, 'order', 'auto'))}).fit(exps)\n"
            "plant = result.model"
        )
    else:
        args += ["--references", ",".join(sets[0]["inputs"]), "--outputs", ",".join(sets[0]["outputs"])]
        args += ["--controller", controller]
        _optional(args, options, [("band", "--band")])
        python = (
            "# the command runs stageid.closedloop's ClosedLoopIdentification on the records\n"
            f"from stageid.models import load_model\nplant = load_model({out + '.json'!r})"
        )
    args += ["-o", f"{out}.json"]

    def then() -> dict[str, Any]:
        made = _register_model(session, out, "plant (closed loop)", data, lambda: _log(session, out))
        return {"model": made["model"], "figures": {"bode": model_bode(made["object"])}}

    return args, python, then


def _frd_settings(options: dict[str, Any]) -> str:
    """The keywords of ``FRDIdentification`` for the form's settings (``dt``, ``fmin``, ``fmax`` as
    ``sample_time`` and ``band``)."""
    given = {k: _literal(v) for k, v in options.items() if k in ("order", "dt", "fmin", "fmax", "delay") and v}
    settings = {"order": given.get("order"), "sample_time": given.get("dt")}
    if "fmin" in given or "fmax" in given:
        settings["band"] = f"({given.get('fmin', 'None')}, {given.get('fmax', 'None')})"
    settings["delay"] = given.get("delay")
    return ", ".join(f"{k}={v}" for k, v in settings.items() if v is not None)


def _literal(text: Any) -> str:
    """A setting as a Python literal: numbers stay numbers, anything else is quoted."""
    try:
        value = float(text)
    except (TypeError, ValueError):
        return repr(str(text))
    return repr(int(value)) if value.is_integer() and "." not in str(text) and "e" not in str(text) else repr(value)


def _log(session: Session, name: str) -> str:
    """What the command printed (its summary), from the job's captured output."""
    lines = []
    for job in session.jobs.values():
        if job.cli.endswith(f"-o {name}.json"):
            for stream in ("stdout", "stderr"):
                path = session.workspace / f"{job.key}.{stream}"
                if path.exists():
                    lines.append(path.read_text(errors="replace").strip())
    return "\n".join(line for line in lines if line)


def singular_values(session: Session, data: str, options: dict[str, Any]) -> dict[str, Any]:
    """Singular values of the Hankel matrix of the Markov parameters, to choose the order.

    The Markov parameters come from a Hankel-MAP fit at the given horizon (eq. 9); a gap in
    the singular values marks the order (as MATLAB's n4sid order plot).
    """
    from ..data.io import read_table
    from ..plots.subspace import error_curve
    from ..subspace import HankelMAP
    from ..subspace.realisation.era import hankel_matrices

    d = _dataset(session, data, "time")
    horizon = int(_text(options, "horizon", "20") if _text(options, "horizon") != "auto" else 20)
    exp = read_table(session.workspace / d["file"]).experiment(d["inputs"], d["outputs"])
    markov, _ = HankelMAP(horizon=horizon, order=1).fit(exp).markov_parameters()
    half = (markov.shape[0] - 3) // 2
    s = np.linalg.svd(hankel_matrices(markov, half, half)[0], compute_uv=False)
    figure = error_curve(np.arange(1, s.size + 1), {"singular value": s}, xlabel="order", ylabel="singular value")
    return {"singular_values": [float(v) for v in s], "figures": {"singular_values": svg(figure)}}


#: estimate name -> builder(session, data set name, options, output name)
ESTIMATES: dict[str, Callable[..., Action]] = {
    "frf": frf,
    "statespace": statespace,
    "frd": frd_fit,
    "hysteresis": hysteresis,
    "closedloop": closedloop,
}
