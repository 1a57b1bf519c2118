"""Deformable sand: a height grid the robot changes (footprints, craters, piles, avalanches).

`DeformableSand` is a `HeightGrid` (so the kernels read its depth like any height field)
over a bed of `size` [x, y] m centred on `center`, with square cells of side `cell` m (one
node per cell; a node's sand column holds height x cell^2 of volume), initialised from a
base surface (plane, slope, grid) at the nodes. Outside the bed the edge values continue.

The rule (volume conserving):

1. **Footprint marks.** While a body is in the sand, every plate below the surface marks the
   four nodes of the cell its centroid lies in (in `coupling.gather_deformable`): they are
   "pending" and keep the lowest plate z seen. (Four nodes, not the nearest one, so that a
   body whose plates are no farther apart than a cell leaves no unmarked node inside its
   footprint; footprints are resolved to one cell.) A pending node's height does not change:
   a body that is in the sand feels the depth below the surface around it, the very depth
   the RFT coefficients were measured against (intruders moved through a bed whose free
   surface is level around them).
2. **Commit.** A pending node that no plate marked in this step has been left by its body:
   its height drops to the lowest plate z seen (if that is below it); the sand it held, (old
   - new) x cell^2, is displaced.
3. **Deposit.** The displaced volume of a node goes in equal parts to the nearest nodes
   around it (the first ring at Chebyshev distance 1, 2, ... up to `DEPOSIT_REACH` that has
   any) that are neither pending nor just committed: the rim of the footprint. With no such
   node within reach the node keeps its sand (no footprint there).
4. **Avalanche.** Around the nodes that changed, any pair of neighbouring nodes (axis and
   diagonal neighbours) steeper than the angle of repose exchanges sand until the slope
   between them is at most tan(repose) (Gauss-Seidel sweeps, each bringing a pair to the
   limit; settled within `SETTLED` of it); pending nodes (under a body) neither give nor
   take. The window of the sweeps grows while sand flows across its border, and an unsettled
   window carries over to the next step, so cost follows the nodes under and around
   intruding bodies, not the bed size.

Every transfer moves the same amount out of one node and into another, so the bed's volume
is conserved up to floating-point rounding (sum of height changes x cell^2; tested to 1e-9
of the displaced volume). `reset()` restores the pristine surface exactly (a copy)."""
import numpy as np
from numba import njit

from .surface import BLOCK, HeightGrid

#: Rings (Chebyshev distance, nodes) searched for the rim that takes displaced sand.
DEPOSIT_REACH = 100
#: Sweeps of the avalanche per step at most (the rest carries over to the next step).
MAX_SWEEPS = 64
#: A pair whose height difference exceeds the repose limit by less than this fraction of
#: the limit counts as settled (slopes end within 0.1 % of tan(repose)).
SETTLED = 1e-3

#: The small int64 state vector: pending count; avalanche window (inclusive node bounds
#: i0, i1 (x), j0, j1 (y)) and whether it is open; steps that ended with an unsettled
#: window.
COUNT, WI0, WI1, WJ0, WJ1, OPEN, UNSETTLED = range(7)
STATE_SIZE = 7


