"""Deformable sand: a height grid the robot changes (footprints, craters, piles, avalanches).

`DeformableSand` is a `HeightGrid` (so the kernels read its depth like any height field)
over a bed of `size` [x, y] m centred on `center`, with square cells of side `cell` m (one
node per cell; a node's sand column holds height x cell^2 of volume), initialised from a
base surface (plane, slope, grid) at the nodes. Beyond the bed its base carries the plates,
unchanged (`height`; the gather kernel reads it there too) and they leave no footprints
(counted: `plates_outside`).

The rule (volume conserving):

1. **Footprint marks.** While a body is in the sand, every plate below the surface marks the
   four nodes of the cell its centroid lies in (in `gather.gather_deformable`): they are
   "pending" and keep the lowest plate z seen. (Four nodes, not the nearest one, so that a
   body whose plates are no farther apart than a cell leaves no unmarked node inside its
   footprint; footprints are resolved to one cell. A cell is marked once a step, again only
   for a lower plate: `mark_cell`.) A pending node's height does not change:
   a body that is in the sand feels the depth below the surface around it, the very depth
   the RFT coefficients were measured against (intruders moved through a bed whose free
   surface is level around them).
2. **Commit.** A pending node that no plate marked in this step has been left by its body:
   its height drops to the lowest plate z seen (if that is below it); the sand it held, (old
   - new) x cell^2, is displaced.
3. **Deposit.** The displaced volume of a node goes in equal parts to the nearest nodes
   around it (the first ring at Chebyshev distance 1, 2, ... that has any) that are neither
   pending nor just committed: the rim of the footprint. The rings are searched out to
   `NEAR`; a node farther from every free node (inside a wide footprint) has its distance
   found with all such nodes of the step in one breadth-first pass over the nodes under
   bodies (`_free_distances`), so a footprint of any width is dug whole at a cost that
   follows its nodes. With no free node on the bed at all the node keeps its sand.
4. **Avalanche.** Around the nodes that changed, any pair of neighbouring nodes (axis and
   diagonal neighbours) steeper than the angle of repose exchanges sand until the slope
   between them is at most tan(repose) (each exchange bringing a pair to the limit; settled
   within `SETTLED` of it); pending nodes (under a body) neither give nor take. The work
   follows a queue of nodes: those that changed (committed, given sand) are queued, a
   visited node exchanges with each neighbour too far above or below it and queues it, and
   is queued again itself when it moved sand; the queue empties once every pair around the
   changes is within the limit. Cost follows the exchanges, around intruding bodies only:
   not the bed size, nor the area between distant feet. At most `MAX_VISITS` node visits a
   step; the rest of the queue carries over to the next step (counted as unsettled).

Every transfer moves the same amount out of one node and into another, so the bed's volume
is conserved up to floating-point rounding (sum of height changes x cell^2; tested to 1e-9
of the displaced volume). `reset()` restores the pristine surface exactly (a copy).

The rules' compiled kernels are `deformable_kernels`; this module is the bed and its
bookkeeping, in numpy, so that a run on rigid sand does not import the compiler."""
from contextlib import contextmanager

import numpy as np

from .deformable_codes import (COUNT, DIRTY, EPOCH, HEAD, MAX_VISITS, OUTSIDE, QUEUED,
                               STATE_SIZE)
from .grid_memory import check_grid_memory
from .surface import HeightGrid, block_maximum, block_minimum, heights_digest

#: Bytes a bed holds per node (its heights, the pristine copy, marks and work space: 82
#: measured, 90 at the peak of building it, and the 12 of the deposit's distances and their
#: queue); a bed is refused where that exceeds half the machine's memory (`check_memory`).
BED_BYTES_PER_NODE = 102

#: Element type and rank of each array of `DeformableSand.kernel_arrays`.
KERNEL_ARRAYS = {'deform_stamp': (np.int64, 2), 'deform_lowest': (np.float64, 2),
                 'deform_pending': (np.int64, 1), 'deform_state': (np.int64, 1),
                 'deform_cell_stamp': (np.int64, 2), 'deform_cell_low': (np.float64, 2),
                 'deform_committed': (np.int64, 1), 'deform_amount': (np.float64, 1),
                 'deform_queue': (np.int64, 1), 'deform_in_queue': (np.int8, 2),
                 'deform_dirty': (np.int8, 2), 'deform_dirty_list': (np.int64, 1),
                 'deform_changed': (np.int64, 2), 'deform_distance': (np.int32, 2),
                 'deform_reached': (np.int64, 1)}


