"""
Four-lane float64 vectors for the compiled kernel: the three axes side by side.

The sensor kernel computes the same arithmetic on the x, y and z axes of
every sample. :data:`vec4` is a numba type held in one SIMD register
(LLVM ``<4 x double>``: lanes x, y, z and a spare lane that is computed and
never stored), so each operation on the three axes is one instruction.
Every operation is the IEEE operation of the scalar code it replaces, lane
by lane (no fused multiply-add, no reassociation), so results are bit for
bit those of the scalar kernel.

Built on numba's public extension API (``numba.extending``: a type, a data
model and intrinsics); the operators ``+ - * /`` work between vectors.
"""

import operator

from llvmlite import ir
from numba.extending import intrinsic, models, overload, register_model, types

_F64 = ir.DoubleType()
_VEC = ir.VectorType(_F64, 4)
_I32 = ir.IntType(32)
_LANES = range(3)


class Vec4Type(types.Type):
    """The numba type of a four-lane float64 vector (lanes x, y, z, spare)."""

    def __init__(self):
        super().__init__(name='vec4')


#: The vector type (an instance: use it in signatures).
vec4 = Vec4Type()


@register_model(Vec4Type)
class _Vec4Model(models.PrimitiveModel):
    """Data model: one LLVM ``<4 x double>`` value."""

    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _VEC)


def _lane(i):
    return ir.Constant(_I32, i)


def _element(context, builder, array_type, array, flat_index):
    """Pointer to element ``flat_index`` of a C-contiguous array."""
    data = context.make_array(array_type)(context, builder, array).data
    return builder.gep(data, [flat_index])


@intrinsic
def vpack(typingctx, x, y, z):
    """Vector (x, y, z, 0) from three floats."""
    def codegen(context, builder, sig, args):
        vec = ir.Constant(_VEC, [0.0] * 4)
        for i, value in enumerate(args):
            vec = builder.insert_element(vec, value, _lane(i))
        return vec
    return vec4(types.float64, types.float64, types.float64), codegen


@intrinsic
def vsplat(typingctx, x):
    """Vector (x, x, x, x) from one float."""
    def codegen(context, builder, sig, args):
        vec = builder.insert_element(ir.Constant(_VEC, ir.Undefined), args[0], _lane(0))
        return builder.shuffle_vector(vec, vec, ir.Constant(ir.VectorType(_I32, 4), [0] * 4))
    return vec4(types.float64), codegen


@intrinsic
def vrow(typingctx, array, row):
    """Vector (a[row, 0], a[row, 1], a[row, 2], 0) of a C-contiguous (n, 3) float64 array."""
    def codegen(context, builder, sig, args):
        return _three_loads(context, builder, sig.args[0], args[0], args[1])
    return vec4(array, row), codegen


@intrinsic
def vstore(typingctx, array, row, vec):
    """Store lanes x, y, z of ``vec`` into row ``row`` of a C (n, 3) float64 array."""
    def codegen(context, builder, sig, args):
        _three_stores(context, builder, sig.args[0], args[0], args[1], args[2])
        return context.get_dummy_value()
    return types.none(array, row, vec4), codegen


@intrinsic
def vstore_greater(typingctx, array, row, a, b):
    """Store the lanes x, y, z of ``a > b`` into row ``row`` of a C (n, 3) bool array."""
    def codegen(context, builder, sig, args):
        base = builder.mul(args[1], ir.Constant(args[1].type, 3))
        above = builder.fcmp_ordered('>', args[2], args[3])
        byte = context.get_data_type(types.boolean)
        for i in _LANES:
            ptr = _element(context, builder, sig.args[0], args[0],
                           builder.add(base, ir.Constant(base.type, i)))
            builder.store(builder.zext(builder.extract_element(above, _lane(i)), byte), ptr)
        return context.get_dummy_value()
    return types.none(array, row, vec4, vec4), codegen


def _row_pointer(context, builder, array_type, array, row):
    """Pointer to ``array[row, 0]`` of a C-contiguous 2-d array, as a vector pointer."""
    arr = context.make_array(array_type)(context, builder, array)
    width = builder.extract_value(arr.shape, 1)
    ptr = builder.gep(arr.data, [builder.mul(row, width)])
    return builder.bitcast(ptr, _VEC.as_pointer())


@intrinsic
def vload4(typingctx, array, row):
    """
    Vector of the four doubles from ``array[row, 0]`` on (C-contiguous 2-d array).

    For an (n, 3) array the fourth lane is the next row's first element: use
    it only for rows below n - 1 (the spare lane is never stored).
    """
    def codegen(context, builder, sig, args):
        return builder.load(_row_pointer(context, builder, sig.args[0], args[0], args[1]),
                            align=8)
    return vec4(array, row), codegen


@intrinsic
def vstore4(typingctx, array, row, vec):
    """
    Store the four lanes of ``vec`` from ``array[row, 0]`` on (C-contiguous 2-d array).

    For an (n, 3) array the spare lane lands on the next row's first element:
    use it only for rows below n - 1 whose next row is written afterwards.
    """
    def codegen(context, builder, sig, args):
        builder.store(args[2], _row_pointer(context, builder, sig.args[0], args[0], args[1]),
                      align=8)
        return context.get_dummy_value()
    return types.none(array, row, vec4), codegen


