"""The shared parameter text of the generators' docstrings."""

import re

import pytest

from stageid.signals._docs import PARAMETER_DOCS, fill_doc
from stageid.signals.registry import SIGNAL_KINDS


def test_fill_doc_indents_the_shared_text_and_leaves_other_braces():
    def f():
        """Summary.

        Parameters
        ----------
        {dt}
        mode : {"a", "b"}
            A choice.
        """

    doc = fill_doc(f).__doc__
    assert "        dt : float\n            Sample time in seconds.\n" in doc
    assert '{"a", "b"}' in doc


def test_fill_doc_refuses_an_unknown_key():
    def f():
        """{no_such_parameter}"""

    with pytest.raises(KeyError):
        fill_doc(f)


def test_no_generator_docstring_keeps_a_placeholder():
    pattern = re.compile(r"^\s*\{(" + "|".join(PARAMETER_DOCS) + r")\}\s*$", re.MULTILINE)
    for kind, generator in SIGNAL_KINDS.items():
        assert not pattern.search(generator.__doc__ or ""), kind