def no_bed_arrays():
    """One-element stand-ins for `DeformableSand.kernel_arrays` on rigid sand, whose gather
    kernels never read them."""
    return {name: np.zeros((1,) * rank, dtype) for name, (dtype, rank) in KERNEL_ARRAYS.items()}


class DeformableSand(HeightGrid):
    """A deformable bed over a base surface (see module docstring).

    base: the pristine `surface.Surface`; size: [x, y] m; cell: m; repose_deg: angle of
    repose, degrees; center: [x, y] m. Its `grid` (heights, m), `block_max`, `block_min` and
    `pristine` are read-only views: the kernels change them, and heights changed by hand go
    through `editing`, which keeps the bounds the kernels read and the record of changes
    (`blocks_changed_since`) true."""

    rigid = False

    def __init__(self, base, size=(2.0, 2.0), cell=0.01, repose_deg=30.0, center=(0.0, 0.0)):
        if not cell > 0:
            raise ValueError(f'sand.deformable.cell must be > 0 m, got {cell}')
        if not 0 < repose_deg < 90:
            raise ValueError(f'sand.deformable.repose_deg must be in (0, 90), got {repose_deg}')
        size = tuple(float(s) for s in size)
        if len(size) != 2 or min(size) < 2 * cell:
            raise ValueError(f'sand.deformable.size must be [x, y] m of at least two cells, '
                             f'got {list(size)}')
        check_memory(size, cell)
        nx, ny = bed_nodes(size, cell)
        span = ((nx - 1) * cell, (ny - 1) * cell)  # whole cells
        x = center[0] - span[0] / 2 + cell * np.arange(nx)
        y = center[1] - span[1] / 2 + cell * np.arange(ny)
        heights = base.height(*np.meshgrid(x, y))
        super().__init__(heights, span, center)
        # the writable arrays the kernels and this class change; read-only views for the rest
        self._heights, self._block_max, self._block_min = self.grid, self.block_max, self.block_min
        self.grid, self.block_max, self.block_min = (
            _read_only(a) for a in (self._heights, self._block_max, self._block_min))
        self.base, self.cell, self.repose_deg = base, float(cell), float(repose_deg)
        self.notices = self._notices(base, size, repose_deg)
        self.tan_repose = float(np.tan(np.radians(repose_deg)))
        self.rise = self.tan_repose * self.cell  # m between axis neighbours at repose
        self.pristine = _read_only(self.grid.copy())
        self._pristine_blocks = self.block_max.copy(), self.block_min.copy()
        self.stamp = np.full(self.grid.shape, -1, dtype=np.int64)  # last step marked; -1: not
        self.lowest = np.zeros(self.grid.shape)           # lowest plate z while pending, m
        # per cell (by its lower-left node): the last step a plate marked it, and the lowest
        # plate z in it then (`mark_cell`)
        self.cell_stamp = np.full(self.grid.shape, -1, dtype=np.int64)
        self.cell_low = np.zeros(self.grid.shape)
        self.pending = np.zeros(self.grid.size, dtype=np.int64)  # flat indices of pending nodes
        self.state = np.zeros(STATE_SIZE, dtype=np.int64)
        self._committed = np.zeros(self.grid.size, dtype=np.int64)  # work space
        self._amount = np.zeros(self.grid.size)
        self._queue = np.zeros(self.grid.size, dtype=np.int64)  # the avalanche's nodes to visit
        self._in_queue = np.zeros(self.grid.shape, dtype=np.int8)
        self._dirty = np.zeros(self.block_max.shape, dtype=np.int8)  # blocks to refresh
        self._dirty_list = np.zeros(self.block_max.size, dtype=np.int64)
        # per block: the change epoch (state[EPOCH]) at which its heights last changed
        self._changed = np.zeros(self.block_max.shape, dtype=np.int64)
        # the deposit's distances to the nearest free node (-1: none found) and the nodes
        # they were found for (`_free_distances`)
        self._distance = np.full(self.grid.shape, -1, dtype=np.int32)
        self._reached = np.zeros(self.grid.size, dtype=np.int64)

    def height(self, x, y):
        """The bed's height (bilinear between its nodes) over the bed, the base's beyond."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        (x0, y0), (sx, sy) = self.origin, self.size
        inside = (x >= x0) & (x <= x0 + sx) & (y >= y0) & (y <= y0 + sy)
        bed = super().height(x, y)
        if inside.all():
            return bed
        beyond = np.where(inside, bed, self.base.height(x, y))
        return beyond if beyond.ndim else float(beyond)

    def describe(self):
        """The bed's placement, cell, angle of repose and its pristine heights' SHA-256, and
        the base beyond it (`Surface.describe`)."""
        return {'type': 'deformable', **self.placement(), 'cell_m': self.cell,
                'repose_deg': self.repose_deg, 'heights_sha256': heights_digest(self.pristine),
                'base': self.base.describe()}

    def steepest_deg(self):
        """The steepest inclination (deg) of the bed and of its base beyond it."""
        return max(super().steepest_deg(), self.base.steepest_deg())

    def bounds(self, x0, x1, y0, y1):
        low, top = super().bounds(x0, x1, y0, y1)  # (the bed's edge nodes where it reaches out)
        (bx, by), (sx, sy) = self.origin, self.size
        if x0 < bx or y0 < by or x1 > bx + sx or y1 > by + sy:
            base_low, base_top = self.base.bounds(x0, x1, y0, y1)
            low, top = min(low, base_low), max(top, base_top)
        return low, top

    @property
    def cell_area(self):
        return self.cell * self.cell

    def kernel_arrays(self):
        """The bed's arrays that the deformable gather kernel marks (rule 1) and settles
        (`settle`, rules 2-4) in, by `layout.GatherArrays` name (`KERNEL_ARRAYS`)."""
        return dict(deform_stamp=self.stamp, deform_lowest=self.lowest,
                    deform_pending=self.pending, deform_state=self.state,
                    deform_cell_stamp=self.cell_stamp, deform_cell_low=self.cell_low,
                    deform_committed=self._committed, deform_amount=self._amount,
                    deform_queue=self._queue, deform_in_queue=self._in_queue,
                    deform_dirty=self._dirty, deform_dirty_list=self._dirty_list,
                    deform_changed=self._changed, deform_distance=self._distance,
                    deform_reached=self._reached)

    def relax_all(self):
        """Avalanche the whole bed until settled (e.g. a pile made by hand); returns the
        node visits it took."""
        self._queue[:] = np.arange(self.grid.size)  # every node queued, in order
        self._in_queue[:] = 1
        self.state[HEAD], self.state[QUEUED] = 0, self.grid.size
        from .deformable_kernels import avalanche  # (numba: the kernels load when first used)
        visits = 0
        while self.state[QUEUED]:
            visits += avalanche(self._heights, self.stamp, self._queue, self._in_queue, self.state,
                                self._dirty, self._dirty_list, self.rise, MAX_VISITS)
        self._dirty[:] = 0
        self.state[DIRTY] = 0
        self._edited()
        return visits

    @contextmanager
    def editing(self):
        """Change the bed's heights by hand (a pile, a trench; `relax_all` then settles them
        to the angle of repose): `with bed.editing() as heights: heights[j0:j1, i0:i1] +=
        0.02` (m, [iy, ix] as `grid`). On leaving, the block bounds the gather kernel skips
        bodies by are computed again (a node raised above its block's old maximum would
        otherwise not be read by plates over it) and the whole bed counts as changed
        (`blocks_changed_since`)."""
        try:
            yield self._heights
        finally:
            self._edited()

    def _edited(self):
        self._block_max[:] = block_maximum(self._heights)
        self._block_min[:] = block_minimum(self._heights)
        self._changed_everywhere()

    def reset(self):
        """The pristine surface again, nothing pending."""
        self._heights[:] = self.pristine
        self._block_max[:], self._block_min[:] = self._pristine_blocks
        self.stamp[:] = -1
        self.cell_stamp[:] = -1
        self.state[:EPOCH] = 0
        self._in_queue[:] = 0
        self._dirty[:] = 0
        self._changed_everywhere()

    def _changed_everywhere(self):
        """Every block's heights changed (a reset, a whole-bed relaxation): a new epoch."""
        self.state[EPOCH] += 1
        self._changed[:] = self.state[EPOCH]

    @property
    def change_epoch(self):
        """The bed's change epoch: it grows with every step that changed a height, and with
        every reset (`blocks_changed_since`)."""
        return int(self.state[EPOCH])

    def blocks_changed_since(self, epoch):
        """(rows, columns) block indices of the `BLOCK` x `BLOCK`-cell blocks (block [bj, bi]:
        nodes bj * BLOCK .. (bj + 1) * BLOCK by bi * BLOCK .. (bi + 1) * BLOCK, clipped) holding
        every node whose height changed after change epoch `epoch` (`change_epoch`), and
        maybe some whose height came back: the cost follows the changes, not the bed."""
        return np.nonzero(self._changed > epoch)

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

    @property
    def nodes_under_bodies(self):
        """Nodes under a body still in the sand (pending, rule 1): their footprint is made
        when the body leaves them, so a foot standing in the sand at the end of a run has
        left none there yet."""
        return int(self.state[COUNT])

    def heights_as_seen(self):
        """The bed's heights (m, a new array) with each node under a body still in the sand
        (pending, rule 1) at the lowest plate z seen there: the hole the body stands in, as
        it is drawn, before its footprint is made."""
        heights = self.grid.copy()
        nodes = self.pending[:self.state[COUNT]]
        flat = heights.reshape(-1)
        flat[nodes] = np.minimum(flat[nodes], self.lowest.reshape(-1)[nodes])
        return heights

    @property
    def plates_outside(self):
        """Plates found in the sand outside the bed so far (each step each counts once):
        there the surface stays as it is and they leave no footprint."""
        return int(self.state[OUTSIDE])

    def _notices(self, base, asked, repose_deg):
        """Where the bed lies (its centre defaults to under the robot), its size rounded to
        whole cells, and a base surface that starts steeper than the angle of repose, as the
        avalanche measures it (`neighbour_slope_deg` of the bed's nodes on it)."""
        (x0, y0), (sx, sy), (ny, nx) = self.origin, self.size, self.grid.shape
        rounded = ('' if np.allclose(asked, self.size, rtol=0, atol=1e-9) else
                   f'; sand.deformable.size {list(asked)} m rounded to whole cells')
        said = [f'deformable bed: x {x0:.4g} .. {x0 + sx:.4g} m, y {y0:.4g} .. {y0 + sy:.4g} m, '
                f'{nx} x {ny} nodes {self.cell:g} m apart{rounded}']
        steepest = neighbour_slope_deg(self.grid, self.cell)
        if steepest > repose_deg:
            said.append(f'deformable bed: its base surface is steeper ({steepest:.3g} deg) than '
                        f'the angle of repose ({repose_deg:g} deg): it avalanches wherever the '
                        'robot disturbs it, and on from there')
        return tuple(said)

    def metrics(self):
        """Summary metrics of a deformable run (SI; the footprints made so far: nodes still
        under a body, counted in `sand_nodes_under_bodies`, are not yet changed)."""
        return {'sand_volume_change_m3': self.volume_change(),
                'max_footprint_depth_m': self.max_footprint_depth(),
                'sand_displaced_m3': self.displaced_volume(),
                'sand_piled_m3': self.piled_volume(),
                'sand_nodes_under_bodies': self.nodes_under_bodies,
                'plates_in_sand_outside_bed': self.plates_outside}


