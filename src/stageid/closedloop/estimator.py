"""``ClosedLoopIdentification``: the whole method of Shakir & Kim in one estimator.

Steps (Fig. 2 of the paper), each a function of the module that owns it:

1. every reference-to-output pair ``T_ij`` of the closed loop by prediction error, one
   reference excited per experiment (eq. 11-17; :mod:`~stageid.closedloop.loop_model`,
   :mod:`~stageid.closedloop.pem`, :mod:`~stageid.closedloop.order_selection`), the output-error
   diagonal pairs refitted through their outputs' sensitivity-shaped noise (:mod:`~stageid.closedloop.prefilter`);
2. the plant deduced in discrete time, ``G = T (M - M T)^-1`` (eq. 18), and its unstable
   poles, the zeros of ``M (I - T)`` outside the unit circle (:mod:`~stageid.closedloop.deduction`);
3. the spurious pole-zero pairs cancelled entry by entry, distances reported (sec. 3.2.3;
   :mod:`~stageid.closedloop.cancellation`);
4. each entry reduced to a fixed continuous structure fitted over a band, unstable poles
   kept (sec. 3.3, eq. 22-24), with the band error ``eps`` (:mod:`~stageid.closedloop.reduction`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..base import Band, Boolean, Estimator, InstanceOf, Interval, Options, Satisfies
from ..checks import check_band, is_integer
from ..data import Experiment
from ..models import StateSpaceModel, TransferMatrix
from ..runtime.threads import single_blas_thread
from .cancellation import cancel_entries, z_to_s
from .controller import check_controller, check_grid, discrete_controllers, resolved_grid
from .covariance import COVARIANCE_METHODS, closed_loop_covariance
from .deduction import check_deduction, deduce_plant, plant_response, unstable_plant_poles, wide_response
from .loop_model import assemble_loop, at_rest, closed_loop_experiments, group_by_reference, identify_pairs, remembered
from .order_selection import loop_order_bound, select_order
from .pem import pem
from .plant_reduction import keep_full_order, reduce_plant
from .polynomial import FREE_ORDERS, STRUCTURES, PolynomialModel, structure_orders
from .prefilter import whiten_pairs
from .reduction import paper_orders
from .reliability import deduction_gain, reliability_weights
from .result import ClosedLoopResult

__all__ = ["ClosedLoopIdentification"]

_MODEL = (StateSpaceModel, TransferMatrix)
#: orders above the loop's bound tried too: at 30 the polynomial coefficients are rounded enough
#: that a pair fits its records better with a few spare poles (RESULTS-recovery.md, PEM)
ORDER_MARGIN = 2
#: the automatic range never stops below this order (SISO and 2x2 loops of the paper's class)
MIN_ORDER_TOP = 16


def _is_order_range(value: object) -> bool:
    return (
        isinstance(value, (Sequence, np.ndarray))
        and not isinstance(value, str)
        and len(value) > 0
        and all(is_integer(n) and n >= 1 for n in value)
    )


def _is_order_dict(value: object) -> bool:
    """``{(i, j): (n_zeros, n_poles)}`` with ``0 <= n_zeros <= n_poles`` and ``n_poles >= 1``."""
    return isinstance(value, Mapping) and all(
        isinstance(k, tuple) and len(k) == 2 and all(is_integer(i) and i >= 0 for i in k)
        and isinstance(v, (tuple, list)) and len(v) == 2 and all(is_integer(n) for n in v)
        and 0 <= v[0] <= v[1] and v[1] >= 1
        for k, v in value.items()
    )  # fmt: skip


class ClosedLoopIdentification(Estimator):
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
    order_range : "auto" or sequence of int
        Candidates for "auto".  "auto": 2 up to the largest order a pair of this loop can have,
        :func:`~stageid.closedloop.order_selection.loop_order_bound` of the ``structure``'s entry
        orders (the paper's for "full") and the controller's states, plus two,
        and at least up to 16.
    nk : int
        Delay of the closed loop in samples (1: sampled strictly proper plant).
    structure : "paper", "full" or dict
        "paper": [0, 2] diagonal, [1, 3] couplings; "full": the cancelled full-order
        deduction; a dict ``{(i, j): (n_zeros, n_poles)}`` for other fixed orders.
    band : (float, float)
        Band of the reduction and of the reported errors, Hz (paper: 20-300 Hz), by the one
        rule of :func:`stageid.checks.check_band`: ``0 <= f_low < f_high``, ``f_high`` at most
        the data's Nyquist frequency.  With ``f_low = 0`` the band's log-spaced grids start at
        the first positive line the records resolve, ``1 / duration`` of the longest record.
    cancel_tol : float
        Relative ``s``-plane distance below which a pole-zero pair is cancelled.
    continuous : bool
        Return the plant in continuous time (True) or at the data's sample time.
    controller_discretization : {"tustin", "zoh"}
        How a continuous controller was implemented.
    max_nfev : int
        Evaluation limit of each prediction-error optimisation.
    covariance : {"sandwich", "white", "none"}
        Parameter covariance of each pair for :meth:`ClosedLoopResult.response_uncertainty`
        (:mod:`~stageid.closedloop.covariance`; "none" skips it).
    noise_model : {"sensitivity", "none"}
        "sensitivity": the output-error diagonal pairs are fitted again through a fixed noise
        model of their output, the sensitivity ``1 - T_ii`` of the estimate (the loop shapes the
        outputs' noise by it; :func:`~stageid.closedloop.prefilter.whiten_pairs`), which places
        the unstable poles; "none": output error alone.

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
        order_range: str | Sequence[int] = "auto",
        nk: int = 1,
        structure: str | Mapping[tuple[int, int], tuple[int, int]] = "paper",
        band: tuple[float, float] = (20.0, 300.0),
        cancel_tol: float = 1e-2,
        continuous: bool = True,
        controller_discretization: str = "tustin",
        max_nfev: int = 200,
        covariance: str = "sandwich",
        noise_model: str = "sensitivity",
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
        self.covariance = covariance
        self.noise_model = noise_model

    parameter_constraints = {
        "controller": [InstanceOf(_MODEL, "a StateSpaceModel or TransferMatrix")],
        "reference_filter": [InstanceOf(_MODEL, "a StateSpaceModel or TransferMatrix"), None],
        "method": [Options(*STRUCTURES)],
        "orders": [Options("auto"), Interval(int, 1, None), InstanceOf(Mapping, "a dict of orders")],
        "order_range": [Options("auto"), Satisfies(_is_order_range, "a non-empty sequence of integers >= 1")],
        "nk": [Interval(int, 0, None)],
        "structure": [
            Options("paper", "full"),
            Satisfies(_is_order_dict, "a dict {(i, j): (n_zeros, n_poles)} with 0 <= n_zeros <= n_poles, n_poles >= 1"),
        ],
        "band": [Band()],
        "cancel_tol": [Interval(float, 0, None, closed="left")],
        "continuous": [Boolean()],
        "controller_discretization": [Options("tustin", "zoh")],
        "max_nfev": [Interval(int, 1, None)],
        "covariance": [Options(*COVARIANCE_METHODS, "none")],
        "noise_model": [Options("sensitivity", "none")],
    }

    def check_together(self) -> None:
        """A dict of ``orders`` gives the free orders of ``method`` only (integers >= 0, ``nb >= 1``)."""
        if isinstance(self.orders, Mapping):
            free = FREE_ORDERS[self.method]
            o = self.orders
            if not (
                all(k in free and is_integer(v) and v >= 0 for k, v in o.items())
                and is_integer(o.get("nb"))
                and o["nb"] >= 1
            ):
                raise self.invalid(
                    "orders",
                    f"a dict of the free orders of a {self.method} model ({', '.join(free)}) as integers >= 0 with nb >= 1",
                )

    def _check_with_data(self, exps: Sequence[Experiment]) -> tuple[float, float]:
        """The band against the data (Nyquist; a 0 Hz edge starts at the records' resolution) and
        the structure against the plant's size; returns the band's positive edges."""
        first = exps[0]
        nyq = 0.5 / first.dt
        lo, hi = check_band(self.band, "band", type(self).__name__, nyquist=nyq)
        if lo == 0.0:  # a log grid starts at the first positive line the records resolve
            lo = 1.0 / max(e.n_samples * e.dt for e in exps)
            if lo >= hi:
                raise self.invalid("band", f"a band reaching above the records' frequency resolution {lo:g} Hz")
        p = first.n_outputs
        if isinstance(self.structure, Mapping) and any(
            (i, j) not in self.structure for i in range(p) for j in range(p)
        ):
            raise self.invalid(
                "structure", f"'paper', 'full' or a dict with (n_zeros, n_poles) for every entry of the {p}x{p} plant"
            )
        return lo, hi

    def _candidate_orders(self, p: int, controller_states: int) -> Sequence[int]:
        """``order_range``, or for "auto" 2 up to the loop's order bound (at least 16)."""
        if not isinstance(self.order_range, str):
            return self.order_range
        entries = dict(self.structure) if isinstance(self.structure, Mapping) else paper_orders(p)
        return range(2, max(MIN_ORDER_TOP, loop_order_bound(entries, controller_states) + ORDER_MARGIN) + 1)

    def _pair_fitter(self, orders: Sequence[int]):
        """One closed-loop pair (eq. 12-14): BIC over ``orders`` or the given orders."""

        def fit_pair(r: list[np.ndarray], y: list[np.ndarray], dt: float) -> PolynomialModel:
            if self.orders == "auto":
                kw = {"max_nfev": self.max_nfev, "refine_largest": True}
                return select_order(r, y, self.method, orders, self.nk, dt, **kw)[0]
            o = self.orders
            o = dict(o) if isinstance(o, Mapping) else structure_orders(self.method, int(o))
            return pem(r, y, self.method, o, self.nk, dt, max_nfev=self.max_nfev)

        return fit_pair

    def _loop_pairs(self, groups, fit_pair, dt: float, duration: float):
        """Step 1: the pairs by output error, the diagonal ones refitted through their outputs'
        sensitivity noise model (:func:`~stageid.closedloop.prefilter.whiten_pairs`)."""
        T, models, fits, groups = identify_pairs(groups, fit_pair)
        if self.noise_model == "sensitivity":  # below the records' resolution the noise spectrum is unknown
            models, groups = whiten_pairs(groups, models, np.exp(-2 * np.pi * dt / duration), self.max_nfev, fit_pair)
            T, fits = assemble_loop(models, groups)
        return T, models, fits, groups

    def _reduce(self, T, M, Mr, P_band, f_band, entries, s_unstable):
        """Step 4 with a fixed structure: every entry reduced over the band, its lines weighed by
        how far an error of T reaches it there (:mod:`~stageid.closedloop.reliability`)."""
        p = T.n_outputs
        orders = paper_orders(p) if self.structure == "paper" else dict(self.structure)
        Mr_band = None if Mr is None else Mr.frequency_response(f_band)
        gain = deduction_gain(T.frequency_response(f_band), M.frequency_response(f_band), P_band, Mr_band)
        weights = reliability_weights(P_band, gain)
        names = (M.outputs, T.outputs)
        return reduce_plant(P_band, f_band, T.dt, orders, entries, s_unstable, names, self.continuous, weights)

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
        ParameterError
            A bad setting, a ``band`` ending above the Nyquist frequency, or a dict
            ``structure`` missing an entry (all checked before any fit).
        DataError
            Not experiments, wrong channel counts, several references excited in one
            experiment, or a reference never excited.
        IdentificationError
            A controller of the wrong size or singular somewhere, a singular deduction, or a
            failed fit.
        """
        self.validate_params()
        exps = closed_loop_experiments(data)
        lo, hi = self._check_with_data(exps)  # before any fit: the pairs take minutes on long records
        dt, p = exps[0].dt, exps[0].n_outputs
        M, Mr = discrete_controllers(self.controller, self.reference_filter, dt, self.controller_discretization, p)
        check_controller(M if Mr is None else Mr, check_grid(lo, dt))
        fit_pair = remembered(self._pair_fitter(self._candidate_orders(p, M.n_states)))
        groups = at_rest(group_by_reference(exps), fit_pair)

        # 1. the closed loop pair by pair (eq. 11-17)
        duration = max(e.n_samples * e.dt for e in exps)
        T, pem_models, fits, groups = self._loop_pairs(groups, fit_pair, dt, duration)
        # 2. the plant G = T (M - M T)^-1 (eq. 18) and its unstable poles
        G_full = deduce_plant(T, M, Mr)
        check_deduction(T, M, Mr, resolved_grid(lo, dt, 1.0 / duration))
        s_unstable = z_to_s(unstable_plant_poles(T, M, Mr), dt)
        # 3. spurious pole-zero pairs cancelled entry by entry (sec. 3.2.3)
        G_cancel, entries = cancel_entries(
            G_full, self.cancel_tol, float(np.sqrt(lo * hi)), None, wide_response(T, M, Mr, G_full)
        )
        # 4. each entry reduced over the band, or the cancelled full order kept (sec. 3.3)
        f_band = np.geomspace(lo, hi, 120)
        P_band = plant_response(T, M, Mr, f_band)
        if self.structure == "full":
            plant, reduced, eps, eps_c = keep_full_order(G_cancel, P_band, f_band, self.continuous)
        else:
            plant, reduced, eps, eps_c = self._reduce(T, M, Mr, P_band, f_band, entries, s_unstable)
        return ClosedLoopResult(
            model=plant,
            plant_full=G_full,
            plant_cancelled=G_cancel,
            closed_loop=T,
            controller=M,
            unstable_poles=s_unstable,
            cancellations=tuple(c for e in entries for c in e.pairs),
            entries=entries,
            reduced=reduced,
            band=(float(self.band[0]), hi),
            band_error=eps,
            band_error_complex=eps_c,
            pem_models=pem_models,
            closed_loop_fit=fits,
            dt=dt,
            structure=self.structure if isinstance(self.structure, str) else "custom",
            band_error_median=np.array([[reduced[(i, j)].eps_median for j in range(p)] for i in range(p)])
            if reduced
            else None,
            covariance=None
            if self.covariance == "none"
            else closed_loop_covariance(groups, pem_models, f_band, Mr, self.covariance),
            estimator=self.clone(),
        )
