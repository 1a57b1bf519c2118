"""Which body that is not a sand body reaches into the sand: the sand does not act on it, so
it passes through (a shin where the feet sink deep, a trunk when the robot falls over).

`SandEntryWatch` looks at the collision geoms of the moving bodies that carry no plates
(bodies fixed to the world are ground, not robot) and finds the one whose lowest point lies
deepest below the sand surface under it. The lowest point is that of the geom's bounding box
(world z), which lies at or below the geom itself, so ENTRY_DEPTH is a margin as well as a
threshold. A run says it once (`Simulation.run_warnings`).
"""
import mujoco
import numpy as np

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
        self._center, self._half = (model.geom_aabb[self._geoms, :3],
                                    model.geom_aabb[self._geoms, 3:])

    def deepest(self, data, surface):
        """(body name, depth m) of the geom whose lowest point lies deepest below `surface`
        (a sand.surface.Surface) under the geom's centre, if deeper than ENTRY_DEPTH; else
        None."""
        if not self._geoms.size:
            return None
        down = data.geom_xmat[self._geoms].reshape(-1, 3, 3)[:, 2]  # world z of each axis
        lowest = (data.geom_xpos[self._geoms, 2] + np.einsum('gi,gi->g', down, self._center)
                  - np.einsum('gi,gi->g', np.abs(down), self._half))
        xy = data.geom_xpos[self._geoms, :2]
        depth = surface.height(xy[:, 0], xy[:, 1]) - lowest
        g = int(np.argmax(depth))
        if not depth[g] > ENTRY_DEPTH:
            return None
        body = self._model.geom_bodyid[self._geoms[g]]
        name = mujoco.mj_id2name(self._model, mujoco.mjtObj.mjOBJ_BODY, body) or f'body{body}'
        return name, float(depth[g])
