"""What of the sand surface is published, and when (ROS-free; the node and the bag recorder
share it).

`TerrainFeed` watches a simulation's sand surface. Only grid surfaces are published (a
height grid, an MJCF hfield, deformable sand); a plane or a slope is the same analytic surface
all run long and publishes nothing, at no cost. A publication has two parts: the cloud (the
grid's nodes) and the markers (the deformed nodes, one marker per square tile of `TILE` nodes
a side). The first call publishes every node of the grid and every tile; later calls publish
the nodes whose height changed since the last publication (footprints, piles, a terrain reset)
and the tiles holding them, and nothing when none did, at `rate` per second of sim time on
average: publications fall on a fixed grid of sim time, one `rate` period apart, each at the
first call at or after its grid time, at most one per grid time (so publish cycles that do
not divide the period keep the mean rate). `resend_cloud()` (the node calls it when a
subscriber of the cloud joins) makes the next publication carry every node again, and
`resend_markers()` (a subscriber of the markers joins) every tile, so that a late subscriber
gets the whole surface. Heights in m, world z; x, y in m in the odom frame (the MuJoCo world
frame). What changed is found in the blocks of deformable sand that changed since the last
publication (`DeformableSand.blocks_changed_since`), so a publication costs what changed,
not the bed's size (a first publication and a re-send excepted).
"""
import math
from dataclasses import dataclass

import numpy as np

from rft_sim_ros.ros.parameters import TERRAIN_RATE, publish_rate
from rft_sim_ros.sand.surface import BLOCK, HeightGrid

#: Default publications per second of sim time (the node's `terrain_rate`, the bags' rate).
DEFAULT_RATE = 2.0

#: Nodes along a side of a marker tile. A publication rebuilds only the tiles holding a
#: changed node, so it costs at most TILE^2 points per changed tile, whatever the whole
#: deformation (with rclpy about 4.5 us a point: a fully deformed tile about 5 ms); a whole
#: re-send is one marker per deformed tile (a 2 m bed of 1 cm cells: 7 x 7 tiles). A foot's
#: footprint (a few cm) touches one to four tiles of 32 cm.
TILE = 32


@dataclass(frozen=True)
class TerrainTile:
    """The marker content of one tile: `index` (row-major over the tiles: tile row
    iy // TILE times the tiles in a row, plus ix // TILE), `deformed` (K, 3) float32 x, y, z
    (m, odom) of its nodes that differ from the pristine surface, row-major, `change` (K,)
    their height change (m; negative: dug, positive: piled). K = 0: the tile is pristine."""
    index: int
    deformed: np.ndarray
    change: np.ndarray


@dataclass(frozen=True)
class TerrainUpdate:
    """One publication of the surface at sim time `time` (s).

    points: (N, 3) float32 x, y, z (m, odom) of the nodes changed since the last publication,
    or of every node (the first time, and after `TerrainFeed.resend_cloud`) row-major in the
    grid's [iy, ix] order; None: no cloud in this publication (only the markers are re-sent).
    shape: (rows, columns) of `points`: the grid's (ny, nx) when it is every node, (1, N) for
    the changed nodes (None without points). clear: the markers are sent whole (the first
    time, and after `TerrainFeed.resend_markers`): every earlier tile is to be deleted first
    and `tiles` holds every deformed tile. tiles: the `TerrainTile`s to (re)build, by index.
    spacing: the grid's node spacing, m (the smaller of x and y)."""
    time: float
    points: np.ndarray
    shape: tuple
    clear: bool
    tiles: tuple
    spacing: float


