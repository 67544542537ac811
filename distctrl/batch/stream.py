"""Non-temporal ("streaming") stores for the batch kernels' trace outputs.

A sweep writes its traces once and reads them later: 16 bytes per set and cycle, far more than any
cache holds. An ordinary store first reads the cache line it writes into (read for ownership), so
every trace byte crosses the memory bus twice. A non-temporal store writes a whole line straight
to memory through a write-combining buffer, without reading it; it pays when the 8 doubles of one
64-byte line are stored back to back. :func:`distctrl.batch.soa.block_loop` therefore keeps the
last 8 cycles of every lane and streams a line when it is complete (the writes alone: 2.0-2.8 ns
-> 1.2 ns per set-cycle on the bench machine, docs/batch.md).

Non-temporal stores are weakly ordered: :func:`store_fence` must follow them before anybody else
reads the memory (or this thread stores to it the ordinary way). On a machine without such
stores LLVM emits ordinary ones; the numbers are the same either way.
"""
from __future__ import annotations

import platform

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["store_stream", "store_fence"]


@intrinsic
def store_stream(typingctx, array, row, col, value):
    """``array[row, col] = value`` (2-D float64 array, indices in range) as a non-temporal store."""
    if not (isinstance(array, types.Array) and array.ndim == 2 and array.dtype == types.float64):
        return None
    sig = types.void(array, types.intp, types.intp, types.float64)

    def codegen(context, builder, signature, args):
        ary_t = signature.args[0]
        ary = context.make_array(ary_t)(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, ary_t, ary, [args[1], args[2]])
        store = builder.store(args[3], ptr)
        store.set_metadata("nontemporal", builder.module.add_metadata([ir.IntType(32)(1)]))
        return context.get_dummy_value()

    return sig, codegen


_X86 = platform.machine().lower() in ("x86_64", "amd64")


@intrinsic
def store_fence(typingctx):
    """Order all earlier stores (the non-temporal ones included) before all later memory accesses:
    ``sfence`` on x86-64 (what its manuals prescribe after non-temporal stores), else LLVM's
    sequentially consistent fence."""
    sig = types.void()

    def codegen(context, builder, signature, args):
        if _X86:
            sfence = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), []),
                                                    "llvm.x86.sse.sfence")
            builder.call(sfence, [])
        else:
            builder.fence("seq_cst")
        return context.get_dummy_value()

    return sig, codegen
