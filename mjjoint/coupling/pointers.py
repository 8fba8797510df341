"""Raw-pointer helpers for numba callbacks that receive ``mjModel*``/``mjData*`` as void*."""
from __future__ import annotations

from numba import carray, njit, types
from numba.extending import intrinsic


@intrinsic
def _addr(typingctx, ptr):
    """void* -> integer address."""
    def codegen(context, builder, sig, args):
        return builder.ptrtoint(args[0], context.get_value_type(types.uintp))
    return types.uintp(types.voidptr), codegen


def _typed(dtype):
    @intrinsic
    def cast(typingctx, address):
        def codegen(context, builder, sig, args):
            return builder.inttoptr(args[0], context.get_value_type(types.CPointer(dtype)))
        return types.CPointer(dtype)(types.uintp), codegen
    return cast


_as_u64 = _typed(types.uint64)
_as_f64 = _typed(types.float64)
_as_i32 = _typed(types.int32)


@njit(inline="always")
def field(struct, offset):
    """Value of the pointer field at byte ``offset`` of a struct given as void*."""
    return carray(_as_u64(_addr(struct) + offset), 1)[0]


@njit(inline="always")
def i32_array(address, n):
    return carray(_as_i32(address), n)


@njit(inline="always")
def f64_ptr(address):
    """A double* at ``address``: indexable like an array, with no array object behind it."""
    return _as_f64(address)


@njit(inline="always")
def f64_at(struct, offset):
    """A double stored inline at byte ``offset`` of a struct given as void*."""
    return carray(_as_f64(_addr(struct) + offset), 1)[0]


@njit(inline="always")
def f64_ptr_array(ptr, n):
    """A double array passed as void* (the reset callback's plugin_state)."""
    return carray(_as_f64(_addr(ptr)), n)


@njit(inline="always")
def u64_array(address, n):
    return carray(_as_u64(address), n)
