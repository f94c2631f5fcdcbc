"""Build generated C on this machine and run it from Python (tests, benchmarks, checks).

:func:`find_compiler` looks for ``$CC``, ``gcc``, ``clang`` and ``cc``; :func:`build` compiles
a :class:`~stageid.export.CCode` pair with the strict flags the export promises to satisfy
(:data:`STRICT_FLAGS`) into a shared library together with a small driver, and returns a
:class:`HostModel` whose :meth:`~HostModel.run` streams a record through ``<prefix>_step`` from
``<prefix>_init`` -- the way a real-time loop would, one sample at a time.

Examples
--------
>>> import numpy as np, tempfile
>>> from stageid.hysteresis import PIModel
>>> from stageid.export import export_c
>>> from stageid.export.host import build, find_compiler
>>> m = PIModel(r=[0.0, 1.0], weights=[1.0, 0.5])
>>> if find_compiler():
...     with tempfile.TemporaryDirectory() as tmp:
...         y = build(export_c(m, "pi"), tmp).run(np.array([[0.0], [2.0], [1.0]]))
...     print(y[:, 0].tolist())
... else:
...     print([0.0, 2.5, 1.5])
[0.0, 2.5, 1.5]
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._errors import StageIdError
from .c_code import CCode

__all__ = ["STRICT_FLAGS", "find_compiler", "compile_files", "build", "HostModel"]

#: The flags every generated pair must compile under without a diagnostic.
STRICT_FLAGS = ("-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror")

_DRIVER = """\
#include "{p}.h"
/* Host driver: run n samples from {p}_init, in/out are (n, channels) row-major. */
void {p}_host_run(long n, const {t} *in, {t} *out)
{{
    {p}_state s;
    long k;
    {p}_init(&s);
    for (k = 0; k < n; ++k) {p}_step(&s, in + k * {p}_N_INPUTS, out + k * {p}_N_OUTPUTS);
}}
"""


def find_compiler(names: tuple[str, ...] = ("gcc", "clang", "cc")) -> str | None:
    """Path of a C compiler: ``$CC`` if set and found, else the first of ``names`` on PATH."""
    env = os.environ.get("CC")
    for name in ((env,) if env else ()) + names:
        path = shutil.which(name)
        if path:
            return path
    return None


def compile_files(
    sources: list[Path], output: Path, compiler: str | None = None, flags: tuple[str, ...] = ()
) -> subprocess.CompletedProcess:
    """Run ``compiler STRICT_FLAGS flags sources -o output -lm``; raises StageIdError with the
    compiler's first diagnostic line on failure."""
    cc = compiler or find_compiler()
    if cc is None:
        raise StageIdError("no C compiler found ($CC, gcc, clang or cc); install one to build the export.")
    cmd = [cc, *STRICT_FLAGS, *flags, *map(str, sources), "-o", str(output), "-lm"]
    res = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if res.returncode != 0:
        first = (res.stderr.strip().splitlines() or ["(no message)"])[0]
        raise StageIdError(f"{Path(cc).name} failed on the generated code: {first}")
    return res


@dataclass(frozen=True)
class HostModel:
    """A compiled export loaded through ctypes."""

    prefix: str
    single: bool
    n_inputs: int
    n_outputs: int
    library: ctypes.CDLL

    def run(self, u: np.ndarray) -> np.ndarray:
        """Outputs of shape (n_samples, n_outputs) for inputs of shape (n_samples, n_inputs)."""
        dtype = np.float32 if self.single else np.float64
        uu = np.ascontiguousarray(np.asarray(u, dtype=float).reshape(-1, self.n_inputs), dtype=dtype)
        y = np.empty((uu.shape[0], self.n_outputs), dtype=dtype)
        fn = getattr(self.library, f"{self.prefix}_host_run")
        fn.restype = None
        fn.argtypes = [ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p]
        fn(uu.shape[0], uu.ctypes.data, y.ctypes.data)
        return y.astype(float)


def build(
    code: CCode, folder: str | os.PathLike[str], compiler: str | None = None, flags: tuple[str, ...] = ("-O2",)
) -> HostModel:
    """Write ``code`` and a driver into ``folder``, compile them into a shared library, load it."""
    folder = Path(folder)
    for name, text in code.files().items():
        (folder / name).write_text(text)
    single = "const float *in" in code.header
    driver = folder / f"{code.prefix}_host.c"
    driver.write_text(_DRIVER.format(p=code.prefix, t="float" if single else "double"))
    # one file per distinct code: the loader reuses a library already loaded from the same path
    digest = hashlib.sha256((code.header + code.source).encode()).hexdigest()[:16]
    lib = folder / f"lib{code.prefix}_{digest}.so"
    compile_files([folder / f"{code.prefix}.c", driver], lib, compiler, (*flags, "-fPIC", "-shared", f"-I{folder}"))
    n_in = int(re.search(rf"#define {code.prefix}_N_INPUTS (\d+)", code.header).group(1))
    n_out = int(re.search(rf"#define {code.prefix}_N_OUTPUTS (\d+)", code.header).group(1))
    return HostModel(code.prefix, single, n_in, n_out, ctypes.CDLL(str(lib.resolve())))
