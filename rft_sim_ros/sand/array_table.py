"""Many arrays as one argument of a compiled kernel: their addresses in an int64 table.

Numba unboxes every array argument of a compiled function on each call from Python (about
50 ns per array on our CI machine). The engine's per-step kernels read some fifty arrays
(views of mjModel/mjData and the engine's own work space): about 2.5 us of a 40 us step
went to passing them. The arrays stay the same objects, at the same addresses, for the life of
an engine (MuJoCo allocates mjModel and mjData once), so an `ArrayTable` records each
array's address, dtype and shape once, and a kernel takes the table as one argument and reads
the arrays back with the accessors below, which check the dtype and rank each entry was
recorded with, so that a table built in another order raises instead of reading garbage.

The table holds references to its arrays, so they stay alive while it does; an array must
never be replaced by a new object while a table of it is in use.
"""
import numpy as np
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.arrayobj import make_array, populate_array

#: Element types a table records, by code. MuJoCo's mjtByte arrays are numpy bool in
#: MuJoCo 4 and uint8 in MuJoCo 3: both are read as uint8 (0 or 1).
_CODES = {np.dtype(np.float64): 0, np.dtype(np.int64): 1, np.dtype(np.int32): 2,
          np.dtype(np.int8): 3, np.dtype(np.uint8): 4, np.dtype(np.bool_): 4}
ADDRESS, CODE, RANK, ROWS, COLUMNS = range(5)  # the table's columns


class ArrayTable:
    """Addresses, element codes, ranks and shapes of C-contiguous 1-D or 2-D arrays, one row
    per array in the order given (`table`, int64, (n, 5)); keeps the arrays alive."""

    def __init__(self, *arrays):
        rows = []
        for index, array in enumerate(arrays):
            if not isinstance(array, np.ndarray) or array.ndim not in (1, 2):
                raise TypeError(f'array table entry {index}: a 1-D or 2-D numpy array is '
                                f'needed, got {type(array).__name__}')
            if not array.flags.c_contiguous:
                raise ValueError(f'array table entry {index} is not C-contiguous')
            if array.dtype not in _CODES:
                raise TypeError(f'array table entry {index} has dtype {array.dtype}; '
                                f'supported: {sorted({str(d) for d in _CODES})}')
            shape = array.shape + (1,) * (2 - array.ndim)
            rows.append((array.ctypes.data, _CODES[array.dtype], array.ndim, *shape))
        self.arrays = arrays
        self.table = np.array(rows, dtype=np.int64).reshape(-1, 5)


def _view_intrinsic(rank):
    """A compiled function (address, shape, dtype) -> C-contiguous array of that rank over
    the memory at address (no copy, no owner), built directly: numba's carray checks and
    formats its arguments at every call site, which made the kernels take twice as long to
    compile."""
    @intrinsic
    def view(typingctx, address, shape, dtype):
        element = dtype.instance_type
        array_type = types.Array(element, rank, 'C')

        def codegen(context, builder, signature, args):
            address_value, shape_value, _ = args
            dims = cgutils.unpack_tuple(builder, shape_value, rank) if rank > 1 else [shape_value]
            itemsize = context.get_abi_sizeof(context.get_data_type(element))
            strides, stride = [], context.get_constant(types.intp, itemsize)
            for dim in reversed(dims):
                strides.insert(0, stride)
                stride = builder.mul(stride, dim)
            array = make_array(array_type)(context, builder)
            data = builder.inttoptr(address_value, context.get_data_type(element).as_pointer())
            populate_array(array, data=data, shape=cgutils.pack_array(builder, dims),
                           strides=cgutils.pack_array(builder, strides),
                           itemsize=context.get_constant(types.intp, itemsize), meminfo=None)
            return array._getvalue()
        shape_type = types.UniTuple(types.int64, rank) if rank > 1 else types.int64
        return array_type(types.int64, shape_type, dtype), codegen
    return view


_vector_view, _matrix_view = _view_intrinsic(1), _view_intrinsic(2)


@njit
def _mismatch():
    """Raise for an entry read with another element type or rank. A call of its own: a
    raise inlined into every accessor made each read ~20 times dearer."""
    raise TypeError('array table entry read with another dtype or rank than recorded')


@njit(inline='always')
def _check(table, i, code, rank):
    if (table[i, CODE] != code) | (table[i, RANK] != rank):
        _mismatch()


def _vector_reader(dtype):
    code = _CODES[np.dtype(dtype)]

    @njit(inline='always')
    def read(table, i):
        _check(table, i, code, 1)
        return _vector_view(table[i, ADDRESS], table[i, ROWS], dtype)
    return read


def _matrix_reader(dtype):
    code = _CODES[np.dtype(dtype)]

    @njit(inline='always')
    def read(table, i):
        _check(table, i, code, 2)
        return _matrix_view(table[i, ADDRESS], (table[i, ROWS], table[i, COLUMNS]), dtype)
    return read


#: Compiled accessors: entry i of a table as an array (no copy), by element type and rank.
float_vector, float_matrix = _vector_reader(np.float64), _matrix_reader(np.float64)
int_vector, int_matrix = _vector_reader(np.int64), _matrix_reader(np.int64)
int32_vector, int32_matrix = _vector_reader(np.int32), _matrix_reader(np.int32)
int8_vector, int8_matrix = _vector_reader(np.int8), _matrix_reader(np.int8)
byte_vector = _vector_reader(np.uint8)
