"""plate_drop: a free thin horizontal plate dropped onto sand.

Analytic reference: RFT resists only while the plate intrudes, with force zeta A z on the
bottom face at depth z, so the impact depth solves m g (h + z) = zeta A z^2 / 2 (energy),
z = (m g + sqrt((m g)^2 + 2 zeta A m g h)) / (zeta A). After impact the plate must stay in
the sand (no bounce) and come to rest. The plate starts `drop_height` above the sand surface
under its centre when the scene starts (any surface shape; a second drop into deformable
sand's crater starts there too), and its depth is measured from that surface. The expected
depths use the zeta the plate met (`SandEngine.zeta_at` under its centre: a zeta map's
factor included): where the impact stops it for the impact, at the end for the static
depth. The impact's energy balance holds only where the surface under the plate is level
(a slope meets one edge first): elsewhere expected_max_sinkage_m and max_sinkage_error are None,
as they are for a run that ended before the plate reached the sand (a duration shorter than
its fall: nothing to compare, and max_sinkage_m is then negative, the plate's height above
the sand).
The static depth m g / (zeta A) holds wherever the surface under the plate is planar.
"""
import numpy as np

from ...units import zeta_to_si
from . import BaseScenario


#: m/s: the plate has stopped (the impact is over) once it is slower than this in the sand.
STOPPED_SPEED = 1e-3


def expected_impact_depth(mass, area, zeta, drop_height, gravity=9.81):
    """Depth (m) at which a thin plate (kg, m^2, N/cm^3, m) dropped from drop_height stops."""
    k = zeta_to_si(zeta) * area
    weight = mass * gravity
    return (weight + np.sqrt(weight ** 2 + 2 * k * weight * drop_height)) / k


class Scenario(BaseScenario):
    constraint_rows = False  # (a free or driven body: no limits, equalities or contacts)

    def __init__(self, scene):
        super().__init__(scene)
        self.mass = self.number('mass', positive=True)
        self.side = self.number('side', positive=True)
        self.thickness = self.number('thickness', positive=True)
        self.drop_height = self.number('drop_height', minimum=0.0)
        self.ground = None  # m: the sand surface under the plate's centre at the start
        self.level = None  # whether the sand surface under the plate is level there

    def edit_model(self, spec):
        geom = spec.geom('plate_geom')
        geom.size = [self.side / 2, self.side / 2, self.thickness / 2]
        geom.mass = self.mass

    def initialize(self, sim):
        if self.ground is None:
            self.ground = float(sim.engine.surface.height(0.0, 0.0))
            half = self.side / 2
            low, high = sim.engine.surface.bounds(-half, half, -half, half)
            self.level = low == high
        qpos = sim.data.joint('plate_free').qpos
        qpos[:3] = (0.0, 0.0, self.ground + self.drop_height + self.thickness / 2)
        qpos[3:] = (1.0, 0.0, 0.0, 0.0)
        self.depths, self.speeds, self.zetas = [], [], []  # (a reset starts them afresh)

    def observe(self, sim):
        centre = sim.data.body('plate').xpos
        self.depths.append(self.ground - (centre[2] - self.thickness / 2))
        self.speeds.append(float(np.linalg.norm(sim.data.joint('plate_free').qvel[:3])))
        self.zetas.append(float(sim.engine.zeta_at(centre[0], centre[1])))

    def metrics(self, sim):
        depth = np.asarray(self.depths)
        speed = np.asarray(self.speeds)
        gravity = float(-sim.model.opt.gravity[2])
        touched = np.flatnonzero(depth > 0)
        rebound, impact = 0.0, int(np.argmax(depth))
        if touched.size:
            after = depth[touched[0]:]
            rebound = float(np.max(np.maximum.accumulate(after) - after))
            stopped = np.flatnonzero(speed[touched[0]:] < STOPPED_SPEED)  # the impact's end
            if stopped.size:
                impact = int(touched[0] + stopped[0])
        expected = (expected_impact_depth(self.mass, self.side ** 2, self.zetas[impact],
                                          self.drop_height, gravity)
                    if self.level and touched.size else None)
        tail = max(1, int(round(0.5 / sim.timestep)))
        return {
            'max_sinkage_m': float(depth.max()),
            'expected_max_sinkage_m': expected,
            'max_sinkage_error': None if expected is None else float(depth.max() / expected - 1.0),
            'final_sinkage_m': float(depth[-1]),
            'static_sinkage_m': float(self.mass * gravity
                                    / (zeta_to_si(self.zetas[-1]) * self.side ** 2)),
            'rebound_m': rebound,
            'settled_speed_mps': float(speed[-tail:].mean()),
        }
