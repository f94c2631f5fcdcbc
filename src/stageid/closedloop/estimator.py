"""``ClosedLoopIdentification``: the whole method of Shakir & Kim in one estimator.

Steps (Fig. 2 of the paper):

1. for every reference-to-output pair, a prediction-error model of the closed loop
   ``T_ij`` (eq. 11-17), one reference excited per experiment;
2. the plant deduced in discrete time, ``G = T (M - M T)^-1`` (eq. 18), and its unstable
   poles (the zeros of ``M (I - T)`` outside the unit circle);
3. the spurious pole-zero pairs cancelled entry by entry, distances reported (sec. 3.2.3);
4. each entry reduced to a fixed continuous structure fitted over a band, unstable poles
   kept (sec. 3.3; eq. 22-24), with the band error ``eps``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from .._errors import DataError, IdentificationError, ModelError
from .._threads import single_blas_thread
from ..data import Experiment, as_experiments
from ..models import StateSpaceModel, TransferMatrix
from .cancellation import CancelledPair, EntryPoleZero, cancel_entries, z_to_s
from .deduction import as_discrete_controller, deduce_plant, deduce_response, unstable_plant_poles
from .pem import STRUCTURES, PolynomialModel, pem, select_order
from .reduction import ReducedEntry, paper_orders, reduce_entry

__all__ = ["ClosedLoopIdentification", "ClosedLoopResult", "excited_reference"]

_PLANT_STRUCTURES = ("paper", "full")


def excited_reference(exp: Experiment, rel_threshold: float = 1e-3) -> int:
    """Index of the one excited reference column of ``exp`` (the paper excites one axis per run).

    Raises
    ------
    DataError
        When no reference or more than one reference carries a signal (RMS above
        ``rel_threshold`` times the largest).
    """
    rms = np.sqrt(np.mean((exp.u - exp.u.mean(axis=0)) ** 2, axis=0))
    if not np.any(rms > 0):
        raise DataError(
            f"experiment '{exp.name or 'unnamed'}' has no excited reference: every reference column is constant."
        )
    active = np.flatnonzero(rms > rel_threshold * rms.max())
    if active.size != 1:
        names = ", ".join(exp.input_names[k] for k in active)
        raise DataError(
            f"experiment '{exp.name or 'unnamed'}' excites {active.size} references ({names}); expected one reference per experiment."
        )
    return int(active[0])


@dataclass(frozen=True, eq=False)
class ClosedLoopResult:
    """Frozen result of :meth:`ClosedLoopIdentification.fit` (no training data kept).

    Attributes
    ----------
    plant : TransferMatrix
        The identified plant in the requested structure (continuous unless
        ``continuous=False``); inputs named after the controller's outputs.
    plant_full : StateSpaceModel
        The full-order discrete deduction of eq. 18 (with its spurious pairs).
    plant_cancelled : TransferMatrix
        The discrete deduction after cancelling pole-zero pairs closer than ``cancel_tol``.
    closed_loop : TransferMatrix
        The identified discrete ``T`` (references to outputs).
    controller : StateSpaceModel
        The controller used, discrete at the data's sample time.
    unstable_poles : ndarray
        Continuous-time (rad/s) unstable poles of the deduced plant, ``ln(z) / dt``.
    cancellations : tuple of CancelledPair
        Every cancelled pair with its ``s``-plane distance.
    entries : tuple of EntryPoleZero
        Per-entry poles/zeros before and after cancellation (for pole-zero maps).
    reduced : dict
        ``(i, j) -> ReducedEntry`` for the fixed-structure fits (empty for ``"full"``).
    band : (float, float)
        Band of the reduction and of the errors, Hz.
    band_error : ndarray of shape (p, p)
        The paper's ``eps = max | |P_i| - |P_r| | / |P_i|`` over the band, per entry.
    band_error_complex : ndarray of shape (p, p)
        ``max |P_i - P_r| / |P_i|`` over the band.
    pem_models : dict
        ``(i, j) -> PolynomialModel`` of each closed-loop pair.
    closed_loop_fit : ndarray of shape (p, p)
        Simulation fit (percent) of each ``T_ij`` on its experiment(s).
    dt : float
        Sample time of the data.
    """

    plant: TransferMatrix
    plant_full: StateSpaceModel
    plant_cancelled: TransferMatrix
    closed_loop: TransferMatrix
    controller: StateSpaceModel
    unstable_poles: np.ndarray
    cancellations: tuple[CancelledPair, ...]
    entries: tuple[EntryPoleZero, ...]
    reduced: dict
    band: tuple[float, float]
    band_error: np.ndarray
    band_error_complex: np.ndarray
    pem_models: dict
    closed_loop_fit: np.ndarray
    dt: float
    structure: str = "paper"
    diagnostics: dict = field(default_factory=dict)

    def deduced_response(self, freqs_hz: Sequence[float] | np.ndarray) -> np.ndarray:
        """Full-order deduced plant response (eq. 18) at ``freqs_hz``, shape (n_freqs, p, p)."""
        f = np.asarray(freqs_hz, dtype=float)
        return deduce_response(
            self.closed_loop.frequency_response(f), self.controller.frequency_response(f), freqs_hz=f
        )

    @property
    def plant_unstable_poles(self) -> np.ndarray:
        """Right-half-plane poles of the returned plant's entries (rad/s; duplicates merged)."""
        poles: list[complex] = []
        for row in self.plant.den:
            for d in row:
                r = np.roots(d)
                if self.plant.dt is not None:
                    r = z_to_s(r, self.plant.dt)
                for q in r[r.real > 0]:
                    if not any(abs(q - o) <= 1e-9 * max(1.0, abs(q)) for o in poles):
                        poles.append(complex(q))
        return np.array(sorted(poles, key=lambda q: (q.real, q.imag)), dtype=complex)

    def summary(self) -> str:
        """A plain-text summary: orders, fits, unstable poles, band errors, cancellations."""
        p = self.closed_loop.n_outputs
        lines = [
            f"closed-loop identification ({self.structure} structure), dt = {self.dt:g} s, band {self.band[0]:g}-{self.band[1]:g} Hz"
        ]
        for (i, j), m in sorted(self.pem_models.items()):
            lines.append(
                f"  T[{self.closed_loop.outputs[i]}<-{self.closed_loop.inputs[j]}]: {m.structure} order {m.F.size - 1 + m.A.size - 1}, "
                f"fit {self.closed_loop_fit[i, j]:.2f} %"
            )
        lines.append("  unstable poles of M (I - T) [rad/s]: " + ", ".join(f"{p_:.4g}" for p_ in self.unstable_poles))
        lines.append(
            "  unstable poles of the plant returned [rad/s]: "
            + ", ".join(f"{p_:.4g}" for p_ in self.plant_unstable_poles)
        )
        for i in range(p):
            for j in range(p):
                lines.append(
                    f"  G[{self.plant.outputs[i]}<-{self.plant.inputs[j]}]: eps = {100 * self.band_error[i, j]:.3f} % "
                    f"(complex {100 * self.band_error_complex[i, j]:.3f} %)"
                )
        lines.append(
            f"  {len(self.cancellations)} pole-zero pairs cancelled; largest distance "
            f"{max((c.distance for c in self.cancellations), default=0.0):.2e}"
        )
        return "\n".join(lines)


