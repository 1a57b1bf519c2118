"""What of the sand surface is published, and when (ROS-free; the node and the bag recorder
share it).

`TerrainFeed` watches a simulation's sand surface. Only grid surfaces are published (a
height grid, an MJCF hfield, deformable sand); a plane or a slope is the same analytic surface
all run long and publishes nothing, at no cost. The first call publishes every node of the
grid; later calls publish the nodes whose height changed since the last publication
(footprints, piles, a terrain reset) and nothing when none did, at `rate` per second of sim
time on average: publications fall on a fixed grid of sim time, one `rate` period apart,
each at the first call at or after its grid time, at most one per grid time (so publish
cycles that do not divide the period keep the mean rate). `resend()` (the node calls
it when a subscriber of the cloud joins) makes the next publication carry every node again, so
that a late subscriber gets the whole surface. Heights in m, world z; x, y in m in the odom
frame (the MuJoCo world frame).
"""
import math
from dataclasses import dataclass

import numpy as np

from rft_sim_ros.ros.parameters import TERRAIN_RATE, publish_rate
from rft_sim_ros.sand.surface import HeightGrid

#: Default publications per second of sim time (the node's `terrain_rate`, the bags' rate).
DEFAULT_RATE = 2.0


@dataclass(frozen=True)
class TerrainUpdate:
    """One publication of the surface at sim time `time` (s).

    points: (N, 3) float32 x, y, z (m, odom) of the nodes changed since the last publication,
    or of every node (the first time, and after `TerrainFeed.resend`) row-major in the grid's
    [iy, ix] order. shape: (rows, columns) of `points`: the grid's (ny, nx) when it is every
    node, (1, N) for the changed nodes. deformed: (M, 3) float32 nodes whose height differs from
    the pristine surface; change: (M,) their height change, m (negative: dug, positive:
    piled). spacing: the grid's node spacing, m (the smaller of x and y)."""
    time: float
    points: np.ndarray
    shape: tuple
    deformed: np.ndarray
    change: np.ndarray
    spacing: float


class TerrainFeed:
    """Decides the terrain publications of `surface` (see module docstring).

    surface: the simulation's sand surface (`sim.engine.surface`). rate: publications per
    second of sim time at most."""

    def __init__(self, surface, rate=DEFAULT_RATE):
        self._surface = surface if isinstance(surface, HeightGrid) else None
        self._period = 1.0 / publish_rate(rate, TERRAIN_RATE)
        self._published = None  # heights at the last publication
        self._next = -math.inf

    @property
    def active(self):
        """Whether this surface is published at all (grids only)."""
        return self._surface is not None

    def resend(self):
        """Publish every node again at the next publication (due at once), changed or not."""
        self._published = None
        self._next = -math.inf

    def update(self, time, due=False):
        """The `TerrainUpdate` due at sim time `time` (s), or None (nothing due or changed).
        due: publish the changes now whatever the rate (e.g. the last state of a run)."""
        if self._surface is None or (time < self._next and not due):
            return None
        grid = self._surface.grid
        pristine = getattr(self._surface, 'pristine', None)  # only deformable sand changes
        if self._published is None:  # the first publication, or resent
            changed = np.ones(grid.shape, dtype=bool)
        elif pristine is None:
            return None
        else:
            changed = grid != self._published
            if not changed.any():
                return None
        whole = self._published is None
        self._published = grid.copy()
        self._schedule(time)
        if pristine is None:
            pristine = grid
        deformed = grid != pristine
        points = self._points(changed)
        return TerrainUpdate(float(time), points, grid.shape if whole else (1, len(points)),
                             self._points(deformed), (grid - pristine)[deformed],
                             float(min(self._surface.spacing)))

    def _schedule(self, time):
        """The next publication's sim time after one at `time` (s): the next time of the
        fixed grid of periods; restarted from `time` if the grid fell more than a period
        behind (the surface stood still, or the publications come less often than the rate)."""
        self._next += self._period
        if self._next <= time:
            self._next = time + self._period

    def _points(self, nodes):
        """(N, 3) float32 x, y, z of the grid nodes where `nodes` is True."""
        surface = self._surface
        j, i = np.nonzero(nodes)
        return np.column_stack([surface.origin[0] + i * surface.spacing[0],
                                surface.origin[1] + j * surface.spacing[1],
                                surface.grid[j, i]]).astype(np.float32)