class DeformableSand(HeightGrid):
    """A deformable bed over a base surface (see module docstring).

    base: the pristine `surface.Surface`; size: [x, y] m; cell: m; repose_deg: angle of
    repose, degrees; center: [x, y] m."""

    def __init__(self, base, size=(2.0, 2.0), cell=0.01, repose_deg=30.0, center=(0.0, 0.0)):
        if not cell > 0:
            raise ValueError(f'sand.deformable.cell must be > 0 m, got {cell}')
        if not 0 < repose_deg < 90:
            raise ValueError(f'sand.deformable.repose_deg must be in (0, 90), got {repose_deg}')
        size = tuple(float(s) for s in size)
        if len(size) != 2 or min(size) < 2 * cell:
            raise ValueError(f'sand.deformable.size must be [x, y] m of at least two cells, '
                             f'got {list(size)}')
        nx, ny = int(round(size[0] / cell)) + 1, int(round(size[1] / cell)) + 1
        span = ((nx - 1) * cell, (ny - 1) * cell)  # whole cells
        x = center[0] - span[0] / 2 + cell * np.arange(nx)
        y = center[1] - span[1] / 2 + cell * np.arange(ny)
        heights = base.height(*np.meshgrid(x, y))
        super().__init__(heights, span, center)
        self.base, self.cell, self.repose_deg = base, float(cell), float(repose_deg)
        self.tan_repose = float(np.tan(np.radians(repose_deg)))
        self.rise = self.tan_repose * self.cell  # m between axis neighbours at repose
        self.pristine = self.grid.copy()
        self._pristine_blocks = self.block_max.copy(), self.block_min.copy()
        self.stamp = np.full(self.grid.shape, -1, dtype=np.int64)  # last step marked; -1: not
        self.lowest = np.zeros(self.grid.shape)           # lowest plate z while pending, m
        self.pending = np.zeros(self.grid.size, dtype=np.int64)  # flat indices of pending nodes
        self.state = np.zeros(STATE_SIZE, dtype=np.int64)
        self._committed = np.zeros(self.grid.size, dtype=np.int64)  # work space
        self._amount = np.zeros(self.grid.size)

    @property
    def cell_area(self):
        return self.cell * self.cell

    def settle(self, step):
        """Commit the nodes left by their bodies at `step`, deposit and avalanche (rules
        2-4). Called by the engine after each gather."""
        settle(self.grid, self.block_max, self.block_min, self.stamp, self.lowest, self.pending,
               self.state, self._committed, self._amount, step, self.rise)

    def relax_all(self):
        """Avalanche the whole bed until settled (e.g. a pile made by hand); returns the
        sweeps it took."""
        ny, nx = self.grid.shape
        self.state[WI0:OPEN + 1] = (0, nx - 1, 0, ny - 1, 1)
        sweeps = 0
        while self.state[OPEN]:
            sweeps += avalanche(self.grid, self.stamp, self.state, self.rise)
        refresh_blocks(self.grid, self.block_max, self.block_min, 0, nx - 1, 0, ny - 1)
        return sweeps

    def reset(self):
        """The pristine surface again, nothing pending."""
        self.grid[:] = self.pristine
        self.block_max[:], self.block_min[:] = self._pristine_blocks
        self.stamp[:] = -1
        self.state[:] = 0

    def volume_change(self):
        """Net change of the bed's sand volume since the start (m^3): should stay ~0."""
        return float((self.grid - self.pristine).sum() * self.cell_area)

    def displaced_volume(self):
        """Volume below the pristine surface (craters and footprints), m^3."""
        return float(np.maximum(self.pristine - self.grid, 0.0).sum() * self.cell_area)

    def piled_volume(self):
        """Volume above the pristine surface (piles and rims), m^3."""
        return float(np.maximum(self.grid - self.pristine, 0.0).sum() * self.cell_area)

    def max_footprint_depth(self):
        """Deepest point below the pristine surface, m."""
        return float(max(0.0, (self.pristine - self.grid).max()))

    def metrics(self):
        """Summary metrics of a deformable run (SI)."""
        return {'sand_volume_change_m3': self.volume_change(),
                'max_footprint_depth_m': self.max_footprint_depth(),
                'sand_displaced_m3': self.displaced_volume(),
                'sand_piled_m3': self.piled_volume()}


@njit(cache=True, inline='always')
def touch_cell(grid, u, v, z, cells, cell_z, count):
    """Note a plate at height z (m) at node coordinates (u, v) in the list of cells a body's
    plates are in (`cells[:count]`, flat indices j * nx + i of each cell's lower-left node,
    in order of first touch; `cell_z`: the lowest z in each); outside the bed: nothing.
    Returns the new count."""
    ny, nx = grid.shape
    if u < 0.0 or v < 0.0 or u >= nx - 1 or v >= ny - 1:
        return count
    cell = int(v) * nx + int(u)
    m = count - 1
    while m >= 0 and cells[m] != cell:  # from the latest: neighbours share cells
        m -= 1
    if m < 0:
        cells[count], cell_z[count] = cell, z
        return count + 1
    cell_z[m] = min(cell_z[m], z)
    return count


