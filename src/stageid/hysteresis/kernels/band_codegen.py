"""LLVM vector code of the banded sums: block updates, bands and runs of samples (intrinsics).

The banded kernels (:mod:`.banded`) work on blocks of 4 operators, one 256-bit register of
doubles.  numba runs no SLP vectoriser and its loop vectoriser leaves 4-operator loops and
min/max reductions scalar, so the block updates are written as vector code through
``numba.extending.intrinsic``, with the shared emitter :class:`stageid.simd.Lanes`.  Each lane
does the plain formula of the reference (Python's ``max(a, c) = c if c > a else a``), so the
operator outputs are bit for bit those of :mod:`stageid.hysteresis.operators`.

Packed layout of the operators: an array of shape ``(n_blocks, rows, 4)``; CP rows ``-r,
-rc, ra, rb, w, z, tolerance`` (:data:`CP_ROWS`), play rows ``r, w, z, tolerance``
(:data:`PLAY_ROWS`).
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from ...runtime.simd import EXACT, LANES, REASSOC, VECTOR, Lanes, contiguous_float64, load_lanes

__all__ = [
    "LANES",
    "N_REGISTER_BLOCKS",
    "CP_ROWS",
    "PLAY_ROWS",
    "INERT",
    "make_hot",
    "make_block",
    "make_run",
    "outside4",
    "reduce4",
]

N_REGISTER_BLOCKS = 4  #: hot blocks whose outputs stay in registers during a run (5 or 6 spill)
CP_ROWS = 7
PLAY_ROWS = 4
INERT = 1e300  #: thresholds of the padding operators (zero weight, never move)
_I64 = ir.IntType(64)


def _layout(kind):
    """(rows per block, weight row, output row, tolerance row)."""
    return (CP_ROWS, 4, 5, 6) if kind == "cp" else (PLAY_ROWS, 1, 2, 3)


def _block_rows(context, builder, aryty, ary, b, n_rows):
    """Pointers to the rows of block b of a C-contiguous (n_blocks, n_rows, 4) array."""
    data = context.make_array(aryty)(context, builder, ary).data
    base = builder.mul(b, ir.Constant(b.type, LANES * n_rows))
    return [
        builder.bitcast(builder.gep(data, [builder.add(base, ir.Constant(b.type, LANES * j))]), VECTOR.as_pointer())
        for j in range(n_rows)
    ]


def _update_lanes(vec, kind, rows, xs, t):
    """Plain update of the 4 operators of a block; the new outputs are stored and returned.

    CP: ``max(x + max(-r, min(-rc, -x)), min(x + max(rb, min(ra, -x)), z))`` as in
    :func:`.loops.cp_sum`; play: ``max(x - r, min(x + r, z))`` as the reference.
    """
    if kind == "cp":
        nr, nrc, ra, rb = (vec.load(rows[j]) for j in range(4))
        up = vec.add(xs, vec.max(nr, vec.min(nrc, t)))
        down = vec.add(xs, vec.max(rb, vec.min(ra, t)))
        v = vec.max(up, vec.min(down, vec.load(rows[5])))
        vec.store(v, rows[5])
    else:
        r = vec.load(rows[0])
        v = vec.max(vec.sub(xs, r), vec.min(vec.add(xs, r), vec.load(rows[2])))
        vec.store(v, rows[2])
    return v


def _emit_memory_blocks(context, builder, aryty, P, start, stop, xs, t, kind):
    """Update blocks start..stop-1 (outputs in memory); the vector of their weighted sums.

    Two accumulators, so consecutive blocks do not wait for each other's fused multiply-add.
    """
    vec = Lanes(builder)
    n_rows, wrow = _layout(kind)[:2]
    accs = [cgutils.alloca_once_value(builder, vec.const(0.0)) for _ in range(2)]

    def add_block(acc, blk):
        rows = _block_rows(context, builder, aryty, P, blk, n_rows)
        v = _update_lanes(vec, kind, rows, xs, t)
        builder.store(vec.add(builder.load(acc), vec.mul(vec.load(rows[wrow]), v), REASSOC), acc)

    n = builder.sub(stop, start)
    with cgutils.for_range(builder, builder.ashr(n, ir.Constant(_I64, 1))) as loop:
        b0 = builder.add(start, builder.shl(loop.index, ir.Constant(_I64, 1)))
        for j, acc in enumerate(accs):
            add_block(acc, builder.add(b0, ir.Constant(_I64, j)))
    odd = builder.icmp_signed("!=", builder.and_(n, ir.Constant(_I64, 1)), ir.Constant(_I64, 0))
    with builder.if_then(odd):
        add_block(accs[0], builder.sub(stop, ir.Constant(_I64, 1)))
    return vec.add(builder.load(accs[0]), builder.load(accs[1]), REASSOC)


def make_hot(kind):
    """Intrinsic ``hot(P, n_hot, x) -> float``: update blocks 0..n_hot-1 at x, their weighted sum."""

    @intrinsic
    def hot(typingctx, P, n_hot, x):
        if not contiguous_float64(P):
            return None
        sig = types.float64(P, n_hot, x)

        def codegen(context, builder, signature, args):
            Pa, nh, xk = args
            vec = Lanes(builder)
            t = vec.splat(builder.fneg(xk))
            nh = context.cast(builder, nh, signature.args[1], types.int64)
            zero = ir.Constant(_I64, 0)
            acc = _emit_memory_blocks(context, builder, signature.args[0], Pa, zero, nh, vec.splat(xk), t, kind)
            return vec.hsum(acc)

        return sig, codegen

    return hot


def make_block(kind):
    """Intrinsic ``block(P, b, x) -> (weighted sum, lo, hi)``: update block b at x and return
    the open band (lo, hi) of inputs at which none of its operators moves.

    Rising, an operator with output v starts to move beyond ``v + rc`` (v < 0) or ``v + r``;
    falling, beyond ``v - rb`` (v > 0) or ``v - ra``; the band is pulled inwards by
    ``1e-15 (r + rc + ra + rb) + 1e-15 |v|`` so rounding never hides a move.
    """
    n_rows, wrow, zrow, tsrow = _layout(kind)

    @intrinsic
    def block(typingctx, P, b, x):
        if not contiguous_float64(P):
            return None
        sig = types.UniTuple(types.float64, 3)(P, b, x)

        def codegen(context, builder, signature, args):
            Pa, bv, xk = args
            vec = Lanes(builder)
            bv = context.cast(builder, bv, signature.args[1], types.int64)
            rows = _block_rows(context, builder, signature.args[0], Pa, bv, n_rows)
            zero = vec.const(0.0)
            v = _update_lanes(vec, kind, rows, vec.splat(xk), vec.splat(builder.fneg(xk)))
            if kind == "cp":
                nr, nrc, ra, rb = (vec.load(rows[j]) for j in range(4))
                s_up = builder.select(builder.fcmp_ordered("<", v, zero, flags=EXACT), nrc, nr)
                s_down = builder.select(builder.fcmp_ordered(">", v, zero, flags=EXACT), rb, ra)
            else:
                r = vec.load(rows[0])
                s_up = builder.fneg(r)
                s_down = r
            absv = builder.select(builder.fcmp_ordered("<", v, zero, flags=EXACT), builder.fneg(v), v)
            tol = vec.add(vec.load(rows[tsrow]), vec.mul(vec.const(1e-15), absv, EXACT))
            hi = vec.sub(vec.sub(v, s_up), tol)
            lo = vec.add(vec.sub(v, s_down), tol)
            cb = vec.hsum(vec.mul(vec.load(rows[wrow]), v))
            return context.make_tuple(builder, signature.return_type, [cb, vec.hmax(lo), vec.hmin(hi)])

        return sig, codegen

    return block


def _emit_hot_sums(context, builder, vec, kind, registers, memory, xk):
    """The hot blocks updated at ``xk``, as one vector of weighted outputs (an empty list
    without any): the register blocks (``registers``: their rows and output slots), then with
    ``memory`` = ``(array type, P, n_hot)`` the others in memory, summed pairwise."""
    _, wrow, zrow = _layout(kind)[:3]
    rows, z_slots = registers
    xs = vec.splat(xk)
    t = vec.splat(builder.fneg(xk))
    parts = []
    for b in range(len(z_slots)):
        in_register = list(rows[b])
        in_register[zrow] = z_slots[b]
        v = _update_lanes(vec, kind, in_register, xs, t)
        parts.append(vec.mul(vec.load(rows[b][wrow]), v))
    if memory is not None:
        aryty, Pa, nh = memory
        first = ir.Constant(_I64, len(z_slots))
        parts.append(_emit_memory_blocks(context, builder, aryty, Pa, first, nh, xs, t, kind))
    while len(parts) > 1:  # pairwise sum of the block sums
        pairs = [vec.add(parts[i], parts[i + 1], REASSOC) for i in range(0, len(parts) - 1, 2)]
        parts = pairs + ([parts[-1]] if len(parts) % 2 else [])
    return parts


def _emit_run(context, builder, signature, args, kind, n_reg, memory):
    """One variant of the run loop (see :func:`make_run`); returns the values (k, xl, yl).

    The first ``n_reg`` hot blocks keep their outputs in registers (no store-to-load latency
    from one sample to the next); with ``memory`` the others are updated in memory.
    """
    n_rows, _, zrow = _layout(kind)[:3]
    xa, ya, k0, k1v, Pa, nh, Cv, lov, hiv, W0v, xlv, ylv = args
    k0 = context.cast(builder, k0, signature.args[2], types.int64)
    k1v = context.cast(builder, k1v, signature.args[3], types.int64)
    nh = context.cast(builder, nh, signature.args[5], types.int64)
    aryty = signature.args[4]
    vec = Lanes(builder)
    xd = context.make_array(signature.args[0])(context, builder, xa).data
    yd = context.make_array(signature.args[1])(context, builder, ya).data
    rows = [_block_rows(context, builder, aryty, Pa, ir.Constant(_I64, b), n_rows) for b in range(n_reg)]
    k_slot = cgutils.alloca_once_value(builder, k0)
    xl_slot = cgutils.alloca_once_value(builder, xlv)
    yl_slot = cgutils.alloca_once_value(builder, ylv)
    z_slots = [cgutils.alloca_once_value(builder, vec.load(rows[b][zrow])) for b in range(n_reg)]
    fn = builder.function
    head, body, still, move, update, done = (
        fn.append_basic_block(f"band.{s}") for s in ("head", "body", "still", "move", "update", "done")
    )
    one = ir.Constant(_I64, 1)
    builder.branch(head)
    builder.position_at_end(head)
    kk = builder.load(k_slot)
    builder.cbranch(builder.icmp_signed("<", kk, k1v), body, done)
    builder.position_at_end(body)
    xk = builder.load(builder.gep(xd, [kk]))
    builder.cbranch(builder.fcmp_ordered("==", xk, builder.load(xl_slot), flags=EXACT), still, move)
    builder.position_at_end(still)  # standing still: nothing moves
    builder.store(builder.load(yl_slot), builder.gep(yd, [kk]))
    builder.store(builder.add(kk, one), k_slot)
    builder.branch(head)
    builder.position_at_end(move)
    inside = builder.and_(
        builder.fcmp_ordered("<", xk, hiv, flags=EXACT), builder.fcmp_ordered(">", xk, lov, flags=EXACT)
    )
    builder.cbranch(inside, update, done)
    builder.position_at_end(update)
    parts = _emit_hot_sums(context, builder, vec, kind, (rows, z_slots), (aryty, Pa, nh) if memory else None, xk)
    yk = vec.add(Cv, vec.mul(W0v, xk), REASSOC)
    if parts:
        yk = vec.add(yk, vec.hsum(parts[0]), REASSOC)
    builder.store(yk, builder.gep(yd, [kk]))
    builder.store(yk, yl_slot)
    builder.store(xk, xl_slot)
    builder.store(builder.add(kk, one), k_slot)
    builder.branch(head)
    builder.position_at_end(done)
    for b in range(n_reg):
        vec.store(builder.load(z_slots[b]), rows[b][zrow])
    return builder.load(k_slot), builder.load(xl_slot), builder.load(yl_slot)


def make_run(kind):
    """Intrinsic ``run(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl) -> (k, xl, yl)``.

    Runs samples k.. while the input stays inside the cold blocks' band (lo, hi): the hot
    blocks (the first ``n_hot``) are updated at every sample that moves and
    ``y = C + W0 x + hot sum``.  Returns at k1 or at the first sample that leaves the band
    (not processed), with the last input and output.

    The loop is generated once per entry of a table indexed by ``min(n_hot, 5)``: entry ``i <=
    4`` keeps all ``i`` hot blocks in registers, the last entry keeps 4 in registers and the
    rest in memory; the switch over the table is one LLVM ``switch`` (a jump table).
    """
    variants = [(n_reg, False) for n_reg in range(N_REGISTER_BLOCKS + 1)] + [(N_REGISTER_BLOCKS, True)]

    @intrinsic
    def run(typingctx, x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl):
        if not contiguous_float64(x, y, P):
            return None
        ret = types.Tuple((types.int64, types.float64, types.float64))
        sig = ret(x, y, k, k1, P, n_hot, C, lo, hi, W0, xl, yl)

        def codegen(context, builder, signature, args):
            nh = context.cast(builder, args[5], signature.args[5], types.int64)
            last = ir.Constant(_I64, len(variants) - 1)
            index = builder.select(builder.icmp_signed("<", nh, last), nh, last)
            slots = [cgutils.alloca_once(builder, t) for t in (_I64, ir.DoubleType(), ir.DoubleType())]
            fn = builder.function
            cases = [fn.append_basic_block(f"run.{i}") for i in range(len(variants))]
            merge = fn.append_basic_block("run.merge")
            switch = builder.switch(index, cases[-1])
            for i, case in enumerate(cases[:-1]):
                switch.add_case(ir.Constant(_I64, i), case)
            for case, (n_reg, memory) in zip(cases, variants):
                builder.position_at_end(case)
                values = _emit_run(context, builder, signature, args, kind, n_reg, memory)
                for slot, value in zip(slots, values):
                    builder.store(value, slot)
                builder.branch(merge)
            builder.position_at_end(merge)
            return context.make_tuple(builder, signature.return_type, [builder.load(s) for s in slots])

        return sig, codegen

    return run


@intrinsic
def outside4(typingctx, lob, hib, g, x):
    """Bit j set when x is outside the band (lob[g + j], hib[g + j]), j = 0..3."""
    if not contiguous_float64(lob, hib):
        return None
    sig = types.int64(lob, hib, g, x)

    def codegen(context, builder, signature, args):
        la, ha, gv, xk = args
        gv = context.cast(builder, gv, signature.args[2], types.int64)
        lo = load_lanes(context, builder, signature.args[0], la, gv)
        hi = load_lanes(context, builder, signature.args[1], ha, gv)
        xs = Lanes(builder).splat(xk)
        out = builder.or_(
            builder.fcmp_ordered(">=", xs, hi, flags=EXACT), builder.fcmp_ordered("<=", xs, lo, flags=EXACT)
        )
        return builder.zext(builder.bitcast(out, ir.IntType(LANES)), _I64)

    return sig, codegen


@intrinsic
def reduce4(typingctx, Cb, lob, hib, g):
    """(sum of Cb, max of lob, min of hib) over entries g..g+3."""
    if not contiguous_float64(Cb, lob, hib):
        return None
    sig = types.UniTuple(types.float64, 3)(Cb, lob, hib, g)

    def codegen(context, builder, signature, args):
        gv = context.cast(builder, args[3], signature.args[3], types.int64)
        vecs = [load_lanes(context, builder, signature.args[i], args[i], gv) for i in range(3)]
        vec = Lanes(builder)
        return context.make_tuple(
            builder, signature.return_type, [vec.hsum(vecs[0]), vec.hmax(vecs[1]), vec.hmin(vecs[2])]
        )

    return sig, codegen
