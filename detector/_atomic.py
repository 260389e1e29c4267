"""Three primitives numba lacks, for strips that wait on each other (:mod:`evedge.detector._tiles`).

``_load_acquire(a, i)`` / ``_store_release(a, i, v)``: an atomic read / write of one
element of an int8 array with acquire / release ordering (a value written by
one thread is seen by another, and not before what was written ahead of it);
``_sched_yield()``: give the core away while waiting (the machine may be
shared). LLVM intrinsics, so the kernels using them stay cacheable.
"""

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def _load_acquire(typingctx, arr, i):
    """``arr[i]`` read atomically (acquire)."""
    def codegen(context, builder, sig, args):
        a = context.make_array(sig.args[0])(context, builder, args[0])
        ptr = builder.gep(a.data, [args[1]])
        return builder.load_atomic(ptr, "acquire", 1)
    return arr.dtype(arr, i), codegen


@intrinsic
def _store_release(typingctx, arr, i, v):
    """``arr[i] = v`` written atomically (release); ``v`` is cast to the array's dtype."""
    def codegen(context, builder, sig, args):
        a = context.make_array(sig.args[0])(context, builder, args[0])
        ptr = builder.gep(a.data, [args[1]])
        val = context.cast(builder, args[2], sig.args[2], sig.args[0].dtype)
        builder.store_atomic(val, ptr, "release", 1)
        return context.get_dummy_value()
    return types.void(arr, i, v), codegen


@intrinsic
def _sched_yield(typingctx):
    """POSIX ``sched_yield()``."""
    def codegen(context, builder, sig, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.IntType(32), []), "sched_yield")
        builder.call(fn, [])
        return context.get_dummy_value()
    return types.void(), codegen
