"""Random open-loop-unstable stages of the closed-loop paper's class under a stabilising
controller, their closed-loop records, and the measures the PEM and closed-loop cases share.

Class (Shakir & Kim, eq. 16 and sec. 3.3): p = 2 or 3 axes; each diagonal entry
``k / ((s - a)(s + b))`` with an unstable pole ``a`` of 30-100 rad/s; each coupling of third
order ``c (s + z) / ((s + d)(s^2 + 2 zeta w s + w^2))`` with a lightly damped mode (damping
0.3-5 %, 80-400 Hz) and a size of 1-10 % of the diagonal's at the crossover. The controller is a
decentralised [2, 2] lead-lag per axis with its crossover drawn in 80-150 Hz, Tustin at 5 kHz; a
draw whose loop is unstable is drawn again. One record per axis: a chirp (DC to 2.5 kHz) or a
random-phase multisine on that axis's reference, 1-2 s, with logger time columns and white output
noise at ``noise`` times each output's RMS.
"""

from __future__ import annotations

import dataclasses
import pathlib
import pickle

import numpy as np
from common import TIME_STYLES, CliFailure, run_cli, write_record

DT = 1.0 / 5000.0
BAND = (20.0, 300.0)  # the CLI's default band of the reduction and errors


def _p(*factors) -> np.ndarray:
    out = np.array([1.0])
    for f in factors:
        out = np.polymul(out, np.asarray(f, dtype=float))
    return out


def draw_loop(rng: np.random.Generator):
    """(plant TransferMatrix continuous, controller StateSpaceModel at DT, unstable poles rad/s)."""
    from stageid.models import TransferMatrix
    from stageid.plants.maglev import lead_lag

    for _ in range(50):
        n = int(rng.integers(2, 4))
        a = rng.uniform(30.0, 100.0, n)
        b = rng.uniform(50.0, 120.0, n)
        k = 10 ** rng.uniform(0.0, 3.0, n)
        wc_hz = rng.uniform(80.0, 150.0)
        s_c = 2j * np.pi * wc_hz
        num = [[None] * n for _ in range(n)]
        den = [[None] * n for _ in range(n)]
        for i in range(n):
            for j in range(n):
                if i == j:
                    num[i][j], den[i][j] = [k[i]], _p([1, -a[i]], [1, b[i]])
                    continue
                w = 2 * np.pi * rng.uniform(80.0, 400.0)
                zeta = 10 ** rng.uniform(np.log10(0.003), np.log10(0.05))
                d = rng.uniform(50.0, 500.0)
                nz = [1.0, rng.uniform(100.0, 2000.0)] if rng.random() < 0.5 else [1.0]
                dd = _p([1, d], [1, 2 * zeta * w, w**2])
                shape = abs(np.polyval(nz, s_c) / np.polyval(dd, s_c))
                size = 10 ** rng.uniform(-2, -1) * k[j] / abs((s_c - a[j]) * (s_c + b[j]))
                num[i][j], den[i][j] = list(np.sign(rng.standard_normal()) * size / shape * np.array(nz)), dd
        plant = TransferMatrix(num, den, None, [f"u{i + 1}" for i in range(n)], [f"y{i + 1}" for i in range(n)])
        parts = [lead_lag(k[i], a[i], b[i], wc_hz) for i in range(n)]
        cnum = [[parts[i][0] if i == j else [0.0] for j in range(n)] for i in range(n)]
        cden = [[parts[i][1] if i == j else [1.0] for j in range(n)] for i in range(n)]
        K = TransferMatrix(cnum, cden, None, [f"e{i + 1}" for i in range(n)], plant.inputs)
        K = K.to_statespace(minimal=False).c2d(DT, "tustin")
        if loop_is_stable(plant, K):
            return plant, K, np.sort(a)
    raise RuntimeError("no stabilised loop in 50 draws")


def loop_is_stable(plant, K) -> bool:
    from stageid.models import feedback

    G = plant.to_statespace(minimal=False).c2d(DT, "zoh")
    return bool(np.abs(feedback(G, K).poles()).max() < 1.0 - 1e-6)


def closed_loop_response(plant, K, f: np.ndarray) -> np.ndarray:
    """``T = G M (I + G M)^-1`` at ``f`` (Hz), plant ZOH-sampled at DT: shape (n_freqs, p, p)."""
    G = plant.to_statespace(minimal=False) if hasattr(plant, "to_statespace") else plant
    G = G.c2d(DT, "zoh") if G.dt is None else G
    g, m = G.frequency_response(f), K.frequency_response(f)
    eye = np.eye(g.shape[1])
    return np.stack([gk @ mk @ np.linalg.inv(eye + gk @ mk) for gk, mk in zip(g, m)])