@intrinsic
def vget(typingctx, array, row, wide):
    """
    Row ``row`` of a C (n, 3) float64 array as a vector.

    One four-double load for rows below ``wide`` (the spare lane reads the
    next row's first element), three loads otherwise (spare lane 0).
    """
    def codegen(context, builder, sig, args):
        array_type, (array, row, wide) = sig.args[0], args
        result = _alloca_vec(builder)
        with builder.if_else(builder.icmp_signed('<', row, wide)) as (fast, slow):
            with fast:
                builder.store(builder.load(
                    _row_pointer(context, builder, array_type, array, row), align=8), result)
            with slow:
                builder.store(_three_loads(context, builder, array_type, array, row), result)
        return builder.load(result)
    return vec4(array, row, wide), codegen


@intrinsic
def vput(typingctx, array, row, vec, wide):
    """
    Store lanes x, y, z of ``vec`` into row ``row`` of a C (n, 3) float64 array.

    One four-double store for rows below ``wide`` (the spare lane lands on
    the next row's first element, which the caller writes afterwards), three
    stores otherwise.
    """
    def codegen(context, builder, sig, args):
        array_type, (array, row, vec, wide) = sig.args[0], args
        with builder.if_else(builder.icmp_signed('<', row, wide)) as (fast, slow):
            with fast:
                builder.store(vec, _row_pointer(context, builder, array_type, array, row),
                              align=8)
            with slow:
                _three_stores(context, builder, array_type, array, row, vec)
        return context.get_dummy_value()
    return types.none(array, row, vec4, wide), codegen


def _alloca_vec(builder):
    """Return a stack slot for one vector, in the function's entry block."""
    with builder.goto_entry_block():
        return builder.alloca(_VEC)


def _three_loads(context, builder, array_type, array, row):
    base = builder.mul(row, ir.Constant(row.type, 3))
    vec = ir.Constant(_VEC, [0.0] * 4)
    for i in _LANES:
        ptr = _element(context, builder, array_type, array,
                       builder.add(base, ir.Constant(base.type, i)))
        vec = builder.insert_element(vec, builder.load(ptr), _lane(i))
    return vec


def _three_stores(context, builder, array_type, array, row, vec):
    base = builder.mul(row, ir.Constant(row.type, 3))
    for i in _LANES:
        ptr = _element(context, builder, array_type, array,
                       builder.add(base, ir.Constant(base.type, i)))
        builder.store(builder.extract_element(vec, _lane(i)), ptr)


@intrinsic
def vlane(typingctx, vec, i):
    """Lane ``i`` (0, 1 or 2) of ``vec`` as a float."""
    def codegen(context, builder, sig, args):
        return builder.extract_element(args[0], builder.trunc(args[1], _I32))
    return types.float64(vec4, i), codegen


def _binary(name, doc):
    @intrinsic
    def op(typingctx, a, b):
        def codegen(context, builder, sig, args):
            return getattr(builder, name)(args[0], args[1])
        return vec4(vec4, vec4), codegen
    op.__doc__ = doc
    return op


vadd = _binary('fadd', 'Lane-wise a + b.')
vsub = _binary('fsub', 'Lane-wise a - b.')
vmul = _binary('fmul', 'Lane-wise a * b.')
vdiv = _binary('fdiv', 'Lane-wise a / b.')


def _unary(llvm_name, doc):
    @intrinsic
    def op(typingctx, a):
        def codegen(context, builder, sig, args):
            name = llvm_name + '.v4f64'
            fn = builder.module.globals.get(name) or ir.Function(
                builder.module, ir.FunctionType(_VEC, [_VEC]), name=name)
            return builder.call(fn, [args[0]])
        return vec4(vec4), codegen
    op.__doc__ = doc
    return op


vsqrt = _unary('llvm.sqrt', 'Lane-wise square root (IEEE, as math.sqrt).')
vrint = _unary('llvm.rint', 'Lane-wise round half to even (as numpy.rint).')
vabs = _unary('llvm.fabs', 'Lane-wise absolute value.')


def _select(predicate, doc):
    @intrinsic
    def op(typingctx, a, b):
        def codegen(context, builder, sig, args):
            take_b = builder.fcmp_ordered(predicate, args[1], args[0])
            return builder.select(take_b, args[1], args[0])
        return vec4(vec4, vec4), codegen
    op.__doc__ = doc
    return op


vmin = _select('<', "Lane-wise Python min(a, b): b if b < a else a (numba's order).")
vmax = _select('>', "Lane-wise Python max(a, b): b if b > a else a (numba's order).")


@intrinsic
def vwhere(typingctx, mask, a, b):
    """Lane-wise ``a if mask != 0 else b``."""
    def codegen(context, builder, sig, args):
        take_a = builder.fcmp_unordered('!=', args[0], ir.Constant(_VEC, [0.0] * 4))
        return builder.select(take_a, args[1], args[2])
    return vec4(vec4, vec4, vec4), codegen


def _operator(op, impl):
    @overload(op)
    def _overload(a, b):
        if isinstance(a, Vec4Type) and isinstance(b, Vec4Type):
            return lambda a, b: impl(a, b)
        return None
    return _overload


for _op, _impl in ((operator.add, vadd), (operator.sub, vsub), (operator.mul, vmul),
                   (operator.truediv, vdiv)):
    _operator(_op, _impl)
