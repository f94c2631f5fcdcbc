"""
Exporting a compensator to C for a real-time controller
=======================================================

:func:`~stageid.export.export_c` writes a model or a hysteresis compensator as two self-contained
C99 files (no heap, no I/O, only ``<math.h>``): a state struct, ``<prefix>_init`` and
``<prefix>_step``. Here the modified-PI compensator of the reference piezo actuator, with its
drive limits; when a C compiler is on the machine, the generated code is compiled and run on a
reference and compared with the Python compensator sample by sample.
"""

import shutil
import subprocess
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from stageid.export import export_c
from stageid.hysteresis import Compensator, PIIdentifier
from stageid.plants import plant_module
from stageid.signals import triangle

actuator = plant_module("piezo-actuator")
fit = PIIdentifier("modified-pi", n_operators=20, input_warp=False).fit(
    actuator.EXPERIMENTS["decaying-triangle"](seed=0)
)
code = export_c(fit.model, "comp", inverse=True, limits=(-500.0, 500.0))
header = code.header
print("\n".join(line for line in header.splitlines() if line.startswith(("void", "typedef", "#define COMP"))))

y_ref = triangle(1.0, 2.0, 1e-3, amplitude=1.2) + 0.4  # um
drive_python = Compensator(fit.model, limits=(-500.0, 500.0)).run(y_ref)[:, 0]

compiler = shutil.which("cc") or shutil.which("gcc")
drive_c = None
if compiler:
    main = """#include <stdio.h>
#include "comp.h"
int main(void) { comp_state s; double y, u; comp_init(&s);
  while (scanf("%lf", &y) == 1) { comp_step(&s, &y, &u); printf("%.17g\\n", u); } return 0; }
"""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name, text in code.files().items():
            (folder / name).write_text(text)
        (folder / "main.c").write_text(main)
        subprocess.run(
            [
                compiler,
                "-std=c99",
                "-O2",
                "-o",
                str(folder / "run"),
                str(folder / "main.c"),
                str(folder / "comp.c"),
                "-lm",
            ],
            check=True,
        )
        text = "\n".join(repr(float(v)) for v in y_ref)
        out = subprocess.run([str(folder / "run")], input=text, capture_output=True, text=True, check=True).stdout
        drive_c = np.array([float(v) for v in out.split()])
    print(f"C against Python: largest difference {np.abs(drive_c - drive_python).max():.2e} V")
else:
    print("no C compiler on this machine: the C code is not compiled here")

t = np.arange(y_ref.size) * 1e-3
fig, ax = plt.subplots(figsize=(8, 3.5), layout="constrained")
ax.plot(t, drive_python, "C0", lw=2, label="Python compensator")
if drive_c is not None:
    ax.plot(t, drive_c, "C1--", lw=1, label="exported C99 compensator")
ax.set_xlabel("time [s]")
ax.set_ylabel("drive [V]")
ax.grid(True, alpha=0.3)
ax.legend(fontsize=8)
plt.show()