class ClosedLoopIdentification:
    """Identify an (unstable) MIMO plant from closed-loop data and a known controller.

    Parameters
    ----------
    controller : StateSpaceModel or TransferMatrix
        Known ``M`` in ``u = M (r - y)``: p tracking errors to p plant inputs. Continuous
        controllers are discretised with ``controller_discretization`` at the data's ``dt``.
    reference_filter : StateSpaceModel or TransferMatrix, optional
        ``M_r`` of a two-degree-of-freedom law ``u = M_r r - M y`` (default: ``M``).
    method : {"oe", "armax", "bj", "arx"}
        Closed-loop model structure of eq. 12 for every pair (default output error, the
        paper's noise-free reading at 80 dB SNR).
    orders : "auto", int or dict
        "auto": BIC over ``order_range``; an int ``n``: ``nb = nf = n`` (OE) or
        ``na = nb = n`` (ARX/ARMAX); a dict: the orders for :func:`~stageid.closedloop.pem.pem`.
    order_range : sequence of int
        Candidates for "auto".
    nk : int
        Delay of the closed loop in samples (1: sampled strictly proper plant).
    structure : "paper", "full" or dict
        "paper": [0, 2] diagonal, [1, 3] couplings; "full": the cancelled full-order
        deduction; a dict ``{(i, j): (n_zeros, n_poles)}`` for other fixed orders.
    band : (float, float)
        Band of the reduction and of the reported errors, Hz (paper: 20-300 Hz).
    cancel_tol : float
        Relative ``s``-plane distance below which a pole-zero pair is cancelled.
    continuous : bool
        Return the plant in continuous time (True) or at the data's sample time.
    controller_discretization : {"tustin", "zoh"}
        How a continuous controller was implemented.
    max_nfev : int
        Evaluation limit of each prediction-error optimisation.

    Examples
    --------
    >>> from stageid.plants import maglev
    >>> exps = [maglev.EXPERIMENTS[k](seed=0).experiment(["r_x", "r_y", "r_phi"], ["x", "y", "phi"])
    ...         for k in ("chirp-x", "chirp-y", "chirp-phi")]                      # doctest: +SKIP
    >>> res = ClosedLoopIdentification(maglev.controller()).fit(exps)            # doctest: +SKIP
    >>> res.unstable_poles                                                       # doctest: +SKIP
    """

    def __init__(
        self,
        controller: StateSpaceModel | TransferMatrix,
        *,
        reference_filter: StateSpaceModel | TransferMatrix | None = None,
        method: str = "oe",
        orders: str | int | Mapping[str, int] = "auto",
        order_range: Sequence[int] = tuple(range(2, 17)),
        nk: int = 1,
        structure: str | Mapping[tuple[int, int], tuple[int, int]] = "paper",
        band: tuple[float, float] = (20.0, 300.0),
        cancel_tol: float = 1e-2,
        continuous: bool = True,
        controller_discretization: str = "tustin",
        max_nfev: int = 200,
    ) -> None:
        self.controller = controller
        self.reference_filter = reference_filter
        self.method = method
        self.orders = orders
        self.order_range = order_range
        self.nk = nk
        self.structure = structure
        self.band = band
        self.cancel_tol = cancel_tol
        self.continuous = continuous
        self.controller_discretization = controller_discretization
        self.max_nfev = max_nfev

    # ------------------------------------------------------------- checks
    def _check_params(self) -> None:
        if self.method not in STRUCTURES:
            raise IdentificationError(
                f"`method` of ClosedLoopIdentification must be one of {', '.join(STRUCTURES)}; got {self.method!r}."
            )
        if not (isinstance(self.structure, Mapping) or self.structure in _PLANT_STRUCTURES):
            raise IdentificationError(
                f"`structure` must be 'paper', 'full' or a dict of orders; got {self.structure!r}."
            )
        if not (isinstance(self.nk, (int, np.integer)) and not isinstance(self.nk, bool) and self.nk >= 0):
            raise IdentificationError(f"`nk` must be a non-negative integer (delay in samples); got {self.nk!r}.")
        tol = self.cancel_tol
        if not (
            isinstance(tol, (int, float, np.integer, np.floating))
            and not isinstance(tol, bool)
            and 0 <= float(tol) < np.inf
        ):
            raise IdentificationError(f"`cancel_tol` must be a finite number >= 0; got {tol!r}.")
        if not (
            isinstance(self.max_nfev, (int, np.integer)) and not isinstance(self.max_nfev, bool) and self.max_nfev >= 1
        ):
            raise IdentificationError(f"`max_nfev` must be a positive integer; got {self.max_nfev!r}.")
        if self.orders == "auto":
            try:
                rng = [int(n) for n in self.order_range]
            except (TypeError, ValueError):
                rng = []
            if not rng or min(rng) < 1:
                raise IdentificationError(
                    f"`order_range` must be a non-empty sequence of positive integers; got {self.order_range!r}."
                )
        b = self.band
        if not (
            isinstance(b, (tuple, list, np.ndarray))
            and len(b) == 2
            and all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) for v in b)
            and 0 < float(b[0]) < float(b[1]) < np.inf
        ):
            raise IdentificationError(f"`band` must be (f_min, f_max) in Hz with 0 < f_min < f_max finite; got {b!r}.")
        if self.controller_discretization not in ("tustin", "zoh"):
            raise IdentificationError(
                f"`controller_discretization` must be 'tustin' or 'zoh'; got {self.controller_discretization!r}."
            )
        if not (isinstance(self.orders, (int, np.integer, Mapping)) or self.orders == "auto"):
            raise IdentificationError(f"`orders` must be 'auto', an int or a dict; got {self.orders!r}.")

    def _orders_for(self, n: int) -> dict[str, int]:
        return {
            "arx": {"na": n, "nb": n},
            "armax": {"na": n, "nb": n, "nc": n},
            "oe": {"nb": n, "nf": n},
            "bj": {"nb": n, "nf": n, "nc": 2, "nd": 2},
        }[self.method]

    # ---------------------------------------------------------------- fit
    @single_blas_thread
    def fit(self, data: Experiment | Sequence[Experiment]) -> ClosedLoopResult:
        """Identify the plant from closed-loop experiments.

        Parameters
        ----------
        data : Experiment or sequence of Experiment
            Inputs are the references ``r`` (p columns), outputs the measured ``y``
            (p columns, same order); one reference excited per experiment, every
            reference excited in at least one.

        Returns
        -------
        ClosedLoopResult

        Raises
        ------
        DataError
            Not experiments, wrong channel counts, several references excited in one
            experiment, or a reference never excited.
        IdentificationError
            Bad hyper-parameters (among them a ``band`` not ending below the Nyquist
            frequency, checked before any fit), a controller of the wrong size, a singular
            deduction, or a failed fit.
        """
        self._check_params()
        if not isinstance(data, (Experiment, list, tuple)):
            raise DataError(
                f"ClosedLoopIdentification.fit needs an Experiment or a sequence of them; got {type(data).__name__}."
            )
        exps = as_experiments(data)
        first = exps[0]
        p = first.n_outputs
        if first.n_inputs != p:
            raise DataError(
                f"closed-loop data need one reference per output; got {first.n_inputs} references and {p} outputs."
            )
        dt = first.dt
        nyq = 0.5 / dt
        if float(self.band[1]) >= nyq:  # before any fit: the pairs take minutes on long records
            raise IdentificationError(
                f"`band` must end below the Nyquist frequency {nyq:g} Hz (dt = {dt:g} s); "
                f"got {float(self.band[0]):g}-{float(self.band[1]):g} Hz."
            )
        try:
            M = as_discrete_controller(self.controller, dt, self.controller_discretization)
            Mr = (
                None
                if self.reference_filter is None
                else as_discrete_controller(self.reference_filter, dt, self.controller_discretization)
            )
        except ModelError as exc:
            raise IdentificationError(str(exc)) from None
        if M.n_inputs != p or M.n_outputs != p:
            raise IdentificationError(
                f"the controller must have {p} inputs (tracking errors) and {p} outputs (plant inputs) for {p} outputs; "
                f"got {M.n_inputs} inputs and {M.n_outputs} outputs."
            )
        # a controller singular at some frequency makes eq. 18 singular there whatever T is: check first
        nyq = 0.5 / dt
        f_pre = np.concatenate([[0.0], np.geomspace(min(float(self.band[0]) / 10, 1.0), 0.95 * nyq, 400)])
        with np.errstate(all="ignore"):
            M_pre = (M if Mr is None else Mr).frequency_response(f_pre)
        ok = np.all(np.isfinite(M_pre), axis=(1, 2))
        sv = np.linalg.svd(M_pre[ok], compute_uv=False)
        bad = np.flatnonzero(sv[:, -1] <= 1e-6 * sv[:, 0].max())
        if bad.size:
            k = int(bad[0])
            raise IdentificationError(
                f"the plant deduction G = T (M - M T)^-1 is singular at {f_pre[ok][k]:.6g} Hz: the controller itself is singular "
                f"there (smallest singular value {sv[k, -1]:.3g}, {sv[k, -1] / sv[:, 0].max():.2g} of its peak gain)."
            )
        groups: dict[int, list[Experiment]] = {}
        for e in exps:
            groups.setdefault(excited_reference(e), []).append(e)
        missing = [first.input_names[j] for j in range(p) if j not in groups]
        if missing:
            raise DataError(f"every reference must be excited in some experiment; none excites {', '.join(missing)}.")

        # 1. closed-loop pairs (eq. 11-17)
        pem_models: dict[tuple[int, int], PolynomialModel] = {}
        fits = np.zeros((p, p))
        num = [[None] * p for _ in range(p)]
        den = [[None] * p for _ in range(p)]
        for j, group in groups.items():
            r = [e.u[:, j] - e.u[0, j] for e in group]
            for i in range(p):
                y = [e.y[:, i] - e.y[0, i] for e in group]
                if self.orders == "auto":
                    m, _ = select_order(r, y, self.method, self.order_range, self.nk, dt, max_nfev=self.max_nfev)
                else:
                    o = dict(self.orders) if isinstance(self.orders, Mapping) else self._orders_for(int(self.orders))
                    m = pem(r, y, self.method, o, self.nk, dt, max_nfev=self.max_nfev)
                pem_models[(i, j)] = m
                sim = np.concatenate([m.simulate(rk) for rk in r])
                yy = np.concatenate(y)
                fits[i, j] = 100.0 * (1.0 - np.linalg.norm(yy - sim) / max(np.linalg.norm(yy - yy.mean()), 1e-300))
                num[i][j], den[i][j] = m.plant_polynomials()
        T = TransferMatrix(num, den, dt, first.input_names, first.output_names)

        # 2. deduction (eq. 18) and its unstable poles
        G_full = deduce_plant(T, M, Mr)
        lo, hi = (float(b) for b in self.band)
        f_check = np.concatenate([[0.0], np.geomspace(min(lo / 10, 1.0), 0.95 * nyq, 400)])
        with np.errstate(all="ignore"):
            T_chk = T.frequency_response(f_check)
            M_chk = M.frequency_response(f_check)
            Mr_chk = M_chk if Mr is None else Mr.frequency_response(f_check)
        ok = np.all(np.isfinite(T_chk) & np.isfinite(M_chk) & np.isfinite(Mr_chk), axis=(1, 2))  # skip controller poles
        deduce_response(T_chk[ok], M_chk[ok], Mr_chk[ok], f_check[ok])
        zu = unstable_plant_poles(T, M, Mr)
        s_unstable = z_to_s(zu, dt)

        # 3. cancellation (sec. 3.2.3)
        G_cancel, entries = cancel_entries(G_full, self.cancel_tol, f_ref_hz=float(np.sqrt(lo * hi)))
        pairs = tuple(c for e in entries for c in e.pairs)

        # 4. reduction over the band (sec. 3.3)
        f_band = np.geomspace(lo, hi, 120)
        P_band = deduce_response(
            T.frequency_response(f_band),
            M.frequency_response(f_band),
            None if Mr is None else Mr.frequency_response(f_band),
            f_band,
        )
        reduced: dict[tuple[int, int], ReducedEntry] = {}
        eps = np.zeros((p, p))
        eps_c = np.zeros((p, p))
        structure_name = self.structure if isinstance(self.structure, str) else "custom"
        if self.structure == "full":
            plant = G_cancel
            if self.continuous:
                try:
                    plant = G_cancel.d2c("zoh")
                except ModelError as exc:
                    raise IdentificationError(
                        f"the full-order deduced plant has no continuous ZOH equivalent ({exc}); "
                        "ask for a discrete plant or a reduced structure."
                    ) from None
            resp = plant.frequency_response(f_band) if not self.continuous else _zoh_matrix(plant, dt, f_band)
            eps = np.max(np.abs(np.abs(P_band) - np.abs(resp)) / np.abs(P_band), axis=0)
            eps_c = np.max(np.abs(P_band - resp) / np.abs(P_band), axis=0)
            if eps_c.max() > 0.05:
                i, j = np.unravel_index(int(np.argmax(eps_c)), eps_c.shape)
                raise IdentificationError(
                    f"the cancelled full-order model of entry ({i}, {j}) misses the deduced response by {100 * eps_c[i, j]:.1f} % "
                    f"over {lo:g}-{hi:g} Hz (expected < 5 %): its pole-zero cancellation is unreliable; use a reduced structure."
                )
        else:
            orders = paper_orders(p) if self.structure == "paper" else dict(self.structure)  # type: ignore[arg-type]
            nums, dens = [[None] * p for _ in range(p)], [[None] * p for _ in range(p)]
            for i in range(p):
                for j in range(p):
                    if (i, j) not in orders:
                        raise IdentificationError(
                            f"`structure` has no orders for entry ({i}, {j}); give (n_zeros, n_poles) for every entry."
                        )
                    nz, n_p = orders[(i, j)]
                    ent = next(e for e in entries if e.output == i and e.input == j)
                    keep = _entry_unstable(ent, s_unstable, dt)
                    red = _reduce_choice(P_band[:, i, j], f_band, dt, nz, n_p, keep, diagonal=(i == j))
                    reduced[(i, j)] = red
                    eps[i, j], eps_c[i, j] = red.eps_magnitude, red.eps_complex
                    nums[i][j], dens[i][j] = red.num, red.den
            plant = TransferMatrix(nums, dens, None, M.outputs, T.outputs)
            if not self.continuous:
                plant = plant.c2d(dt, "zoh")
        plant = _rename(plant, M.outputs, first.output_names)
        return ClosedLoopResult(
            plant=plant,
            plant_full=G_full,
            plant_cancelled=G_cancel,
            closed_loop=T,
            controller=M,
            unstable_poles=s_unstable,
            cancellations=pairs,
            entries=entries,
            reduced=reduced,
            band=(lo, hi),
            band_error=eps,
            band_error_complex=eps_c,
            pem_models=pem_models,
            closed_loop_fit=fits,
            dt=dt,
            structure=structure_name,
        )


