"""`identify frd --order auto` on the measured AFM stage: the error of every order, and the choice.

Prints a Markdown table (order, held-out RMS error of the order scan, max error of the full fit
over the measured response relative to its peak) and the order ``order="auto"`` picks, for the
whole band at ``dt = 4e-5``.  Needs ``../shared/data/afm_piezo_stage_frf``.  Usage:
``python studies/frd/afm_auto_order.py [MAX_ORDER]`` (default 24; the full fits of orders above
20 take minutes each on a loaded 2-core machine).
"""

from __future__ import annotations

import sys
import time
import warnings

import numpy as np
import scipy.io

from stageid.data import datasets
from stageid.frf import FRDIdentification, FrequencyResponse
from stageid.validation import order_choice


def afm() -> FrequencyResponse:
    path = datasets.SHARED_DATA / "afm_piezo_stage_frf" / "FRF_data_current_stage2.mat"
    frf = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False)["modelFit"].frf
    return FrequencyResponse(np.asarray(frf.freqs_Hz), np.asarray(frf.G_uz2stage), inputs=("uz",), outputs=("stage",))


def main(max_order: int) -> None:
    frd = afm()
    warnings.simplefilter("ignore")
    t = time.perf_counter()
    auto = FRDIdentification(order="auto", sample_time=4e-5).fit(frd)
    print(f"order='auto': order {auto.order}, max error {100 * auto.max_error:.2f} % ({time.perf_counter() - t:.0f} s)")
    # the whole table: the scan without its early end (rule 1), for the record
    order_choice.PATIENCE = max_order
    held_out = dict(FRDIdentification(order="auto", sample_time=4e-5, max_order=max_order).fit(frd).order_errors)
    print("\n| order | held-out RMS (scan) | max error of the fit |\n|---|---|---|")
    for n in range(1, max_order + 1):
        fit = FRDIdentification(order=n, sample_time=4e-5).fit(frd)
        print(f"| {n} | {held_out.get(n, float('nan')):.4g} | {100 * fit.max_error:.2f} % |", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 24)