def _read_only(array):
    """A read-only view of `array` (the same memory)."""
    view = array.view()
    view.flags.writeable = False
    return view


def bed_nodes(size, cell):
    """(nx, ny): the nodes of a bed of `size` [x, y] m in whole cells of `cell` m."""
    return int(round(size[0] / cell)) + 1, int(round(size[1] / cell)) + 1


def neighbour_slopes(grid, cell):
    """(axis, diagonal): the largest |height difference| / distance (tan of the slope) between
    axis and between diagonal neighbours of `grid` (m, nodes `cell` m apart): the pairs the
    avalanche (rule 4) holds to the angle of repose."""
    axis = max(np.abs(np.diff(grid, axis=0)).max(), np.abs(np.diff(grid, axis=1)).max()) / cell
    diagonal = max(np.abs(grid[1:, 1:] - grid[:-1, :-1]).max(),
                   np.abs(grid[1:, :-1] - grid[:-1, 1:]).max()) / (cell * np.sqrt(2.0))
    return float(axis), float(diagonal)


def neighbour_slope_deg(grid, cell):
    """The steepest slope (deg) between neighbouring nodes of `grid` (`neighbour_slopes`)."""
    return float(np.degrees(np.arctan(max(neighbour_slopes(grid, cell)))))


def bed_node_counts(size, cell):
    """(nx, ny) nodes of a bed of `size` [x, y] m in `cell` m cells, as floats (inf for an
    absurd bed), for memory checks before anything is allocated."""
    return [float(np.rint(float(s) / cell)) + 1.0 for s in size]


def bed_bytes(size, cell):
    """Bytes a bed of `size` [x, y] m in `cell` m cells holds (`BED_BYTES_PER_NODE`)."""
    nx, ny = bed_node_counts(size, cell)
    return nx * ny * BED_BYTES_PER_NODE


def check_memory(size, cell):
    """Refuse (ValueError) a bed of `size` [x, y] m in `cell` m cells that would take more
    than half of this machine's memory (`BED_BYTES_PER_NODE`; `grid_memory`), before any of
    it is allocated."""
    nodes = bed_node_counts(size, cell)
    check_grid_memory(nodes, BED_BYTES_PER_NODE, f'sand.deformable: a bed ({cell:g} m cells)',
                      'make sand.deformable.size smaller or sand.deformable.cell larger (the '
                      'bed need only cover where the robot goes)')
