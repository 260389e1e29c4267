"""Five primitives numba lacks, for strips that wait on each other (:mod:`evedge.detector._tiles`).

``_load_acquire(a, i)`` / ``_store_release(a, i, v)``: an atomic read / write of one
element of an array (naturally aligned, as numpy allocates) with acquire / release ordering (a value written by one
thread is seen by another, and not before what was written ahead of it);
``_claim(a, i)``: atomically turn ``a[i]`` from 0 into 1, True when this call did
(a lock taken without waiting); ``_sched_yield()``: give the core away while
waiting (the machine may be shared); ``_clock_ns(id)``: ``clock_gettime``
(a thread's CPU time, to tell work from waiting). LLVM intrinsics, so the kernels using them
stay cacheable.
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
        align = context.get_abi_sizeof(context.get_value_type(sig.args[0].dtype))
        return builder.load_atomic(ptr, "acquire", align)
    return arr.dtype(arr, i), codegen


@intrinsic
def _store_release(typingctx, arr, i, v):
    """``arr[i] = v`` written atomically (release); ``v`` is cast to the array's dtype."""
    def codegen(context, builder, sig, args):
        a = context.make_array(sig.args[0])(context, builder, args[0])
        ptr = builder.gep(a.data, [args[1]])
        val = context.cast(builder, args[2], sig.args[2], sig.args[0].dtype)
        builder.store_atomic(val, ptr, "release", context.get_abi_sizeof(context.get_value_type(sig.args[0].dtype)))
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


@intrinsic
def _claim(typingctx, arr, i):
    """Compare-and-swap ``arr[i]``: 0 -> 1; True when it was 0 (sequentially consistent)."""
    def codegen(context, builder, sig, args):
        a = context.make_array(sig.args[0])(context, builder, args[0])
        ptr = builder.gep(a.data, [args[1]])
        ty = context.get_value_type(sig.args[0].dtype)
        res = builder.cmpxchg(ptr, ir.Constant(ty, 0), ir.Constant(ty, 1), "seq_cst", "seq_cst")
        return builder.extract_value(res, 1)
    return types.boolean(arr, i), codegen


@intrinsic
def _clock_ns(typingctx, clock_id):
    """POSIX ``clock_gettime(clock_id)`` in nanoseconds (int64); e.g. 3 = this thread's CPU time on Linux."""
    def codegen(context, builder, sig, args):
        i64 = ir.IntType(64)
        spec = ir.LiteralStructType([i64, i64])
        fn = cgutils.get_or_insert_function(builder.module,
                                            ir.FunctionType(ir.IntType(32), [ir.IntType(32), spec.as_pointer()]),
                                            "clock_gettime")
        buf = cgutils.alloca_once(builder, spec)
        builder.call(fn, [builder.trunc(args[0], ir.IntType(32)), buf])
        sec = builder.load(builder.gep(buf, [ir.Constant(ir.IntType(32), 0), ir.Constant(ir.IntType(32), 0)]))
        nsec = builder.load(builder.gep(buf, [ir.Constant(ir.IntType(32), 0), ir.Constant(ir.IntType(32), 1)]))
        return builder.add(builder.mul(sec, ir.Constant(i64, 1_000_000_000)), nsec)
    return types.int64(clock_id), codegen
