"""Eight float64 numbers side by side, one per filter, as one SIMD value in compiled code (numba).

:data:`Lanes` is numba's name for LLVM's ``<8 x double>``: the compiler keeps such a value in vector
registers and does each arithmetic step on all eight lanes at once, one lane per filter. numba's own
loops over filters rarely become vector code, because numba cannot tell the compiler that two arrays
do not overlap; a value that is not in memory needs no such promise.

Arithmetic (``+ - * /``, unary ``-``, with a float on either side), ``abs`` and ``math.copysign``
work on Lanes lane by lane with IEEE rounding, so a function written for floats,
such as :func:`~quad_wrench_env.numerics.quaternions.qmul`, compiles for Lanes too and gives each lane
exactly the float result. Branches cannot depend on Lanes: :func:`all_less` and the masks below
turn comparisons into plain booleans and bits.

Lanes live in flat, C-contiguous float64 arrays in "lane layout": entry ``e`` of the eight filters
at ``[8 e, 8 e + 8)``. :func:`load` and :func:`store` check that range (:class:`IndexError`).
Needs numba (``pip install "quad-wrench-env[fast]"``).
"""

from __future__ import annotations

import math
import operator

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, models, overload, register_model

from quad_wrench_env.numerics import njit

WIDTH = 8
"""Lanes per value: eight filters per SIMD value (one AVX-512 register, two AVX ones)."""
_ALL = (1 << WIDTH) - 1
_VECTOR = ir.VectorType(ir.DoubleType(), WIDTH)


