"""ArrayTable: arrays handed to compiled kernels as one table of addresses."""
import mujoco
import numpy as np
import pytest
from numba import njit

from rft_sim_ros.sand.array_table import ArrayTable
from rft_sim_ros.sand.table_readers import (byte_vector, float_matrix, float_vector, int8_matrix,
                                            int8_vector, int32_matrix, int32_vector, int_matrix,
                                            int_vector)


@njit
def _sums(table):
    """Each entry read back with its accessor (entry order as in the test), summed; and a
    write through the float matrix view."""
    matrix = float_matrix(table, 1)
    matrix[0, 0] += 1.0
    return (float_vector(table, 0).sum(), matrix.sum(), int_vector(table, 2).sum(),
            int32_vector(table, 3).sum(), int32_matrix(table, 4).sum(),
            int8_vector(table, 5).sum(), int8_matrix(table, 6).sum(),
            byte_vector(table, 7).sum(), int_matrix(table, 8).sum(), matrix.shape[0],
            matrix.shape[1])


@njit
def _read_as_float_vector(table):
    return float_vector(table, 0).sum()


def test_kernels_read_and_write_the_recorded_arrays_in_place():
    arrays = (np.arange(5.0), np.arange(12.0).reshape(3, 4), np.arange(4, dtype=np.int64),
              np.arange(3, dtype=np.int32), np.ones((2, 2), dtype=np.int32),
              np.array([1, -2], dtype=np.int8), np.ones((2, 3), dtype=np.int8),
              np.array([True, False, True]), np.arange(6, dtype=np.int64).reshape(2, 3))
    table = ArrayTable(*arrays)
    sums = _sums(table.table)
    assert sums == (10.0, 67.0, 6, 3, 4, -1, 6, 2, 15, 3, 4)
    assert arrays[1][0, 0] == 1.0  # written through the view: no copy


def test_mujoco_views_keep_their_address():
    """The engine's tables rely on mjData's arrays staying where they are."""
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><freejoint/><geom size="0.1"/></body></worldbody></mujoco>')
    data = mujoco.MjData(model)
    table = ArrayTable(data.qvel, data.xpos)
    data.qvel[:] = 1.0
    mujoco.mj_step(model, data)
    assert _read_as_float_vector(table.table) == data.qvel.sum()
    assert table.table[1, 0] == data.xpos.ctypes.data


def test_an_entry_read_with_another_type_raises():
    table = ArrayTable(np.arange(3, dtype=np.int64))
    with pytest.raises(TypeError, match='another dtype or rank'):
        _read_as_float_vector(table.table)
    with pytest.raises(TypeError, match='another dtype or rank'):
        _read_as_float_vector(ArrayTable(np.zeros((2, 2))).table)


@pytest.mark.parametrize('array, error', [
    (np.zeros((4, 4))[:, 1], ValueError),         # strided
    (np.zeros(3, dtype=np.float32), TypeError),   # element type
    (np.zeros((2, 2, 2)), TypeError),             # rank 3
    ([1.0, 2.0], TypeError),                      # not an array
])
def test_unsupported_arrays_are_refused(array, error):
    with pytest.raises(error, match='entry 0'):
        ArrayTable(array)
