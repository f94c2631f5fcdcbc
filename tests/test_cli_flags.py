"""Library messages name parameters as in a call; the command line prints them as its flags."""

from __future__ import annotations

import numpy as np
import pytest

from stageid import DataError
from stageid.cli.flags import as_flags
from stageid.frf import FRDIdentification, FrequencyResponse


@pytest.mark.parametrize(
    ("library", "cli"),
    [
        ("give `fmax=` or a smaller `dt=`.", "give --fmax or a smaller --dt."),
        ("use `weight='none'`.", "use --weight none."),
        ("drop `per_channel=True`.", "drop --per-channel."),
        ("give `dt=S` [`method=zoh|tustin`]", "give --dt S [--method zoh|tustin]"),
        ("export it without `single=True`.", "export it without --float."),
        # a name in backticks without '=' is a column, key or setting named in prose: kept
        ("`format` is missing; the `dt` of the model", "`format` is missing; the `dt` of the model"),
    ],
)
def test_parameters_become_flags(library, cli):
    assert as_flags(library) == cli


def test_a_library_error_names_the_parameter_not_the_flag():
    frd = FrequencyResponse(np.linspace(1.0, 400.0, 50), np.ones((50, 1, 1), complex))
    with pytest.raises(DataError) as err:
        FRDIdentification(order=2, sample_time=0.01).fit(frd)  # Nyquist 50 Hz, the response reaches 400 Hz
    assert "`band=`" in str(err.value) and "`sample_time=`" in str(err.value) and "--" not in str(err.value)


def test_one_command_maps_parameters_it_spells_differently():
    message = "end the band below it (`band=`) or give a smaller `sample_time=`."
    assert (
        as_flags(message, {"sample_time": "dt", "band": "fmax"})
        == "end the band below it (--fmax) or give a smaller --dt."
    )
