"""Bias against scatter of the realised Hankel-MAP model (issue 20): why some bands under-cover.

For one stage and ``n_seeds`` noise seeds: the seeds' mean error (bias) and scatter of the
realised model and of the eq. 9 response, each over the model's std, median over frequency,
per entry; and the coverage of ``|err| <= 1.73 std``.

    .venv/bin/python studies/uncertainty/bias_check.py siso|p558|channels [n_seeds]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from stageid.plants import piezo_stage as ps
from stageid.subspace import HankelMAP

sys.path.insert(0, str(Path(__file__).parents[2] / "tests"))
from _subspace_systems import band_limited, random_stage, record  # noqa: E402

F = np.geomspace(1.5, 98, 100)


def fit(case: str, seed: int):
    if case == "siso":  # the unseen SISO stage 31 of run_study's random-siso case
        g = random_stage(31, m=1, q=1, modes=3)
        return g, HankelMAP(order=g.n_states).fit(record(g, band_limited(8000, 1, g.dt, 2 * seed), 0.03, 2 * seed))
    g = ps.model()
    if case == "channels":
        exps = [ps.EXPERIMENTS[k](seed) for k in ("chirp-z", "chirp-rx", "chirp-ry")]
        return g, HankelMAP(order=[7, 4, 4], per_channel=True).fit(exps)
    exp = record(g, band_limited(20000, 3, g.dt, seed) * np.array([10.0, 100.0, 100.0]), 0.01, seed)
    return g, HankelMAP(order=15, horizon=40).fit(exp)


def main() -> None:
    case = sys.argv[1]
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 10
    err, std, err9 = [], [], []
    for seed in range(n):
        g, res = fit(case, seed)
        Gt = g.frequency_response(F)
        fr = res.response_uncertainty(F)
        err.append(fr.response - Gt)
        std.append(fr.std)
        err9.append(res.response_bands(F)[0] - Gt)
    E, S, E9 = np.array(err), np.array(std), np.array(err9)
    rms_std = np.sqrt((S**2).mean(0))
    bias, spread, bias9 = E.mean(0), E.std(0), E9.mean(0)
    names = [(o, i) for o in fr.outputs for i in fr.inputs]
    for a, (o, i) in enumerate(names):
        k, j = divmod(a, len(fr.inputs))
        st = rms_std[:, k, j]
        print(
            f"{i}->{o}: |bias|/std {np.median(np.abs(bias[:, k, j]) / st):.2f}, scatter/std "
            f"{np.median(spread[:, k, j] / st):.2f}, eq. 9 |bias|/std {np.median(np.abs(bias9[:, k, j]) / st):.2f}, "
            f"coverage {100 * np.mean(np.abs(E[:, :, k, j]) <= 1.73 * S[:, :, k, j]):.0f} %"
        )


if __name__ == "__main__":
    main()
