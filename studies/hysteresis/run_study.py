"""Reproduction study of the modified Prandtl-Ishlinskii letter, on the reference actuator and real data.

Run:  .venv/bin/python studies/hysteresis/run_study.py [--quick]

Writes figures and ``summary.md`` to ``studies/hysteresis/output/`` (git-ignored) and prints the
summary beside the letter's numbers.

1. Reference actuator (``stageid.plants.piezo_actuator``), the letter's experiments:
   identification with 20 operators over -500...500 V on the decaying triangle of Fig. 4;
   maximum modelling error of the classical and the modified PI model (letter: 5.31 % vs
   1.02 %), also on two other records; a 1 Hz triangle of 3 um peak-to-peak at 1 kHz tracked
   open loop without correction (drive = reference / nominal gain), with the classical-PI
   inverse and with the modified-PI inverse (letter: 11 % -> 4.8 % -> 2.6 % FSR, hysteresis
   8.3 % -> 2.9 % -> 1.5 %).  Figures like Figs. 4-8 and 10-12.
2. Real data ``shared/data/piezo_dspace_preisach``: identify on the 20 Hz first-order-reversal
   record, validate on the 40 Hz and 100 Hz records and the tracking records (own sensor zero
   and starting state per record, see ``align_record``); max and RMS error in % of range.
3. Real data ``shared/data/piezo_smarthysteresis``: identify on the first half, validate on the
   second.

Data preparation for the real records (documented, not hidden): the dSPACE records begin with
a sensor start-up transient (the output slews by several um in the first 10-20 samples while
the drive is constant) and end with one corrupted sample; the study drops the idle stretch up
to 0.1 s before the drive starts moving and the last 10 samples.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
KINDS = (
    ("pi", "classical PI"),
    ("modified-pi", "modified PI (letter, no input warp)"),
    ("modified-pi+warp", "modified PI + monotone quadratic input warp (our extension)"),
)
OUT = HERE / "output"


def _trim_dspace(exp):
    u, y = exp.u[:, 0], exp.y[:, 0]
    moving = np.flatnonzero(np.abs(np.diff(u)) > 1e-9)
    start = max(0, int(moving[0]) - int(round(0.1 / exp.dt))) if moving.size else 0
    return u[start:-10], y[start:-10]


def reference_actuator(lines, figures: bool):
    from stageid.hysteresis import (
        Compensator,
        PIIdentifier,
        hysteresis_percent,
        max_error_percent,
        tracking_error_percent,
    )
    from stageid.plants.piezo_actuator import EXPERIMENTS, model, open_loop_gain
    from stageid.signals import triangle

    act = model()
    ident = EXPERIMENTS["decaying-triangle"]()
    u, y = ident.u[:, 0], ident.y[:, 0]
    h_major = hysteresis_percent(u[:1000], y[:1000])
    fits = {}
    for kind, _label in KINDS:
        t0 = time.perf_counter()
        est = PIIdentifier(
            "pi" if kind == "pi" else "modified-pi", n_operators=20, input_warp=kind == "modified-pi+warp"
        )
        fits[kind] = (est.fit(ident), time.perf_counter() - t0)
    lines.append("## 1. Reference actuator (simulated), the letter's experiments\n")
    lines.append(
        f"Actuator: `stageid.plants.piezo_actuator.model()`, output {y.min():.2f}...{y.max():.2f} um over "
        f"-500...500 V, hysteresis of the first (full-range) cycle {h_major:.1f} % (letter: 8.3 %).\n"
    )
    lines.append(
        "| max modelling error, % of output range | classical PI | modified PI (letter) | modified PI + input warp | letter (classical / modified) |"
    )
    lines.append("|---|---|---|---|---|")
    preds = {}
    for name in ("decaying-triangle", "triangle-1hz", "decaying-sine"):
        exp = EXPERIMENTS[name]() if name != "decaying-triangle" else ident
        row = []
        for kind, _ in KINDS:
            m = fits[kind][0].model
            yh = m.simulate(exp.u)[:, 0]  # model as stored: zero state at 0 V, identification offset
            row.append(max_error_percent(exp.y, yh))
            if name == "decaying-triangle":
                preds[kind] = yh
        letter = "5.31 / 1.02" if name == "decaying-triangle" else "-"
        tag = " (identification record)" if name == "decaying-triangle" else " (validation)"
        lines.append(f"| {name}{tag} | {row[0]:.2f} | {row[1]:.2f} | {row[2]:.2f} | {letter} |")
    lines.append("")
    lines.append(
        f"Identification time: classical {fits['pi'][1]:.1f} s, modified {fits['modified-pi'][1]:.1f} s, "
        f"modified + warp {fits['modified-pi+warp'][1]:.1f} s (input warp q = {fits['modified-pi+warp'][0].model.input_warp:.3f}).\n"
    )

    dt = 1e-3
    yref = triangle(1.0, 3.0, dt, amplitude=1.5) + 0.5  # 1 Hz, 3 um peak-to-peak, 1 kHz, 3 cycles
    k = open_loop_gain(act)
    drives = {"open loop (no correction)": yref / k}
    for kind, label in (
        ("pi", "classical-PI inverse"),
        ("modified-pi", "modified-PI inverse"),
        ("modified-pi+warp", "modified-PI + warp inverse"),
    ):
        drives[label] = Compensator(fits[kind][0].model, limits=(-500.0, 500.0)).run(yref)[:, 0]
    letter_t = {
        "open loop (no correction)": ("11.0", "8.3"),
        "classical-PI inverse": ("4.8", "2.9"),
        "modified-PI inverse": ("2.6", "1.5"),
        "modified-PI + warp inverse": ("-", "-"),
    }
    lines.append("1 Hz triangle, 3 um peak-to-peak (0.5 +- 1.5 um), 1 kHz, open-loop feedforward:\n")
    lines.append("| drive | tracking error, % FSR | hysteresis, % | letter: error / hysteresis |")
    lines.append("|---|---|---|---|")
    outs = {}
    for label, drive in drives.items():
        ya = act.simulate(drive)[:, 0]
        outs[label] = ya
        lines.append(
            f"| {label} | {tracking_error_percent(yref, ya):.2f} | {hysteresis_percent(yref, ya):.2f} | "
            f"{letter_t[label][0]} / {letter_t[label][1]} |"
        )
    lines.append("")
    if figures:
        from stageid.plots.hysteresis import loop_figure, model_errors_figure, tracking_figure

        t = ident.time
        f = model_errors_figure(t, {"input [V]": u}, ylabel="input [V]", title="Fig. 4: identification input")
        f.savefig(OUT / "fig04_input.png")
        loop_figure(u, {"actuator": y}, title="Fig. 5: actuator response").savefig(OUT / "fig05_actuator.png")
        loop_figure(
            u,
            {"modified PI": preds["modified-pi"], "modified PI + warp": preds["modified-pi+warp"]},
            title="Fig. 6: modified PI model",
        ).savefig(OUT / "fig06_modified_pi.png")
        loop_figure(u, {"classical PI": preds["pi"]}, title="Fig. 7: classical PI model").savefig(
            OUT / "fig07_classical_pi.png"
        )
        model_errors_figure(
            t,
            {
                "classical PI": y - preds["pi"],
                "modified PI": y - preds["modified-pi"],
                "modified PI + warp": y - preds["modified-pi+warp"],
            },
            title="Fig. 8: modelling errors",
        ).savefig(OUT / "fig08_errors.png")
        tt = np.arange(yref.size) * dt
        for fig_no, label in zip((10, 11, 12, 13), drives):
            tracking_figure(tt, yref, outs[label], title=f"Fig. {fig_no}: {label}").savefig(
                OUT / f"fig{fig_no}_tracking.png"
            )
    return fits


def dspace(lines, quick: bool, figures: bool):
    from stageid.data.datasets import load_dspace_piezo, shared_data_dir
    from stageid.hysteresis import PIIdentifier, align_record, max_error_percent, rms_error_percent

    root = shared_data_dir()
    folder = None if root is None else root / "piezo_dspace_preisach"
    if folder is None or not folder.is_dir():
        lines.append("## 2. dSPACE piezo records: data not found, skipped\n")
        return
    names = [
        "20_hz_no_lp",
        "40_hz_no_lp",
        "100_hz_no_lp",
        "tri50_1",
        "tri100_1",
        "sine50_1",
        "sine100_1",
        "prbn_1",
        "bigsine_1",
    ]
    recs = {n: _trim_dspace(load_dspace_piezo(folder / f"{n}.mat")) for n in names}
    lines.append("## 2. Real data: `piezo_dspace_preisach` (identify on the 20 Hz FORC record)\n")
    lines.append(
        "| record | input range [V] | classical PI max / RMS % | modified PI (letter) | modified PI + warp | "
        "modified PI (letter) + creep |"
    )
    lines.append("|---|---|---|---|---|---|")
    fits = {
        k: PIIdentifier("pi" if k == "pi" else "modified-pi", n_operators=20, input_warp=k == "modified-pi+warp").fit(
            recs["20_hz_no_lp"]
        )
        for k, _ in KINDS
    }
    # our extension (studies/hysteresis/creep_study.py): linear creep, lags 0.05...20 s, weights >= 0
    fits["modified-pi+creep"] = PIIdentifier(
        "modified-pi",
        n_operators=20,
        input_warp=False,
        sample_time=load_dspace_piezo(folder / "20_hz_no_lp.mat").dt,
        creep=(0.05, 0.2, 1.0, 5.0, 20.0),
    ).fit(recs["20_hz_no_lp"])
    for n in names:
        u, y = recs[n]
        cells = []
        for k in [k for k, _ in KINDS] + ["modified-pi+creep"]:
            _, yh = align_record(fits[k].model, u, y)
            cells.append(f"{max_error_percent(y, yh):.2f} / {rms_error_percent(y, yh):.2f}")
        tag = " (identification)" if n == "20_hz_no_lp" else ""
        lines.append(
            f"| {n}{tag} | {u.min():.0f}...{u.max():.0f} | {cells[0]} | {cells[1]} | {cells[2]} | {cells[3]} |"
        )
    lines.append("")
    lines.append(
        "Issue's reference: classical PI with 20 equally spaced operators about 3.5 % (fit) and 4.1 % (40 Hz) "
        "max error; target for the modified PI: 2 % or better.  Validation records: own output offset "
        "(sensor zero) and starting state fitted, model untouched.\n"
    )
    lines.append(
        "```\n"
        + fits["modified-pi"].summary()
        + "\n"
        + fits["modified-pi+warp"].summary()
        + "\n"
        + fits["modified-pi+creep"].summary()
        + "\n```\n"
    )


def smarthysteresis(lines):
    from stageid.data.datasets import load_smarthysteresis, shared_data_dir
    from stageid.hysteresis import PIIdentifier, max_error_percent, rms_error_percent

    root = shared_data_dir()
    path = None if root is None else root / "piezo_smarthysteresis" / "hysteresis_v_150_1hz.csv"
    if path is None or not path.exists():
        lines.append("## 3. smarthysteresis record: data not found, skipped\n")
        return
    exp = load_smarthysteresis(path)
    u, y = exp.u[:, 0], exp.y[:, 0]
    start = int(np.flatnonzero(np.abs(np.diff(u)) > 1e-9)[0])
    start += int(round(0.1 / exp.dt))  # the drive jumps from 0 to -87 V: skip the 0.1 s the sensor needs to settle
    u, y = u[start:], y[start:]
    half = u.size // 2
    lines.append("## 3. Real data: `piezo_smarthysteresis` (150 V, 1 Hz sine; identify first half, validate second)\n")
    lines.append("| model | fit max / RMS % | validation max / RMS % |")
    lines.append("|---|---|---|")
    for k, _ in KINDS:
        fit = PIIdentifier(
            "pi" if k == "pi" else "modified-pi", n_operators=20, input_warp=k == "modified-pi+warp"
        ).fit((u[:half], y[:half]))
        # the second half continues the first: resume from the state where the first half ended
        m0 = fit.model.with_state(fit.model.consistent_state(u[0], fit.initial_states[0]))
        m0 = type(m0)(**{**m0.__dict__, "output_offset": fit.output_offsets[0]})
        _, state = m0.run(u[:half])
        yv = m0.with_state(state).simulate(u[half:])[:, 0]
        lines.append(
            f"| {k} | {fit.max_error_percent[0]:.2f} / {fit.rms_error_percent[0]:.2f} | "
            f"{max_error_percent(y[half:], yv):.2f} / {rms_error_percent(y[half:], yv):.2f} |"
        )
    lines.append("")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Modified PI letter reproduction study")
    ap.add_argument("--quick", action="store_true", help="skip the real data")
    ap.add_argument("--no-figures", action="store_true")
    args = ap.parse_args(argv)
    OUT.mkdir(parents=True, exist_ok=True)
    lines = ["# Modified Prandtl-Ishlinskii letter: reproduction study\n"]
    reference_actuator(lines, not args.no_figures)
    if not args.quick:
        dspace(lines, args.quick, not args.no_figures)
        smarthysteresis(lines)
    text = "\n".join(lines)
    (OUT / "summary.md").write_text(text + "\n", encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