def _reduce_choice(
    P: np.ndarray, f: np.ndarray, dt: float, nz: int, n_p: int, keep: np.ndarray, diagonal: bool
) -> ReducedEntry:
    """Fit one entry three ways and keep the best.

    * unstable poles fixed at the values the deduction gives (when they fit the structure);
    * all poles free over the band (the zeros of ``M (I - T)`` that place the unstable poles
      are fixed by data below the band, where a chirp spends little time, so in MIMO they are
      often less accurate than the in-band response itself);
    * all poles stable: preferred for a coupling when within 1.5 x of the best band error,
      because an unstable pole that only one coupling carries is no feedback loop's to
      stabilise (see the +9.74 rad/s pole of eq. 22c) and usually a displaced spurious doublet.
    """
    cands = []
    if keep.size and keep.size <= n_p:
        cands.append(reduce_entry(P, f, dt, nz, n_p, keep))
    cands.append(reduce_entry(P, f, dt, nz, n_p, np.zeros(0), stable_free=False))
    stable = reduce_entry(P, f, dt, nz, n_p, np.zeros(0), stable_free=True)
    stable_ok = not np.any(stable.poles.real > 0)
    if stable_ok:
        cands.append(stable)
    best = min(cands, key=lambda r: r.eps_complex)
    if not diagonal and stable_ok and stable.eps_complex <= 1.5 * best.eps_complex:
        return stable
    return best


def _rename(plant: TransferMatrix, inputs: Sequence[str], outputs: Sequence[str]) -> TransferMatrix:
    from dataclasses import replace

    return replace(plant, inputs=tuple(inputs), outputs=tuple(outputs))


def _zoh_matrix(plant: TransferMatrix, dt: float, f: np.ndarray) -> np.ndarray:
    return plant.c2d(dt, "zoh").frequency_response(f)


def _entry_unstable(ent: EntryPoleZero, s_unstable: np.ndarray, dt: float, rel: float = 0.05) -> np.ndarray:
    """Unstable poles the entry keeps after cancellation, snapped to the plant's deduced values."""
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
    # complete conjugate pairs; real poles as real
    arr = np.where(np.abs(arr.imag) < 1e-9 * np.maximum(1, np.abs(arr)), arr.real, arr)
    return arr
