"""The problem's data without reference counts, for the length of a compiled loop.

numba counts a reference to every array a compiled function receives (an atomic increment at
entry, a decrement at exit), array by array through a tuple: an operator that takes a scheme's
data ``D`` (a named tuple of ≈ 40 arrays) pays ≈ 80 atomic operations a call, and a loop makes
such calls several times a step.  :func:`unmanaged` gives the loop a copy of ``D`` whose arrays
view the same memory without an owner (numba's ``meminfo`` null, as for an array made by
``carray``): counting their references is then a test of a null pointer.  The arrays stay
alive through ``D`` itself, which the loop holds until it returns; the copy must not outlive
the loop (no operator returns or stores one of its arrays: they return numbers or new arrays).
"""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["unmanaged"]


@intrinsic
def unmanaged(typingctx, data):
    """``data`` (a tuple or named tuple) with its arrays' owners cleared (see the module docstring);
    other members as they are."""
    if not isinstance(data, types.BaseTuple):
        return None

    def codegen(context, builder, signature, args):
        (value,) = args
        out = value
        for i, ty in enumerate(data):
            item = builder.extract_value(value, i)
            if isinstance(ty, types.Array):
                ary = context.make_array(ty)(context, builder, item)
                ary.meminfo = cgutils.get_null_value(ary.meminfo.type)
                ary.parent = cgutils.get_null_value(ary.parent.type)
                out = builder.insert_value(out, ary._getvalue(), i)
            else:
                context.nrt.incref(builder, ty, item)  # (a new reference, as an intrinsic returns)
        return out

    return data(data), codegen
