"""plate_press: a thin horizontal plate driven straight down into sand at constant speed.

The vertical force on a horizontal plate pushed straight down is zeta A z (the definition
of zeta), so the fitted slope of force against depth must equal zeta A (SI: N/m). The plate
starts `start_height` above the sand surface under its centre (any surface shape), and its
depth is measured from that surface. Under a surface that is not level the plate's force
is zeta times the integral of its depth over its area, zeta A (mean surface height over the
plate - z) once it is wholly in: still zeta A per depth, so the fit takes the samples from
there on (and from a fifth of the deepest depth); a plate never wholly in has no
force_per_depth (None). The expected slope uses the zeta the plate met over the samples
fitted (`SandEngine.zeta_at` under its centre, a zeta map's factor included; their mean).
"""
import numpy as np

from ...units import zeta_to_si
from . import BaseScenario


class Scenario(BaseScenario):
    constraint_rows = False  # (a free or driven body: no limits, equalities or contacts)

    def __init__(self, scene):
        super().__init__(scene)
        self.side = self.number('side', positive=True)
        self.thickness = self.number('thickness', positive=True)
        self.speed = self.number('speed', positive=True)
        self.start_height = self.number('start_height', minimum=0.0)
        self.ground = None  # m: the sand surface under the plate's centre at the start
        self.wholly_in = None  # m: the depth from which the plate is wholly in the sand

    def edit_model(self, spec):
        spec.geom('plate_geom').size = [self.side / 2, self.side / 2, self.thickness / 2]
        spec.body('plate').pos = [0.0, 0.0, self.scene.surface_height + self.start_height
                                  + self.thickness / 2]

    def initialize(self, sim):
        if self.ground is None:
            self.ground = float(sim.engine.surface.height(0.0, 0.0))
            half = self.side / 2
            self.wholly_in = self.ground - sim.engine.surface.bounds(-half, half, -half, half)[0]
        press = sim.data.joint('press')  # (a vertical slide: from sand.surface_height)
        press.qpos[:] = self.ground - self.scene.surface_height
        press.qvel[:] = -self.speed
        self.depths, self.forces, self.lateral, self.zetas = [], [], [], []  # (after a reset
        # too: the run that follows is a fresh start's)

    def control(self, sim):
        sim.data.actuator('press').ctrl[:] = -self.speed

    def observe(self, sim):
        centre = sim.data.body('plate').xpos
        wrench = sim.engine.body_wrenches[0]
        self.depths.append(self.ground - (centre[2] - self.thickness / 2))
        self.forces.append(wrench[2])
        self.lateral.append(np.hypot(wrench[0], wrench[1]))
        self.zetas.append(float(sim.engine.zeta_at(centre[0], centre[1])))

    def metrics(self, sim):
        depth = np.asarray(self.depths)
        force = np.asarray(self.forces)
        inside = (depth > 0.2 * depth.max()) & (depth >= self.wholly_in)
        slope = float(np.polyfit(depth[inside], force[inside], 1)[0]) if inside.sum() > 2 else None
        zeta = np.mean(np.asarray(self.zetas)[inside]) if inside.any() else self.zetas[-1]
        expected = zeta_to_si(zeta) * self.side ** 2
        return {
            'force_per_sinkage_N_per_m': slope,
            'expected_force_per_sinkage_N_per_m': float(expected),
            'force_per_sinkage_error': None if slope is None else slope / expected - 1.0,
            'max_sinkage_m': float(depth.max()),
            'max_force_N': float(force.max()),
            'max_lateral_force_N': float(max(self.lateral)),
        }
