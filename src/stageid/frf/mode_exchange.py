"""Mode exchange: a way out of the local minima of the output-error fit of a frequency response.

A refined fit can settle with one of its pole pairs on noise (a sharp pair between lines, or
past the last mode) while a weak mode of the data goes unfitted: every start of the
subspace and vector-fitting routes sees the weak mode below the noise of its own linear fit,
and the refinement cannot move a pair across the band, because the cost rises in between.
The missing mode shows as a peak of the weighted residual ``w_k ||G_model(z_k) - G_k||^2``
(:func:`residual_peaks`).  :func:`exchanged_modes` proposes the model with the weakest pole
pair (least weighted energy of its term over the lines) replaced by a lightly damped pair at
such a peak, its output direction the residual's dominant one there; the caller refits
``B``, ``D``, refines, and keeps the exchange only when the cost falls.
"""

from __future__ import annotations

import numpy as np

__all__ = ["real_modal_form", "residual_peaks", "exchanged_modes", "NEW_MODE_DAMPING"]

#: Relative damping of the pair placed at the residual's peak (the refinement adjusts it).
NEW_MODE_DAMPING = 0.01


def real_modal_form(
    A: np.ndarray, B: np.ndarray, C: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[slice]] | None:
    """``(A, B, C)`` in real block-diagonal form (``[[Re a, Im a], [-Im a, Re a]]`` per pair) and
    the states of each mode; None when ``A`` is not diagonalisable to working precision."""
    lam, V = np.linalg.eig(A)
    if not np.all(np.isfinite(lam)) or np.linalg.cond(V) > 1e10:
        return None
    cols, blocks, i = [], [], 0
    for k in np.argsort(np.abs(lam.imag) > 0, kind="stable"):  # real poles first
        if lam[k].imag < 0:
            continue
        if lam[k].imag == 0:
            cols.append(V[:, k].real)
            blocks.append(slice(i, i + 1))
            i += 1
        else:
            cols += [V[:, k].real, V[:, k].imag]  # A [Re v, Im v] = [Re v, Im v] [[Re a, Im a], [-Im a, Re a]]
            blocks.append(slice(i, i + 2))
            i += 2
    if i != A.shape[0]:
        return None
    T = np.column_stack(cols)
    Ti = np.linalg.inv(T)
    return Ti @ A @ T, Ti @ B, C @ T, blocks


#: Lines summed into one score of the residual: a light mode spans a few lines, a noise spike one.
PEAK_WINDOW = 3
#: Residual peaks tried per exchange round, the largest first.
N_PEAKS = 3


def residual_peaks(residual: np.ndarray, w: np.ndarray, n_peaks: int = N_PEAKS) -> list[int]:
    """The lines at the ``n_peaks`` largest maxima of the weighted residual energy summed over
    ``PEAK_WINDOW`` lines, at least ``PEAK_WINDOW`` lines apart."""
    energy = w * np.sum(np.abs(residual) ** 2, axis=(1, 2))
    score = np.convolve(energy, np.ones(PEAK_WINDOW), mode="same")
    peaks: list[int] = []
    for k in np.argsort(score)[::-1]:
        if all(abs(int(k) - p) >= PEAK_WINDOW for p in peaks):
            peaks.append(int(k))
        if len(peaks) == n_peaks:
            break
    return peaks


def exchanged_modes(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, residual: np.ndarray, zs: np.ndarray, w: np.ndarray, peak: int
) -> tuple[np.ndarray, np.ndarray] | None:
    """``(A, C)`` with the weakest pole pair of ``(A, B, C)`` replaced by one at line ``peak``
    (one of :func:`residual_peaks` of ``residual = G_model - G`` at the unit-circle points
    ``zs``); None when the model has no pair or no real modal form."""
    modal = real_modal_form(A, B, C)
    if modal is None:
        return None
    Am, Bm, Cm, blocks = modal
    pairs = [b for b in blocks if b.stop - b.start == 2]
    if not pairs:
        return None
    energy = []
    for b in pairs:
        (a11, a12), (a21, a22) = Am[b, b]
        # (z I - A_b)^-1 of a 2x2 block in closed form, all lines at once
        inv = np.empty((zs.size, 2, 2), complex)
        inv[:, 0, 0], inv[:, 0, 1], inv[:, 1, 0], inv[:, 1, 1] = zs - a22, a12, a21, zs - a11
        inv /= ((zs - a11) * (zs - a22) - a12 * a21)[:, None, None]
        term = np.einsum("qi,zij,jm->zqm", Cm[:, b], inv, Bm[b])
        energy.append(float(np.sum(w[:, None, None] * np.abs(term) ** 2)))
    weakest = pairs[int(np.argmin(energy))]
    theta = float(np.angle(zs[peak]))
    if theta <= 0:
        return None
    pole = np.exp(-NEW_MODE_DAMPING * theta + 1j * theta)
    c = np.linalg.svd(residual[peak])[0][:, 0]
    A2, C2 = Am.copy(), Cm.copy()
    A2[weakest, :], A2[:, weakest] = 0.0, 0.0
    A2[weakest, weakest] = [[pole.real, pole.imag], [-pole.imag, pole.real]]
    C2[:, weakest.start], C2[:, weakest.start + 1] = c.real, c.imag
    return A2, C2
