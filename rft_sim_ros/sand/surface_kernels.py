"""Compiled look-ups of the sand surface (`surface.SurfaceData`), of deformable sand's base
beyond its bed, and of the zeta map, inlined into the gather kernels
(`gather`); and `grid_heights`, the same look-up for points handed in from
Python (`surface.HeightGrid.height`). World frame, m.

The grid is read in node coordinates u = (x - x0) / dx, v = (y - y0) / dy, clamped to the
grid, so the edge values continue outside it.
"""
import numpy as np
from numba import njit

from ..kernel_cache import forget_stale
from .surface_codes import BLOCK, FLAT, GRID, SLOPE


@njit(inline='always')
def cell_height(grid, i, j, fu, fv):
    """Bilinear height in the cell of lower-left node [j, i] (0 <= i < nx - 1, 0 <= j < ny - 1,
    not checked) at fractions fu, fv in [0, 1] of it, m."""
    ui, uj, one = np.uint64(i), np.uint64(j), np.uint64(1)  # (no negative-index handling)
    low = grid[uj, ui] + fu * (grid[uj, ui + one] - grid[uj, ui])
    high = grid[uj + one, ui] + fu * (grid[uj + one, ui + one] - grid[uj + one, ui])
    return low + fv * (high - low)


@njit(inline='always')
def node_height(grid, u, v):
    """Bilinear height of the grid at node coordinates (u, v), m."""
    ny, nx = grid.shape
    i = int(min(max(u, 0.0), nx - 2.0))  # (clamped before the conversion: any u, however
    j = int(min(max(v, 0.0), ny - 2.0))  # far, gives a node inside)
    return cell_height(grid, i, j, min(max(u - i, 0.0), 1.0), min(max(v - j, 0.0), 1.0))


@njit(cache=True)
def grid_heights(grid, x0, y0, inv_dx, inv_dy, x, y, out):
    """`node_height` at each world point (x[k], y[k]) (m) into out[k] (m): the height the
    gather kernels read there, for any number of points in one call."""
    for k in range(x.shape[0]):
        out[k] = node_height(grid, (x[k] - x0) * inv_dx, (y[k] - y0) * inv_dy)


@njit(inline='always')
def square_nodes(ny, nx, x0, y0, inv_dx, inv_dy, x, y, r):
    """Node columns u0 .. u1 and rows v0 .. v1 of the cells the square |x' - x|, |y' - y|
    <= r (m) touches on a grid of ny x nx nodes (clamped to the grid; u1, v1 may be one
    past its last node): every node a bilinear look-up in the square reads."""
    u0 = int(min(max((x - r - x0) * inv_dx, 0.0), nx - 1.0))
    u1 = int(min(max((x + r - x0) * inv_dx, 0.0), nx - 1.0)) + 1
    v0 = int(min(max((y - r - y0) * inv_dy, 0.0), ny - 1.0))
    v1 = int(min(max((y + r - y0) * inv_dy, 0.0), ny - 1.0)) + 1
    return u0, u1, v0, v1


