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
import numba
import numpy as np
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.arrayobj import make_array, populate_array

#: Element types a table records, by code. MuJoCo's mjtByte arrays are numpy bool in
#: MuJoCo 4 and uint8 in MuJoCo 3: both are read as uint8 (0 or 1).
_CODES = {np.dtype(np.float64): 0, np.dtype(np.int64): 1, np.dtype(np.int32): 2,
          np.dtype(np.int8): 3, np.dtype(np.uint8): 4, np.dtype(np.bool_): 4}
ADDRESS, CODE, RANK, ROWS, COLUMNS = range(5)  # the table's columns
#: numba's text of the argument types of a kernel taking one table (its int64 table).
TABLE_SIGNATURE = '(int64[:, ::1],)'


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


def _reader(dtype, rank):
    """A compiled accessor (table, i) -> entry i of the table as a C-contiguous array of
    `dtype` and `rank` over the recorded memory (no copy, no owner). It raises TypeError
    when the entry was recorded with another element type or rank, so that a table built in
    another order raises instead of reading garbage.

    An intrinsic: the check and the view are emitted straight as LLVM IR at each call site.
    (As an inline numba function, each of the ~90 reads in the kernels was inlined and
    typed again at compile time, a large part of the cold compile; numba's carray also
    checked and formatted its arguments at every call site.)"""
    code = _CODES[np.dtype(dtype)]
    element = numba.from_dtype(np.dtype(dtype))
    array_type = types.Array(element, rank, 'C')

    @intrinsic
    def read(typingctx, table, index):
        if not (isinstance(table, types.Array) and table.dtype == types.int64
                and table.ndim == 2 and table.layout == 'C'
                and isinstance(index, types.Integer)):
            return None

        def codegen(context, builder, signature, args):
            table_type, index_type = signature.args
            entries = make_array(table_type)(context, builder, args[0])
            row = builder.mul(context.cast(builder, args[1], index_type, types.intp),
                              context.get_constant(types.intp, 5))

            def column(which):
                offset = builder.add(row, context.get_constant(types.intp, which))
                return builder.load(builder.gep(entries.data, [offset]))

            def differs(which, value):
                return builder.icmp_signed('!=', column(which),
                                           context.get_constant(types.int64, value))
            with builder.if_then(builder.or_(differs(CODE, code), differs(RANK, rank)),
                                 likely=False):
                context.call_conv.return_user_exc(builder, TypeError, (_MISMATCH,))
            dims = [column(ROWS), column(COLUMNS)][:rank]
            item_type = context.get_data_type(element)
            itemsize = context.get_constant(types.intp, context.get_abi_sizeof(item_type))
            strides, stride = [], itemsize
            for dim in reversed(dims):
                strides.insert(0, stride)
                stride = builder.mul(stride, dim)
            array = make_array(array_type)(context, builder)
            data = builder.inttoptr(column(ADDRESS), item_type.as_pointer())
            populate_array(array, data=data, shape=cgutils.pack_array(builder, dims),
                           strides=cgutils.pack_array(builder, strides), itemsize=itemsize,
                           meminfo=None)
            return array._getvalue()
        return array_type(table, index), codegen
    return read


_MISMATCH = 'array table entry read with another dtype or rank than recorded'

#: Compiled accessors: entry i of a table as an array (no copy), by element type and rank.
float_vector, float_matrix = _reader(np.float64, 1), _reader(np.float64, 2)
int_vector, int_matrix = _reader(np.int64, 1), _reader(np.int64, 2)
int32_vector, int32_matrix = _reader(np.int32, 1), _reader(np.int32, 2)
int8_vector, int8_matrix = _reader(np.int8, 1), _reader(np.int8, 2)
byte_vector = _reader(np.uint8, 1)
