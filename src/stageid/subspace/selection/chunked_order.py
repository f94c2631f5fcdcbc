"""``order="auto"`` on a chunked record: the held-out simulation error of every candidate order
in one pass over the record (:func:`~stageid.subspace.selection.select_order` needs the record in memory).

Each candidate model is realised from the training posterior as in the in-memory selection
and simulated from rest over the whole (mean-removed, scaled) record, chunk after chunk with
its state carried across chunk borders; only the held-out ranges of
:func:`~stageid.subspace.selection.held_out_segments` count, with each range's own mean removed from the
output energy.  All candidates share one read of every chunk.  The pass is sequential (the
state of chunk ``k`` needs chunk ``k - 1``), so it runs here, not on the cluster.
"""

from __future__ import annotations

import numpy as np

from ..._errors import IdentificationError
from ...data.chunked import DEFAULT_CHUNK, ChunkedRecord
from ...models.statespace import StateSpaceModel
from ..map.posterior import Posterior
from ..realisation.era import realize
from ..realisation.weighting import output_weights
from ..statistics.chunked_statistics import ColumnMoments
from . import SelectionTable, held_out_segments, order_by_rule

__all__ = ["select_order_chunked"]


def _candidates(post: Posterior, max_order: int, freqs: np.ndarray, dt: float, settings: dict) -> list:
    """The realised model of every order ``1 .. max_order`` (None where it fails or is unstable)."""
    models = []
    for n in range(1, max_order + 1):
        try:
            mdl, _ = realize(post, n, freqs, dt, max_iter=8, **settings)
        except (IdentificationError, np.linalg.LinAlgError):
            mdl = None
        models.append(mdl if mdl is not None and mdl.is_stable() else None)
    return models


def _with_state(model: StateSpaceModel) -> StateSpaceModel:
    """``model`` whose outputs are followed by its state (so a chunk's last state is known)."""
    n, m = model.n_states, model.n_inputs
    return StateSpaceModel(
        model.A, model.B, np.vstack([model.C, np.eye(n)]), np.vstack([model.D, np.zeros((n, m))]), model.dt
    )


def select_order_chunked(
    post: Posterior,
    max_order: int,
    freqs: np.ndarray,
    dt: float,
    record: ChunkedRecord,
    validation_fraction: float,
    shift: np.ndarray,
    scale: np.ndarray,
    chunk: int = DEFAULT_CHUNK,
    **realize_settings,
) -> tuple[int, SelectionTable]:
    """:func:`~stageid.subspace.selection.select_order` on a chunked record (channels ``(x - shift) / scale``).

    Raises
    ------
    IdentificationError
        When no candidate order gives a stable model.
    """
    m, q = record.n_inputs, record.n_outputs
    models = _candidates(post, max_order, freqs, dt, realize_settings)
    sims = [None if mdl is None else _with_state(mdl) for mdl in models]
    states = [None if mdl is None else np.zeros(mdl.n_states) for mdl in models]
    scored = held_out_segments(record.n_samples, validation_fraction)[1]
    num = [np.zeros(q) for _ in models]
    energy: list[ColumnMoments | None] = [None] * len(scored)
    for a in range(0, record.n_samples, chunk):
        b = min(record.n_samples, a + chunk)
        z = (record.read(a, b) - shift) / scale
        u, y = z[:, :m], z[:, m:]
        parts = [(i, max(s, a) - a, min(e, b) - a) for i, (s, e) in enumerate(scored) if s < b and e > a]
        for i, s, e in parts:
            mom = _moments(y[s:e])
            energy[i] = mom if energy[i] is None else energy[i] + mom
        for k, sim in enumerate(sims):
            if sim is None:
                continue
            out = sim.simulate(u, x0=states[k])
            x_last = out[-1, q:]
            states[k] = sim.A @ x_last + sim.B @ u[-1]
            for _, s, e in parts:
                err = y[s:e] - out[s:e, :q]
                num[k] += np.einsum("ij,ij->j", err, err)
    den = sum(e.m2 for e in energy if e is not None)
    den = np.where(den > 0, den, 1.0)
    w2 = output_weights(post) ** 2
    errors = [
        float("inf") if sim is None else float(np.sum(w2 * num[k]) / np.sum(w2 * den)) for k, sim in enumerate(sims)
    ]
    errors = [e if np.isfinite(e) else float("inf") for e in errors]
    cands = list(range(1, max_order + 1))
    chosen = order_by_rule(cands, errors)  # as select_order
    return chosen, SelectionTable("order", tuple(cands), tuple(errors), chosen)


def _moments(y: np.ndarray) -> ColumnMoments:
    mean = y.mean(axis=0)
    d = y - mean
    return ColumnMoments(y.shape[0], mean, np.einsum("ij,ij->j", d, d), y.min(axis=0), y.max(axis=0))
