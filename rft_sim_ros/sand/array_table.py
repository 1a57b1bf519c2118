"""Many arrays as one argument of a compiled kernel: their addresses in an int64 table.

Numba unboxes every array argument of a compiled function on each call from Python (about
50 ns per array on our CI machine). The engine's per-step kernels read some fifty arrays
(views of mjModel/mjData and the engine's own work space): about 2.5 us of a 40 us step
went to passing them. The arrays stay the same objects, at the same addresses, for the life of
an engine (MuJoCo allocates mjModel and mjData once), so an `ArrayTable` records each
array's address, dtype and shape once, and a kernel takes the table as one argument and reads
the arrays back with the accessors of `table_readers`, which check the dtype and rank each
entry was recorded with, so that a table built in another order raises instead of reading
garbage. This module is plain numpy: code that builds tables does not import the compiler.

The table holds references to its arrays, so they stay alive while it does; an array must
never be replaced by a new object while a table of it is in use.
"""
import numpy as np

#: Element types a table records, by code. MuJoCo's mjtByte arrays are numpy bool in
#: MuJoCo 4 and uint8 in MuJoCo 3: both are read as uint8 (0 or 1).
CODES = {np.dtype(np.float64): 0, np.dtype(np.int64): 1, np.dtype(np.int32): 2,
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
            if array.dtype not in CODES:
                raise TypeError(f'array table entry {index} has dtype {array.dtype}; '
                                f'supported: {sorted({str(d) for d in CODES})}')
            shape = array.shape + (1,) * (2 - array.ndim)
            rows.append((array.ctypes.data, CODES[array.dtype], array.ndim, *shape))
        self.arrays = arrays
        self.table = np.array(rows, dtype=np.int64).reshape(-1, 5)
