"""``stageid identify closedloop ... --controller unknown``: the routes without a controller model.

Truth: :mod:`stageid.plants.levitated_pair` under its filtered PD, 2 % measurement noise.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from stageid.cli.main import main
from stageid.data import write_csv
from stageid.models import load_model
from stageid.plants import levitated_pair as lp


@pytest.fixture(scope="module")
def record(tmp_path_factory) -> str:
    r, u, y = lp.record(4000, seed=2)
    path = tmp_path_factory.mktemp("loop") / "loop.csv"
    cols = {"r1": r[:, 0], "r2": r[:, 1], "u1": u[:, 0], "u2": u[:, 1], "x1": y[:, 0], "x2": y[:, 1]}
    write_csv(path, cols, dt=lp.DT)
    return str(path)


def _args(record: str, out: Path, *extra: str) -> list[str]:
    return [
        "identify",
        "closedloop",
        record,
        "--controller",
        "unknown",
        "--plant-inputs",
        "u1,u2",
        "--outputs",
        "x1,x2",
        "--band",
        "0.5:50",
        "-o",
        str(out),
        *extra,
    ]


def test_direct_route_through_the_cli(record, tmp_path, capsys):
    out, unc, rep = tmp_path / "G.json", tmp_path / "G_std.csv", tmp_path / "report"
    rc = main(_args(record, out, "--order", "4", "--discrete", "--uncertainty", str(unc), "--report", str(rep)))
    assert rc == 0
    G = load_model(out)
    assert G.dt == lp.DT
    s = np.log(G.poles().astype(complex)) / lp.DT
    np.testing.assert_allclose(np.sort(s[s.real > 0].real), lp.UNSTABLE_POLES, rtol=0.02)
    err = capsys.readouterr().err
    assert "direct route" in err and "assumptions" in err and "whiteness" in err
    assert unc.exists()
    metrics = json.loads((rep / "metrics.json").read_text())
    assert metrics["method"] == "direct" and len(metrics["unstable_poles_rad_s"]) == 2


def test_old_spelling_and_continuous_plant(record, tmp_path):
    out = tmp_path / "G.json"
    args = _args(record, out, "--order", "4")
    args[1] = "closed-loop"
    assert main(args) == 0
    G = load_model(out)
    assert G.dt is None
    poles = G.poles()
    np.testing.assert_allclose(np.sort(poles[poles.real > 0].real), lp.UNSTABLE_POLES, rtol=0.02)


def test_two_stage_needs_the_reference(record, tmp_path, capsys):
    out = tmp_path / "G.json"
    rc = main(_args(record, out, "--method", "two-stage"))
    assert rc == 2 and not out.exists()
    assert "needs the recorded references" in capsys.readouterr().err


@pytest.mark.parametrize(
    "extra, words",
    [
        (("--method", "oe"), "needs a known controller"),
        (("--order", "0"), "--order must be"),
        (("--method", "joint", "--reference", "r1,r2", "--uncertainty", "b.csv"), "gives no bands"),
    ],
)
def test_bad_combinations_are_one_line_errors(record, tmp_path, capsys, extra, words):
    out = tmp_path / "G.json"
    extra = tuple(str(tmp_path / e) if e == "b.csv" else e for e in extra)
    rc = main(_args(record, out, *extra))
    err = capsys.readouterr().err
    assert rc == 2 and words in err and "Traceback" not in err
    assert not out.exists()


def test_known_controller_rejects_the_unknown_methods(record, tmp_path, capsys):
    rc = main(
        ["identify", "closedloop", record, "--controller", str(tmp_path / "K.json"), "--references", "r1,r2",
         "--outputs", "x1,x2", "--method", "direct", "-o", str(tmp_path / "G.json")]
    )  # fmt: skip
    assert rc == 2 and "is for --controller unknown" in capsys.readouterr().err
