"""Which body that is not a sand body reaches into the sand: the sand does not act on it, so
it passes through (a shin where the feet sink deep, a trunk when the robot falls over).

`SandEntryWatch` looks at the collision geoms of the moving bodies that carry no plates
(bodies fixed to the world are ground, not robot) and finds the one whose lowest point lies
deepest below the sand surface under it. The lowest point is that of the geom's bounding box
(world z; `robot.sand_bodies.geom_lowest_z`), which lies at or below the geom itself, so
ENTRY_DEPTH is a margin as well as a threshold. A run says it once
(`Simulation.run_warnings`).
"""
import numpy as np

from ..robot.sand_bodies import geom_lowest_z
from ..sand.geoms import is_collision_geom

#: m: how deep below the surface the lowest point of a geom that carries no plates may reach
#: before a run says so.
ENTRY_DEPTH = 0.01


class SandEntryWatch:
    """The collision geoms of moving bodies other than `sand_bodies` (ids) of `model`; with
    `welded_to` (a body id), of that body and the bodies welded to it alone (e.g. the
    robot's base and a URDF's links fixed to it: spawn rest's test of a fall)."""

    def __init__(self, model, sand_bodies, welded_to=None):
        plated = set(int(b) for b in sand_bodies)
        weld = model.body_weldid
        self._geoms = np.array([g for g in range(model.ngeom)
                                if weld[model.geom_bodyid[g]] != 0
                                and int(model.geom_bodyid[g]) not in plated
                                and (welded_to is None
                                     or weld[model.geom_bodyid[g]] == weld[welded_to])
                                and is_collision_geom(model, g)], dtype=int)
        self._model = model

    def deepest(self, data, surface):
        """(body name, depth m) of the geom whose lowest point lies deepest below `surface`
        (a sand.surface.Surface) under the geom's centre, if deeper than ENTRY_DEPTH; else
        None."""
        if not self._geoms.size:
            return None
        lowest = np.array([geom_lowest_z(self._model, data, g) for g in self._geoms])
        xy = data.geom_xpos[self._geoms, :2]
        depth = surface.height(xy[:, 0], xy[:, 1]) - lowest
        g = int(np.argmax(depth))
        if not depth[g] > ENTRY_DEPTH:
            return None
        return self._model.body(self._model.geom_bodyid[self._geoms[g]]).name, float(depth[g])
