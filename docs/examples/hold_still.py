"""An own scenario, outside the package: hold the model's position servos where they start and
report how far the base sank. Use it from a scene file beside it with
`scenario: hold_still.py` (see docs/scene-reference.md, "Own scenarios")."""
import mujoco

from rft_sim_ros.scenes.scenarios import BaseScenario


class Scenario(BaseScenario):
    def initialize(self, sim):
        mujoco.mj_kinematics(sim.model, sim.data)  # body poses of the initial state
        self._start_height = float(sim.data.xpos[sim.model.body(sim.base_body).id, 2])

    def metrics(self, sim):
        height = float(sim.data.xpos[sim.model.body(sim.base_body).id, 2])
        return {'base_sink_m': self._start_height - height}
