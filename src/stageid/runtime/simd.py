"""Four-wide float64 vectors for numba kernels, shared by every compiled kernel of stageid.

numba vectorises a loop only when LLVM can rule out aliasing between its arrays with at most
eight run-time pointer checks; the recursive MAP kernels touch more arrays per loop than that
(rows of ``P``, four gains, four regressors, four accumulators) and then run scalar.  These
intrinsics let a kernel say what it means instead: ``vload(a, i)`` is the vector
``a[i:i + 4]``, ``vfma(a, b, c)`` is ``a * b + c`` lane by lane, and so on.  They lower to
LLVM ``<4 x double>`` operations (one ymm register and one FMA instruction each with AVX2;
two SSE registers on older CPUs, same results).  Loads and stores assume only 8-byte
alignment.  Arithmetic carries LLVM's ``fast`` flags, like ``fastmath=True`` kernels.
numba's on-disk cache keys a kernel on its own source file only: after editing this module,
delete the ``__pycache__/*.nbi``/``*.nbc`` files of the kernels that use it.

Kernels that write their own intrinsics (the banded hysteresis sums) emit the same
``<4 x double>`` code through :class:`Lanes`, which builds the operations inside a codegen
function, with per-instruction flags instead of ``fast`` where rounding must not change;
:func:`contiguous_float64`, :func:`lane_pointer` and :func:`load_lanes` are its array helpers.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.extending import intrinsic, models, register_model

__all__ = [
    "vload",
    "vstore",
    "vbcast",
    "vzero",
    "vfma",
    "vfnma",
    "vmul",
    "vsum",
    "LANES",
    "VECTOR",
    "EXACT",
    "REASSOC",
    "Lanes",
    "contiguous_float64",
    "lane_pointer",
    "load_lanes",
]

LANES = 4
_V = ir.VectorType(ir.DoubleType(), LANES)
VECTOR = _V  #: the LLVM type of four doubles
#: Flags of operations whose rounding must not change (no reassociation, no contraction).
EXACT = ("nnan", "ninf", "nsz")
#: Flags of sums whose association does not matter (weighted sums).
REASSOC = ("nnan", "ninf", "nsz", "reassoc", "contract")
_FAST = ("fast",)


class _F64x4(types.Type):
    def __init__(self) -> None:
        super().__init__(name="f64x4")


f64x4 = _F64x4()


@register_model(_F64x4)
class _F64x4Model(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _V)


def _vector_array(ary, index) -> bool:
    """Typing guard: a contiguous 1-D float64 array and an integer index."""
    return (
        isinstance(ary, types.Array)
        and ary.dtype == types.float64
        and ary.ndim == 1
        and ary.layout == "C"
        and isinstance(index, types.Integer)
    )


def _address(context, builder, aryty, ary, index):
    data = context.make_array(aryty)(context, builder, ary).data
    return builder.bitcast(builder.gep(data, [index]), _V.as_pointer())


@intrinsic
def vload(typingctx, ary, index):
    """``ary[index:index + 4]`` of a contiguous 1-D float64 array (no bounds check)."""
    if not _vector_array(ary, index):
        return None

    def codegen(context, builder, sig, args):
        return builder.load(_address(context, builder, sig.args[0], args[0], args[1]), align=8)

    return f64x4(ary, index), codegen


@intrinsic
def vstore(typingctx, ary, index, value):
    """``ary[index:index + 4] = value`` (no bounds check)."""
    if not (_vector_array(ary, index) and value == f64x4):
        return None

    def codegen(context, builder, sig, args):
        builder.store(args[2], _address(context, builder, sig.args[0], args[0], args[1]), align=8)
        return context.get_dummy_value()

    return types.none(ary, index, value), codegen


@intrinsic
def vbcast(typingctx, x):
    """The vector ``(x, x, x, x)``."""

    def codegen(context, builder, sig, args):
        value = ir.Constant(_V, ir.Undefined)
        for i in range(4):
            value = builder.insert_element(value, args[0], ir.Constant(ir.IntType(32), i))
        return value

    return f64x4(types.float64), codegen


@intrinsic
def vzero(typingctx):
    """The vector ``(0, 0, 0, 0)``."""

    def codegen(context, builder, sig, args):
        return ir.Constant(_V, [0.0] * 4)

    return f64x4(), codegen


@intrinsic
def vfma(typingctx, a, b, c):
    """``a * b + c`` (one fused multiply-add)."""

    def codegen(context, builder, sig, args):
        return builder.fadd(builder.fmul(args[0], args[1], flags=_FAST), args[2], flags=_FAST)

    return f64x4(f64x4, f64x4, f64x4), codegen


@intrinsic
def vfnma(typingctx, a, b, c):
    """``c - a * b`` (one fused multiply-add)."""

    def codegen(context, builder, sig, args):
        return builder.fsub(args[2], builder.fmul(args[0], args[1], flags=_FAST), flags=_FAST)

    return f64x4(f64x4, f64x4, f64x4), codegen


@intrinsic
def vmul(typingctx, a, b):
    """``a * b``."""

    def codegen(context, builder, sig, args):
        return builder.fmul(args[0], args[1], flags=_FAST)

    return f64x4(f64x4, f64x4), codegen


@intrinsic
def vsum(typingctx, a):
    """The sum of the four lanes."""

    def codegen(context, builder, sig, args):
        lane = [builder.extract_element(args[0], ir.Constant(ir.IntType(32), i)) for i in range(4)]
        return builder.fadd(
            builder.fadd(lane[0], lane[1], flags=_FAST), builder.fadd(lane[2], lane[3], flags=_FAST), flags=_FAST
        )

    return types.float64(f64x4), codegen


# ------------------------------------------------------------------ codegen-level helpers
class Lanes:
    """Emits 4-lane double operations into an LLVM ``builder`` (inside an intrinsic's codegen).

    ``max``/``min`` are Python's (``max(a, c) = c if c > a else a``), so a lane computes what
    the plain-Python twin of a kernel computes; ``add``/``sub`` carry :data:`EXACT` flags
    unless told otherwise (flagged instructions are left alone by numba's fastmath pass).
    """

    def __init__(self, builder: ir.IRBuilder) -> None:
        self.b = builder

    @staticmethod
    def _flag(ins, flags):
        for f in flags:
            ins.flags.append(f)
        return ins

    def add(self, a, c, flags=EXACT):
        return self._flag(self.b.fadd(a, c), flags)

    def sub(self, a, c, flags=EXACT):
        return self._flag(self.b.fsub(a, c), flags)

    def mul(self, a, c, flags=REASSOC):
        return self._flag(self.b.fmul(a, c), flags)

    def max(self, a, c):
        return self.b.select(self.b.fcmp_ordered(">", c, a, flags=EXACT), c, a)

    def min(self, a, c):
        return self.b.select(self.b.fcmp_ordered("<", c, a, flags=EXACT), c, a)

    def splat(self, s):
        """``(s, s, s, s)`` as one insert and one shuffle."""
        v = self.b.insert_element(ir.Constant(_V, ir.Undefined), s, ir.Constant(ir.IntType(32), 0))
        mask = ir.Constant(ir.VectorType(ir.IntType(32), LANES), [0] * LANES)
        return self.b.shuffle_vector(v, ir.Constant(_V, ir.Undefined), mask)

    @staticmethod
    def const(c):
        return ir.Constant(_V, [c] * LANES)

    def lanes(self, v):
        return [self.b.extract_element(v, ir.Constant(ir.IntType(32), i)) for i in range(LANES)]

    def hsum(self, v):
        """``(l0 + l2) + (l1 + l3)``: one 2-lane add, then one scalar add."""
        i32 = ir.IntType(32)
        undef = ir.Constant(_V, ir.Undefined)
        lo = self.b.shuffle_vector(v, undef, ir.Constant(ir.VectorType(i32, 2), [0, 1]))
        hi = self.b.shuffle_vector(v, undef, ir.Constant(ir.VectorType(i32, 2), [2, 3]))
        s = self.add(lo, hi, REASSOC)
        return self.add(
            self.b.extract_element(s, ir.Constant(i32, 0)), self.b.extract_element(s, ir.Constant(i32, 1)), REASSOC
        )

    def hmin(self, v):
        l0, l1, l2, l3 = self.lanes(v)
        return self.min(self.min(l0, l1), self.min(l2, l3))

    def hmax(self, v):
        l0, l1, l2, l3 = self.lanes(v)
        return self.max(self.max(l0, l1), self.max(l2, l3))

    def load(self, pointer):
        """The vector at a ``<4 x double>*`` (8-byte alignment assumed)."""
        return self.b.load(pointer, align=8)

    def store(self, value, pointer):
        self.b.store(value, pointer, align=8)


def contiguous_float64(*tys) -> bool:
    """Typing guard: every type is a C-contiguous float64 array (the intrinsics index raw data)."""
    return all(isinstance(t, types.Array) and t.dtype == types.float64 and t.layout == "C" for t in tys)


def lane_pointer(context, builder, aryty, ary, index):
    """``<4 x double>*`` at element ``index`` of a contiguous array (no bounds check)."""
    return _address(context, builder, aryty, ary, index)


def load_lanes(context, builder, aryty, ary, index):
    """The 4 doubles ``ary[index:index + 4]`` of a contiguous array as a vector."""
    return builder.load(_address(context, builder, aryty, ary, index), align=8)