class TerrainFeed:
    """Decides the terrain publications of `surface` (see module docstring).

    surface: the simulation's sand surface (`sim.engine.surface`). rate: publications per
    second of sim time at most."""

    def __init__(self, surface, rate=DEFAULT_RATE):
        self._surface = surface if isinstance(surface, HeightGrid) else None
        self._period = 1.0 / publish_rate(rate, TERRAIN_RATE)
        self._published = None  # deformable sand's heights at the last publication
        self._epoch = 0  # and its change epoch then
        self._whole_cloud = self._whole_markers = True
        self._next = -math.inf

    @property
    def active(self):
        """Whether this surface is published at all (grids only)."""
        return self._surface is not None

    def resend_cloud(self):
        """Publish every node again at the next publication (due at once), changed or not."""
        self._whole_cloud = True

    def resend_markers(self):
        """Publish every tile again at the next publication (due at once), changed or not."""
        self._whole_markers = True

    def update(self, time, due=False):
        """The `TerrainUpdate` due at sim time `time` (s), or None (nothing due or changed).
        due: publish the changes now whatever the rate (e.g. the last state of a run)."""
        whole_cloud, whole_markers = self._whole_cloud, self._whole_markers
        if self._surface is None or (time < self._next and not (due or whole_cloud
                                                                or whole_markers)):
            return None
        grid = self._surface.grid
        pristine = getattr(self._surface, 'pristine', None)  # only deformable sand changes
        changed = self._changed_nodes(pristine is not None)
        if not (whole_cloud or whole_markers or changed[0].size):
            return None
        self._whole_cloud = self._whole_markers = False
        if time >= self._next:  # (one between the grid's times, due or a re-send, keeps it)
            self._schedule(time)
        if whole_cloud:
            points, shape = self._points(*np.indices(grid.shape).reshape(2, -1)), grid.shape
        elif changed[0].size:
            points = self._points(*changed)
            shape = (1, len(points))
        else:
            points, shape = None, None
        if whole_markers:
            tiles = self._tile_indices(*np.nonzero(grid != pristine) if pristine is not None
                                       else changed)  # (rigid: none deformed)
        else:
            tiles = self._tile_indices(*changed)
        return TerrainUpdate(float(time), points, shape, whole_markers,
                             tuple(self._tile(index, pristine) for index in tiles),
                             float(min(self._surface.spacing)))

    def _schedule(self, time):
        """The next publication's sim time after one at `time` (s): the next time of the
        fixed grid of periods; restarted from `time` if the grid fell more than a period
        behind (the surface stood still, or the publications come less often than the rate)."""
        self._next += self._period
        if self._next <= time:
            self._next = time + self._period

    def _changed_nodes(self, deformable):
        """(rows, columns) of the nodes whose height changed since the last publication,
        row-major, and the heights kept for the next comparison brought up to date. The
        first publication keeps them all and reports none; rigid grids never change.
        Deformable sand is compared in the blocks it changed since (`blocks_changed_since`)
        only."""
        grid = self._surface.grid
        if not deformable or self._published is None:
            if deformable:  # (the first publication: what later ones are compared with)
                self._published = grid.copy()
                self._epoch = self._surface.change_epoch
            return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
        rows, columns = self._surface.blocks_changed_since(self._epoch)
        self._epoch = self._surface.change_epoch
        ny, nx = grid.shape
        offsets = np.arange(BLOCK + 1)  # (a block's nodes, clipped to the grid)
        j = np.minimum(rows[:, None] * BLOCK + offsets, ny - 1)
        i = np.minimum(columns[:, None] * BLOCK + offsets, nx - 1)
        nodes = np.unique((j[:, :, None] * nx + i[:, None, :]).ravel())
        heights, published = grid.reshape(-1), self._published.reshape(-1)
        nodes = nodes[heights[nodes] != published[nodes]]
        published[nodes] = heights[nodes]
        return np.divmod(nodes, nx)

    def _tiles_per_row(self):
        return -(-self._surface.grid.shape[1] // TILE)

    def _tile_indices(self, j, i):
        """Sorted indices of the tiles holding the nodes [j, i] (index arrays)."""
        return np.unique((j // TILE) * self._tiles_per_row() + i // TILE).tolist()

    def _tile(self, index, pristine):
        """The `TerrainTile` of tile `index` of deformable sand (`pristine`: its heights
        before any change)."""
        row, column = divmod(index, self._tiles_per_row())
        j0, i0 = row * TILE, column * TILE
        window = (slice(j0, j0 + TILE), slice(i0, i0 + TILE))
        heights = self._surface.grid[window]
        j, i = np.nonzero(heights != pristine[window])
        return TerrainTile(index, self._points(j + j0, i + i0), (heights - pristine[window])[j, i])

    def _points(self, j, i):
        """(N, 3) float32 x, y, z of the grid nodes [j, i] (index arrays)."""
        surface = self._surface
        return np.column_stack([surface.origin[0] + i * surface.spacing[0],
                                surface.origin[1] + j * surface.spacing[1],
                                surface.grid[j, i]]).astype(np.float32)
