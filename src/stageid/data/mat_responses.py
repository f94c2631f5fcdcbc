"""Measured frequency responses stored in a MATLAB ``.mat`` file (structs included).

A MATLAB user keeps an FRF as complex vectors beside a frequency vector, often inside a struct
(``modelFit.frf.G_uz2stage`` with ``modelFit.frf.freqs_Hz``).  The rules, read by
:func:`mat_responses`:

* the **frequency axis** is the one real vector whose last name part is ``f_hz``, ``freqs_hz``,
  ``freq_hz``, ``f``, ``freq``, ``freqs`` or ``frequency`` [Hz], else ``w``, ``w_s``, ``omega``
  [rad/s] (case ignored); several that agree are one axis;
* the **responses** are the complex vectors of its length; one is chosen by its name (the full
  flattened name or its last part);
* a response named ``G_<in>2<out>`` (a common MATLAB naming) gets input ``<in>`` and output
  ``<out>``; any other name is output ``<name>`` of input ``u``.
"""

from __future__ import annotations

import re

import numpy as np

from .._errors import DataError
from .files import PathLike
from .mat_format import mat_leaves

__all__ = ["mat_responses", "mat_response_names", "HZ_NAMES", "RAD_NAMES"]

HZ_NAMES = ("f_hz", "freqs_hz", "freq_hz", "f", "freq", "freqs", "frequency")
RAD_NAMES = ("w", "w_s", "omega")
_PAIR = re.compile(r"^G_?([A-Za-z0-9]+)2([A-Za-z0-9_]+)$")


def _vector(arr: np.ndarray) -> np.ndarray | None:
    """A MATLAB vector (n, 1), (1, n) or (n,) with n > 1 as 1-D; else None."""
    if arr.ndim == 1 or (arr.ndim == 2 and 1 in arr.shape):
        flat = arr.reshape(-1)
        return flat if flat.size > 1 else None
    return None


def _frequency_axis(leaves: list[tuple[str, np.ndarray]], where: str) -> np.ndarray:
    """The frequency vector [Hz] by the module's rule."""
    for names, scale in ((HZ_NAMES, 1.0), (RAD_NAMES, 0.5 / np.pi)):
        found = [
            (k, v)
            for k, a in leaves
            if a.dtype.kind in "iuf" and k.rsplit(".", 1)[-1].lower() in names and (v := _vector(a)) is not None
        ]
        if not found:
            continue
        first = found[0][1]
        if any(v.shape != first.shape or not np.allclose(v, first, rtol=1e-9, atol=0.0) for _, v in found):
            raise DataError(
                f"{where}several different frequency vectors ({', '.join(k for k, _ in found)}); expected one."
            )
        return first.astype(float) * scale
    raise DataError(
        f"{where}no frequency vector; expected a real vector named one of {', '.join(HZ_NAMES)} [Hz] "
        f"or {', '.join(RAD_NAMES)} [rad/s]."
    )


def _file_name(path: PathLike) -> str:
    """The file's name without its folders (either slash), for messages."""
    return str(getattr(path, "name", path)).replace("\\", "/").rsplit("/", 1)[-1]


def _responses(path: PathLike, where: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The frequency axis [Hz] and the complex vectors of its length by flattened name."""
    leaves, _ = mat_leaves(path)
    freqs = _frequency_axis(leaves, where)
    responses = {
        k: v for k, a in leaves if a.dtype.kind == "c" and (v := _vector(a)) is not None and v.size == freqs.size
    }
    if not responses:
        raise DataError(f"{where}no complex response vector of {freqs.size} values (the frequency vector's length).")
    return freqs, responses


def mat_response_names(path: PathLike) -> tuple[str, ...]:
    """The flattened names of a ``.mat`` file's frequency responses, in the file's order.

    Each name selects its response in :func:`mat_responses` (and
    :func:`stageid.models.frequency_response.read_frd`).

    Raises
    ------
    DataError
        As :func:`mat_responses`: no frequency vector, or no complex vector of its length.

    Examples
    --------
    >>> import numpy as np, tempfile, os, scipy.io
    >>> path = os.path.join(tempfile.mkdtemp(), "frf.mat")
    >>> f = np.array([1.0, 2.0, 4.0])
    >>> scipy.io.savemat(path, {"meas": {"freqs_Hz": f, "G_u2y": 1 / (1j * f), "G_u2z": 2 / (1j * f)}})
    >>> mat_response_names(path)
    ('G_u2y', 'G_u2z')
    """
    return tuple(_responses(path, f"file '{_file_name(path)}': ")[1])


def mat_responses(path: PathLike, response: str | None = None) -> tuple[np.ndarray, np.ndarray, str, str]:
    """One measured frequency response of a ``.mat`` file: ``(freqs_hz, values, input, output)``.

    Parameters
    ----------
    path : str or path-like
    response : str, optional
        The complex vector to take, by flattened name or its last part; required when the file
        holds more than one.

    Returns
    -------
    freqs_hz : ndarray of shape (n_freqs,)
    values : complex ndarray of shape (n_freqs,)
    input, output : str
        Channel names (see the module notes).

    Raises
    ------
    DataError
        No frequency vector, no complex vector of its length, several when ``response`` is not
        given, or an unknown ``response`` (listing the available ones).
    """
    name = _file_name(path)
    where = f"file '{name}': "
    freqs, responses = _responses(path, where)
    listed = ", ".join(responses)
    if response is None:
        if len(responses) > 1:
            raise DataError(
                f"file '{name}' holds {len(responses)} frequency responses ({listed}); choose one with `response=`."
            )
        key = next(iter(responses))
    else:
        # the full name, its last part, or with the variable name a lone struct's columns drop
        keys = [k for k in responses if response in (k, k.rsplit(".", 1)[-1]) or response.endswith("." + k)]
        if len(keys) != 1:
            found = "matches several" if keys else "is not one"
            raise DataError(
                f"{where}`response=` '{response}' {found} of the frequency responses; expected one of {listed}."
            )
        key = keys[0]
    last = key.rsplit(".", 1)[-1]
    pair = _PAIR.match(last)
    inp, out = (pair.group(1), pair.group(2)) if pair else ("u", last)
    return freqs, responses[key].astype(complex), inp, out