@njit(inline=True)
def empty(entries):
    """An uninitialised lane-layout array of ``entries`` entries, aligned to 64 bytes, so that no
    lane value straddles two cache lines. numba aligns its arrays to 32 bytes only, on which the lane
    UKF's speed varied from one process to the next."""
    buffer = np.empty((entries + 1) * WIDTH)
    start = (-(buffer.ctypes.data // 8)) % WIDTH
    return buffer[start : start + entries * WIDTH]


class LanesType(types.Type):
    def __init__(self) -> None:
        super().__init__(name=f"Lanes{WIDTH}")


Lanes = LanesType()
"""numba type of a value of :data:`WIDTH` float64 lanes."""


@register_model(LanesType)
class _LanesModel(models.PrimitiveModel):
    def __init__(self, dmm, fe_type) -> None:
        super().__init__(dmm, fe_type, _VECTOR)


_FLAT = types.Array(types.float64, 1, "C")


def _pointer(context, builder, signature, args):
    """Address of the lanes at ``args[1]`` of the flat array ``args[0]``, range checked."""
    array = context.make_array(signature.args[0])(context, builder, args[0])
    offset = context.cast(builder, args[1], signature.args[1], types.intp)
    end = builder.add(offset, ir.Constant(offset.type, WIDTH))
    size = builder.extract_value(array.shape, 0)
    outside = builder.or_(
        builder.icmp_signed("<", offset, ir.Constant(offset.type, 0)), builder.icmp_signed(">", end, size)
    )
    with builder.if_then(outside, likely=False):
        context.call_conv.return_user_exc(builder, IndexError, ("lanes outside the array",))
    return builder.bitcast(builder.gep(array.data, [offset]), _VECTOR.as_pointer())


def _check_flat(array, offset) -> None:
    if array != _FLAT or not isinstance(offset, types.Integer):
        raise TypeError(
            f"lanes need a 1-d C-contiguous float64 array and an integer offset, got {array}, {offset}"
        )


def _splat(context, builder, value, value_type):
    lanes = ir.Constant(_VECTOR, ir.Undefined)
    value = context.cast(builder, value, value_type, types.float64)
    for i in range(WIDTH):
        lanes = builder.insert_element(lanes, value, ir.Constant(ir.IntType(32), i))
    return lanes


@intrinsic
def load(typingctx, array, offset):
    """The lanes ``array[offset : offset + WIDTH]``."""
    _check_flat(array, offset)

    def codegen(context, builder, signature, args):
        return builder.load(_pointer(context, builder, signature, args), align=8)

    return Lanes(array, offset), codegen


@intrinsic
def store(typingctx, array, offset, value):
    """``array[offset : offset + WIDTH] = value``."""
    _check_flat(array, offset)

    def codegen(context, builder, signature, args):
        builder.store(args[2], _pointer(context, builder, signature, args), align=8)
        return context.get_dummy_value()

    return types.void(array, offset, Lanes), codegen


@intrinsic
def splat(typingctx, x):
    """Lanes all equal to the number ``x``."""

    def codegen(context, builder, signature, args):
        return _splat(context, builder, args[0], signature.args[0])

    return Lanes(x), codegen


@intrinsic
def lane(typingctx, lanes, index):
    """Lane ``index`` as a float."""

    def codegen(context, builder, signature, args):
        return builder.extract_element(
            args[0], context.cast(builder, args[1], signature.args[1], types.int32)
        )

    return types.float64(Lanes, index), codegen


@intrinsic
def with_lane(typingctx, lanes, index, x):
    """``lanes`` with lane ``index`` replaced by the float ``x``."""

    def codegen(context, builder, signature, args):
        value = context.cast(builder, args[2], signature.args[2], types.float64)
        position = context.cast(builder, args[1], signature.args[1], types.int32)
        return builder.insert_element(args[0], value, position)

    return Lanes(Lanes, index, x), codegen


def _mask(builder, bits):
    """The ``WIDTH`` comparison bits as an int64, bit ``l`` for lane ``l``."""
    return builder.zext(builder.bitcast(bits, ir.IntType(WIDTH)), ir.IntType(64))


@intrinsic
def greater_mask(typingctx, a, b):
    """Bit ``l`` set where ``a[l] > b[l]`` (false for NaN)."""

    def codegen(context, builder, signature, args):
        return _mask(builder, builder.fcmp_ordered(">", args[0], args[1]))

    return types.int64(Lanes, Lanes), codegen


def _llvm_function(builder, name: str, arity: int):
    """LLVM's intrinsic ``name`` (``sqrt``, ``fabs``, ``copysign``) on lanes."""
    function_type = ir.FunctionType(_VECTOR, [_VECTOR] * arity)
    return cgutils.get_or_insert_function(builder.module, function_type, f"llvm.{name}.v{WIDTH}f64")


@intrinsic
def finite_mask(typingctx, a):
    """Bit ``l`` set where ``a[l]`` is finite."""

    def codegen(context, builder, signature, args):
        magnitude = builder.call(_llvm_function(builder, "fabs", 1), [args[0]])
        return _mask(builder, builder.fcmp_ordered("<", magnitude, ir.Constant(_VECTOR, [math.inf] * WIDTH)))

    return types.int64(Lanes), codegen


@intrinsic
def all_less(typingctx, a, bound):
    """Whether every lane of ``a`` is below the number ``bound`` (false where one is NaN)."""

    def codegen(context, builder, signature, args):
        bounds = _splat(context, builder, args[1], signature.args[1])
        bits = _mask(builder, builder.fcmp_ordered("<", args[0], bounds))
        return builder.icmp_unsigned("==", bits, ir.Constant(ir.IntType(64), _ALL))

    return types.boolean(Lanes, bound), codegen


def _elementwise(instruction: str):
    @intrinsic
    def binary(typingctx, a, b):
        def codegen(context, builder, signature, args):
            return getattr(builder, instruction)(args[0], args[1])

        return Lanes(Lanes, Lanes), codegen

    return binary


def _overload_binary(operation, binary) -> None:
    @overload(operation)
    def lanes_operation(a, b):
        number = (types.Float, types.Integer)
        if isinstance(a, LanesType) and isinstance(b, LanesType):
            return lambda a, b: binary(a, b)
        if isinstance(a, LanesType) and isinstance(b, number):
            return lambda a, b: binary(a, splat(b))
        if isinstance(a, number) and isinstance(b, LanesType):
            return lambda a, b: binary(splat(a), b)
        return None


for _operations, _instruction in (
    ((operator.add, operator.iadd), "fadd"),
    ((operator.sub, operator.isub), "fsub"),
    ((operator.mul, operator.imul), "fmul"),
    ((operator.truediv, operator.itruediv), "fdiv"),
):
    _binary = _elementwise(_instruction)
    for _operation in _operations:
        _overload_binary(_operation, _binary)


@intrinsic
def _negative(typingctx, a):
    def codegen(context, builder, signature, args):
        return builder.fneg(args[0])

    return Lanes(Lanes), codegen


def _unary_function(name: str):
    @intrinsic
    def call(typingctx, a):
        def codegen(context, builder, signature, args):
            return builder.call(_llvm_function(builder, name, 1), list(args))

        return Lanes(Lanes), codegen

    return call


sqrt = _unary_function("sqrt")
"""``math.sqrt`` lane by lane."""
_fabs = _unary_function("fabs")


@intrinsic
def _copysign(typingctx, a, b):
    def codegen(context, builder, signature, args):
        return builder.call(_llvm_function(builder, "copysign", 2), list(args))

    return Lanes(Lanes, Lanes), codegen


@overload(operator.neg)
def _lanes_negative(a):
    if isinstance(a, LanesType):
        return lambda a: _negative(a)
    return None


@overload(abs)
def _lanes_abs(a):
    if isinstance(a, LanesType):
        return lambda a: _fabs(a)
    return None


@overload(math.copysign)
def _lanes_copysign(a, b):
    if isinstance(a, (types.Float, types.Integer)) and isinstance(b, LanesType):
        return lambda a, b: _copysign(splat(a), b)
    if isinstance(a, LanesType) and isinstance(b, LanesType):
        return lambda a, b: _copysign(a, b)
    return None
