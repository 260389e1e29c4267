"""Arrays without a reference count, for numba kernels that pass scratch arrays to other kernels per event.

numba counts references to an array's memory: a kernel that takes an array
argument increments the count on entry and decrements it on exit, two locked
(atomic) instructions each; a non-inlined call per event (:func:`~evedge.detector.
_intra_kernels._fit_points` on the scratch arrays) pays them for every event, and
when two threads pass views of one allocation (the strips' state) they contend
for one counter. :func:`_borrowed` returns the same array (data, shape, strides)
with no meminfo: the counts on it are skipped (numba's ``NRT_incref`` tests for
null). The caller must keep the original array alive while the borrowed one is
used (a kernel's own argument or local always is).
"""

from numba import types
from numba.extending import intrinsic


@intrinsic
def _borrowed(typingctx, arr):
    """``arr`` itself (the same memory), with no reference count: valid while ``arr`` is alive."""
    if not isinstance(arr, types.Array):
        return None

    def codegen(context, builder, sig, args):
        src = context.make_array(sig.args[0])(context, builder, args[0])
        dst = context.make_array(sig.return_type)(context, builder)
        context.populate_array(dst, data=src.data, shape=src.shape, strides=src.strides, itemsize=src.itemsize,
                               meminfo=None, parent=None)
        return dst._getvalue()

    return arr(arr), codegen
