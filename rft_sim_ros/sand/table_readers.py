"""The compiled accessors of an `array_table.ArrayTable` in a kernel: entry i of a table as
an array over the recorded memory (no copy), by element type and rank, raising TypeError
when the entry was recorded with another (numba intrinsics).
"""
import numba
import numpy as np
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.arrayobj import make_array, populate_array

from .array_table import CODES, ADDRESS, CODE, COLUMNS, RANK, ROWS


def _reader(dtype, rank):
    """A compiled accessor (table, i) -> entry i of the table as a C-contiguous array of
    `dtype` and `rank` over the recorded memory (no copy, no owner). It raises TypeError
    when the entry was recorded with another element type or rank, so that a table built in
    another order raises instead of reading garbage.

    An intrinsic: the check and the view are emitted straight as LLVM IR at each call site.
    (As an inline numba function, each of the ~90 reads in the kernels was inlined and
    typed again at compile time, a large part of the cold compile; numba's carray also
    checked and formatted its arguments at every call site.)"""
    code = CODES[np.dtype(dtype)]
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
