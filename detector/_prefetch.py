"""A cache hint for numba kernels whose next accesses are known but scattered over a large state.

The estimator's stream kernel reads, for every event, its pixel's state and the
rows of its window in the SAE: on a megapixel sensor (1280x720, ~15 MB of SAE
alone) consecutive events land far apart and nearly every one of those reads
misses the core's caches. The events to come are known (they are the input), so
the kernel asks for their cache lines a few events ahead with :func:`_prefetch`,
LLVM's ``llvm.prefetch`` (an x86 ``prefetcht0``): a hint, which changes no value
and cannot fault (an address past an array's end is never touched, only hinted;
the kernels still keep their indices inside the arrays).
"""

from llvmlite import ir
from numba import types
from numba.extending import intrinsic


@intrinsic
def _prefetch(typingctx, arr, i):
    """Hint that ``arr.flat[i]`` (a C-contiguous array) will be read soon; returns nothing."""
    if not isinstance(arr, types.Array) or not isinstance(i, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        ary = context.make_array(sig.args[0])(context, builder, args[0])
        idx = context.cast(builder, args[1], sig.args[1], types.intp)
        ptr = builder.gep(ary.data, [idx])
        i8p = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        fn = builder.module.declare_intrinsic("llvm.prefetch", fnty=ir.FunctionType(ir.VoidType(), (i8p, i32, i32, i32)))
        # read, highest locality (keep in every cache level), data cache
        builder.call(fn, (builder.bitcast(ptr, i8p), ir.Constant(i32, 0), ir.Constant(i32, 3), ir.Constant(i32, 1)))
        return context.get_dummy_value()

    return types.none(arr, i), codegen
