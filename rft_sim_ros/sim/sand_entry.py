"""Which body that is not a sand body reaches into the sand: the sand does not act on it, so
it passes through (a shin where the feet sink deep, a trunk when the robot falls over).

`SandEntryWatch` looks at the collision geoms of the moving bodies that carry no plates
(bodies fixed to the world are ground, not robot) and finds the one whose lowest point lies
deepest below the sand surface under that point. The lowest point is the lowest corner of
the geom's bounding box (`robot.sand_bodies.geom_lowest_point`), which lies at or below the
geom itself, so ENTRY_DEPTH is a margin as well as a threshold; the surface is read under
that corner, not under the geom's centre (on a slope a long box's centre stands over higher
ground than its downhill corner). A run says it once (`Simulation.run_warnings`).
"""
import numpy as np

from ..robot.sand_bodies import geom_lowest_point
from ..sand.geoms import is_collision_geom

#: m: how deep below the surface the lowest point of a geom that carries no plates may reach
#: before a run says so.
ENTRY_DEPTH = 0.01


class SandEntryWatch:
    """The collision geoms of moving bodies other than `sand_bodies` (ids) of `model`."""

    def __init__(self, model, sand_bodies):
        plated = set(int(b) for b in sand_bodies)
        self._geoms = np.array([g for g in range(model.ngeom)
                                if model.body_weldid[model.geom_bodyid[g]] != 0
                                and int(model.geom_bodyid[g]) not in plated
                                and is_collision_geom(model, g)], dtype=int)
        self._model = model

    def deepest(self, data, surface):
        """(body name, depth m) of the geom whose lowest point lies deepest below `surface`
        (a sand.surface.Surface) under that point, if deeper than ENTRY_DEPTH; else None."""
        if not self._geoms.size:
            return None
        lowest = np.array([geom_lowest_point(self._model, data, g) for g in self._geoms])
        depth = surface.height(lowest[:, 0], lowest[:, 1]) - lowest[:, 2]
        g = int(np.argmax(depth))
        if not depth[g] > ENTRY_DEPTH:
            return None
        return self._model.body(self._model.geom_bodyid[self._geoms[g]]).name, float(depth[g])