@njit(cache=True, inline='always')
def mark_cells(stamp, lowest, pending, state, step, cells, cell_z, count):
    """Rule 1: mark the four nodes of each of `cells[:count]` (`touch_cell`) as under a
    plate at height cell_z (m) at `step`, in order."""
    nx = stamp.shape[1]
    for m in range(count):
        j, i, z = cells[m] // nx, cells[m] % nx, cell_z[m]
        _mark_node(stamp, lowest, pending, state, nx, step, i, j, z)
        _mark_node(stamp, lowest, pending, state, nx, step, i + 1, j, z)
        _mark_node(stamp, lowest, pending, state, nx, step, i, j + 1, z)
        _mark_node(stamp, lowest, pending, state, nx, step, i + 1, j + 1, z)


@njit(cache=True, inline='always')
def _mark_node(stamp, lowest, pending, state, nx, step, i, j, z):
    if stamp[j, i] < 0:
        pending[state[COUNT]] = j * nx + i
        state[COUNT] += 1
        lowest[j, i] = z
    elif z < lowest[j, i]:
        lowest[j, i] = z
    stamp[j, i] = step


@njit(cache=True)
def settle(grid, block_max, block_min, stamp, lowest, pending, state, committed, amount, step,
           rise):
    """Rules 2-4 (module docstring) for the nodes that were pending before `step`; `rise`:
    see `avalanche`."""
    ny, nx = grid.shape
    count = state[COUNT]
    kept = 0
    n_committed = 0
    for p in range(count):
        index = pending[p]
        j, i = index // nx, index % nx
        if stamp[j, i] == step:
            pending[kept] = index
            kept += 1
            continue
        stamp[j, i] = -2  # committed in this step (not a rim node)
        committed[n_committed] = index
        amount[n_committed] = max(grid[j, i] - lowest[j, i], 0.0)
        grid[j, i] -= amount[n_committed]
        n_committed += 1
    state[COUNT] = kept
    if n_committed == 0:
        if state[OPEN]:
            _continue_avalanche(grid, block_max, block_min, stamp, state, rise)
        return
    i_lo, i_hi, j_lo, j_hi = nx, -1, ny, -1
    for c in range(n_committed):
        j, i = committed[c] // nx, committed[c] % nx
        reach = _deposit(grid, stamp, i, j, amount[c]) + 1  # the avalanche's margin
        i_lo, i_hi = min(i_lo, i - reach), max(i_hi, i + reach)
        j_lo, j_hi = min(j_lo, j - reach), max(j_hi, j + reach)
    for c in range(n_committed):
        stamp[committed[c] // nx, committed[c] % nx] = -1
    i_lo, i_hi = max(i_lo, 0), min(i_hi, nx - 1)
    j_lo, j_hi = max(j_lo, 0), min(j_hi, ny - 1)
    if state[OPEN]:  # join the window still settling from earlier steps
        i_lo, i_hi = min(i_lo, state[WI0]), max(i_hi, state[WI1])
        j_lo, j_hi = min(j_lo, state[WJ0]), max(j_hi, state[WJ1])
    state[WI0], state[WI1], state[WJ0], state[WJ1], state[OPEN] = i_lo, i_hi, j_lo, j_hi, 1
    _continue_avalanche(grid, block_max, block_min, stamp, state, rise)


@njit(cache=True, inline='always')
def _continue_avalanche(grid, block_max, block_min, stamp, state, rise):
    """Avalanche the open window, refresh its blocks, count it if it is still unsettled."""
    avalanche(grid, stamp, state, rise)
    refresh_blocks(grid, block_max, block_min, state[WI0], state[WI1], state[WJ0], state[WJ1])
    if not state[OPEN]:
        return
    state[UNSETTLED] += 1


@njit(cache=True)
def _deposit(grid, stamp, i, j, volume_height):
    """Rule 3: spread `volume_height` (m of one node) evenly over the nearest ring of free
    nodes around (i, j); keep it at (i, j) without one. Returns the ring's distance (nodes)."""
    if volume_height <= 0.0:
        return 0
    ny, nx = grid.shape
    for r in range(1, DEPOSIT_REACH + 1):
        free = 0
        for jj in range(max(j - r, 0), min(j + r, ny - 1) + 1):
            for ii in range(max(i - r, 0), min(i + r, nx - 1) + 1):
                if max(abs(ii - i), abs(jj - j)) == r and stamp[jj, ii] == -1:
                    free += 1
        if free == 0:
            continue
        share = volume_height / free
        given = 0.0
        for jj in range(max(j - r, 0), min(j + r, ny - 1) + 1):
            for ii in range(max(i - r, 0), min(i + r, nx - 1) + 1):
                if max(abs(ii - i), abs(jj - j)) == r and stamp[jj, ii] == -1:
                    free -= 1
                    part = volume_height - given if free == 0 else share
                    grid[jj, ii] += part
                    given += part
        return r
    grid[j, i] += volume_height
    return 0


@njit(cache=True)
def avalanche(grid, stamp, state, rise):
    """Rule 4 within the window in `state` (up to MAX_SWEEPS sweeps): `rise` (m) is the
    largest height difference allowed between axis neighbours (tan(repose) x cell; x sqrt 2
    between diagonal ones). Grows the window where sand crosses its border, closes it
    (state[OPEN] = 0) once settled. Returns the sweeps."""
    ny, nx = grid.shape
    sweeps = 0
    while sweeps < MAX_SWEEPS:
        sweeps += 1
        i0, i1, j0, j1 = state[WI0], state[WI1], state[WJ0], state[WJ1]
        moved = False
        grow_i0 = grow_i1 = grow_j0 = grow_j1 = False
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                if stamp[j, i] >= 0:
                    continue
                for d in range(4):  # neighbours (+1, 0), (0, +1), (+1, +1), (-1, +1)
                    di = 1 if d != 1 else 0
                    if d == 3:
                        di = -1
                    dj = 0 if d == 0 else 1
                    ii, jj = i + di, j + dj
                    if ii < 0 or ii >= nx or jj >= ny or stamp[jj, ii] >= 0:
                        continue
                    diff = grid[j, i] - grid[jj, ii]
                    excess = abs(diff) - rise * (1.4142135623730951 if d >= 2 else 1.0)
                    if excess <= SETTLED * rise:
                        continue
                    transfer = 0.5 * excess if diff > 0 else -0.5 * excess
                    grid[j, i] -= transfer
                    grid[jj, ii] += transfer
                    moved = True
                    grow_i0 |= min(i, ii) <= i0
                    grow_i1 |= max(i, ii) >= i1
                    grow_j0 |= j <= j0
                    grow_j1 |= jj >= j1
        if not moved:
            state[OPEN] = 0
            return sweeps
        state[WI0] = max(i0 - 1, 0) if grow_i0 else i0
        state[WI1] = min(i1 + 1, nx - 1) if grow_i1 else i1
        state[WJ0] = max(j0 - 1, 0) if grow_j0 else j0
        state[WJ1] = min(j1 + 1, ny - 1) if grow_j1 else j1
    return sweeps


@njit(cache=True)
def refresh_blocks(grid, block_max, block_min, i_lo, i_hi, j_lo, j_hi):
    """Recompute the block maxima and minima of the blocks holding nodes [i_lo, i_hi] x
    [j_lo, j_hi] (a node n sits in blocks n // BLOCK and, at a block's end, (n - 1) // BLOCK)."""
    ny, nx = grid.shape
    for bj in range(max((j_lo - 1) // BLOCK, 0), min(j_hi // BLOCK, block_max.shape[0] - 1) + 1):
        for bi in range(max((i_lo - 1) // BLOCK, 0),
                        min(i_hi // BLOCK, block_max.shape[1] - 1) + 1):
            low, high = 1e300, -1e300
            for j in range(bj * BLOCK, min((bj + 1) * BLOCK, ny - 1) + 1):
                for i in range(bi * BLOCK, min((bi + 1) * BLOCK, nx - 1) + 1):
                    low, high = min(low, grid[j, i]), max(high, grid[j, i])
            block_max[bj, bi], block_min[bj, bi] = high, low
