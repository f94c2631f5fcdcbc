"""Formatting for generated C: exact constants, checked identifiers, the two-file template.

Constants are written with Python's shortest round-trip ``repr`` (at most 17 significant
digits), which a C99 compiler parses back to the same ``double``; in single precision the
value is first rounded to ``float`` and written with an ``f`` suffix, which parses back to
that same ``float``.  Every generated pair of files has the same frame (:data:`HEADER`,
:data:`SOURCE`); the model-specific modules fill in the struct members and the bodies.

Examples
--------
>>> from stageid.export.c_writer import CType, literal
>>> literal(0.1, CType("double")), literal(0.1, CType("float"))
('0.1', '0.10000000149011612f')
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from string import Template

import numpy as np

from .._errors import ModelError, ParameterError

__all__ = [
    "C_KEYWORDS",
    "CType",
    "literal",
    "array",
    "define",
    "limit_define",
    "const_tables",
    "check_prefix",
    "comment",
    "fill",
    "init_lines",
    "render_pair",
    "HEADER",
    "SOURCE",
]

#: Reserved words of C99 (and C11's, so a prefix stays valid under newer standards too).
C_KEYWORDS = frozenset(
    """auto break case char const continue default do double else enum extern float for goto if
    inline int long register restrict return short signed sizeof static struct switch typedef union
    unsigned void volatile while _Bool _Complex _Imaginary _Alignas _Alignof _Atomic _Generic
    _Noreturn _Static_assert _Thread_local""".split()
)
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


@dataclass(frozen=True)
class CType:
    """Arithmetic type of the generated code: ``"double"`` or ``"float"``."""

    name: str

    def __post_init__(self) -> None:
        if self.name not in ("double", "float"):
            raise ParameterError(f"the C type must be 'double' or 'float'; got {self.name!r}.")

    @property
    def is_float(self) -> bool:
        return self.name == "float"

    def round(self, value: float) -> float:
        """``value`` rounded to this type (as a Python float)."""
        return float(np.float32(value)) if self.is_float else float(value)


def literal(value: float, ctype: CType) -> str:
    """C literal that parses back to exactly ``value`` (rounded to ``ctype``).

    Raises :class:`ModelError` for NaN or infinity (model constants are finite) and for a value
    beyond the range of ``float`` in single precision.
    """
    v = float(value)
    if not math.isfinite(v):
        raise ModelError(f"a model constant must be finite to be exported to C; got {v}.")
    with np.errstate(over="ignore"):
        r = ctype.round(v)
    if not math.isfinite(r):
        raise ModelError(f"the model constant {v!r} does not fit a {ctype.name}; export it without `single=True`.")
    text = repr(r)
    return text + "f" if ctype.is_float else text


def array(values: object, ctype: CType, per_line: int = 4, indent: str = "    ") -> str:
    """Initializer ``{a, b, ...}`` of a 1-D array, ``per_line`` numbers per line."""
    flat = [literal(v, ctype) for v in np.asarray(values, dtype=float).reshape(-1)]
    if not flat:
        return "{0}"
    lines = [", ".join(flat[i : i + per_line]) for i in range(0, len(flat), per_line)]
    if len(lines) == 1:
        return "{" + lines[0] + "}"
    return "{\n" + ",\n".join(indent + line for line in lines) + "\n}"


def define(prefix: str, name: str, value: float, ctype: CType) -> str:
    """``#define <prefix>_<name> (<literal>)``."""
    return f"#define {prefix}_{name} ({literal(value, ctype)})"


def limit_define(prefix: str, name: str, value: float, ctype: CType) -> str:
    """:func:`define` for a drive limit, which may be infinite (``HUGE_VAL`` / ``HUGE_VALF``, from
    ``<math.h>``)."""
    if np.isfinite(value):
        return define(prefix, name, value, ctype)
    huge = "HUGE_VALF" if ctype.is_float else "HUGE_VAL"
    return f"#define {prefix}_{name} ({'-' if value < 0 else ''}{huge})"


