"""The deduced plant reduced entry by entry to a fixed structure (sec. 3.3), or kept at full order.

Each entry keeps the unstable poles its cancellation left, snapped to the plant's deduced values
(:func:`entry_unstable_poles`), or one of the plant's real unstable poles (:func:`kept_pole_sets`),
or none, as :func:`~stageid.closedloop.reduction.reduce_best` decides, fitted over the band with the lines weighed by the deduction's reliability
(:mod:`~stageid.closedloop.reliability`); with the ``"full"`` structure the cancelled deduction
is returned as it is, checked against the deduced response over the band (:func:`keep_full_order`).
"""

from __future__ import annotations

import numpy as np

from .._errors import IdentificationError, ModelError
from ..models import TransferMatrix
from .cancellation import EntryPoleZero, z_to_s
from .reduction import ReducedEntry, reduce_best

__all__ = ["entry_unstable_poles", "kept_pole_sets", "reduce_plant", "keep_full_order"]


def entry_unstable_poles(ent: EntryPoleZero, s_unstable: np.ndarray, dt: float, rel: float = 0.05) -> np.ndarray:
    """Unstable poles (rad/s) the entry keeps after cancellation, snapped to the plant's deduced values."""
    kept = z_to_s(ent.kept_poles[np.abs(ent.kept_poles) > 1.0 + 1e-9], dt)
    out = []
    pool = list(s_unstable)
    for s in kept:
        if pool:
            k = int(np.argmin([abs(s - q) for q in pool]))
            if abs(pool[k] - s) <= rel * abs(pool[k]):
                out.append(pool.pop(k))
                continue
        out.append(s)
    arr = np.array(out, dtype=complex)
    # real poles as real
    return np.where(np.abs(arr.imag) < 1e-9 * np.maximum(1, np.abs(arr)), arr.real, arr)


def kept_pole_sets(entry_poles: np.ndarray, unstable_poles: np.ndarray) -> list[np.ndarray]:
    """The sets of unstable poles (rad/s) an entry's reduction may keep fixed: those its cancellation
    left, and each real unstable pole of the plant alone.

    Every entry of ``G = T U^-1`` has its poles among the zeros of ``U``, so any of the plant's
    unstable poles may be the entry's.  The cancellation's leftovers can give an entry another
    axis's deduced pole, or pair a real pole with a spurious zero of ``M (I - T)`` into a complex
    pair that no entry has (benchmarks/RESULTS-recovery.md, closed loop), so each real pole is
    offered on its own too, and the reduction's criterion decides.

    Examples
    --------
    >>> sets = kept_pole_sets(np.array([45.7]), np.array([36.1, 45.7, 40.0 + 30.0j, 40.0 - 30.0j]))
    >>> [s.tolist() for s in sets]
    [[45.7], [36.1]]
    """
    sets = [entry_poles]
    for s in np.asarray(unstable_poles, dtype=complex).reshape(-1):
        if abs(s.imag) <= 1e-9 * max(1.0, abs(s)) and not (entry_poles.size == 1 and np.isclose(entry_poles[0], s)):
            sets.append(np.array([s.real]))
    return sets


def reduce_plant(
    response: np.ndarray,
    freqs_hz: np.ndarray,
    dt: float,
    orders: dict[tuple[int, int], tuple[int, int]],
    entries: tuple[EntryPoleZero, ...],
    unstable_poles: np.ndarray,
    names: tuple[tuple[str, ...], tuple[str, ...]],
    continuous: bool = True,
    weights: np.ndarray | None = None,
) -> tuple[TransferMatrix, dict, np.ndarray, np.ndarray]:
    """Every entry reduced to its ``(n_zeros, n_poles)`` of ``orders`` over the band (sec. 3.3).

    ``response`` is the deduced plant over ``freqs_hz`` (n_freqs, p, p); ``names`` are the
    plant's (inputs, outputs); ``weights`` (n_freqs, p, p), optional, weigh each entry's relative
    error per line (:func:`~stageid.closedloop.reliability.reliability_weights`).  Returns ``(plant, reduced, eps, eps_complex)``: the continuous
    (or ZOH-discretised) plant, ``{(i, j): ReducedEntry}`` and the band errors (p, p).
    """
    p = response.shape[1]
    reduced: dict[tuple[int, int], ReducedEntry] = {}
    eps, eps_c = np.zeros((p, p)), np.zeros((p, p))
    nums, dens = [[None] * p for _ in range(p)], [[None] * p for _ in range(p)]
    for i in range(p):
        for j in range(p):
            nz, n_p = orders[(i, j)]
            ent = next(e for e in entries if e.output == i and e.input == j)
            keep = kept_pole_sets(entry_unstable_poles(ent, unstable_poles, dt), unstable_poles)
            w = None if weights is None else weights[:, i, j]
            red = reduce_best(response[:, i, j], freqs_hz, dt, nz, n_p, keep, i == j, w)
            reduced[(i, j)] = red
            eps[i, j], eps_c[i, j] = red.eps_magnitude, red.eps_complex
            nums[i][j], dens[i][j] = red.num, red.den
    plant = TransferMatrix(nums, dens, None, *names)
    return (plant if continuous else plant.c2d(dt, "zoh")), reduced, eps, eps_c


def keep_full_order(
    cancelled: TransferMatrix, response: np.ndarray, freqs_hz: np.ndarray, continuous: bool = True
) -> tuple[TransferMatrix, dict, np.ndarray, np.ndarray]:
    """The cancelled full-order deduction as the plant (structure "full"), checked over the band.

    Returns ``(plant, {}, eps, eps_complex)`` like :func:`reduce_plant`.

    Raises
    ------
    IdentificationError
        When the plant has no continuous ZOH equivalent (``continuous``), or an entry misses
        the deduced response by more than 5 % somewhere in the band (unreliable cancellation).
    """
    plant, resp = cancelled, None
    if continuous:
        try:
            plant = cancelled.d2c("zoh")
        except ModelError as exc:
            raise IdentificationError(
                f"the full-order deduced plant has no continuous ZOH equivalent ({exc}); "
                "ask for a discrete plant or a reduced structure."
            ) from None
        resp = plant.c2d(cancelled.dt, "zoh").frequency_response(freqs_hz)
    else:
        resp = plant.frequency_response(freqs_hz)
    eps = np.max(np.abs(np.abs(response) - np.abs(resp)) / np.abs(response), axis=0)
    eps_c = np.max(np.abs(response - resp) / np.abs(response), axis=0)
    if eps_c.max() > 0.05:
        i, j = np.unravel_index(int(np.argmax(eps_c)), eps_c.shape)
        raise IdentificationError(
            f"the cancelled full-order model of entry ({i}, {j}) misses the deduced response by {100 * eps_c[i, j]:.1f} % "
            f"over {freqs_hz[0]:g}-{freqs_hz[-1]:g} Hz (expected < 5 %): its pole-zero cancellation is unreliable; "
            "use a reduced structure."
        )
    return plant, {}, eps, eps_c