@njit(inline='always')
def grid_range(grid, block_max, block_min, x0, y0, inv_dx, inv_dy, x, y, r):
    """Bounds (low, high) of the grid's height over the square |x' - x|, |y' - y| <= r (m):
    the extreme block minimum and maximum of the blocks it touches (they hold every node a
    bilinear look-up in the square reads, `square_nodes`; low == high: the surface there is
    level at it)."""
    ny, nx = grid.shape
    u0, u1, v0, v1 = square_nodes(ny, nx, x0, y0, inv_dx, inv_dy, x, y, r)
    low, high = 1e300, -1e300
    for bj in range(v0 // BLOCK, min(v1 // BLOCK, block_max.shape[0] - 1) + 1):
        for bi in range(u0 // BLOCK, min(u1 // BLOCK, block_max.shape[1] - 1) + 1):
            low, high = min(low, block_min[bj, bi]), max(high, block_max[bj, bi])
    return low, high


@njit(inline='always')
def window_range(window_max, window_min, x0, y0, inv_dx, inv_dy, x, y, r):
    """Bounds (low, high) of a rigid grid's height over the square |x' - x|, |y' - y| <= r
    (m): the extremes of the window of nodes from its first node (`surface.window_extremes`,
    whose span must reach the square's last node, `square_nodes`), in two reads (low ==
    high: the surface there is level at it)."""
    ny, nx = window_max.shape
    u0, _, v0, _ = square_nodes(ny, nx, x0, y0, inv_dx, inv_dy, x, y, r)
    return window_min[v0, u0], window_max[v0, u0]


@njit(inline='always')
def tile_plane(tiles, step, nx, x0, y0, inv_dx, inv_dy, x, y, r):
    """The plane bounding a grid of nx node columns from above over the square
    |x' - x|, |y' - y| <= r (m), from its `surface.tile_planes(.., step)` (`tiles`):
    (usable, a, gx, gy), z = a + gx x + gy y (m, world). usable is False where no tile holds
    the square (it spans more than `step` nodes) or its tile's plane is marked unusable.
    The square must lie inside the grid's nodes (`inside_grid`)."""
    u0, v0 = (x - r - x0) * inv_dx, (y - r - y0) * inv_dy
    ti, tj = int(u0) // step, int(v0) // step
    row = tj * ((nx - 2) // step + 1) + ti
    if ((x + r - x0) * inv_dx > (ti + 2) * step or (y + r - y0) * inv_dy > (tj + 2) * step
            or tiles[row, 3] == 0.0):
        return False, 0.0, 0.0, 0.0
    return True, tiles[row, 0], tiles[row, 1], tiles[row, 2]


@njit(inline='always')
def plane_top(a, gx, gy, x, y, r):
    """Highest point (m) of the plane z = a + gx x + gy y (world) over the square
    |x' - x|, |y' - y| <= r (m): at the corner it rises towards."""
    return a + gx * x + gy * y + r * (abs(gx) + abs(gy))


@njit(inline='always')
def surface_range(kind, level, gx, gy, g_norm, grid, block_max, block_min, x0, y0, inv_dx,
                  inv_dy, x, y, r):
    """Bounds (low, high) of the surface's height within horizontal distance r of (x, y), m
    (g_norm: the slope's |gradient|); low == high: level there (a plane; a grid's blocks)."""
    if kind == FLAT:
        return level, level
    if kind == SLOPE:
        middle = level + gx * x + gy * y
        return middle - r * g_norm, middle + r * g_norm
    return grid_range(grid, block_max, block_min, x0, y0, inv_dx, inv_dy, x, y, r)


@njit(inline='always')
def base_height(base, x, y):
    """Height of deformable sand's base at world (x, y), m (beyond the bed). base: (kind,
    level, gx, gy, g_norm, grid, block_max, block_min, x0, y0, inv_dx, inv_dy) of a plane or
    slope (level, gradient) or a grid (its arrays, node [0, 0] and 1/spacing)."""
    kind, level, gx, gy, _, grid, _, _, x0, y0, inv_dx, inv_dy = base
    if kind == GRID:
        return node_height(grid, (x - x0) * inv_dx, (y - y0) * inv_dy)
    return level + gx * x + gy * y


@njit(inline='always')
def beyond_grid(grid, x0, y0, inv_dx, inv_dy, x, y, r):
    """Whether the square |x' - x|, |y' - y| <= r (m) reaches beyond the grid's nodes."""
    ny, nx = grid.shape
    return ((x - r - x0) * inv_dx < 0.0 or (y - r - y0) * inv_dy < 0.0
            or (x + r - x0) * inv_dx > nx - 1.0 or (y + r - y0) * inv_dy > ny - 1.0)


@njit(inline='always')
def inside_grid(grid, x0, y0, inv_dx, inv_dy, x, y, r):
    """Whether the square |x' - x|, |y' - y| <= r (m) lies a whole cell inside the grid's
    outer nodes: every point of it has node coordinates 1 <= u <= nx - 2 (likewise v), so a
    look-up there needs no clamping (`cell_height` at int(u), int(v)), with room to spare
    for the rounding of a point computed inside the square."""
    ny, nx = grid.shape
    return ((x - r - x0) * inv_dx >= 1.0 and (y - r - y0) * inv_dy >= 1.0
            and (x + r - x0) * inv_dx <= nx - 2.0 and (y + r - y0) * inv_dy <= ny - 2.0)


@njit(inline='always')
def bed_range(grid, block_max, block_min, x0, y0, inv_dx, inv_dy, x, y, r, base):
    """Bounds (low, high) of deformable sand's surface within horizontal distance r of (x, y),
    m: the bed's blocks (`grid_range`), and where the square reaches beyond the bed also the
    base's bounds there (`surface_range`; base as in `base_height`)."""
    low, high = grid_range(grid, block_max, block_min, x0, y0, inv_dx, inv_dy, x, y, r)
    if beyond_grid(grid, x0, y0, inv_dx, inv_dy, x, y, r):
        kind, level, gx, gy, g_norm, b_grid, b_max, b_min, b_x0, b_y0, b_idx, b_idy = base
        b_low, b_high = surface_range(kind, level, gx, gy, g_norm, b_grid, b_max, b_min,
                                      b_x0, b_y0, b_idx, b_idy, x, y, r)
        low, high = min(low, b_low), max(high, b_high)
    return low, high


@njit(inline='always')
def map_factor(factors, x0, y0, inv_dx, inv_dy, x, y):
    """The zeta map's factor at world (x, y): its cell's value, 1 outside the map."""
    u = (x - x0) * inv_dx
    v = (y - y0) * inv_dy
    if u < 0.0 or v < 0.0 or u >= factors.shape[1] or v >= factors.shape[0]:
        return 1.0
    return factors[int(v), int(u)]


forget_stale(globals())  # (kernel_cache: drops kernels compiled from older sources)