def const_tables(prefix: str, ctype: CType, **tables: object) -> list[str]:
    """``static const`` arrays ``<prefix>_<name>[<prefix>_N_OPERATORS]``, one per keyword."""
    return [
        f"static const {ctype.name} {prefix}_{name}[{prefix}_N_OPERATORS] = {array(v, ctype)};"
        for name, v in tables.items()
    ]


def fill(text: str, ctype: CType, prefix: str, **extra: str) -> str:
    """A C template filled in: ``${T}`` the C type, ``${f}`` and ``${fn}`` the suffix of float
    literals and math functions ("f" in single precision, else ""), ``${p}`` the prefix, and
    ``extra``."""
    f = "f" if ctype.is_float else ""
    return Template(text).substitute(T=ctype.name, f=f, fn=f, p=prefix, **extra)


def init_lines(name: str, values: object, ctype: CType) -> list[str]:
    """The lines of an init body that set ``s->name[i]`` to each of ``values``."""
    return [f"    s->{name}[{i}] = {literal(v, ctype)};" for i, v in enumerate(np.asarray(values).reshape(-1))]


def check_prefix(prefix: object) -> str:
    """``prefix`` if it is a C identifier that is not a keyword, else a one-line ParameterError.

    Examples
    --------
    >>> check_prefix("stage_x")
    'stage_x'
    >>> check_prefix("int")
    Traceback (most recent call last):
    ...
    stageid._errors.ParameterError: `prefix` must be a C identifier that is not a C keyword; got 'int'.
    """
    if not isinstance(prefix, str) or not _IDENT.match(prefix):
        raise ParameterError(
            f"`prefix` must be a C identifier (letters, digits, '_', not starting with a digit); got {prefix!r:.60}."
        )
    if prefix in C_KEYWORDS:
        raise ParameterError(f"`prefix` must be a C identifier that is not a C keyword; got {prefix!r}.")
    return prefix


def comment(text: str) -> str:
    """``text`` made safe inside a C block comment: one line, no ``*/`` or ``/*``, no trigraph ``??``."""
    one = " ".join(str(text).split())
    return one.replace("*/", "* /").replace("/*", "/ *").replace("??", "? ?")


#: The header: sizes, the complete state struct, the two functions.
HEADER = Template(
    """\
/* ${prefix}.h -- ${title}
 * Generated by stageid ${version} (`stageid export c`) from ${source}.
 * ${summary}
 * Self-contained C99: no heap, no I/O, no mutable globals; each ${prefix}_state is one
 * independent instance.  Arithmetic: ${ctype}.
 */
#ifndef ${guard}
#define ${guard}

#define ${prefix}_N_INPUTS ${n_inputs}
#define ${prefix}_N_OUTPUTS ${n_outputs}
${extra_defines}
/* Inputs, in this order: ${input_names}
 * Outputs, in this order: ${output_names} */

typedef struct {
${members}
} ${prefix}_state;

/* Set the state ${init_doc}. */
void ${prefix}_init(${prefix}_state *s);

/* Advance one sample: in[${prefix}_N_INPUTS] -> out[${prefix}_N_OUTPUTS]. */
void ${prefix}_step(${prefix}_state *s, const ${ctype} *in, ${ctype} *out);

#endif /* ${guard} */
"""
)

#: The source: includes, constant tables, helpers, then the two functions.
SOURCE = Template(
    """\
/* ${prefix}.c -- generated by stageid ${version} (`stageid export c`) from ${source}. */
#include "${prefix}.h"
${includes}
${constants}
${helpers}
void ${prefix}_init(${prefix}_state *s)
{
${init_body}
}

void ${prefix}_step(${prefix}_state *s, const ${ctype} *in, ${ctype} *out)
{
${step_body}
}
"""
)


def render_pair(fields: dict[str, object]) -> tuple[str, str]:
    """Fill :data:`HEADER` and :data:`SOURCE`; returns ``(header_text, source_text)``."""
    from .. import __version__

    f = {"version": __version__, "extra_defines": "", "includes": "", "helpers": "", **fields}
    f["guard"] = f"STAGEID_{f['prefix']}_H"  # the prefix as given: two prefixes never share a guard
    return HEADER.substitute(f), SOURCE.substitute(f)
