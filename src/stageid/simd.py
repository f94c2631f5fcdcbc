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
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.extending import intrinsic, models, register_model

__all__ = ["vload", "vstore", "vbcast", "vzero", "vfma", "vfnma", "vmul", "vsum"]

_V = ir.VectorType(ir.DoubleType(), 4)
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