def write_experiments(rng, plant, K, noise: float, workdir: pathlib.Path):
    """One record per axis; returns (paths, [(r, y_measured)], time style, excitation)."""
    from stageid.closedloop.validation import simulate_closed_loop
    from stageid.signals import chirp, multisine

    n = plant.n_outputs
    style = TIME_STYLES[int(rng.integers(len(TIME_STYLES)))]
    kind = "chirp" if rng.random() < 0.5 else "multisine"
    paths, records = [], []
    for axis in range(n):
        n_samples = int(rng.integers(5000, 10001))
        if kind == "chirp":
            r1 = chirp(0.0, 2500.0, duration=n_samples * DT, dt=DT, amplitude=1e-6)[:n_samples]
        else:
            r1 = 1e-6 * multisine(n_samples, DT, 5.0, 2000.0, seed=int(rng.integers(2**31)))
        R = np.zeros((r1.size, n))
        R[:, axis] = r1
        snr = None if noise <= 0 else -20 * np.log10(noise)
        y, _ = simulate_closed_loop(plant, K, R, DT, snr, int(rng.integers(2**31)), "channel")
        cols = {**{f"r{i + 1}": R[:, i] for i in range(n)}, **{f"y{i + 1}": y[:, i] for i in range(n)}}
        paths.append(write_record(workdir / f"exp{axis + 1}.csv", cols, 1 / DT, style, rng))
        records.append((R, y))
    return paths, records, style, kind


def loop_cost(plant, K, records) -> float:
    """Summed squared output error of the loop closed around ``plant`` and driven by the recorded
    references (the output-error cost of the closed loop r -> y), from rest."""
    from stageid.closedloop.validation import simulate_closed_loop

    return sum(float(np.sum((y - simulate_closed_loop(plant, K, R, DT)[0]) ** 2)) for R, y in records)


@dataclasses.dataclass
class LoopDraw:
    plant: object  # the true continuous plant
    controller: object  # the known discrete controller
    unstable: np.ndarray  # the plant's unstable poles, rad/s
    records: list  # [(references, measured outputs)] per experiment
    detail: str
    failed: str  # the command's one-line message, "" when it ran
    key: tuple = ()  # (seed, salt, noise) it was drawn for


SALT = 202  # the draws' stream, one for the PEM and closed-loop cases (tests of older PEM draws pass 303)


def draw_and_fit(seed: int, workdir: pathlib.Path, noise: float, salt: int = SALT) -> LoopDraw:
    """Draw a loop from ``(seed, salt)``, write its records and controller into ``workdir`` and run
    ``stageid identify closed-loop`` on them (plant to ``G.json``, closed loop to ``T.json``).

    One run serves both cases: the prediction-error loop ``T`` is the command's first step and
    the plant ``G`` its last, so a case run after the other in the same folder (the runner's
    shared draw) takes the draw kept there instead of fitting again."""
    kept = workdir / "loop-draw.pkl"
    if kept.exists():
        draw = pickle.loads(kept.read_bytes())
        if draw.key == (seed, salt, noise):
            return draw
    draw = _draw_and_fit(seed, workdir, noise, salt)
    kept.write_bytes(pickle.dumps(draw))
    return draw


def _draw_and_fit(seed: int, workdir: pathlib.Path, noise: float, salt: int) -> LoopDraw:
    from stageid.models import save_model

    rng = np.random.default_rng([seed, salt])
    plant, K, unstable = draw_loop(rng)
    save_model(K, workdir / "K.json")
    paths, records, style, kind = write_experiments(rng, plant, K, noise, workdir)
    n = plant.n_outputs
    failed = ""
    try:
        run_cli([
            "identify", "closed-loop", *paths, "--references", ",".join(f"r{i + 1}" for i in range(n)),
            "--outputs", ",".join(f"y{i + 1}" for i in range(n)), "--controller", workdir / "K.json",
            "-o", workdir / "G.json", "--closed-loop-output", workdir / "T.json",
        ])  # fmt: skip
    except CliFailure as exc:
        failed = str(exc)
    return LoopDraw(plant, K, unstable, records, f"{n}x{n}, {kind}, t {style}", failed, (seed, salt, noise))
